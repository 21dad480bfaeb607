"""Real-time linear algebra of the robot: solver choice, exact solves, and the kept-tangent loop.

Accuracy is checked against independent answers: a dense solve, a SuperLU linearisation, and
the converged equilibrium at the loop's motor angles. Speed is measured in benchmarks/.
"""

import numpy as np
import pytest
import scipy.sparse as sp

from metasheet.errors import ConfigError
from metasheet.mechanics.material import Isotropic
from metasheet.published.paper import PAPER_FOAM
from metasheet.robot.builder import SheetPair, six_dof_robot
from metasheet.robot.robots import tripod
from metasheet.robot.inverse import InverseController, InverseSettings
from metasheet.robot.kinematics import kinematics
from metasheet.fem.factor import SparseSolver, resolve
from metasheet.fem.solvers import available
from metasheet.mechanics.rotations import rotation_matrix, rotation_vector
from metasheet.robot.statics import Linearizer
from metasheet.robot.equilibrium import solve_equilibrium
from metasheet.sheet.geometry import SheetParams, tripod_sheet

# CHOLMOD needs a system library (apt): these run in .ci/run's second phase (``-m system``)
needs_cholmod = [pytest.mark.system,
                 pytest.mark.skipif(not available("cholmod"), reason="scikit-sparse (CHOLMOD) not installed")]


def _spd(n, asym, seed):
    """A sparse SPD-dominated matrix (1D Laplacian + diagonal) with a skew part of size ``asym``."""
    rng = np.random.default_rng(seed)
    main = 2.5 + rng.uniform(0, 1, n)
    off = -np.ones(n - 1)
    skew = asym * rng.uniform(-1, 1, n - 1)
    return sp.diags([off - skew, main, off + skew], [-1, 0, 1], format="csr")


@pytest.mark.parametrize("name", ["superlu", pytest.param("cholmod", marks=needs_cholmod)])
@pytest.mark.parametrize("asym", [0.0, 1e-3, 0.05])
def test_exact_solve_matches_dense(name, asym):
    A = _spd(300, asym, seed=3)
    b = np.random.default_rng(1).normal(size=(300, 5))
    s = SparseSolver(name)
    y, fac = s.solve_exact(s.factorize(A), A, b)
    ref = np.linalg.solve(A.toarray(), b)
    assert np.allclose(y, ref, rtol=0, atol=1e-9 * np.abs(ref).max())
    assert fac.name in ("cholmod", "superlu")


@needs_cholmod[0]
@needs_cholmod[1]
def test_cholmod_falls_back_to_superlu_when_refinement_cannot_converge():
    A = _spd(200, 2.0, seed=0)  # skew part as large as the symmetric one: M^-1 A is far from I
    b = np.ones(200)
    s = SparseSolver("cholmod", max_refine=3)
    y, fac = s.solve_exact(s.factorize(A), A, b)
    assert np.allclose(A @ y, b, atol=1e-9)
    assert fac.name == "superlu" and s.stats["fallbacks"] >= 1


def test_bad_solver_name_is_a_config_error():
    with pytest.raises(ConfigError, match="linear_solver"):
        resolve("umfpack")
    with pytest.raises(ConfigError, match="linear_solver"):
        InverseSettings(linear_solver="mumps")
    with pytest.raises(ConfigError, match="refresh_angle_deg"):
        InverseSettings(refresh_angle_deg=0.0)


@pytest.fixture(scope="module")
def foam_robot():
    rob = six_dof_robot(SheetPair.spiral(SheetParams(mesh_size=15.0)), PAPER_FOAM, density=1.1e-9)
    rest = solve_equilibrium(rob, rob.coupling.rest_angles).state
    moved = solve_equilibrium(rob, rest.angles + np.radians([8, -4, 6, 2, -8, 4]), state=rest).state
    return rob, rest, moved


@pytest.mark.parametrize("name", ["superlu", pytest.param("cholmod", marks=needs_cholmod)])
def test_exact_linearisation_is_solver_independent(foam_robot, name):
    """On the deformed, non-symmetric anisotropic tangent both solvers give the same Jacobian."""
    rob, _, moved = foam_robot
    ref = kinematics(Linearizer(rob, "superlu").linearize(moved))
    lin = Linearizer(rob, name).linearize(moved)
    assert lin.exact
    kin = kinematics(lin)
    assert np.allclose(kin.J, ref.J, rtol=0, atol=1e-7 * np.abs(ref.J).max())


def test_kept_tangent_loop_stays_at_equilibrium_and_refreshes(foam_robot):
    """The kept-tangent loop tracks a moving goal as well as the fresh one, with fewer refreshes."""
    rob, rest, _ = foam_robot
    out = {}
    for label, kw in (("fresh", dict(refactor_every=1)), ("kept", dict())):
        ctl = InverseController(rob, rest, InverseSettings(max_step_deg=2.0, **kw))
        for k in range(16):
            a = 2 * np.pi * k / 16
            info = ctl.step(np.array([0.0, 2 * np.cos(a), 2 * np.sin(a)]), rotation_matrix([0.03 * np.sin(a), 0, 0]))
            assert np.all(ctl.state.angles >= rob.angle_min - 1e-12)
            assert np.all(ctl.state.angles <= rob.angle_max + 1e-12)
        eq = solve_equilibrium(rob, ctl.state.angles, state=ctl.state).state
        out[label] = (ctl, np.linalg.norm(eq.p - ctl.state.p), eq.pose)
        assert info.residual >= 0.0
    fresh, kept = out["fresh"], out["kept"]
    assert fresh[0].refreshes == 16
    assert kept[0].refreshes < 16  # the tangent was kept at least once...
    assert kept[1] <= 0.5 * InverseSettings().pos_tol  # ...without leaving the equilibrium
    # both loops followed the same goals: their converged poses agree to a fraction of a mm
    assert np.linalg.norm(kept[2][:3] - fresh[2][:3]) < 0.3


