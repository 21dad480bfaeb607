"""Periodicity of node-matched tet meshes: the explicit projection P.

A node on a face x = x0 + Lx (or y, z, and the edges and corners where such faces
meet) is a *slave* of the node at the wrapped position. Every node gets one column
of P (3 dofs each): ``P[3 i + d, 3 master(i) + d] = 1``. The periodic problem
``P^T K P x = P^T f`` is then exact; no penalty and no Lagrange multipliers
(scikit-fem's ``mpc`` helper was seen to go wrong on periodic constraints).

Percolation of a tet mesh: the non-periodic connected pieces are glued by the
slave-master pairs, each glue carrying the lattice shift it crosses. A periodic part
wraps around direction d when a loop of glues has a non-zero net shift along d.
"""

from __future__ import annotations

from collections import deque

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..errors import MeshError


def periodic_masters(points: np.ndarray, size, origin=None, tol: float | None = None):
    """Master node of every node of a node-matched periodic mesh.

    Parameters
    ----------
    points : (n, 3) float [mm], inside the box [origin, origin + size].
    size : (3,) float [mm].
    origin : (3,) float [mm], default ``points.min(axis=0)``.
    tol : matching tolerance [mm], default ``1e-6 max(size)``.

    Returns
    -------
    master : (n,) int, compact master index (0 .. m-1) of each node.
    shift : (n, 3) int, lattice shift of each node from its master (1 on the far faces).
    m : number of masters (independent nodes).

    Raises
    ------
    MeshError : points outside the box, or duplicate nodes.
    """
    p = np.asarray(points, float)
    L = np.asarray(size, float)
    o = p.min(axis=0) if origin is None else np.asarray(origin, float)
    tol = 1e-6 * float(L.max()) if tol is None else float(tol)
    q = p - o
    if np.any(q < -tol) or np.any(q > L + tol):
        raise MeshError(f"points: outside the box origin {o.tolist()} + size {L.tolist()} [mm]")
    shift = (np.abs(q - L) <= tol).astype(np.int64)
    q = q - shift * L
    key = np.round(q / tol).astype(np.int64)
    _, master = np.unique(key, axis=0, return_inverse=True)
    master = master.ravel()
    n_master = int(master.max()) + 1
    # A far-face node without a partner (possible where the solid touches only one face
    # at that point, e.g. a voxel mesh) is the master of its class: shifts become relative to it.
    independent = ~shift.any(axis=1)
    lone = np.bincount(master[independent], minlength=n_master) == 0
    first = np.unique(master, return_index=True)[1]
    in_lone = lone[master]
    shift[in_lone] -= shift[first[master[in_lone]]]
    if np.any(np.bincount(master[~shift.any(axis=1)], minlength=n_master) > 1):
        raise MeshError("points: duplicate nodes (two nodes at one position in the box)")
    return master, shift, n_master


def projection(master: np.ndarray, n_master: int) -> sp.csr_matrix:
    """(3 n, 3 m) 0/1 projection: slave dof -> its master's column."""
    n = len(master)
    rows = np.arange(3 * n)
    cols = (3 * master[:, None] + np.arange(3)).ravel()
    return sp.csr_matrix((np.ones(3 * n), (rows, cols)), shape=(3 * n, 3 * n_master))


def wrapping_parts(tets: np.ndarray, n_points: int, master: np.ndarray, shift: np.ndarray):
    """Which tets belong to periodic parts that wrap around all three directions.

    Parameters
    ----------
    tets : (m, 4) int; n_points : number of mesh points;
    master, shift : from :func:`periodic_masters`.

    Returns
    -------
    keep : (m,) bool; wraps : (n_parts, 3) bool per periodic part.
    """
    tets = np.asarray(tets)
    r = np.repeat(tets[:, :1], 3, axis=1).ravel()
    c = tets[:, 1:].ravel()
    G = sp.coo_matrix((np.ones(len(r), np.int8), (r, c)), shape=(n_points, n_points))
    n_pieces, piece = connected_components(G, directed=False)
    # glue every node to the piece holding its master's representative (first node of the class)
    rep = np.full(master.max() + 1, -1)
    indep = np.flatnonzero(~shift.any(axis=1))
    rep[master[indep]] = indep
    used = np.zeros(n_points, bool)
    used[tets.ravel()] = True
    nodes = np.flatnonzero(used & shift.any(axis=1))
    a, b, s = piece[nodes], piece[rep[master[nodes]]], shift[nodes]
    adj: list[list[tuple[int, np.ndarray]]] = [[] for _ in range(n_pieces)]
    for ai, bi, si in zip(a, b, s):
        adj[bi].append((ai, si))
        adj[ai].append((bi, -si))
    offset = np.zeros((n_pieces, 3), np.int64)
    part = np.full(n_pieces, -1)
    wraps = []
    for start in range(n_pieces):
        if part[start] >= 0:
            continue
        k = len(wraps)
        w = np.zeros(3, bool)
        part[start] = k
        queue = deque([start])
        while queue:
            x = queue.popleft()
            for y, sh in adj[x]:
                if part[y] < 0:
                    part[y] = k
                    offset[y] = offset[x] + sh
                    queue.append(y)
                else:
                    w |= offset[y] != offset[x] + sh
        wraps.append(w)
    wraps = np.array(wraps).reshape(-1, 3)
    keep = wraps[part[piece[tets[:, 0]]]].all(axis=1)
    return keep, wraps
