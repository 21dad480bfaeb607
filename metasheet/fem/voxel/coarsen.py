"""Voxel coarsening for geometric multigrid: cells, interpolation, Galerkin coarse matrices.

Along each direction a coarse voxel covers 2 fine voxels (the last one 3 when the count is
odd) or, when that direction is not coarsened, 1. Coarse node ``I`` sits on fine node
``b[I]``; a fine node between ``b[I]`` and ``b[I + 1]`` is interpolated linearly, so the
prolongation ``P`` is trilinear and reproduces rigid translations exactly.

The coarse operator is Galerkin, ``K_c = P^T K P``, built voxel by voxel without assembling
``K``: trilinear interpolation inside a coarse voxel only involves that coarse voxel's
8 corners, so ``P^T K P`` is the sum over coarse voxels of
``K_c,E = sum_{fine e in E} W_e^T K_e W_e`` with ``W_e`` the (24, 24) interpolation from the
coarse voxel's corners to the fine voxel's corners. Coarse levels are therefore again
voxel operators (:class:`~.operator.VoxelOperator`, one matrix per coarse voxel), and they
see the stiffness of thin walls exactly as the fine grid does, where a re-discretised
coarse phase (averaged modulus) would smear a 1-voxel wall into a soft block or a gap.

Prescribed dofs are removed from ``P`` (their rows) before the product; a coarse node is
prescribed where the fine node under it is.
"""

from __future__ import annotations

import numba
import numpy as np

from .operator import VoxelOperator, diagonal, node_shape


def cell_bounds(n: int, coarsen: bool) -> np.ndarray:
    """(m + 1,) int fine-voxel boundaries of the coarse cells along one direction of ``n`` voxels."""
    if not coarsen:
        return np.arange(n + 1, dtype=np.int64)
    m = n // 2
    b = 2 * np.arange(m + 1, dtype=np.int64)
    b[-1] = n  # an odd count: the last coarse cell covers 3 fine voxels
    return b


def choose_directions(shape, h, periodic: bool) -> tuple[bool, bool, bool]:
    """Which directions to coarsen: enough voxels left, and voxels not already much longer
    than in the others (semi-coarsening of elongated voxels keeps the smoother effective)."""
    least = 4 if periodic else 2
    ok = [n >= least for n in shape]
    if not any(ok):
        return (False, False, False)
    hmin = min(float(hd) for hd, o in zip(h, ok) if o)
    return tuple(bool(o and hd <= 1.5 * hmin * (1 + 1e-12)) for hd, o in zip(h, ok))


def node_weights(b: np.ndarray, n_fine_nodes: int, periodic: bool):
    """Per fine node along one direction: coarse neighbours ``lo, hi`` and weights ``wlo, whi``."""
    m = len(b) - 1
    n_coarse_nodes = m if periodic else m + 1
    i = np.arange(n_fine_nodes)
    cell = np.clip(np.searchsorted(b, i, side="right") - 1, 0, m - 1)
    t = (i - b[cell]) / (b[cell + 1] - b[cell])
    lo = cell.astype(np.int64)
    hi = (cell + 1) % n_coarse_nodes
    return lo, hi, 1.0 - t, t


