"""Rigid couplings (eq. 2), static equilibrium (eq. 1) and the Jacobian (eq. 6-7) on a coarse tripod."""

import numpy as np
import pytest

from metasheet.errors import ConfigError, ConvergenceError
from metasheet.mechanics.material import Isotropic
from metasheet.robot.robots import grip_centre, ServoGeometry, tripod
from metasheet.robot.kinematics import kinematics_at
from metasheet.mechanics.rotations import rotation_matrix, rotation_vector
from metasheet.robot.equilibrium import solve_equilibrium
from metasheet.sheet.geometry import SheetParams, tripod_sheet


@pytest.fixture(scope="module")
def robot():
    sheet = tripod_sheet(SheetParams(mesh_size=15.0))
    return tripod(sheet, Isotropic(0.25, 0.45).stiffness(), density=1.07e-9)


@pytest.fixture(scope="module")
def rest(robot):
    return solve_equilibrium(robot, robot.coupling.rest_angles, tol=1e-12)


@pytest.mark.parametrize("seed", range(4))
def test_rotation_vector_round_trip(seed):
    rng = np.random.default_rng(seed)
    for t in (1e-9, 0.3, 2.0, np.pi - 1e-6):
        w = rng.normal(size=3)
        w *= t / np.linalg.norm(w)
        R = rotation_matrix(w)
        assert np.allclose(R @ R.T, np.eye(3), atol=1e-12) and np.isclose(np.linalg.det(R), 1.0)
        assert np.allclose(rotation_vector(R), w, atol=1e-6 if t > 3 else 1e-12)


def test_rigid_jacobian_and_geometric_term_match_finite_differences(robot, rest):
    c, st = robot.coupling, rest.state
    rng = np.random.default_rng(1)
    r = rng.normal(size=(robot.body.n_nodes, 3))  # arbitrary fixed nodal forces [N]
    J = c.rigid_jacobian(st.x, st.p)
    G = c.rigid_geometric(st.x, st.p, r)
    h = 1e-6

    def rigid_x(dq):
        p = st.p + dq[:3]
        R = rotation_matrix(dq[3:6]) @ st.R
        x = c.positions(p, R, st.angles + dq[6:], st.x[c.free])
        return x, p

    for j in range(c.n_rigid_dof):
        d = np.zeros(c.n_rigid_dof)
        d[j] = h
        xp, pp = rigid_x(d)
        xm, pm = rigid_x(-d)
        fd = (xp[c.rigid_nodes] - xm[c.rigid_nodes]).ravel() / (2 * h)
        assert np.allclose(J[:, j], fd, atol=1e-6 * np.abs(J).max())
        gfd = (c.rigid_jacobian(xp, pp).T @ r[c.rigid_nodes].ravel()
               - c.rigid_jacobian(xm, pm).T @ r[c.rigid_nodes].ravel()) / (2 * h)
        assert np.allclose(G[:, j], gfd, atol=1e-6 * np.abs(G).max())


def test_servo_convention_and_rest_geometry(robot):
    """Angle 0 = horizontal horn, 90 = vertical; the rest angle places the pivots behind the sheet."""
    servos = robot.coupling.servos
    assert np.allclose(np.degrees(robot.coupling.rest_angles), ServoGeometry().rest_angle, rtol=0, atol=1e-12)
    for k, s in enumerate(servos):
        tags = np.zeros(robot.body.n_nodes, dtype=int)
        tags[s.nodes] = 1
        tip = grip_centre(robot.coupling.rest, robot.body.tets, tags, 1)  # what places the pivot
        r_tip = np.hypot(*tip[:2])
        # pivot = tip - horn (-cos 60 u + sin 60 n): 12.5 mm further out, 21.65 mm below
        assert np.isclose(np.hypot(*s.pivot[:2]), r_tip + 25.0 * np.cos(np.radians(60.0)), atol=0.5)
        assert np.isclose(s.pivot[2], tip[2] - 25.0 * np.sin(np.radians(60.0)), atol=1e-9)
        assert np.isclose(np.linalg.norm(tip - s.pivot), 25.0)
        assert np.isclose(robot.info["servos"][k]["servo_radius_mm"], np.hypot(*s.pivot[:2]), atol=2e-3)
        for deg, expect_vertical in ((0.0, False), (90.0, True)):
            moved = robot.coupling.servo_positions(
                [np.radians(deg) if i == k else t.rest_angle for i, t in enumerate(servos)])
            x = robot.coupling.rest.copy()
            x[s.nodes] = moved[k]
            horn = grip_centre(x, robot.body.tets, tags, 1) - s.pivot
            if expect_vertical:
                assert np.isclose(horn[2], 25.0, atol=1e-9)
            else:
                assert abs(horn[2]) < 1e-9 and np.dot(horn[:2], s.pivot[:2]) < 0  # points inwards
    with pytest.raises(ConfigError, match="rest_angle"):
        ServoGeometry(rest_angle=95.0)  # outside the 0-90 stroke


