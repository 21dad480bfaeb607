"""Where a voxel model of a printed foam is thinner than its walls: hinges and one-voxel walls.

Two solid voxels that meet along an edge only (both voxels that would join them by a face are
void) are a hinge in the voxel model: trilinear voxels joined by two nodes turn freely about
their common edge, where the printed walls are fused. A wall one voxel thick bends with one
element through its thickness. Both shrink as the voxels do; their counts say how far a voxel
size is from resolving the walls.
"""

from __future__ import annotations

import numpy as np

from ...errors import ConfigError


def _solid(phases) -> np.ndarray:
    ph = np.asarray(phases)
    if ph.ndim != 3:
        raise ConfigError(f"phases: shape {ph.shape}: must be a 3-D array (0 = void)")
    return np.pad(ph > 0, 1)  # a void border: no pair wraps around


def _shift(a: np.ndarray, d) -> np.ndarray:
    """a[i + d] at i (the padded border keeps wrapped values void)."""
    return np.roll(a, shift=tuple(-x for x in d), axis=(0, 1, 2))


def edge_hinges(phases) -> int:
    """The number of solid voxel pairs of ``phases`` (nx, ny, nz) int (0 void) that share an edge
    and no face path through a voxel next to both."""
    P = _solid(phases)
    count = 0
    for a, b in ((0, 1), (0, 2), (1, 2)):
        for sb in (1, -1):
            da, db = [0, 0, 0], [0, 0, 0]
            da[a], db[b] = 1, sb
            diag = [x + y for x, y in zip(da, db)]
            count += int((P & _shift(P, diag) & ~_shift(P, da) & ~_shift(P, db)).sum())
    return count


def thin_share(phases) -> float:
    """The share of solid voxels whose two neighbours along some axis are both void: walls one
    voxel thick [-] (0 with no solid)."""
    P = _solid(phases)
    thin = np.zeros_like(P)
    for ax in range(3):
        d = [0, 0, 0]
        d[ax] = 1
        thin |= ~_shift(P, d) & ~_shift(P, [-x for x in d])
    n = int(P.sum())
    return float((P & thin).sum()) / n if n else 0.0