def coarse_operator(op: VoxelOperator, fixed: np.ndarray, coarsen):
    """Galerkin coarse level of ``op``.

    Parameters
    ----------
    op : the fine level.
    fixed : (Nx, Ny, Nz, 3) bool, prescribed fine dofs.
    coarsen : (3,) bool, directions to coarsen (:func:`choose_directions`).

    Returns
    -------
    coarse : :class:`VoxelOperator`; fixed_c : (Mx, My, Mz, 3) bool;
    transfer : the 1D interpolations ``((lo, hi, wlo, whi) per direction)`` for
    :func:`prolong` and :func:`restrict`.
    """
    bounds = [cell_bounds(n, c) for n, c in zip(op.index.shape, coarsen)]
    cells = [np.repeat(np.arange(len(b) - 1), np.diff(b)) for b in bounds]
    cshape = tuple(len(b) - 1 for b in bounds)
    occupied = _occupied(op.index, cells[0], cells[1], cells[2], cshape)
    cindex = np.full(cshape, -1, np.int64)
    cindex[occupied] = np.arange(int(occupied.sum()))
    cmats = np.zeros((int(occupied.sum()), 24, 24))
    free = op.free * (~fixed)
    _galerkin(op.index, op.matrices, op.scale, np.ascontiguousarray(free), bounds[0], bounds[1], bounds[2],
              cells[0], cells[1], cells[2], cindex, cmats)
    cmats = 0.5 * (cmats + cmats.transpose(0, 2, 1))
    Nf = op.node_shape
    Nc = node_shape(cshape, op.periodic)
    fixed_c = fixed[np.ix_(bounds[0][:Nc[0]], bounds[1][:Nc[1]], bounds[2][:Nc[2]])]
    h = op.h * np.array([2.0 if c else 1.0 for c in coarsen])
    coarse = VoxelOperator(cindex, cmats, np.ones(cshape), op.periodic, np.ones(Nc + (3,)), h)
    d = diagonal(coarse)
    coarse = VoxelOperator(cindex, cmats, coarse.scale, op.periodic, ((d > 0) & ~fixed_c).astype(float), h)
    transfer = tuple(node_weights(b, nf, op.periodic) for b, nf in zip(bounds, Nf))
    return coarse, fixed_c, transfer


def prolong(uc: np.ndarray, transfer, fine_nodes) -> np.ndarray:
    """``P uc``: (Mx, My, Mz, 3[, m]) -> (Nx, Ny, Nz, 3[, m]), trilinear."""
    u5 = _columns(uc)
    uf = np.zeros(tuple(fine_nodes) + u5.shape[3:])
    (x, y, z) = transfer
    _prolong(u5, *x, *y, *z, uf)
    return uf.reshape(tuple(fine_nodes) + uc.shape[3:])


def restrict(rf: np.ndarray, transfer, coarse_nodes) -> np.ndarray:
    """``P^T rf``: (Nx, Ny, Nz, 3[, m]) -> (Mx, My, Mz, 3[, m])."""
    r5 = _columns(rf)
    rc = np.zeros(tuple(coarse_nodes) + r5.shape[3:])
    (x, y, z) = transfer
    _restrict(r5, *x, *y, *z, rc)
    return rc.reshape(tuple(coarse_nodes) + rf.shape[3:])


def _columns(v: np.ndarray) -> np.ndarray:
    """(.., 3) or (.., 3, m) -> contiguous (.., 3 m) view for the kernels (3 m values per node)."""
    return np.ascontiguousarray(v, dtype=float).reshape(v.shape[:3] + (-1,))


# --------------------------------------------------------------------------- kernels


@numba.njit(cache=True)
def _occupied(index, cx, cy, cz, cshape):
    occ = np.zeros(cshape, np.bool_)
    nx, ny, nz = index.shape
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                if index[i, j, k] >= 0:
                    occ[cx[i], cy[j], cz[k]] = True
    return occ


