"""Penalty contact between voxel walls (metasheet/fem/voxel/contact.py) against exact answers: the
forces are the energy's gradient and the tangent the forces' derivative (central differences),
and two voxel bars pressed together across a gap whose closure is known by hand: each bar in
homogeneous uniaxial stress (exact for trilinear voxels), the neo-Hookean closed form, the
penalty's pairs in series."""

import numpy as np
import pytest
from scipy.optimize import brentq

from metasheet.errors import ConfigError
from metasheet.fem.voxel.contact import Contact, SurfacePairs
from metasheet.fem.voxel.hyperelastic import NeoHookean
from metasheet.fem.voxel.nonlinear import solve_hyperelastic

TPU = NeoHookean(12.0, 0.3)
L, GAP_VOXELS = 5, 3  # each bar's length and the void between them [voxels of 1 mm]
# the bars' 3 x 3 voxel section [mm]: pressed through frictionless contact, a bar buckles as a
# column of twice its length, at pi^2 (SECTION^2 / 12) / (2 L)^2 = 7.4 % strain (a 2 x 2 mm bar 10
# mm long: 0.8 %, and the solver found it bent, the lower energy)
SECTION = 3


def _pairs(contact=Contact(0.3, 50.0, 1.5)):
    """Two pairs of surface nodes 2 mm apart at rest, moved to within the gap (one pair
    oblique), and a fifth node far from all."""
    rest = np.array([[0, 0, 0], [2, 0, 0], [0, 5, 0], [2, 5, 0], [9, 9, 9]], float)
    u = np.array([[0.9, 0.02, -0.01], [-0.95, 0.05, 0.03], [0.88, 0.0, 0.1], [-0.9, -0.12, 0.0], [0, 0, 0]])
    return SurfacePairs(np.arange(5), rest, np.ones(5), contact), u


def test_the_forces_are_the_energys_gradient_and_the_tangent_their_derivative():
    sp, u = _pairs()
    f, e, crossed = sp.forces(u)
    assert crossed == 0 and len(sp.pairs) == 2 and e > 0
    assert np.allclose(f.sum(axis=0), 0.0, atol=1e-15) and not f[4].any()  # action = reaction
    eps = 1e-6
    for i in range(4):
        for k in range(3):
            d = np.zeros_like(u)
            d[i, k] = eps
            fd_e = (sp.forces(u + d)[1] - sp.forces(u - d)[1]) / (2 * eps)
            assert fd_e == pytest.approx(f[i, k], rel=1e-7, abs=1e-12)
    sp.forces(u)
    v = np.random.default_rng(3).standard_normal(u.shape)
    fd_t = (sp.forces(u + eps * v)[0] - sp.forces(u - eps * v)[0]) / (2 * eps)
    sp.forces(u)
    np.testing.assert_allclose(sp.tangent(v), fd_t, rtol=1e-6, atol=1e-9)


def test_nodes_that_were_neighbours_or_are_beyond_the_gap_do_not_push():
    sp, u = _pairs(Contact(0.3, 50.0, 2.5))  # the pairs were 2 mm apart: neighbours for this separation
    f, e, _ = sp.forces(u)
    assert e == 0.0 and not f.any() and not len(sp.pairs)
    sp, u = _pairs()
    f, e, _ = sp.forces(np.zeros_like(u))  # at rest: 2 mm apart, beyond the 0.3 mm gap
    assert e == 0.0 and not f.any()


def test_a_pair_met_past_itself_is_refused_and_one_pushed_past_pushes_back():
    sp, u = _pairs()
    assert sp.forces(1.5 * u)[2] == 2  # from rest straight through each other: both pairs refused
    sp.reset()
    e_near = sp.forces(0.5 * u)[1]  # approaching: 1.1 mm apart, within separation, met the right way
    f, e_past, crossed = sp.forces(1.5 * u)  # then carried 0.8 mm past each other: pushed back
    assert e_near == 0.0 and crossed == 0 and len(sp.pairs) == 2
    assert e_past > 0.5 * 50.0 * 1.0**2  # the overlap is the gap and more: (0.3 + 0.7)^2 k / 2 at least
    assert f[0, 0] > 0 > f[1, 0]  # the energy grows as a (now right of b) moves further right


def test_sliding_along_the_pair_costs_nothing():
    """Frictionless: a sideways slip of one node, across the pair's direction, leaves the energy."""
    sp, u = _pairs()
    sp.forces(u)
    m = sp._m[0]
    side = np.cross(m, [0.0, 0.0, 1.0])
    e0 = sp.forces(u)[1]
    slid = u.copy()
    slid[0] += 0.05 * side / np.linalg.norm(side)
    assert sp.forces(slid)[1] == pytest.approx(e0, rel=1e-12)


def _two_bars():
    """Bars A (x in [0, L]) and B (x in [L + GAP, 2 L + GAP]), 2 x 2 mm, across a void; A's end
    x = 0 and B's end x = 2 L + GAP slide on their planes (the lines y = 0, z = 0 hold them)."""
    nx = 2 * L + GAP_VOXELS
    phases = np.zeros((nx, SECTION, SECTION), np.int64)
    phases[:L] = 1
    phases[L + GAP_VOXELS:] = 1
    N = (nx + 1, SECTION + 1, SECTION + 1)
    fixed = np.zeros(N + (3,), bool)
    for end in (0, -1):
        fixed[end, :, :, 0] = True
        fixed[end, 0, :, 1] = True
        fixed[end, :, 0, 2] = True
    return phases, np.array([nx, SECTION, SECTION], float), N, fixed


