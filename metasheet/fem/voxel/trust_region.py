"""The trust-region step of a Newton method on an energy whose tangent may be indefinite:
Steihaug-Toint truncated conjugate gradients.

Thin printed walls buckle: past a few degrees of motor travel the hyperelastic tangent of a
printed sheet loses definiteness, and a line-search Newton step (CG on an indefinite matrix)
points anywhere. The trust-region step stays meaningful: it minimises the quadratic model

    m(p) = g . p + 1/2 p . K p    over    |p| <= radius

approximately, by preconditioned CG from p = 0 that stops at the boundary when an iterate
leaves the region or a direction of non-positive curvature appears (then the model decreases
without bound along it, and the step follows it to the boundary), or inside when the model's
gradient ``g + K p`` is small enough (Steihaug 1983; Nocedal & Wright, *Numerical
Optimization*, 2nd ed., Algorithm 7.2). The norm is the Euclidean one of the displacements
[mm], in which a radius is a physical length.

The preconditioner may vary with its input (a K-cycle multigrid): the directions then follow
Notay's flexible CG, as :func:`.pcg.pcg` does. Every reduction is a fixed-order sum
(:func:`.vectors.dots`): the same bits on any thread count.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from . import vectors as vec


@dataclass(frozen=True)
class TrustStep:
    """A trust-region step.

    p : (a, 3) [mm] the step; model : m(p) [N mm] (< 0 unless g = 0); iterations : CG
    iterations; ended : why CG stopped: "converged" (the model's gradient reached the
    tolerance inside the region), "boundary" (an iterate left the region), "curvature"
    (a direction of non-positive curvature, followed to the boundary), "maxiter" or
    "indefinite" (the preconditioner gave ``r . z <= 0``: it is not positive definite, and the
    step so far is not a descent the caller should trust);
    direction : (a, 3) that direction d (d . K d <= 0) when ended == "curvature", else None.
    """

    p: np.ndarray
    model: float
    iterations: int
    ended: str
    direction: np.ndarray | None = None


def _dot(a: np.ndarray, b: np.ndarray) -> float:
    return float(vec.dots(a[..., None], b[..., None])[0])


def _to_boundary(p: np.ndarray, d: np.ndarray, radius: float) -> float:
    """tau >= 0 with |p + tau d| = radius (|p| <= radius)."""
    dd, pd, pp = _dot(d, d), _dot(p, d), _dot(p, p)
    disc = max(pd * pd + dd * (radius * radius - pp), 0.0)
    return (np.sqrt(disc) - pd) / dd


def steihaug(apply: Callable[[np.ndarray], np.ndarray], g: np.ndarray,
             precondition: Callable[[np.ndarray], np.ndarray], radius: float, *, rtol: float, maxiter: int,
             flexible: bool = False) -> TrustStep:
    """The Steihaug-Toint step for the model ``g . p + 1/2 p . K p`` within ``|p| <= radius``.

    apply : v (a, 3) -> K v (a, 3), symmetric; g : (a, 3) [N] the energy's gradient (zero off
    the unknowns); precondition : r (a, 3) -> z (a, 3), symmetric positive definite;
    radius : [mm] > 0 (inf: no region; CG then stops at a direction of non-positive curvature
    without stepping along it, the search for one that a stability probe makes);
    rtol : CG stops inside the region when ``|g + K p| <= rtol |g|``;
    maxiter : CG iterations at most.
    """
    if not radius > 0:
        raise ValueError(f"radius: {radius!r}: must be > 0")
    p = np.zeros_like(g)
    r = np.array(g, dtype=float, copy=True)  # the model's gradient g + K p
    gn = np.sqrt(_dot(g, g))
    if gn == 0.0:
        return TrustStep(p, 0.0, 0, "converged")
    z = precondition(r)
    d = -z
    rz = _dot(r, z)
    if not rz > 0.0:
        return TrustStep(p, 0.0, 0, "indefinite")

    def model(p, r):  # m(p) = g.p + 1/2 p.(r - g) = 1/2 (g.p + r.p)
        return 0.5 * (_dot(g, p) + _dot(r, p))

    for it in range(1, maxiter + 1):
        q = apply(d)
        dq = _dot(d, q)
        if dq <= 0.0:  # non-positive curvature: the model falls without bound along d
            if not np.isfinite(radius):  # no region: report the direction, not a step along it
                return TrustStep(p, model(p, r), it, "curvature", d)
            tau = _to_boundary(p, d, radius)
            p, r = p + tau * d, r + tau * q
            return TrustStep(p, model(p, r), it, "curvature", d)
        alpha = rz / dq
        p_next = p + alpha * d
        if _dot(p_next, p_next) >= radius * radius:
            tau = _to_boundary(p, d, radius)
            p, r = p + tau * d, r + tau * q
            return TrustStep(p, model(p, r), it, "boundary")
        p = p_next
        r = r + alpha * q
        if np.sqrt(_dot(r, r)) <= rtol * gn:
            return TrustStep(p, model(p, r), it, "converged")
        z = precondition(r)
        rz_new = _dot(r, z)
        if not rz_new > 0.0:
            return TrustStep(p, model(p, r), it, "indefinite")
        beta = _dot(z, q) / dq if flexible else rz_new / rz  # K-conjugate to d either way
        d = -z + beta * d
        rz = rz_new
    return TrustStep(p, model(p, r), maxiter, "maxiter")


def update_radius(radius: float, rho: float, step_norm: float, at_boundary: bool, largest: float) -> float:
    """The next radius [mm] after a step of ``step_norm`` [mm] whose actual over predicted
    reduction was ``rho`` (Nocedal & Wright, Algorithm 4.1): a quarter of the step when the
    model was poor (rho < 1/4), doubled (at most ``largest``) when it was good and the step
    reached the boundary, else unchanged."""
    if not np.isfinite(rho) or rho < 0.25:
        return 0.25 * step_norm
    if rho > 0.75 and at_boundary:
        return min(2.0 * radius, largest)
    return radius
