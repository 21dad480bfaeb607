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
