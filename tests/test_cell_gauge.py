"""The compiled polyhedral gauge (metasheet/cells/gauge.py), shared by the cell skeleton and the
printed walls, against the vectorised metric and the gauge's own properties."""

import numpy as np
import pytest

from metasheet.cells.gauge import polyhedral_gauge
from metasheet.cells.metrics import PolyhedralMetric


@pytest.mark.parametrize("metric", [PolyhedralMetric(), PolyhedralMetric(k=4, height=2.5, x_shrink=0.6, angle=17.0,
                                                                          axis=0)])
def test_the_compiled_gauge_is_the_metrics_gauge_and_positively_homogeneous(metric):
    g = metric.facets
    v = np.random.default_rng(3).normal(size=(200, 3))
    got = np.array([polyhedral_gauge(g, *w) for w in v])
    np.testing.assert_allclose(got[:, 0], metric.distance(v), rtol=0, atol=1e-14)
    np.testing.assert_array_equal(g[got[:, 1].astype(int)], metric.gradient(v))  # the active facet
    scaled = np.array([polyhedral_gauge(g, *(2.5 * w))[0] for w in v])
    np.testing.assert_allclose(scaled, 2.5 * got[:, 0], rtol=1e-13)  # N(t v) = t N(v), t > 0
    assert np.all(got[:, 0] > 0)  # a bounded unit ball around the origin
