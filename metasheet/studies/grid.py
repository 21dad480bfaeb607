"""The star-shaped grid of goal points of the workspace study (paper Fig. 5).

Rays leave the rest pose along the actuation directions: ``n_azimuth`` directions in the
plane normal to the rod (the motors sit every 60 deg around it once both tripods are
counted, so the default 12 directions hold the motor directions and those between them),
at ``n_elevation`` elevations towards the rod axis, plus the two rod directions. Points sit
on each ray at ``t = 1/n, 2/n, ..., 1`` of an ellipsoidal extent (``extent_axial`` along
the rod, ``extent_lateral`` across it). The paper removes most points near the centre to
save time: points with ``t < thin_below`` are kept only every ``thin_every``-th one.
The defaults give 1,798 points (62 rays).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, check_range


@dataclass(frozen=True)
class StarGrid:
    """Goal points of the workspace study.

    Attributes
    ----------
    points : (n, 3) float, offsets from the rest position [mm].
    ray : (n,) int, the ray of each point.
    index : (n,) int, the point's step number along its ray (1 = nearest the centre).
    directions : (n_rays, 3) float, unit ray directions (before the ellipsoidal scaling).
    azimuth : (n_rays,) int, azimuth index of each ray (-1 for the two rod rays).
    elevation : (n_rays,) int, elevation index of each ray (-1 / n_elevation for the rod rays).
    n_steps : points per ray before thinning.
    """

    points: np.ndarray
    ray: np.ndarray
    index: np.ndarray
    directions: np.ndarray
    azimuth: np.ndarray
    elevation: np.ndarray
    n_steps: int

    def __len__(self) -> int:
        return len(self.points)

    def ray_points(self, r: int) -> np.ndarray:
        """Indices of the points of ray ``r``, from the centre outwards."""
        sel = np.flatnonzero(self.ray == r)
        return sel[np.argsort(self.index[sel])]

    def neighbour_rays(self) -> list[tuple[int, int]]:
        """Pairs of adjacent rays (next azimuth, next elevation; rod rays to the nearest ring)."""
        n_az = int(self.azimuth.max()) + 1
        n_el = int(self.elevation[self.azimuth >= 0].max()) + 1
        rid = {(int(a), int(e)): r for r, (a, e) in enumerate(zip(self.azimuth, self.elevation)) if a >= 0}
        pairs = set()
        for (a, e), r in rid.items():
            pairs.add(tuple(sorted((r, rid[((a + 1) % n_az, e)]))))
            if (a, e + 1) in rid:
                pairs.add(tuple(sorted((r, rid[(a, e + 1)]))))
        for r in np.flatnonzero(self.azimuth < 0):
            ring = 0 if self.elevation[r] < 0 else n_el - 1
            for a in range(n_az):
                pairs.add(tuple(sorted((int(r), rid[(a, ring)]))))
        return sorted(pairs)


def star_grid(
    *,
    n_azimuth: int = 12,
    n_elevation: int = 5,
    max_elevation_deg: float = 60.0,
    n_steps: int = 37,
    extent_axial: float = 20.0,
    extent_lateral: float = 20.0,
    thin_below: float = 0.35,
    thin_every: int = 3,
    rod_axis: int = 0,
) -> StarGrid:
    """Build the star grid (see the module docstring); all lengths in mm.

    Elevations are spread evenly over ``[-max_elevation_deg, max_elevation_deg]``
    (one elevation means the plane normal to the rod only).
    """
    for f, v, lo, hi in (("n_azimuth", n_azimuth, 2, 720), ("n_elevation", n_elevation, 1, 181),
                         ("n_steps", n_steps, 1, 10000), ("thin_every", thin_every, 1, 10000),
                         ("rod_axis", rod_axis, 0, 2)):
        if int(v) != v:
            raise ConfigError(f"{f}: {v!r}: expected an integer")
        check_range(f, v, lo, hi)
    check_range("max_elevation_deg", max_elevation_deg, 0.0, 90.0, hi_open=True)
    check_range("extent_axial", extent_axial, 0.0, None, lo_open=True)
    check_range("extent_lateral", extent_lateral, 0.0, None, lo_open=True)
    check_range("thin_below", thin_below, 0.0, 1.0)

    az = 2 * np.pi * np.arange(n_azimuth) / n_azimuth
    el = np.radians(np.linspace(-max_elevation_deg, max_elevation_deg, n_elevation)) if n_elevation > 1 else np.zeros(1)
    dirs, a_idx, e_idx = [], [], []
    for j, e in enumerate(el):
        for i, a in enumerate(az):
            dirs.append((np.sin(e), np.cos(e) * np.cos(a), np.cos(e) * np.sin(a)))
            a_idx.append(i)
            e_idx.append(j)
    for sgn, tag in ((-1.0, -1), (1.0, n_elevation)):
        dirs.append((sgn, 0.0, 0.0))
        a_idx.append(-1)
        e_idx.append(tag)
    dirs = np.array(dirs)
    scale = np.array([extent_axial, extent_lateral, extent_lateral])
    # local frame: component 0 along the rod; permute into the robot's axes
    perm = [(rod_axis + k) % 3 for k in range(3)]
    t = np.arange(1, n_steps + 1) / n_steps
    keep = (t >= thin_below) | ((np.arange(1, n_steps + 1) % thin_every) == 0)
    pts, ray, idx = [], [], []
    for r, d in enumerate(dirs):
        for k in np.flatnonzero(keep):
            p = np.empty(3)
            p[perm] = t[k] * d * scale
            pts.append(p)
            ray.append(r)
            idx.append(k + 1)
    dirs_world = np.empty_like(dirs)
    dirs_world[:, perm] = dirs
    return StarGrid(np.array(pts), np.array(ray), np.array(idx), dirs_world,
                    np.array(a_idx), np.array(e_idx), int(n_steps))
