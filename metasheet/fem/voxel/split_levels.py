"""Split coarse levels below the first: node copies at spacing 2^k, split by the fine solid.

Level 1 (:func:`~.split.split_prolongation`) gives every trilinear coarse node one copy per
face-connected part of the fine solid voxels in its support. Level k does the same on the grid
of spacing 2^k: a copy is (a level-k node, a face-connected part of the *fine* solid voxels in
that node's 2 x 2 x 2 level-k cells). Splitting by the fine voxels keeps two walls a voxel
apart separate on every level; splitting by the coarse operator's graph instead joined them
again (89 CG iterations against 25 on the crop of the paper cell, docs/voxel.md).

Transfer from level k-1 to level k: copy c of node N (level k-1) interpolates to the level-k
nodes I with trilinear weight w(N, I), each onto the level-k copy of I whose part holds c's
part. The level-k cells are unions of level-(k-1) cells, so c's support lies inside I's
support and its (connected) part inside exactly one part of I; any voxel of c's part finds it.
Each row therefore holds exactly the trilinear weights of N and sums to 1: translations stay
exactly interpolated on every level (``P 1 = 1``, tested).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .coarsen import cell_bounds, choose_directions, node_weights
from .operator import node_shape
from .split import CONNECTIVITY, _merge_same_support, _parts

_CORNERS = np.array([[a & 1, (a >> 1) & 1, (a >> 2) & 1] for a in range(8)])


@dataclass(frozen=True)
class CellGrid:
    """One level's cells, seen from the fine solid voxels.

    Attributes
    ----------
    cell : (v, 3) int64, the cell of each fine solid voxel (rows of ``np.argwhere(index >= 0)``).
    shape : (3,) cells per direction; nodes : (3,) nodes per direction (periodic: = shape).
    bounds : three (shape_d + 1,) int64, the previous level's cells bounding this level's cells.
    h : (3,) float [mm], the cell's edge lengths.
    """

    cell: np.ndarray
    shape: tuple[int, int, int]
    nodes: tuple[int, int, int]
    bounds: tuple
    h: np.ndarray


@dataclass(frozen=True)
class Copies:
    """The node copies of one split level: a grid node and a voxel of its part each.

    Attributes
    ----------
    node : (c, 3) int64, the grid node of each copy; rep : (c,) int64, a fine solid voxel of its part.
    """

    node: np.ndarray
    rep: np.ndarray


def fine_grid(occ: np.ndarray, shape, h) -> CellGrid:
    """The fine voxels as level 0: occ (v, 3) int64 their indices, shape (3,), h (3,) [mm]."""
    shape = tuple(int(n) for n in shape)
    return CellGrid(np.asarray(occ, np.int64), shape, shape, tuple(np.arange(n + 1) for n in shape),
                    np.asarray(h, float))


def coarser_grid(grid: CellGrid, periodic: bool) -> CellGrid | None:
    """The next level's cells (2 of ``grid``'s per coarsened direction, 3 at an odd end;
    :func:`~.coarsen.choose_directions`), None when no direction can be coarsened."""
    dirs = choose_directions(grid.shape, grid.h, periodic)
    if not any(dirs):
        return None
    bounds = tuple(cell_bounds(n, c) for n, c in zip(grid.shape, dirs))
    up = [np.repeat(np.arange(len(b) - 1), np.diff(b)) for b in bounds]  # old cell -> new cell
    cell = np.stack([up[d][grid.cell[:, d]] for d in range(3)], 1)
    shape = tuple(len(b) - 1 for b in bounds)
    h = grid.h * np.array([2.0 if c else 1.0 for c in dirs])
    return CellGrid(cell, shape, node_shape(shape, periodic), bounds, h)


def split_parts(index: np.ndarray, occ: np.ndarray, grid: CellGrid, periodic: bool,
                connectivity: str = "face") -> tuple[np.ndarray, np.ndarray]:
    """Parts of every level-node support: (v, 8) int64 label of each (fine voxel, corner of its
    cell) pair, labels 0..n-1, and (v, 8) int64 the flat node of each pair."""
    N = np.array(grid.nodes)
    cnode = (grid.cell[:, None, :] + _CORNERS) % N
    cflat = (cnode[..., 0] * N[1] + cnode[..., 1]) * N[2] + cnode[..., 2]
    return _parts(index, occ, cflat, periodic, CONNECTIVITY[connectivity]), cflat


def copy_prolongation(prev: Copies, prev_grid: CellGrid, grid: CellGrid, part: np.ndarray, cflat: np.ndarray,
                      periodic: bool) -> tuple[sp.csr_matrix, Copies]:
    """The transfer from the copies ``prev`` of ``prev_grid`` to the parts of ``grid``.

    Parameters
    ----------
    prev : the previous level's copies; prev_grid, grid : their cells and the next level's.
    part, cflat : (v, 8) of :func:`split_parts` on ``grid``.

    Returns
    -------
    P : (c_prev, c) csr [-], rows summing to 1 (the trilinear weights of each copy's node);
    copies : the c copies of ``grid`` (parts reached by no row dropped; parts whose columns act on
        the same previous copies merged into one, as on level 1, so ``P^T A P`` is not made
        singular by parallel columns).
    """
    N = np.array(grid.nodes)
    nodes = (grid.cell[prev.rep][:, None, :] + _CORNERS) % N  # (c_prev, 8, 3) corners of the rep's cell
    w = np.ones(nodes.shape[:2])
    for d in range(3):
        lo, hi, wl, wh = node_weights(grid.bounds[d], prev_grid.nodes[d], periodic)
        n = prev.node[:, d][:, None]
        w *= np.where(lo[n] == nodes[..., d], wl[n], 0.0) + np.where(hi[n] == nodes[..., d], wh[n], 0.0)
    target = part[prev.rep]  # (c_prev, 8) the part of each corner holding the rep voxel
    rows = np.repeat(np.arange(len(prev.rep)), 8)
    keep = w.ravel() != 0
    used, cols = np.unique(target.ravel()[keep], return_inverse=True)
    P = sp.csr_matrix((w.ravel()[keep], (rows[keep], cols.ravel())), (len(prev.rep), len(used)))
    P.sum_duplicates()
    P.sort_indices()
    P, first = _merge_same_support(P)
    P.sort_indices()
    label_first = np.unique(part.ravel(), return_index=True)[1]  # first (voxel, corner) of each label
    pick = label_first[used[first]]
    node = np.stack(np.unravel_index(cflat.ravel()[pick], tuple(N)), 1)
    return P, Copies(node.astype(np.int64), (pick // 8).astype(np.int64))
