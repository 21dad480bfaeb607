"""The printed sheet's limits from its walls at first order (metasheet/sheet/wall_limits.py):
strains of affine fields exactly, the travel to contact on a two-wall toy by hand and by the
deformed surfaces' own closest approach (metasheet/fem/voxel/gaps.py, a second method), and the
linear printed robot's grip motions per motor in equilibrium (metasheet/robot/condensed.py)."""

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.fem.voxel.gaps import closest_approach
from metasheet.mechanics.material import Isotropic
from metasheet.published import paper
from metasheet.robot.builder import SheetPair, six_dof_robot
from metasheet.robot.condensed import grip_motions_per_motor, robot_grip_maps
from metasheet.robot.kinematics import kinematics_from_schur
from metasheet.robot.condensed import condensed_robot_S
from metasheet.sheet.dns import grip_labels
from metasheet.sheet.grips import grip_references
from metasheet.sheet.outline import SheetParams
from metasheet.sheet.printed_foam import tripod_region
from metasheet.sheet.voxel_grips import held_solid, rigid_bodies_stiffness
from metasheet.sheet.wall_limits import (SheetWalls, contact_travel, principal_range, travel_to_strain,
                                         voxel_strains, wall_pairs)
from metasheet.cells.foam import voxel_centres

SMALL = SheetParams(arm_width=10.0, reach=20.0, thickness=2.0, hole_radius=1.0, fillet_radius=1.0,
                    tip_box=(5.0, 15.0, 10.0), centre_radius=3.0, mesh_size=5.0)


def _nodes(shape, h):
    N = tuple(n + 1 for n in shape)
    return np.stack(np.meshgrid(*[np.arange(n) * hh for n, hh in zip(N, h)], indexing="ij"), -1)


def test_strains_of_an_affine_field_are_exact():
    h = np.array([0.3, 0.2, 0.25])
    X = _nodes((4, 5, 3), h)
    A = np.array([[0.01, 0.004, -0.002], [0.0, -0.003, 0.006], [0.005, 0.001, 0.002]])
    E = voxel_strains(X @ A.T, h)
    assert E.shape == (4, 5, 3, 3, 3)
    assert np.allclose(E, 0.5 * (A + A.T), atol=1e-15)
    # a pure shear gamma: principal strains +-gamma/2, the travel to 0.3 the same either way
    S = np.zeros((3, 3))
    S[0, 1] = 0.02
    solid = np.ones((4, 5, 3), bool)
    assert principal_range(X @ S.T, h, solid) == pytest.approx((0.01, -0.01), abs=1e-15)
    assert travel_to_strain(X @ S.T, h, solid, 0.3) == pytest.approx((30.0, 30.0))
    # a uniaxial stretch: nothing stretches backward ... until the travel turns it into compression
    T = np.diag([0.01, 0.0, 0.0])
    fwd, back = travel_to_strain(X @ T.T, h, solid, 0.3)
    assert fwd == pytest.approx(30.0) and back == np.inf
    with pytest.raises(ConfigError, match="limit"):
        travel_to_strain(X @ T.T, h, solid, 0.0)


def _two_walls(gap: int = 4):
    """Two walls 2 voxels thick across x, ``gap`` voxels of void between them; the right wall moves
    left by 1 mm per unit travel, the left one stays."""
    h = np.array([0.25, 0.25, 0.25])
    solid = np.zeros((4 + gap, 3, 3), bool)
    solid[:2] = True
    solid[2 + gap:] = True
    X = _nodes(solid.shape, h)
    u = np.zeros_like(X)
    u[X[..., 0] >= (2 + gap) * h[0] - 1e-12, 0] = -1.0
    return solid, h, u


def test_contact_travel_on_two_walls_is_the_gap_less_the_touch():
    solid, h, u = _two_walls()
    pairs = wall_pairs(solid, h, radius=1.5)
    t, k = contact_travel(pairs, u)
    g, touch = 4 * 0.25, 0.25 * 0.25
    assert t == pytest.approx(g - touch, rel=1e-14)  # by hand: the faces approach at 1 mm per unit
    assert np.isclose(np.linalg.norm(pairs.X[k]), g)
    # the deformed surfaces' own closest approach (a KD-tree on the moved nodes) agrees
    before = closest_approach(solid, h, (t - 1e-6) * u, reach=0.25)
    after = closest_approach(solid, h, (t + 1e-6) * u, reach=0.25)
    assert not before.closed and after.closed
    assert before.distance == pytest.approx(touch, abs=2e-6)
    # moving apart, or a rigid motion of both walls, never closes the gap
    assert contact_travel(pairs, -u) == (np.inf, -1)
    assert contact_travel(pairs, np.broadcast_to([0.3, -0.2, 0.1], u.shape)) == (np.inf, -1)