def test_rest_angle_is_the_same_on_every_mesh():
    """The rest angle is a design parameter: coarse and fine meshes get the same rest angle,
    and (the sheet being meshed conforming to its grips) the same servo circle: the grip's
    centroid does not move with the mesh."""
    geo = ServoGeometry(rest_angle=50.0)
    radii = []
    for h in (10.0, 15.0, 20.0):
        rob = tripod(tripod_sheet(SheetParams(mesh_size=h)), Isotropic(0.25, 0.45).stiffness(), geometry=geo)
        assert np.allclose(np.degrees(rob.coupling.rest_angles), 50.0, rtol=0, atol=1e-12)
        radii.append(rob.info["servo_geometry"]["servo_radius_mm_derived"])
    assert np.ptp(radii) < 1e-9  # 62.25 mm tip (66 - 15 / 4) + 25 cos 50 deg


def test_gravity_sags_downwards_and_newton_converges(robot, rest):
    res = np.array(rest.residuals)
    assert res[-1] <= 1e-12 * rest.reference
    # chord steps included: 7 with the sphere-tied centre, 16 with the cylinder (chord steps
    # contracting by ~0.2 each); 37 before the step-projected line search
    assert rest.iterations <= 20
    assert rest.state.p[2] < -0.1  # the effector sinks [mm]
    assert abs(rest.state.p[0]) < 0.05 * abs(rest.state.p[2])
    dz = rest.state.x[robot.coupling.free, 2] - robot.coupling.rest[robot.coupling.free, 2]
    assert dz.mean() < 0
    # no gravity: the rest state is the equilibrium, with zero residual
    no_g = tripod(tripod_sheet(SheetParams(mesh_size=15.0)), Isotropic(0.25, 0.45).stiffness(),
                  gravity=(0.0, 0.0, 0.0))
    eq = solve_equilibrium(no_g, no_g.coupling.rest_angles)
    assert eq.iterations == 0 and np.allclose(eq.state.x, no_g.coupling.rest)


def fd_jacobian_error(robot, st, J, h: float) -> float:
    """Largest relative error [-] over the motors of the central difference of equilibria with
    step h [rad] against J (rotations compared as mm at 50 mm)."""
    scale = np.array([1, 1, 1, 50, 50, 50.0])
    errs = []
    for j in range(3):
        d = np.zeros(3)
        d[j] = h
        sp = solve_equilibrium(robot, st.angles + d, state=st, tol=1e-12).state
        sm = solve_equilibrium(robot, st.angles - d, state=st, tol=1e-12).state
        fd = np.concatenate([(sp.p - sm.p) / (2 * h), rotation_vector(sp.R @ sm.R.T) / (2 * h)])
        errs.append(np.abs(scale * (fd - J[:, j])).max() / np.abs(scale * J[:, j]).max())
    return max(errs)


def test_jacobian_matches_finite_differences_of_the_static_solution(robot, rest):
    assert fd_jacobian_error(robot, rest.state, kinematics_at(robot, rest.state).J, 1e-4) < 1e-3


