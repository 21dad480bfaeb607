"""The kept tangent of the control loop: a NaN chord update is never kept."""

from types import SimpleNamespace

import numpy as np

from metasheet.robot.inverse import InverseSettings
from metasheet.robot.tangent import TangentCache


class _Lin:
    def __init__(self, residual, step):
        self.residual_norm, self._step = residual, step

    def newton_step(self, _):
        return (self._step,)


def _cache():
    cache = TangentCache(SimpleNamespace(force_scale=lambda lin: 1.0))
    cache.angles, cache.age = np.zeros(6), 1
    return cache


def test_finite_small_chord_update_is_kept_and_nan_is_stale():
    s, state = InverseSettings(), SimpleNamespace(angles=np.zeros(6))
    cache = _cache()
    assert cache.stale(_Lin(0.0, np.zeros(6)), state, s) is None
    assert cache.stale(_Lin(np.nan, np.zeros(6)), state, s) == "residual"
    assert cache.stale(_Lin(0.0, np.full(6, np.nan)), state, s) == "drift"


def test_residual_first_chord_update_is_the_plain_one_or_none(foam_robot_14, foam_rest_14):
    """``update_within`` (the residual tested before the solve) hands back the plain chord
    update bit for bit, or None exactly when its residual is beyond ``chord_tol``."""
    from metasheet.robot.statics import Linearizer

    rob, rest = foam_robot_14, foam_rest_14.state
    lz = Linearizer(rob)
    lin = lz.linearize(rest)
    dq = np.radians([4.0, -3.0, 2.0, 0.0, 1.0, -2.0])
    dq_e, dx_f = lin.newton_step(dq)
    moved = lz.apply(rest, dq_e, dx_f, dq)  # one predictor step: a residual well above zero
    plain = lz.update(lin, moved)
    rel = plain.residual_norm / lz.force_scale(plain)
    for tol in (0.5 * rel, 2.0 * rel, None):
        got = lz.update_within(lin, moved, tol)
        if tol is not None and tol < rel:
            assert got is None
            continue
        for f in ("r", "y_r", "R_rigid", "res_e", "res_f"):
            assert np.array_equal(getattr(got, f), getattr(plain, f)), f


def test_a_tangent_too_old_or_too_far_is_dropped_before_any_force():
    """Age and angle are decided without a chord update (no forces, no solve)."""
    s = InverseSettings(refactor_every=3, refresh_angle_deg=5.0)
    cache = _cache()
    assert cache.aged(SimpleNamespace(angles=np.zeros(6)), s) is None
    assert cache.aged(SimpleNamespace(angles=np.radians([6.0, 0, 0, 0, 0, 0])), s) == "angle"
    cache.age = 3
    assert cache.aged(SimpleNamespace(angles=np.zeros(6)), s) == "age"
