"""Connected components by union-find, numbered as scipy's ``connected_components`` numbers them.

scipy's undirected ``connected_components`` labels the components in the order of their smallest
member. :func:`first_member_labels` does the same from a union-find forest, so the voxel
hierarchy's labels (and every bit that depends on their order) are those of the graph route,
without building a graph of tens of millions of edges (the 64-cell Polyfoam cell: 20 s of its
set-up went to the graph and its components; tested against scipy in tests/test_voxel_split.py).
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def find(parent, i):
    """The root of ``i`` in the forest ``parent`` (n,) int64, halving the path on the way."""
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@numba.njit(cache=True)
def union(parent, i, j):
    """Join the trees of ``i`` and ``j`` under the smaller root."""
    r1, r2 = find(parent, i), find(parent, j)
    if r1 != r2:
        parent[max(r1, r2)] = min(r1, r2)


@numba.njit(cache=True)
def first_member_labels(parent):
    """(n,) int64 component label of each element: 0, 1, ... in the order of each component's
    smallest element."""
    n = len(parent)
    label = np.full(n, -1, np.int64)
    out = np.empty(n, np.int64)
    k = 0
    for i in range(n):
        r = find(parent, i)
        if label[r] < 0:
            label[r] = k
            k += 1
        out[i] = label[r]
    return out


@numba.njit(cache=True)
def components(n, a, b):
    """(n,) labels of the graph on n nodes with undirected edges ``(a[k], b[k])``."""
    parent = np.arange(n)
    for k in range(len(a)):
        union(parent, a[k], b[k])
    return first_member_labels(parent)