def test_wall_pairs_refuse_a_radius_below_the_separation():
    solid, h, _ = _two_walls()
    with pytest.raises(ConfigError, match="radius"):
        wall_pairs(solid, h, radius=0.4)


@pytest.fixture(scope="module")
def small_printed():
    """The small tripod in solid TPU at 1 mm voxels, its 24 unit grip fields, and its robot."""
    reg = tripod_region(SMALL)
    ext = reg.hi - reg.lo
    shape = tuple(int(v) for v in np.maximum(1, np.round(ext / 1.0)))
    phases = reg.inside(reg.lo + voxel_centres(ext, np.array(shape))).reshape(shape).astype(np.int64)
    h = ext / np.array(shape)
    bodies = grip_labels(shape, reg.lo, h, SMALL)
    refs = grip_references(SMALL)
    r = rigid_bodies_stiffness(phases, ext, {1: Isotropic(12.0, 0.3).stiffness()}, bodies=bodies,
                               references=refs - reg.lo, rtol=1e-10, displacements=True)
    robot = six_dof_robot(SheetPair.spiral(SMALL), paper.PAPER_FOAM, density=paper.FOAM_DENSITY,
                          gravity=(0.0, 0.0, 0.0))
    walls = SheetWalls(held_solid(phases > 0, bodies > 0), h, r.U)
    return walls, r.K, robot, refs


def test_unit_grip_fields_add_up_to_rigid_motions(small_printed):
    walls, K, _, refs = small_printed
    on = np.zeros(walls.U.shape[:3], bool)  # the nodes of the held solid
    for o in np.ndindex(2, 2, 2):
        on[o[0]:o[0] + walls.solid.shape[0], o[1]:o[1] + walls.solid.shape[1],
           o[2]:o[2] + walls.solid.shape[2]] |= walls.solid
    for c in range(3):  # every grip translated alike: the whole sheet translates
        q = np.zeros(24)
        q[c::6] = 1.0
        u = walls.field(q)[on]
        assert np.abs(u - np.eye(3)[c]).max() < 1e-8
        assert principal_range(walls.field(q), walls.h, walls.solid)[0] < 1e-8


def test_grip_motions_per_motor_hold_the_rod_in_equilibrium(small_printed):
    walls, K, robot, refs = small_printed
    Ga, Gb, J = grip_motions_per_motor(K, K, robot, refs)
    S = condensed_robot_S(K, K, robot, refs)
    assert np.allclose(J, kinematics_from_schur(S).J, rtol=1e-9, atol=1e-12 * np.abs(J).max())
    Ea, Eb = robot_grip_maps(robot, refs)
    rod = (Ea.T @ K @ Ga + Eb.T @ K @ Gb)[:6]  # the two centre grips' wrench on the rod
    assert np.abs(rod).max() <= 1e-9 * np.abs(Ea.T @ K @ Ga).max()
    fields = walls.per_motor(Ga)
    d = np.array([1.0, -0.5, 0.25, 0, 0, 0])
    assert np.allclose(np.einsum("...im,m->...i", fields, d), walls.field(Ga @ d), atol=1e-14)


def test_first_contact_steps_to_the_same_travel_as_the_all_pairs_search():
    from metasheet.sheet.wall_limits import first_contact

    solid, h, u = _two_walls(gap=6)
    want, _ = contact_travel(wall_pairs(solid, h, radius=2.0), u)
    for steps in (None, 1, 7):
        t, (a, b) = first_contact(solid, h, u, 3.0, steps=steps)
        assert t == pytest.approx(want, rel=1e-12)
    assert first_contact(solid, h, u, 0.9 * want)[0] == np.inf  # not within the travel asked
    assert first_contact(solid, h, -u, 3.0)[0] == np.inf
    # head-on at twice a node's speed, the reach's worst case: the faces (6 voxels apart) touch at
    # (1.5 - touch) / 2 = 0.71875, in the last 5 % of the first of three steps of 0.75, where
    # only the full reach (touch plus a node's largest motion in a step) holds them at the middle
    u2 = u.copy()
    u2[_nodes(solid.shape, h)[..., 0] <= 2 * h[0] + 1e-12, 0] = 1.0
    t, _ = first_contact(solid, h, u2, 2.25, steps=3)
    assert t == pytest.approx((6 * 0.25 - 0.25 * 0.25) / 2, rel=1e-12)


