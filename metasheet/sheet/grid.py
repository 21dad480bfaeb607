"""The texel grid of a print map: ``n`` texels per axis over a box, each sampled at its centre.

IceSL's 3D textures (:mod:`.icesl`) are ``N`` = 64 texels per axis over a box in world
millimetres; texel (i, j, k), along x, y, z, has its centre at ``lo + (i + 1/2) (hi - lo) / n``.
The grid sits apart from the texture files so the angle branches (:mod:`.angles`), which
read texel centres, and the print map (:mod:`.icesl`), which uses the branches, each
import it without importing the other.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

N = 64  # IceSL's texture size per axis (tex3d_r8f(64, 64, 64))


@dataclass(frozen=True)
class GridBox:
    """The texture box: ``lo``, ``hi`` (3,) [mm] and ``n`` texels per axis."""

    lo: np.ndarray
    hi: np.ndarray
    n: int = N

    @property
    def spacing(self) -> np.ndarray:
        """Texel size (3,) [mm]."""
        return (self.hi - self.lo) / self.n

    def axes(self) -> list[np.ndarray]:
        """Texel-centre coordinates along x, y, z: three (n,) arrays [mm]."""
        return [self.lo[a] + (np.arange(self.n) + 0.5) * self.spacing[a] for a in range(3)]

    def centers(self) -> np.ndarray:
        """Texel centres (n, n, n, 3) [mm], indexed [i, j, k]."""
        return np.stack(np.meshgrid(*self.axes(), indexing="ij"), axis=-1)

    def index_of(self, points: np.ndarray) -> np.ndarray:
        """Index (m, 3) int of the texel containing each point (m, 3) [mm] (clipped to the box)."""
        ijk = np.floor((np.asarray(points) - self.lo) / self.spacing).astype(np.int64)
        return np.clip(ijk, 0, self.n - 1)

    def texel_coordinates(self, points: np.ndarray) -> np.ndarray:
        """Continuous texel coordinates (m, 3) of points (m, 3) [mm]: texel centre i -> i."""
        return (np.asarray(points, dtype=float) - self.lo) / self.spacing - 0.5


def grid_box(points: np.ndarray, n: int = N) -> GridBox:
    """The bounding box of points (k, 3) [mm] as a texture box of n^3 texels."""
    p = np.asarray(points, dtype=float)
    return GridBox(p.min(axis=0), p.max(axis=0), int(n))
