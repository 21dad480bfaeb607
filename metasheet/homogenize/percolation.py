"""Which voxels of a periodic cell carry load: face-connected parts that wrap around.

A part that does not wrap around the periodic box in all three directions (an island,
or a layer that does not connect across a void) carries no macroscopic stress and
makes the stiffness matrix singular, so it is removed. Face connectivity is used
because voxels touching only along an edge or at a corner form hinges (mechanisms).
A part wraps around direction d exactly when its lift to the box doubled along d is
still connected (a loop with odd winding number exists; the even-only case does not
occur for cells that repeat with the box's period).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy import ndimage
from scipy.sparse.csgraph import connected_components

from ..errors import InfeasibleError

_FACES = ndimage.generate_binary_structure(3, 1)


def periodic_label(mask: np.ndarray) -> tuple[np.ndarray, int]:
    """Face-connected parts of a periodic boolean grid.

    Parameters
    ----------
    mask : (nx, ny, nz) bool.

    Returns
    -------
    labels : (nx, ny, nz) int, 0 outside ``mask``, 1..n inside.
    n : number of parts.
    """
    lab, n = ndimage.label(mask, structure=_FACES)
    if n == 0:
        return lab, 0
    rows, cols = [], []
    for d in range(3):
        a = np.take(lab, 0, axis=d).ravel()
        b = np.take(lab, -1, axis=d).ravel()
        both = (a > 0) & (b > 0)
        rows.append(a[both])
        cols.append(b[both])
    r = np.concatenate(rows + [np.arange(1, n + 1)])
    c = np.concatenate(cols + [np.arange(1, n + 1)])
    G = sp.coo_matrix((np.ones(len(r), np.int8), (r, c)), shape=(n + 1, n + 1))
    _, merged = connected_components(G, directed=False)
    # relabel 1..k in order of first appearance, void stays 0
    roots = merged[1:]
    uniq, relabel = np.unique(roots, return_inverse=True)
    table = np.concatenate([[0], relabel + 1])
    return table[lab], len(uniq)


def percolating_solid(solid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Keep the parts of ``solid`` that wrap around the box in x, y and z.

    Parameters
    ----------
    solid : (nx, ny, nz) bool.

    Returns
    -------
    keep : (nx, ny, nz) bool, the load-carrying solid.
    wraps : (n_parts, 3) bool, which directions each part wraps around.

    Raises
    ------
    InfeasibleError : no part wraps around all three directions.
    """
    labels, n = periodic_label(solid)
    if n == 0:
        raise InfeasibleError("phases: the cell has no solid voxel (all phases are 0 = void)")
    flat = labels.ravel()
    labs, first = np.unique(flat, return_index=True)
    first = first[labs > 0]  # one voxel per part, in label order 1..n
    wraps = np.zeros((n, 3), bool)
    for d in range(3):
        lab2, _ = periodic_label(np.concatenate([solid, solid], axis=d))
        idx = np.array(np.unravel_index(first, solid.shape))
        shifted = idx.copy()
        shifted[d] += solid.shape[d]
        wraps[:, d] = lab2[tuple(idx)] == lab2[tuple(shifted)]
    ok = np.flatnonzero(wraps.all(axis=1))
    if len(ok) == 0:
        best = wraps.sum(axis=1).argmax()
        missing = "".join("xyz"[d] for d in range(3) if not wraps[best, d])
        raise InfeasibleError(
            f"phases: the solid does not percolate: no connected part wraps around the cell in "
            f"every direction (the best one misses {missing}); a non-percolating cell has no "
            "macroscopic stiffness"
        )
    keep = np.isin(labels, ok + 1)
    return keep, wraps
