"""Steihaug's truncated CG (metasheet/fem/voxel/trust_region.py) on small dense models whose
answers are known: the Newton step inside a large region, the boundary, a direction of
negative curvature, the Cauchy point's decrease, and the flexible directions."""

import numpy as np
import pytest

from metasheet.fem.voxel.trust_region import steihaug, update_radius


def _model(K, g, p):
    return float(g.ravel() @ p.ravel() + 0.5 * p.ravel() @ K @ p.ravel())


def _case(seed, indefinite=False, n=4):
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.normal(size=(3 * n, 3 * n)))
    lam = np.geomspace(0.1, 10.0, 3 * n)
    if indefinite:
        lam[0] = -0.5
    K = Q @ np.diag(lam) @ Q.T
    g = rng.normal(size=(n, 3))
    return K, g, (lambda v: (K @ v.ravel()).reshape(v.shape))


def test_inside_a_large_region_the_step_is_newtons():
    K, g, apply = _case(0)
    D = np.diag(K).copy()
    s = steihaug(apply, g, lambda r: r / D.reshape(r.shape), 1e6, rtol=1e-12, maxiter=200)
    exact = -np.linalg.solve(K, g.ravel()).reshape(g.shape)
    assert s.ended == "converged"
    np.testing.assert_allclose(s.p, exact, rtol=1e-9, atol=1e-12)
    assert s.model == pytest.approx(_model(K, g, exact), rel=1e-10)


@pytest.mark.parametrize("indefinite", [False, True])
def test_a_small_region_ends_on_its_boundary_below_the_cauchy_point(indefinite):
    """Unpreconditioned, Steihaug's step lowers the model at least as much as the Cauchy point
    (the model's minimum along -g within the region), and ends on the boundary."""
    K, g, apply = _case(1, indefinite)
    radius = 0.05 * np.linalg.norm(g)
    s = steihaug(apply, g, lambda r: r.copy(), radius, rtol=1e-12, maxiter=200)
    assert s.ended in ("boundary", "curvature")
    assert np.linalg.norm(s.p) == pytest.approx(radius, rel=1e-12)
    gv = g.ravel()
    gKg = gv @ K @ gv
    t = radius / np.linalg.norm(gv) if gKg <= 0 else min(gv @ gv / gKg, radius / np.linalg.norm(gv))
    assert s.model <= _model(K, g, -t * g) + 1e-12
    assert s.model == pytest.approx(_model(K, g, s.p), rel=1e-10)


def test_negative_curvature_is_followed_to_the_boundary():
    """K = diag(-1, 1, 1, ...), g = (1, 2, 0, ...): CG's first direction -g has curvature
    -1 + 4 > 0; the second, (-40/9, -20/9, 0, ...) by hand, has -1600/81 + 400/81 < 0, and
    the step leaves along it to the boundary: the model is unbounded below."""
    K = np.eye(12)
    K[0, 0] = -1.0
    g = np.zeros((4, 3))
    g[0, :2] = (1.0, 2.0)
    apply = lambda v: (K @ v.ravel()).reshape(v.shape)  # noqa: E731
    s = steihaug(apply, g, lambda r: r.copy(), 1e3, rtol=1e-12, maxiter=50)
    assert s.ended == "curvature" and s.iterations == 2
    assert np.linalg.norm(s.p) == pytest.approx(1e3, rel=1e-12)
    p1 = -(5.0 / 3.0) * np.array([1.0, 2.0])  # the first iterate; then along (-2, -1) to the boundary
    d = np.array([-2.0, -1.0]) / np.sqrt(5.0)
    tau = -p1 @ d + np.sqrt((p1 @ d) ** 2 + 1e6 - p1 @ p1)
    np.testing.assert_allclose(s.p.ravel()[:2], p1 + tau * d, rtol=1e-10)
    assert s.model == pytest.approx(_model(K, g, s.p), rel=1e-10) and s.model < -1e5


def test_flexible_directions_equal_the_classic_ones_under_a_fixed_preconditioner():
    K, g, apply = _case(3)
    D = np.diag(K).copy()
    pre = lambda r: r / D.reshape(r.shape)  # noqa: E731
    a = steihaug(apply, g, pre, 1e6, rtol=1e-10, maxiter=200)
    b = steihaug(apply, g, pre, 1e6, rtol=1e-10, maxiter=200, flexible=True)
    assert a.iterations == b.iterations
    np.testing.assert_allclose(a.p, b.p, rtol=1e-8, atol=1e-12)


def test_the_radius_follows_the_models_quality():
    assert update_radius(1.0, 0.1, 0.8, True, 10.0) == pytest.approx(0.2)
    assert update_radius(1.0, float("nan"), 0.8, True, 10.0) == pytest.approx(0.2)
    assert update_radius(1.0, 0.9, 1.0, True, 10.0) == 2.0
    assert update_radius(8.0, 0.9, 8.0, True, 10.0) == 10.0
    assert update_radius(1.0, 0.9, 0.5, False, 10.0) == 1.0
    assert update_radius(1.0, 0.5, 1.0, True, 10.0) == 1.0
    with pytest.raises(ValueError, match="radius"):
        steihaug(lambda v: v, np.ones((2, 3)), lambda r: r, 0.0, rtol=1e-3, maxiter=3)


def test_without_a_region_the_direction_is_reported_not_followed():
    """radius = inf (the stability probe): CG stops at the first direction of non-positive
    curvature and returns it, with the iterate before it."""
    K = np.eye(12)
    K[0, 0] = -1.0
    g = np.zeros((4, 3))
    g[0, :2] = (1.0, 2.0)
    s = steihaug(lambda v: (K @ v.ravel()).reshape(v.shape), g, lambda r: r.copy(), np.inf, rtol=1e-12, maxiter=50)
    assert s.ended == "curvature" and s.iterations == 2 and np.all(np.isfinite(s.p))
    d = s.direction.ravel()
    assert d @ K @ d < 0
    np.testing.assert_allclose(s.p.ravel()[:2], -(5.0 / 3.0) * np.array([1.0, 2.0]), rtol=1e-12)


def test_a_preconditioner_that_is_not_positive_definite_is_reported():
    K = np.diag([3.0, 2.0, 1.0, 0.5, 4.0, 1.5])
    g = np.ones((2, 3))

    def apply(v):
        return (K @ v.ravel()).reshape(v.shape)

    s = steihaug(apply, g, lambda r: -r, 1e3, rtol=1e-12, maxiter=50)
    assert s.ended == "indefinite" and s.iterations == 0 and not s.p.any()
    flip = np.array([1.0, 1.0, 1.0, 1.0, 1.0, -1.0]).reshape(2, 3)  # positive on g, not on every residual
    s = steihaug(apply, g, lambda r: flip * r, 1e3, rtol=1e-12, maxiter=50)
    assert s.ended == "indefinite" and s.iterations >= 1