@numba.njit(cache=True)
def _galerkin(index, mats, scale, free, bx, by, bz, cx, cy, cz, cindex, cmats):
    nx, ny, nz = index.shape
    Nx, Ny, Nz = free.shape[0], free.shape[1], free.shape[2]
    w = np.empty((3, 2, 2))  # w[d, a_d, A_d]: weight of coarse corner A_d at fine corner a_d
    W = np.empty((8, 8))
    mf = np.empty(24)
    Km = np.empty((24, 24))
    T = np.empty((24, 24))
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                e = index[i, j, k]
                if e < 0:
                    continue
                I, J, K = cx[i], cy[j], cz[k]
                ce = cindex[I, J, K]
                pos = (i - bx[I], j - by[J], k - bz[K])
                ln = (bx[I + 1] - bx[I], by[J + 1] - by[J], bz[K + 1] - bz[K])
                for d in range(3):
                    for a in range(2):
                        t = (pos[d] + a) / ln[d]
                        w[d, a, 0] = 1.0 - t
                        w[d, a, 1] = t
                for a in range(8):
                    for A in range(8):
                        W[a, A] = w[0, a & 1, A & 1] * w[1, (a >> 1) & 1, (A >> 1) & 1] * w[2, (a >> 2) & 1, (A >> 2) & 1]
                for a in range(8):
                    ii = (i + (a & 1)) % Nx
                    jj = (j + ((a >> 1) & 1)) % Ny
                    kk = (k + ((a >> 2) & 1)) % Nz
                    for c in range(3):
                        mf[3 * a + c] = free[ii, jj, kk, c]
                s = scale[i, j, k]
                for r in range(24):
                    for q in range(24):
                        Km[r, q] = s * mats[e, r, q] * mf[r] * mf[q]
                # T = Km W (W acting per displacement component), then Kc += W^T T
                for r in range(24):
                    for B in range(8):
                        for c in range(3):
                            acc = 0.0
                            for b in range(8):
                                acc += Km[r, 3 * b + c] * W[b, B]
                            T[r, 3 * B + c] = acc
                for A in range(8):
                    for c in range(3):
                        for q in range(24):
                            acc = 0.0
                            for a in range(8):
                                acc += W[a, A] * T[3 * a + c, q]
                            cmats[ce, 3 * A + c, q] += acc


@numba.njit(cache=True)
def _prolong(uc, xlo, xhi, xwl, xwh, ylo, yhi, ywl, ywh, zlo, zhi, zwl, zwh, uf):
    Nx, Ny, Nz = uf.shape[0], uf.shape[1], uf.shape[2]
    for i in range(Nx):
        ix = (xlo[i], xhi[i])
        wx = (xwl[i], xwh[i])
        for j in range(Ny):
            iy = (ylo[j], yhi[j])
            wy = (ywl[j], ywh[j])
            for k in range(Nz):
                iz = (zlo[k], zhi[k])
                wz = (zwl[k], zwh[k])
                for a in range(8):
                    wt = wx[a & 1] * wy[(a >> 1) & 1] * wz[(a >> 2) & 1]
                    if wt == 0.0:
                        continue
                    src = uc[ix[a & 1], iy[(a >> 1) & 1], iz[(a >> 2) & 1]]
                    for c in range(uf.shape[3]):
                        uf[i, j, k, c] += wt * src[c]


@numba.njit(cache=True)
def _restrict(rf, xlo, xhi, xwl, xwh, ylo, yhi, ywl, ywh, zlo, zhi, zwl, zwh, rc):
    Nx, Ny, Nz = rf.shape[0], rf.shape[1], rf.shape[2]
    for i in range(Nx):
        ix = (xlo[i], xhi[i])
        wx = (xwl[i], xwh[i])
        for j in range(Ny):
            iy = (ylo[j], yhi[j])
            wy = (ywl[j], ywh[j])
            for k in range(Nz):
                iz = (zlo[k], zhi[k])
                wz = (zwl[k], zwh[k])
                for a in range(8):
                    wt = wx[a & 1] * wy[(a >> 1) & 1] * wz[(a >> 2) & 1]
                    if wt == 0.0:
                        continue
                    dst = rc[ix[a & 1], iy[(a >> 1) & 1], iz[(a >> 2) & 1]]
                    for c in range(rf.shape[3]):
                        dst[c] += wt * rf[i, j, k, c]


# --------------------------------------------------------------------------- compact transfers
# The same sums on compact blocks (:mod:`.compact`): fine and coarse nodes renumbered through
# their node maps (-1: inactive, zero, skipped), visited in the same order as above, so the
# active values have the bits of ``free * restrict(..)`` and ``x + free * prolong(..)``.


