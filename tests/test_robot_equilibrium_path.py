"""solve_increments along a path: loose intermediate increments, and a linearisation carried
from one solve to the next."""

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.robot.equilibrium import PATH_TOL, solve_increments

MOVE_DEG = np.array([6.0, -4.0, 8.0, 2.0, -6.0, 4.0])




def _pose_gap(a, b) -> float:
    """Largest node distance between two states [mm]."""
    return float(np.abs(a.x - b.x).max())


def test_intermediate_increments_are_converged_to_the_path_tolerance_only(foam_robot_14, foam_rest_14):
    target = foam_rest_14.state.angles + np.radians(MOVE_DEG)
    step = np.radians(2.0)  # four increments
    loose = solve_increments(foam_robot_14, target, state=foam_rest_14.state, max_angle_step=step)
    tight = solve_increments(foam_robot_14, target, state=foam_rest_14.state, max_angle_step=step, path_tol=1e-8)
    for eq in (loose, tight):
        assert eq.residual <= 1e-8 * eq.reference and not eq.at_floor  # the end meets tol
    assert loose.iterations < tight.iterations
    # the same equilibrium: both ends are within 1e-8 of the force scale of it
    assert _pose_gap(loose.state, tight.state) < 1e-5
    assert np.allclose(loose.state.pose, tight.state.pose, rtol=0, atol=1e-6)
    # an intermediate increment stopped once below PATH_TOL, not at 1e-8
    h = np.asarray(loose.residuals) / loose.reference
    assert np.any((h > 1e-8) & (h <= PATH_TOL))
    with pytest.raises(ConfigError, match="path_tol"):
        solve_increments(foam_robot_14, target, state=foam_rest_14.state, path_tol=0.0)


def test_a_solve_starts_on_the_linearisation_the_last_one_ended_on(foam_robot_14, foam_rest_14):
    lz = foam_robot_14.linearizer()
    a = foam_rest_14.state.angles + np.radians(0.5 * MOVE_DEG)
    b = foam_rest_14.state.angles + np.radians(MOVE_DEG)
    first = solve_increments(foam_robot_14, a, state=foam_rest_14.state, linearizer=lz)
    assert first.linearization is not None and first.linearization.state is first.state
    n0 = lz.factorizations
    fresh = solve_increments(foam_robot_14, b, state=first.state, linearizer=lz)
    n_fresh = lz.factorizations - n0
    n0 = lz.factorizations
    carried = solve_increments(foam_robot_14, b, state=first.state, linearizer=lz, start=first.linearization)
    n_carried = lz.factorizations - n0
    assert n_carried == n_fresh - 1  # the predictor's factorisation saved
    assert carried.residual <= 1e-8 * carried.reference
    assert _pose_gap(carried.state, fresh.state) < 1e-5
    # a linearisation taken at another state is not used
    n0 = lz.factorizations
    other = solve_increments(foam_robot_14, b, state=first.state, linearizer=lz, start=foam_rest_14.linearization)
    assert lz.factorizations - n0 == n_fresh
    assert _pose_gap(other.state, fresh.state) < 1e-9


def test_a_study_ramp_carries_the_linearisation_and_loosens_its_intermediate_steps():
    """FemRobot.equilibrium: a ramp's next step from the state the last one returned starts on
    its linearisation (one factorisation fewer); ``intermediate`` steps meet PATH_TOL only;
    the ramp ends where a single solve from rest ends."""
    from metasheet.studies.adapter import paper_robot_spec

    model = paper_robot_spec(mesh_size=16.0).build()
    q0 = model.rest_motors()
    lz = model.lz
    pose, st = model.equilibrium(q0 + 0.5 * MOVE_DEG, intermediate=True)
    eq = model._last_equilibrium
    assert eq.residual <= PATH_TOL * eq.reference
    n0 = lz.factorizations
    pose_end, _ = model.equilibrium(q0 + MOVE_DEG, state=st)
    carried = lz.factorizations - n0
    eq = model._last_equilibrium
    assert eq.residual <= 1e-8 * eq.reference
    n0 = lz.factorizations
    pose_again, _ = model.equilibrium(q0 + MOVE_DEG, state=st)  # st is no longer the last state
    assert lz.factorizations - n0 == carried + 1
    assert np.allclose(pose_again, pose_end, rtol=0, atol=1e-6)
    direct, _ = model.equilibrium(q0 + MOVE_DEG)
    assert np.allclose(direct, pose_end, rtol=0, atol=1e-6)
