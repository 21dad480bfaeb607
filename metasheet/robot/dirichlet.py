"""Static equilibrium of one elastic body with prescribed nodes (Dirichlet conditions).

Solves ``f(x) = l`` on the free nodes (eq. 1 without rigid couplings) by Newton's method with
a line search; the fixed nodes are held at given positions. The robot's coupled solver is
:mod:`.statics`; this one checks the body on its own (beams, patch tests, benchmarks).
The tangent's free block is gathered from the body's CSR data through a cached index map
(:meth:`~metasheet.fem.assembly.SparsityPattern.submatrix_map`) and factorised by SuperLU
(:func:`metasheet.fem.solvers.superlu`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, ConvergenceError, check_range
from ..fem.solvers import superlu


@dataclass(frozen=True)
class StaticResult:
    """Result of :func:`solve_static`.

    x : (n, 3) equilibrium positions [mm]; iterations : Newton iterations done;
    residuals : relative residual norm before each iteration and at the end [-];
    time : wall time of the solve [s].
    """

    x: np.ndarray
    iterations: int
    residuals: tuple[float, ...]
    time: float


def solve_static(body, fixed, *, x_fixed=None, loads=None, tol: float = 1e-8, max_iter: int = 50,
                 x0=None) -> StaticResult:
    """Static equilibrium ``f(x) = loads`` on the free nodes, Newton with a backtracking line search.

    Parameters
    ----------
    body : :class:`~metasheet.robot.body.ElasticBody`.
    fixed : (k,) int node indices held at ``x_fixed``.
    x_fixed : (k, 3) float [mm], default their rest positions.
    loads : (n, 3) float [N] external nodal forces (add ``body.gravity()`` for weight).
    tol : relative tolerance on the free residual norm, relative to the largest of the
        external load, the first residual and the fixed nodes' reactions.
    max_iter : Newton iterations allowed (the prescribed-motion predictor is not counted).
    x0 : (n, 3) float [mm] start (default rest), e.g. a previous solution to warm-start.

    The first step moves the fixed nodes to ``x_fixed`` and the free ones by the
    linearised response (tangent at ``x0``). Nodes no element uses stay where they are.
    Raises :class:`ConvergenceError` with the residual history if ``max_iter`` is reached
    or the line search stalls.
    """
    t0 = time.perf_counter()
    n = body.n_nodes
    fixed = np.asarray(fixed)
    if fixed.ndim != 1 or not np.issubdtype(fixed.dtype, np.integer):
        raise ConfigError(f"fixed: shape {fixed.shape} dtype {fixed.dtype}: should be (k,) int node indices")
    if len(fixed) and (fixed.min() < 0 or fixed.max() >= n):
        raise ConfigError(f"fixed: indices span [{fixed.min()}, {fixed.max()}], allowed [0, {n - 1}]")
    if len(np.unique(fixed)) != len(fixed):
        raise ConfigError("fixed: contains repeated node indices")
    check_range("tol", tol, 0.0, 1.0, lo_open=True)
    check_range("max_iter", max_iter, 1, None)
    x = body.rest.copy() if x0 is None else body.check_positions(x0).copy()
    if x_fixed is None:
        x_fixed = body.rest[fixed]
    x_fixed = np.asarray(x_fixed, dtype=float)
    if x_fixed.shape != (len(fixed), 3) or not np.all(np.isfinite(x_fixed)):
        raise ConfigError(f"x_fixed: shape is {x_fixed.shape} and should be ({len(fixed)}, 3), finite")
    loads = np.zeros((n, 3)) if loads is None else np.asarray(loads, dtype=float)
    if loads.shape != (n, 3) or not np.all(np.isfinite(loads)):
        raise ConfigError(f"loads: shape is {loads.shape} and should be ({n}, 3), finite")

    free_nodes = np.ones(n, bool)
    free_nodes[fixed] = False
    orphans = free_nodes & ~body.used
    if np.any(loads[orphans] != 0):
        raise ConfigError(f"loads: node {np.flatnonzero(orphans & np.any(loads != 0, axis=1))[0]} "
                          "is in no element and cannot carry a load")
    free_nodes &= body.used
    free = (3 * np.flatnonzero(free_nodes)[:, None] + np.arange(3)).ravel()
    cons = (3 * fixed[:, None] + np.arange(3)).ravel()
    l = loads.reshape(-1)
    K_ff, take_ff = body.pattern.submatrix_map(free, free)
    K_fc, take_fc = body.pattern.submatrix_map(free, cons)

    def solve(data, rhs):
        K_ff.data[:] = data[take_ff]
        return superlu(K_ff).solve(rhs)

    xf = x.reshape(-1)  # a view: updating xf updates x
    dc = (x_fixed - x[fixed]).reshape(-1)
    if len(free) == 0:
        x[fixed] = x_fixed
        return StaticResult(x, 0, (0.0,), time.perf_counter() - t0)
    if np.any(dc != 0):  # predictor: linearised response to the prescribed motion
        f, data = body.evaluate(x, tangent=True)
        K_fc.data[:] = data[take_fc]
        xf[free] += solve(data, -(f[free] - l[free]) - K_fc @ dc)
        x[fixed] = x_fixed

    f, data = body.evaluate(x, tangent=True)
    r = f[free] - l[free]
    # Reference force: loads, first residual and reactions, so tol is scale-free.
    ref = max(np.linalg.norm(l[free]), np.linalg.norm(r), np.linalg.norm(f[cons] - l[cons]))
    # Round-off floor of f: below it no residual can be trusted, whatever tol asks.
    floor = 10 * np.finfo(float).eps * body.stiffness_scale * np.abs(x).max() * np.sqrt(len(free))
    ref = max(ref, floor)
    hist = [np.linalg.norm(r) / ref]
    it = 0
    while hist[-1] > tol and np.linalg.norm(r) > floor:
        if it >= max_iter:
            raise ConvergenceError(
                f"static solve: residual {hist[-1]:.3g} > tol {tol:g} after max_iter={max_iter} iterations",
                hist,
            )
        it += 1
        dx = solve(data, -r)
        x_old = xf[free].copy()
        alpha = _line_search(body, x, xf, free, l, x_old, dx, r)
        if alpha is None:
            xf[free] = x_old
            raise ConvergenceError(
                f"static solve: line search failed at iteration {it} (residual {hist[-1]:.3g})", hist
            )
        f, data = body.evaluate(x, tangent=True)
        r = f[free] - l[free]
        hist.append(np.linalg.norm(r) / ref)
    return StaticResult(x, it, tuple(float(h) for h in hist), time.perf_counter() - t0)


def _line_search(body, x, xf, free, l, x_old, dx, r):
    """Step length along ``dx`` (sets ``x``); None if no acceptable step.

    Not on the residual norm: along a slender body's Newton step the norm can grow
    a hundredfold while the step is right (stiff axial terms of the rotations). Instead
    the projected residual ``g(a) = dx . r(x + a dx)``, the energy slope for a
    conservative force, must shrink to 0.8 |g(0)| (Crisfield's criterion), with
    regula falsi steps otherwise and halving on non-finite or inverted states.
    """
    g0 = float(dx @ r)
    if not g0 < 0.0:  # not a descent direction of the energy-like merit: take Newton's step
        xf[free] = x_old + dx
        return 1.0
    lo, g_lo, hi, g_hi, alpha, g = 0.0, g0, None, None, 1.0, np.nan
    for _ in range(12):
        xf[free] = x_old + alpha * dx
        f, _ = body.evaluate(x, tangent=False)
        g = float(dx @ (f[free] - l[free]))
        if not np.isfinite(g):
            hi, g_hi = alpha, None
        elif abs(g) <= 0.8 * abs(g0) or (g < 0.0 and hi is None):
            return alpha  # slope small enough, or still descending at the full step
        elif g < 0.0:
            lo, g_lo = alpha, g
        else:
            hi, g_hi = alpha, g
        if g_hi is None:
            alpha = 0.5 * (lo + hi)
        else:  # regula falsi on the bracket, kept away from its ends
            new = lo - g_lo * (hi - lo) / (g_hi - g_lo)
            alpha = float(np.clip(new, lo + 0.1 * (hi - lo), hi - 0.1 * (hi - lo)))
    if np.isfinite(g) and abs(g) < abs(g0):
        return alpha
    return None