def test_jacobian_matches_finite_differences_at_a_deformed_pose(robot, rest):
    """Away from rest (motors 8-15 deg off, gravity on: J differs from the rest one by as
    much as its own size) every configuration-dependent term of eq. (6) counts; a missing one
    leaves an error that does not shrink with the step.

    Central differences of equilibria err by ``h^2 q_e''' / 6`` plus the equilibria's
    round-off over ``h``. Measured: 8.5e-9 relative at h = 1e-4 rad and 3.4e-8 at 2e-4 (h^2,
    a truncation constant ~0.85), round-off ~5e-10 (the error levels off there for
    h <= 3e-5, equilibria solved to tol 1e-12, residuals ~4e-13 N). Asserted: below 1e-6 at
    h = 1e-4, a hundredfold margin, and falling as h^2 between 2h and h (a missing term
    would not).
    """
    moved = solve_equilibrium(robot, rest.state.angles + np.radians([12.0, -8.0, 15.0]),
                              state=rest.state, tol=1e-12)
    st = moved.state
    J = kinematics_at(robot, st).J
    assert np.abs(J - kinematics_at(robot, rest.state).J).max() > 0.2 * np.abs(J).max()

    def fd_error(h):
        return fd_jacobian_error(robot, st, J, h)

    h = 1e-4
    err, err2 = fd_error(h), fd_error(2 * h)
    assert err < 1e-6
    assert 3.0 < err2 / err < 5.0  # truncation, O(h^2): the analytic J has no missing term


def test_compliance_symmetric_positive_definite_and_eq7(robot, rest):
    lin = robot.linearizer().linearize(rest.state)
    kin = kinematics_at(robot, rest.state)
    W = kin.W
    assert np.abs(W - W.T).max() <= 1e-8 * np.abs(W).max()
    assert np.linalg.eigvalsh(0.5 * (W + W.T)).min() > 0
    S = lin.S
    J_direct = -np.linalg.solve(S[:6, :6], S[:6, 6:])
    assert np.allclose(kin.J, J_direct, rtol=1e-8, atol=1e-10 * np.abs(J_direct).max())
    # all three motors together: by the tripod's symmetry a translation along its axis
    v = kin.all_together
    assert abs(v[2]) > 0.3  # [mm/deg]
    assert np.linalg.norm(v[:2]) < 0.05 * abs(v[2])


def test_bad_input_and_nonconvergence_are_reported(robot, rest):
    with pytest.raises(ConfigError, match="angles"):
        solve_equilibrium(robot, [0.1, 0.2])
    with pytest.raises(ConvergenceError) as exc:
        solve_equilibrium(robot, rest.state.angles - np.radians(40), state=rest.state, max_iter=1,
                          max_angle_step=np.radians(40), tol=1e-14)
    assert len(exc.value.history) >= 2


def _quadratic_sheet_check(mesh_size: float, both_steps: bool = True) -> None:
    from metasheet.sheet.elements import as_element

    sheet = as_element(tripod_sheet(SheetParams(mesh_size=mesh_size)), "p2")
    rob = tripod(sheet, Isotropic(1.39, 0.26).stiffness(), density=1.8e-10)
    assert rob.body.element == "p2"
    rest = solve_equilibrium(rob, rob.coupling.rest_angles, tol=1e-12)
    st = solve_equilibrium(rob, rest.state.angles + np.radians([12.0, -8.0, 15.0]), state=rest.state,
                           tol=1e-12).state
    J = kinematics_at(rob, st).J
    err = fd_jacobian_error(rob, st, J, 1e-4)
    assert err < 1e-6
    if both_steps:
        err2 = fd_jacobian_error(rob, st, J, 2e-4)
        assert 3.0 < err2 / err < 5.0


@pytest.mark.slow
def test_quadratic_sheet_jacobian_matches_finite_differences_at_a_deformed_pose():
    """The same check on quadratic sheets: the P2 kernel's tangent inside the coupled robot.
    A foam-like sheet: the heavy silicone plate's gravity sag is a geometrically nonlinear
    plate problem whose Newton iterations creep (the flat plate's tangent has no membrane
    stress stiffening), which is not what this test is about.
    Default-selection sibling: test_quadratic_sheet_jacobian_on_coarse_sheets."""
    _quadratic_sheet_check(15.0)


def test_quadratic_sheet_jacobian_on_coarse_sheets():
    """The P2 check of the slow test above on 24 mm sheets (934 tets, not 1,178), one step:
    the same code path, the same tolerance (1e-6 relative at h = 1e-4; the P1 test above
    checks the O(h^2) fall between 2h and h in the default selection)."""
    _quadratic_sheet_check(24.0, both_steps=False)
