"""Mesh convergence on one foam geometry (resolution-independent definition, edge_foam).

The observed rate p comes from three resolutions n1 < n2 < n3 with Richardson's
relation |E(n2) - E(n1)| / |E(n3) - E(n2)| = (h1^p - h2^p) / (h2^p - h3^p), solved for p;
the printed value goes to the report. Voxelised geometry converges slowly (the
staircase changes with n), so only a positive rate and shrinking changes are asserted.
"""

import numpy as np
import pytest
from scipy.optimize import brentq

from metasheet.homogenize import homogenize_voxels
from metasheet.mechanics.material import Isotropic

from homogenize_samples import edge_foam

TPU = Isotropic(12.0, 0.3)


def observed_rate(ns, values) -> float:
    """Convergence order p from three resolutions ``ns`` and values (NaN when not monotone)."""
    h = 1.0 / np.asarray(ns, float)
    d1, d2 = values[1] - values[0], values[2] - values[1]
    if d1 * d2 <= 0:
        return float("nan")
    q = abs(d1 / d2)
    f = lambda p: (h[0] ** p - h[1] ** p) / (h[1] ** p - h[2] ** p) - q  # noqa: E731
    try:
        return brentq(f, 0.05, 8.0)
    except ValueError:
        return float("nan")


def _run(ns, density):
    vals = []
    for n in ns:
        r = homogenize_voxels(edge_foam(n, density, seeds=6, rng_seed=4), (1.0, 1.0, 1.0), {1: TPU},
                              axis=(0, 0, 1), localise=False)
        vals.append(r.fit.material.E_t)
    p = observed_rate(ns, vals)
    print(f"n={ns}: E_t = {np.round(vals, 5)} MPa, observed rate p = {p:.2f}")
    return vals, p


def test_observed_rate_helper():
    ns = (10, 20, 40)
    vals = [1.0 + 3.0 / n**1.5 for n in ns]
    assert observed_rate(ns, vals) == pytest.approx(1.5, rel=1e-6)


def test_convergence_small():
    vals, p = _run((12, 16, 24), 0.3)
    assert abs(vals[2] - vals[1]) < abs(vals[1] - vals[0]) * 1.5
    assert abs(vals[2] - vals[1]) / vals[2] < 0.1


@pytest.mark.slow
def test_convergence_32_48_64():
    vals, p = _run((32, 48, 64), 0.15)
    assert abs(vals[2] - vals[1]) < abs(vals[1] - vals[0])
    assert p > 0.3
