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

from ..cells.connectivity import periodic_labels
from ..errors import InfeasibleError

def periodic_label(mask: np.ndarray) -> tuple[np.ndarray, int]:
    """Face-connected parts of a periodic boolean grid (the cell stage's labelling).

    Parameters
    ----------
    mask : (nx, ny, nz) bool.

    Returns
    -------
    labels : (nx, ny, nz) int, 0 outside ``mask``, 1..n inside.
    n : number of parts.
    """
    labels, n, _, _ = periodic_labels(mask)
    return labels, n


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
