"""Preconditioned conjugate gradients on voxel vectors, with a null space projected out.

The periodic operator is singular: every node-connected part of the solid can translate
freely (rotations are not periodic). Rather than pin a node per part, as the assembled
path does (which would spoil the multigrid hierarchy's coarse levels), CG works in the
complement of those translations: the right-hand side and every preconditioned residual are
projected onto it (:func:`translation_projector`). The energy-form stiffness does not see
the translation, so the effective tensor equals the pinned solution's.

Vectors are compact blocks (a, 3, m) on the active nodes (:mod:`.compact`); the updates and
dot products are fused numba kernels with a fixed summation order (:mod:`.vectors`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from . import vectors as vec


@dataclass(frozen=True)
class PCGResult:
    """A CG solve of ``m`` right-hand sides.

    Attributes
    ----------
    x : (a, 3[, m]) float [mm], the solutions (the shape of ``b``).
    iterations : (m,) int, CG iterations of each column.
    residual : (m,) float, final relative residuals ``||b - K x|| / ||b||`` (recomputed, not recursive).
    converged : (m,) bool, the recursive residual reached rtol and the recomputed one is <= 10 rtol
        (the assembled AMG-CG path's check).
    history : (max(iterations) + 1, m) relative recursive residuals.
    """

    x: np.ndarray
    iterations: np.ndarray
    residual: np.ndarray
    converged: np.ndarray
    history: np.ndarray


def translation_projector(labels: np.ndarray, n_parts: int) -> Callable[[np.ndarray], np.ndarray]:
    """Orthogonal projection removing each part's mean displacement.

    Parameters
    ----------
    labels : (a,) int, part of every node of the compact block, -1 for nodes without unknowns.
    n_parts : number of parts.

    Returns
    -------
    project : (a, 3, m) -> same shape, ``v - sum_p t_p (t_p . v) / (t_p . t_p)``
        over the per-part, per-component translations ``t_p``, column by column, in a fixed
        summation order (:func:`.vectors.column_sums`; np.bincount sums in index order).
    """
    lab = np.asarray(labels).reshape(-1)
    on = lab >= 0
    li = lab[on]
    count = np.bincount(li, minlength=n_parts).astype(float)
    every = bool(on.all())

    def project(v: np.ndarray) -> np.ndarray:
        out = np.array(v, dtype=float, copy=True, order="C")
        if n_parts == 1 and every:  # the usual cell: one mean per column, fused kernels
            vec.subtract_mean(out, vec.column_sums(out) / max(len(li), 1))
            return out
        flat = out.reshape(len(lab), -1)  # (nodes, 3 m)
        for c in range(flat.shape[1]):
            mean = np.bincount(li, weights=flat[on, c], minlength=n_parts) / np.maximum(count, 1.0)
            flat[on, c] -= mean[li]
        return out

    return project


def pcg(apply: Callable, b: np.ndarray, precondition: Callable, *, rtol: float, maxiter: int,
        project: Callable | None = None, flexible: bool = False) -> PCGResult:
    """Solve ``K x = b`` by preconditioned CG from ``x = 0``, every column of ``b`` on its own.

    Parameters
    ----------
    apply : v -> K v, symmetric positive (semi-)definite on the free dofs, for (a, 3, m) blocks.
    b : (a, 3) or (a, 3, m) right-hand sides [N] on compact nodes, zero outside the free dofs.
    precondition : r -> z, a symmetric positive-definite approximation of ``K^-1``, column-wise.
    rtol : relative residual to reach; maxiter : iteration cap.
    project : v -> v without the null space (None: K is non-singular).
    flexible : the preconditioner may vary with r (a K-cycle): Notay's flexible CG,
        ``beta = -(z . q) / (p . q)`` instead of ``(r . z) / (r_old . z_old)`` (equal for a fixed
        linear preconditioner in exact arithmetic).
    """
    single = b.ndim == 2
    proj = project if project is not None else (lambda v: v)
    b = np.ascontiguousarray(proj(b[..., None] if single else b), dtype=float)
    m = b.shape[2]
    x = np.zeros_like(b)
    bn = np.sqrt(vec.dots(b, b))
    scale = np.where(bn > 0, bn, 1.0)
    r = b.copy()
    active = bn > 0
    iterations = np.zeros(m, np.int64)
    hist = [np.where(active, 1.0, 0.0)]
    if active.any():
        z = proj(precondition(r))
        p = z.copy()
        rz = vec.dots(r, z)
    while active.any() and iterations.max() < maxiter:
        q = apply(p)
        pq = vec.dots(p, q)
        alpha = np.where(active, rz / np.where(active, pq, 1.0), 0.0)  # 0: a frozen column stays put
        vec.cg_step(x, r, p, q, alpha)  # x += alpha p; r -= alpha q
        if not flexible:
            del q
        iterations += active
        hist.append(np.where(active, np.sqrt(vec.dots(r, r)) / scale, hist[-1]))
        active = active & (hist[-1] > rtol) & (iterations < maxiter)
        if not active.any():
            break
        z = proj(precondition(r))
        rz_new = vec.dots(r, z)
        if flexible:
            beta = np.where(active, -vec.dots(z, q) / np.where(active, pq, 1.0), 0.0)
            del q
        else:
            beta = np.where(active, rz_new / np.where(active, rz, 1.0), 0.0)
        vec.cg_direction(p, z, beta)  # p = z + beta p
        del z
        rz = np.where(active, rz_new, rz)
    rb = proj(vec.residual(b, apply(x)))
    res = np.sqrt(vec.dots(rb, rb)) / scale
    return PCGResult(x[..., 0] if single else x, iterations, res, res <= rtol * 10.0, np.array(hist))
