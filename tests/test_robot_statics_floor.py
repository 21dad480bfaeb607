"""solve_equilibrium stops at the round-off floor of the coupled residual (issue 14, item 6).

The light foam robot's force scale is ~0.05 N at rest, so ``tol = 1e-12`` asks for 5e-14 N,
below what the residual can resolve (it stalls near 2e-12 N): the solve must report where it
stopped instead of raising, and still raise when a step fails far above the floor.
"""

import numpy as np
import pytest

from metasheet.errors import ConvergenceError
from metasheet.robot.equilibrium import solve_equilibrium
from metasheet.robot.statics import Linearization, RobotState, residual_floor

MOVE_DEG = np.array([3.0, -2.0, 4.0, 1.0, -3.0, 2.0])  # a few degrees on each motor


@pytest.fixture(scope="module")
def robot(foam_robot_14):
    return foam_robot_14


@pytest.fixture(scope="module")
def rest(foam_rest_14):
    return foam_rest_14


def test_unreachable_tolerance_stops_at_the_floor(robot, rest):
    eq = solve_equilibrium(robot, robot.coupling.rest_angles, tol=1e-12)
    assert rest.reference < 0.1  # [N]: tol * reference ~ 5e-14 N, below round-off
    assert eq.at_floor
    assert eq.residual == eq.residuals[-1] <= eq.floor
    assert eq.residual > 1e-12 * eq.reference  # the tolerance itself was not met
    # it went on to round-off (~2e-12 N), not just under the (conservative) floor (~9e-11 N)
    assert eq.residual < 0.2 * eq.floor


def test_moved_motors_with_tight_tolerance(robot, rest):
    angles = rest.state.angles + np.radians(MOVE_DEG)
    eq = solve_equilibrium(robot, angles, state=rest.state, tol=1e-13)
    assert eq.at_floor and eq.residual <= eq.floor
    assert eq.iterations <= 30  # stalls are recognised, not iterated to max_iter
    assert np.allclose(eq.state.angles, angles, rtol=0, atol=1e-14)
    # a reachable tolerance is met as such, not excused by the floor
    loose = solve_equilibrium(robot, angles, state=rest.state, tol=1e-8)
    assert not loose.at_floor and loose.residual <= 1e-8 * loose.reference


def test_floor_bounds_the_round_off_of_the_residual(robot, rest):
    """One-ulp changes of the free positions move the residual by less than the floor,
    and the floor is not so loose that it would excuse real errors."""
    eq = solve_equilibrium(robot, robot.coupling.rest_angles, tol=1e-12)
    c, st = robot.coupling, eq.state
    lz = robot.linearizer()
    lin = lz.linearize(st)
    floor = residual_floor(robot, lin)
    rng = np.random.default_rng(0)
    spread = []
    for _ in range(5):
        x = st.x.copy()
        x[c.free] = np.nextafter(x[c.free], x[c.free] + rng.choice([-1.0, 1.0], size=x[c.free].shape))
        spread.append(lz.update(lin, RobotState(st.p, st.R, st.angles, x)).residual_norm)
    assert max(spread) <= floor
    assert floor <= 1e3 * max(spread)


def test_genuine_failures_above_the_floor_still_raise(robot, rest, monkeypatch):
    # too few iterations for a big motion
    with pytest.raises(ConvergenceError, match="no convergence") as exc:
        solve_equilibrium(robot, rest.state.angles - np.radians(40), state=rest.state, max_iter=1,
                          max_angle_step=np.radians(40), tol=1e-14)
    assert exc.value.history[-1] > 1.0  # [N]
    # a line search that cannot descend (the step reversed) fails above the floor and says so
    step = Linearization.newton_step
    monkeypatch.setattr(Linearization, "newton_step",
                        lambda self, dq_a=None: tuple(-v for v in step(self, dq_a)))
    with pytest.raises(ConvergenceError, match="line search failed.*above the round-off floor") as exc:
        solve_equilibrium(robot, rest.state.angles + np.radians(MOVE_DEG), state=rest.state, tol=1e-8)
    assert exc.value.history[-1] > 1e3 * robot.body.force_floor


def test_a_cut_that_repeats_the_failed_solve_is_skipped(monkeypatch):
    """A motion shorter than the halved step takes the same single increment: retrying it would
    repeat the failed solve exactly. Each distinct increment count is tried once, and the last
    error is raised."""
    from types import SimpleNamespace

    from metasheet.robot import equilibrium as eqm

    steps = []

    def failing(robot, angles, *, state=None, max_angle_step, **kw):
        steps.append(round(float(np.degrees(max_angle_step)), 6))
        raise ConvergenceError(f"attempt {len(steps)}", [1.0])

    monkeypatch.setattr(eqm, "solve_increments", failing)
    fake = SimpleNamespace(coupling=SimpleNamespace(n_act=2, rest_angles=np.zeros(2)))
    with pytest.raises(ConvergenceError, match="attempt 3"):
        eqm.solve_equilibrium(fake, np.radians([5.0, -1.0]))  # 10 deg steps, 3 cuts: 1, 1, 2, 4 increments
    assert steps == [10.0, 2.5, 1.25]
    steps.clear()
    with pytest.raises(ConvergenceError, match="attempt 1"):
        eqm.solve_equilibrium(fake, np.zeros(2))  # no motion: one increment however it is cut
    assert steps == [10.0]
    with pytest.raises(Exception, match="angles: shape"):
        eqm.solve_equilibrium(fake, np.zeros(3))
