"""Preconditioned conjugate gradients on voxel vectors, with a null space projected out.

The periodic operator is singular: every node-connected part of the solid can translate
freely (rotations are not periodic). Rather than pin a node per part, as the assembled
path does (which would spoil the multigrid hierarchy's coarse levels), CG works in the
complement of those translations: the right-hand side and every preconditioned residual are
projected onto it (:func:`translation_projector`). The energy-form stiffness does not see
the translation, so the effective tensor equals the pinned solution's.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PCGResult:
    """A CG solve of ``m`` right-hand sides.

    Attributes
    ----------
    x : (Nx, Ny, Nz, 3[, m]) float [mm], the solutions (the shape of ``b``).
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
    labels : (Nx, Ny, Nz) int, part of every node, -1 for nodes without unknowns.
    n_parts : number of parts.

    Returns
    -------
    project : (Nx, Ny, Nz, 3[, m]) -> same shape, ``v - sum_p t_p (t_p . v) / (t_p . t_p)``
        over the per-part, per-component translations ``t_p``, column by column (np.bincount
        sums in index order: deterministic).
    """
    lab = labels.reshape(-1)
    on = lab >= 0
    li = lab[on]
    count = np.bincount(li, minlength=n_parts).astype(float)

    weight = on.astype(float) / max(len(li), 1)

    def project(v: np.ndarray) -> np.ndarray:
        out = v.copy()
        flat = out.reshape(len(lab), -1)  # (nodes, 3 m)
        if n_parts == 1:  # the usual cell: one mean per column, one fixed-order pass
            flat -= on[:, None] * np.einsum("i,ij->j", weight, flat)
            return out
        for c in range(flat.shape[1]):
            mean = np.bincount(li, weights=flat[on, c], minlength=n_parts) / np.maximum(count, 1.0)
            flat[on, c] -= mean[li]
        return out

    return project


def pcg(apply: Callable, b: np.ndarray, precondition: Callable, *, rtol: float, maxiter: int,
        project: Callable | None = None) -> PCGResult:
    """Solve ``K x = b`` by preconditioned CG from ``x = 0``, every column of ``b`` on its own.

    Parameters
    ----------
    apply : v -> K v, symmetric positive (semi-)definite on the free dofs, for (.., 3, m) blocks.
    b : (Nx, Ny, Nz, 3) or (Nx, Ny, Nz, 3, m) right-hand sides [N], zero outside the free dofs.
    precondition : r -> z, a symmetric positive-definite approximation of ``K^-1``, column-wise.
    rtol : relative residual to reach; maxiter : iteration cap.
    project : v -> v without the null space (None: K is non-singular).
    """
    single = b.ndim == 4
    proj = project if project is not None else (lambda v: v)
    b = proj(b[..., None] if single else b)
    m = b.shape[4]
    x = np.zeros_like(b)
    bn = np.sqrt(_dots(b, b))
    scale = np.where(bn > 0, bn, 1.0)
    r = b.copy()
    active = bn > 0
    iterations = np.zeros(m, np.int64)
    hist = [np.where(active, 1.0, 0.0)]
    if active.any():
        z = proj(precondition(r))
        p = z.copy()
        rz = _dots(r, z)
    while active.any() and iterations.max() < maxiter:
        q = apply(p)
        pq = _dots(p, q)
        alpha = np.where(active, rz / np.where(active, pq, 1.0), 0.0)  # 0: a frozen column stays put
        x += alpha * p
        r -= alpha * q
        iterations += active
        hist.append(np.where(active, np.sqrt(_dots(r, r)) / scale, hist[-1]))
        active = active & (hist[-1] > rtol) & (iterations < maxiter)
        if not active.any():
            break
        z = proj(precondition(r))
        rz_new = _dots(r, z)
        beta = np.where(active, rz_new / np.where(active, rz, 1.0), 0.0)
        p = z + beta * p
        rz = np.where(active, rz_new, rz)
    rb = proj(b - apply(x))
    res = np.sqrt(_dots(rb, rb)) / scale
    return PCGResult(x[..., 0] if single else x, iterations, res, res <= rtol * 10.0, np.array(hist))


def _dots(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(m,) column dot products of two (.., m) blocks, in one fixed order."""
    return np.einsum("ij,ij->j", a.reshape(-1, a.shape[-1]), b.reshape(-1, b.shape[-1]))