def test_first_contact_on_a_rough_field_is_the_all_pairs_first_contact():
    """A random porous block, its halves moving head-on with every node wobbling besides (pairs far
    apart at rest close, neighbours pass each other): the stepped search finds the exact first contact
    of all the pairs that can close within the travel, found by :func:`wall_pairs` with a radius no
    pair beyond can cover (touch plus twice the fastest node's travel)."""
    from metasheet.sheet.wall_limits import first_contact

    rng = np.random.default_rng(7)
    h = np.array([0.25, 0.25, 0.25])
    for trial in range(3):
        solid = rng.random((9, 8, 5)) < 0.45
        X = _nodes(solid.shape, h)
        # the two halves head-on (pairs close at twice a node's speed, the reach's worst case), every
        # node with its own wobble besides
        u = 0.2 * rng.normal(size=X.shape)
        u[..., 0] += np.where(X[..., 0] < 0.5 * X[..., 0].max(), 1.0, -1.0)
        t_max = 0.4
        speed = np.sqrt((u.reshape(-1, 3) ** 2).sum(1)).max()
        pairs = wall_pairs(solid, h, radius=0.25 * 0.25 + 2 * speed * t_max + 1e-9)
        want, _ = contact_travel(pairs, u)
        assert want < t_max  # the search has something to find
        for steps in (None, 1, 5, 23):
            t, (a, b) = first_contact(solid, h, u, t_max, steps=steps)
            assert t == pytest.approx(want, rel=1e-9), (trial, steps)
            Xn, un = _nodes(solid.shape, h).reshape(-1, 3), u.reshape(-1, 3)
            assert np.linalg.norm(Xn[a] - Xn[b]) >= 2 * 0.25 - 1e-12  # a gap was open at rest
            assert np.linalg.norm(Xn[a] - Xn[b] + t * (un[a] - un[b])) == pytest.approx(0.25 * 0.25, rel=1e-9)


def test_principal_extremes_are_those_of_every_matrix():
    """The Gershgorin pre-selection gives exactly eigvalsh's extremes over all the matrices: random
    scales, zeros, ties, a single matrix."""
    from metasheet.sheet.wall_limits import principal_extremes

    rng = np.random.default_rng(3)
    for trial in range(12):
        n = int(rng.integers(1, 3000))
        A = rng.normal(size=(n, 3, 3)) * 10.0 ** rng.uniform(-8, 2)
        E = 0.5 * (A + np.swapaxes(A, 1, 2))
        if trial % 3 == 0:
            E[:, 0, 1] = E[:, 1, 0] = 0.0
        if trial % 4 == 0:
            E[: n // 2] = E[0]  # ties
        ev = np.linalg.eigvalsh(E)
        assert principal_extremes(E) == (ev[:, -1].max(), ev[:, 0].min())
    with pytest.raises(ConfigError, match="solid"):
        principal_extremes(np.zeros((0, 3, 3)))


def test_motor_walls_search_as_the_grid_fields_do():
    """:class:`MotorWalls` (the six motor fields at the surface nodes and solid voxels, each
    direction their sum) finds the contact, the strain travel and the rates of the grid's field
    along each direction (:func:`first_contact`, :func:`travel_to_strain`, :func:`principal_range`)
    on a porous block with random unit grip fields."""
    from metasheet.sheet.wall_limits import MotorWalls, first_contact

    rng = np.random.default_rng(11)
    h = np.array([0.25, 0.25, 0.25])
    solid = rng.random((10, 9, 5)) < 0.45
    U = 0.05 * rng.normal(size=tuple(n + 1 for n in solid.shape) + (3, 24))
    G = rng.normal(size=(24, 6))
    walls = SheetWalls(solid, h, U)
    motors = MotorWalls.from_fields(walls, G)
    F = walls.per_motor(G)
    for k in range(6):
        hi, lo = principal_range(F[..., k], h, solid)
        assert motors.rates()[k] == [max(hi, 0.0), max(-lo, 0.0)]
    found = 0
    for d in ([1, 0, 0, 0, 0, 0], [1, 1, 1, -1, -1, -1], rng.uniform(-1, 1, 6)):
        field = np.einsum("...im,m->...i", F, np.asarray(d, float))
        t, pair = motors.contact(d, 2.0)
        want_t, want_pair = first_contact(solid, h, field, 2.0)
        assert t == pytest.approx(want_t, rel=1e-12) and pair == want_pair
        found += np.isfinite(t)
        assert motors.strain_travel(d, 0.3) == pytest.approx(travel_to_strain(field, h, solid, 0.3)[0], rel=1e-12)
    assert found  # a contact to compare
    with pytest.raises(ConfigError, match="limit"):
        motors.strain_travel(np.ones(6), 0.0)