def test_state_set_from_outside_forces_a_fresh_linearisation(foam_robot):
    rob, rest, moved = foam_robot
    ctl = InverseController(rob, rest, InverseSettings())
    assert ctl.step(rest.p, rest.R).fresh
    assert not ctl.step(rest.p, rest.R).fresh  # kept: nothing moved
    ctl.state = moved
    assert ctl.step(rest.p, rest.R).fresh


def test_another_user_of_the_shared_linearizer_forces_a_fresh_linearisation(foam_robot):
    """The kept tangent's factor is the linearizer's: a refactorisation by another user (the
    kinematics, an equilibrium solve) is seen through the linearizer's factorisation count."""
    rob, rest, _ = foam_robot
    ctl = InverseController(rob, rest, InverseSettings())
    assert ctl.step(rest.p, rest.R).fresh
    assert not ctl.step(rest.p, rest.R).fresh  # kept: nothing moved
    ctl.linearizer.linearize(ctl.state)  # e.g. the Jacobian at this point: K_ff refactorised
    assert ctl.step(rest.p, rest.R).fresh
    assert ctl.refreshes == 2 and not ctl.refresh_reasons  # not counted as a dropped tangent


def test_isotropic_tripod_reaches_with_cholmod_or_superlu():
    rob = tripod(tripod_sheet(SheetParams(mesh_size=15.0)), Isotropic(0.25, 0.45).stiffness(), density=1.07e-9)
    rest = solve_equilibrium(rob, rob.coupling.rest_angles).state
    target = solve_equilibrium(rob, rest.angles + np.radians([-5.0, -2.0, -8.0]), state=rest).state
    goal = np.concatenate([target.p, np.degrees(target.pose[3:])])
    for name in ["superlu"] + (["cholmod"] if available("cholmod") else []):
        res = InverseController(rob, rest, InverseSettings(pos_tol=0.02, rot_tol_deg=0.05, linear_solver=name)).goto(goal)
        assert res.status == "reached", (name, res.to_dict())
        assert np.allclose(res.angles_deg, np.degrees(target.angles), atol=0.5)


def test_rigid_forces_equal_the_jacobian_transpose(foam_robot):
    """The chord update's generalised forces equal J_r^T r computed with the explicit Jacobian."""
    from metasheet.robot.statics import rigid_forces

    rob, _, moved = foam_robot
    c = rob.coupling
    r = np.random.default_rng(4).normal(size=moved.x.shape)
    ref = c.rigid_jacobian(moved.x, moved.p).T @ r[c.rigid_nodes].ravel()
    assert np.allclose(rigid_forces(c, moved.x, moved.p, r), ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())


def test_certified_pose_is_an_equilibrium_and_continuation_keeps_the_tangent(foam_robot):
    """goto's reported pose is certified by the loop's own corrections: its residual is within
    eq_tol, and it matches an independent 1e-10 Newton solve at the same motor angles."""
    from dataclasses import replace

    rob, rest, _ = foam_robot
    s = InverseSettings(pos_tol=0.05, rot_tol_deg=0.1)
    ctl = InverseController(rob, rest, s)
    targets = [solve_equilibrium(rob, rest.angles + np.radians(d), state=rest).state
               for d in ([3, -2, 1, 0, -3, 2], [5, -3, 2, 1, -5, 3])]
    goals = [np.concatenate([t.p, np.degrees(t.pose[3:])]) for t in targets]
    r1 = ctl.goto(goals[0])
    assert r1.status == "reached", r1.to_dict()
    assert r1.certified in ("chord", "newton") and r1.residual <= s.eq_tol * r1.reference
    ref = solve_equilibrium(rob, r1.state.angles, state=r1.state, tol=1e-10).state
    assert np.linalg.norm(ref.p - r1.state.p) < 1e-4  # [mm] (the one-Newton-step state is ~3e-3 off)
    assert np.linalg.norm(rotation_vector(ref.R @ r1.state.R.T)) < 1e-5  # [rad]
    assert np.isclose(r1.pos_error, np.linalg.norm(goals[0][:3] - r1.pose[:3]))
    # continuation from our own result: no fresh linearisation forced...
    assert ctl.owns(r1.state)
    ctl.state = r1.state
    assert not ctl.step(r1.state.p, r1.state.R).fresh
    # ...but an equal state built outside the controller is not trusted
    ctl.state = replace(r1.state)
    assert ctl.step(r1.state.p, r1.state.R).fresh
    r2 = ctl.goto(goals[1], state=r1.state)
    assert r2.status == "reached" and r2.residual <= s.eq_tol * r2.reference
    assert np.allclose(r2.angles_deg, np.degrees(targets[1].angles), atol=0.5)


def test_certify_falls_back_to_newton_and_states_its_residual(foam_robot):
    rob, rest, moved = foam_robot
    s = InverseSettings(polish_iters=0, eq_tol=1e-7)
    ctl = InverseController(rob, rest, s)
    # a state off equilibrium: the motors moved, nothing else (a large residual)
    from metasheet.robot.statics import RobotState

    ctl.state = RobotState(rest.p, rest.R, moved.angles, rob.coupling.positions(rest.p, rest.R, moved.angles,
                                                                                rest.x[rob.coupling.free]))
    st, res, ref, how = ctl.certify(start=rest)
    assert how == "newton" and res <= 1e-7 * ref
    assert np.linalg.norm(st.p - moved.p) < 1e-4  # the same equilibrium as an independent solve
    with pytest.raises(ConfigError, match="eq_tol"):
        InverseSettings(eq_tol=0.0)
