"""Sample cells built with numpy alone: test fixtures of the homogenisation (a helper module,
no tests here; it lived in ``metasheet/homogenize/samples.py``, which only tests used).

They let the homogenisation be tested without the cell stage: the solid cube, a
two-phase laminate (exact answer: :func:`homogenize_bounds.backus_laminate`),
a simple cubic strut lattice (stretch-dominated estimate E = E_s A / L^2) and an
open-cell "edge foam": voxels close to the edges of a periodic Voronoi tessellation,
where the third-nearest seed is almost as near as the nearest one.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from metasheet.errors import ConfigError


def laminate(n: int, fraction: float, *, axis: int = 2) -> np.ndarray:
    """(n, n, n) phases 1 | 2 in two layers normal to ``axis``; phase 1 takes ``fraction`` of n.

    ``fraction * n`` must be an integer number of voxels (the laminate is then exact).
    """
    k = fraction * n
    if abs(k - round(k)) > 1e-9 or not 0 < round(k) < n:
        raise ConfigError(f"fraction: {fraction!r}: fraction * n must be an integer in [1, {n - 1}]")
    ph = np.full((n, n, n), 2, np.int64)
    idx = [slice(None)] * 3
    idx[axis] = slice(0, int(round(k)))
    ph[tuple(idx)] = 1
    return ph


def cubic_lattice(n: int, width: int) -> np.ndarray:
    """(n, n, n) simple cubic lattice of square struts ``width`` voxels wide along x, y, z.

    Struts are centred in the cell, so the lattice has cubic symmetry.
    """
    if not (1 <= width < n) or (n - width) % 2:
        raise ConfigError(f"width: {width!r}: allowed 1 <= width < n with n - width even (n = {n})")
    band = np.zeros(n, bool)
    band[(n - width) // 2:(n + width) // 2] = True
    bx, by, bz = np.meshgrid(band, band, band, indexing="ij")
    return ((by & bz) | (bx & bz) | (bx & by)).astype(np.int64)


def edge_foam(n: int, density: float, *, seeds: int = 8, stretch: float = 1.0, rng_seed: int = 0,
              size=(1.0, 1.0, 1.0)) -> np.ndarray:
    """(n, n, n) phases of an open-cell periodic Voronoi foam of solid fraction ``density``.

    A voxel is solid where ``d3 - d1 < t`` (d_k distance to the k-th nearest seed in a
    metric compressed by ``stretch`` along z, so cells are elongated along z); ``t`` is
    set by bisection to hit ``density``. Same arguments give the same array.
    """
    if not 0.01 <= density <= 0.9:
        raise ConfigError(f"density: {density!r}: allowed range is [0.01, 0.9]")
    L = np.asarray(size, float) / np.array([1.0, 1.0, stretch])
    rng = np.random.default_rng(rng_seed)
    pts = rng.random((seeds, 3)) * L
    tree = cKDTree(pts, boxsize=L)
    h = 1.0 / n
    g = (np.arange(n) + 0.5) * h
    X = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3) * L
    d, _ = tree.query(X, k=3)
    gap = (d[:, 2] - d[:, 0]).reshape(n, n, n)
    t = np.quantile(gap, density)
    return (gap <= t).astype(np.int64)
