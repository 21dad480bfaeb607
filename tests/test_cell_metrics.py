"""Metrics that shape the cells: the polyhedral gauge is a norm (issue 3, item 2)."""

import numpy as np

from metasheet.cells.metrics import PolyhedralMetric


def test_polyhedral_gauge_is_a_norm_within_its_bounds():
    m = PolyhedralMetric(k=6, height=2.0, x_shrink=0.7, angle=10.0, axis=1)
    rng = np.random.default_rng(0)
    u, v = rng.normal(size=(2, 5000, 3))
    assert np.all(m.distance(u + v) <= m.distance(u) + m.distance(v) + 1e-12)
    assert np.allclose(m.distance(3.0 * u), 3.0 * m.distance(u))
    w = np.linalg.norm(u * m.scale, axis=1)
    assert np.all(m.distance(u) >= m.lower * w - 1e-12)
    assert np.all(m.distance(u) <= m.upper * w + 1e-12)
    # the gradient is the active facet: N(v) = grad . v (positively homogeneous of degree 1)
    assert np.allclose(np.einsum("ij,ij->i", m.gradient(u), u), m.distance(u))