def restrict_compact(rf: np.ndarray, transfer, fine_map: np.ndarray, fine_nodes, coarse_map: np.ndarray,
                     coarse_nodes, coarse_free: np.ndarray) -> np.ndarray:
    """``free_c * P^T rf`` on compact blocks: (a_f, 3, m) -> (a_c, 3, m).

    fine_map, coarse_map : flat grid node -> compact index (-1 inactive) of each level;
    fine_nodes, coarse_nodes : node grid shapes; coarse_free : (a_c, 3) in {0, 1}.
    """
    m = rf.shape[2]
    rc = np.zeros((len(coarse_free), 3, m))
    (x, y, z) = transfer
    _restrict_c(np.ascontiguousarray(rf), fine_map, np.array(fine_nodes, np.int64), coarse_map,
                np.array(coarse_nodes, np.int64), *x, *y, *z, rc)
    rc *= coarse_free[..., None]
    return rc


def prolong_add_compact(x: np.ndarray, fine_free: np.ndarray, xc: np.ndarray, transfer, fine_map: np.ndarray,
                        fine_nodes, coarse_map: np.ndarray, coarse_nodes) -> None:
    """``x += free_f * P xc`` on compact blocks, in place: x (a_f, 3, m), xc (a_c, 3, m)."""
    (tx, ty, tz) = transfer
    _prolong_c(np.ascontiguousarray(xc), coarse_map, np.array(coarse_nodes, np.int64), fine_map,
               np.array(fine_nodes, np.int64), *tx, *ty, *tz, fine_free, x)


@numba.njit(cache=True)
def _restrict_c(rf, fmap, Nf, cmap, Nc, xlo, xhi, xwl, xwh, ylo, yhi, ywl, ywh, zlo, zhi, zwl, zwh, rc):
    m = rf.shape[2]
    for i in range(Nf[0]):
        ix = (xlo[i], xhi[i])
        wx = (xwl[i], xwh[i])
        for j in range(Nf[1]):
            iy = (ylo[j], yhi[j])
            wy = (ywl[j], ywh[j])
            for k in range(Nf[2]):
                f = fmap[(i * Nf[1] + j) * Nf[2] + k]
                if f < 0:
                    continue
                iz = (zlo[k], zhi[k])
                wz = (zwl[k], zwh[k])
                for a in range(8):
                    wt = wx[a & 1] * wy[(a >> 1) & 1] * wz[(a >> 2) & 1]
                    if wt == 0.0:
                        continue
                    d = cmap[(ix[a & 1] * Nc[1] + iy[(a >> 1) & 1]) * Nc[2] + iz[(a >> 2) & 1]]
                    if d < 0:
                        continue
                    for c in range(3):
                        for l in range(m):
                            rc[d, c, l] += wt * rf[f, c, l]


@numba.njit(cache=True, parallel=True)
def _prolong_c(xc, cmap, Nc, fmap, Nf, xlo, xhi, xwl, xwh, ylo, yhi, ywl, ywh, zlo, zhi, zwl, zwh, free, x):
    m = x.shape[2]
    for i in numba.prange(Nf[0]):  # each fine node is written by its own iteration only
        acc = np.empty((3, m))
        ix = (xlo[i], xhi[i])
        wx = (xwl[i], xwh[i])
        for j in range(Nf[1]):
            iy = (ylo[j], yhi[j])
            wy = (ywl[j], ywh[j])
            for k in range(Nf[2]):
                f = fmap[(i * Nf[1] + j) * Nf[2] + k]
                if f < 0:
                    continue
                iz = (zlo[k], zhi[k])
                wz = (zwl[k], zwh[k])
                acc[:] = 0.0
                for a in range(8):
                    wt = wx[a & 1] * wy[(a >> 1) & 1] * wz[(a >> 2) & 1]
                    if wt == 0.0:
                        continue
                    s = cmap[(ix[a & 1] * Nc[1] + iy[(a >> 1) & 1]) * Nc[2] + iz[(a >> 2) & 1]]
                    if s < 0:
                        continue
                    for c in range(3):
                        for l in range(m):
                            acc[c, l] += wt * xc[s, c, l]
                for c in range(3):
                    for l in range(m):
                        x[f, c, l] += free[f, c] * acc[c, l]
