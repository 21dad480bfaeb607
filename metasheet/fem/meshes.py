"""Structured tetrahedral meshes of a box, for tests, benchmarks and examples.

:func:`box_mesh` splits every cell of a regular grid into 6 conforming tets (Kuhn), with an
optional random jitter of the interior nodes for an irregular mesh with flat faces.
"""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError, check_range


def box_mesh(size, divisions, *, jitter: float = 0.0, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A box [0, a] x [0, b] x [0, c] split into 6 conforming tets per cell (Kuhn subdivision).

    Parameters
    ----------
    size : (3,) float [mm]; divisions : (3,) int cells per axis.
    jitter : interior nodes move randomly by up to ``jitter`` times the cell size (< 0.3
        keeps every tet valid), giving an irregular mesh with a flat boundary.
    seed : for the jitter.

    Returns points (n, 3) [mm], tets (m, 4) int64 (positively oriented).
    """
    size = np.asarray(size, float)
    nd = np.asarray(divisions, int)
    if size.shape != (3,) or np.any(size <= 0):
        raise ConfigError(f"size: {size.tolist()}: should be three lengths > 0 [mm]")
    if nd.shape != (3,) or np.any(nd < 1):
        raise ConfigError(f"divisions: {nd.tolist()}: should be three integers >= 1")
    check_range("jitter", jitter, 0.0, 0.3)
    axes = [np.linspace(0.0, size[k], nd[k] + 1) for k in range(3)]
    P = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    idx = np.arange(len(P)).reshape(nd + 1)
    if jitter > 0:
        interior = np.all((P > 1e-12 * size) & (P < size * (1 - 1e-12)), axis=1)
        rng = np.random.default_rng(seed)
        P[interior] += jitter * (size / nd) * rng.uniform(-1, 1, (interior.sum(), 3))
    corner = {}
    for b in range(8):
        i, j, k = (b >> 0) & 1, (b >> 1) & 1, (b >> 2) & 1
        corner[(i, j, k)] = idx[i : i + nd[0], j : j + nd[1], k : k + nd[2]].ravel()
    tets = []
    for perm in ((0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)):
        path, v = [(0, 0, 0)], [0, 0, 0]
        for ax in perm:
            v[ax] = 1
            path.append(tuple(v))
        t = np.stack([corner[c] for c in path], 1)
        tets.append(t)
    tets = np.concatenate(tets)
    X = P[tets]
    det = np.linalg.det(X[:, 1:] - X[:, :1])
    tets[det < 0] = tets[det < 0][:, [0, 2, 1, 3]]
    return P, tets.astype(np.int64)