def _uniaxial(stretch):
    """A bar's exact state in uniaxial stress: lateral stretch, first Piola stress P11 [MPa]."""
    def p22(l2):
        return TPU.mu * l2 + (TPU.lam * np.log(stretch * l2 * l2) - TPU.mu) / l2

    l2 = brentq(p22, 0.2, 2.0)
    return l2, TPU.mu * stretch + (TPU.lam * np.log(stretch * l2 * l2) - TPU.mu) / stretch


def _overlap(c: Contact, pressure: float) -> float:
    """The overlap [mm] at which the penalty carries ``pressure`` [MPa]: phi'(o) / area =
    s o^2 / (2 w) within the ramp w, s (o - w / 2) beyond (s the stiffness per unit area)."""
    s, w = c.stiffness, c.ramp
    return np.sqrt(2 * w * max(pressure, 0.0) / s) if pressure <= 0.5 * s * w else pressure / s + 0.5 * w


def test_the_penalty_grows_smoothly_from_the_gap():
    """phi, phi', phi'' continuous at o = 0 and at the ramp's end, phi' and phi'' its
    derivatives (central differences), and beyond the ramp the plain quadratic shifted by w / 2."""
    c = Contact(0.3, 50.0, 1.5, ramp=0.1)
    k = np.full(1, 2.0)

    def at(o):
        return [float(v[0]) for v in c.penalty(np.array([o]), k)]

    assert at(0.0) == [0.0, 0.0, 0.0]
    below, above = at(0.1 - 1e-12), at(0.1 + 1e-12)
    np.testing.assert_allclose(below, above, rtol=1e-9)
    eps = 1e-6
    for o in (0.03, 0.1, 0.25):
        e, f, t = at(o)
        assert (at(o + eps)[0] - at(o - eps)[0]) / (2 * eps) == pytest.approx(f, rel=1e-8)
        assert (at(o + eps)[1] - at(o - eps)[1]) / (2 * eps) == pytest.approx(t, rel=1e-5)  # phi''' jumps at w
    assert at(0.25)[1] == pytest.approx(2.0 * (0.25 - 0.05), rel=1e-14)
    assert at(0.25)[2] == 2.0 and at(0.05)[2] == pytest.approx(1.0)  # half the stiffness half way
    plain = Contact(0.3, 50.0, 1.5, ramp=0.0)
    assert [float(v[0]) for v in plain.penalty(np.array([0.2]), k)] == pytest.approx([0.04, 0.4, 2.0])


@pytest.mark.parametrize("push", [2.85, 3.2])
def test_two_bars_pressed_together_meet_the_hand_answer(push):
    """B's end pushed by ``push`` [mm] towards A: the 3 mm void closes to the penalty's gap less
    its give (the contact pressure over the stiffness: nine pairs whose areas spread it as a
    uniform stress's consistent nodal forces), and each bar is compressed to the stretch whose
    uniaxial stress carries that force (1 % and 4.4 % strain). 3.2 mm pushes B's face past where
    A's face was: one predictor step would carry the walls through each other, which the solver
    refuses."""
    phases, size, N, fixed = _two_bars()
    values = np.zeros(N + (3,))
    values[-1, :, :, 0] = -push
    c = Contact.default(1.0, TPU.E)
    sol = solve_hyperelastic(phases, size, TPU, prescribed=fixed, values=values, rtol=1e-10, contact=c)

    area = SECTION * SECTION

    def closure(stretch):  # the motion the bars and the pairs take up, less the push
        pressure = -_uniaxial(stretch)[1]  # compressive [MPa] (nominal: on the rest section)
        return (GAP_VOXELS - c.gap + _overlap(c, pressure) + 2 * L * (1 - stretch)) - push

    stretch = brentq(closure, 0.7, 1.0)
    force = -_uniaxial(stretch)[1] * area
    ends = sol.full(sol.forces)[:, :, :, 0]
    assert ends[0].sum() == pytest.approx(force, rel=1e-7)  # internal forces at the ends: A pressed left
    assert ends[-1].sum() == pytest.approx(-force, rel=1e-7)  # and B right
    assert sol.contact["pairs"] == (SECTION + 1) ** 2 and sol.stable
    assert sol.contact["force_N"] == pytest.approx(force, rel=1e-7)
    assert sol.contact["min_distance_mm"] == pytest.approx(c.gap - _overlap(c, force / area), rel=1e-7)
    l2 = _uniaxial(stretch)[0]  # the largest principal Green-Lagrange strain: the bars' lateral swelling
    np.testing.assert_allclose(sol.strain[phases > 0], (l2**2 - 1) / 2, rtol=1e-6)


def test_without_contact_the_walls_pass_through_each_other():
    phases, size, N, fixed = _two_bars()
    values = np.zeros(N + (3,))
    values[-1, :, :, 0] = -3.2
    sol = solve_hyperelastic(phases, size, TPU, prescribed=fixed, values=values, rtol=1e-10)
    assert sol.contact is None
    x = np.arange(N[0])[:, None, None] + sol.full(sol.u)[:, :, :, 0]
    assert (x[L + GAP_VOXELS] < x[L]).all()  # B's face is inside A: nothing stopped it


def test_contact_parameters_are_checked():
    with pytest.raises(ConfigError, match="contact.gap"):
        Contact(2.0, 1.0, 1.0)
    with pytest.raises(ConfigError, match="reach"):
        Contact(0.1, 1.0, 1.0, 2.0)
    with pytest.raises(ConfigError, match="contact.stiffness"):
        Contact(0.1, -1.0, 1.0)
    with pytest.raises(ConfigError, match="contact.ramp"):
        Contact(0.1, 1.0, 1.0, ramp=0.2)
    phases, size, N, fixed = _two_bars()
    with pytest.raises(ConfigError, match="contact"):
        solve_hyperelastic(phases, size, TPU, prescribed=fixed, values=np.zeros(N + (3,)), contact="yes")
