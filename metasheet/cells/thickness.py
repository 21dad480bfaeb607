"""The density solve: the strut radius or wall thickness giving a foam's relative density.

The voxel solid fraction of a foam is a step function of its offset (strut radius, or half
the wall thickness) whose exact solution is an order statistic of the skeleton distances at
the voxel centres (:mod:`metasheet.cells.skeleton`); :func:`solve_thickness` picks it and
reports the reachable range when the target cannot be met at that resolution.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, InfeasibleError, check_range
from .foam import TOPOLOGIES, check_resolution, voxel_centres
from .metrics import Metric
from .skeleton import SkeletonIndex


@dataclass(frozen=True)
class ThicknessSolution:
    """The solved strut radius or wall thickness of a foam.

    Attributes
    ----------
    thickness : strut radius (open) or wall thickness (closed) [mm].
    relative_density : solid fraction of the voxel grid it gives [-].
    volume_estimate : sub-voxel (partial-volume) estimate of the solid fraction of the
        continuous foam at that thickness [-]; what a fine surface mesh should enclose.
    target : the asked relative density [-].
    reachable : (lo, hi) range of relative densities this grid can give [-].
    resolution : voxels per side.
    """

    thickness: float
    relative_density: float
    volume_estimate: float
    target: float
    reachable: tuple[float, float]
    resolution: int


def _partial_volume(dist: np.ndarray, offset: float, h: float) -> float:
    """Solid fraction with each voxel counted by the part of it inside (unit-slope ramp)."""
    return float(np.mean(np.clip(0.5 + (offset - dist) / h, 0.0, 1.0)))


def solve_thickness(
    seeds: np.ndarray,
    size,
    metric: Metric,
    topology: str,
    target: float,
    n: int,
    *,
    min_voxels: float = 2.0,
    distances: np.ndarray | None = None,
) -> ThicknessSolution:
    """Strut radius / wall thickness giving a voxel solid fraction of ``target``.

    The solid is ``{distance < offset}`` with one distance per voxel centre, so the voxel
    fraction is a step function of the offset whose exact solution is an order statistic
    of the distances: the offset is put halfway between the ``m``-th and ``m+1``-th smallest
    distances, ``m = round(target * n^3)``, which hits the target to ``1 / n^3``.

    Parameters
    ----------
    seeds : (N, 3) [mm]; size : (3,) [mm]; metric; topology : 'open' or 'closed'.
    target : relative density [-], in (0, 1).
    n : voxels per side.
    min_voxels : the thinnest strut diameter or wall thickness allowed, in voxels; it sets
        the lowest reachable density at this resolution.
    distances : (n^3,) precomputed skeleton distances at the voxel centres (optional).

    Raises
    ------
    InfeasibleError : ``target`` outside the reachable range, named in the message.
    """
    if topology not in TOPOLOGIES:
        raise ConfigError(f"topology: {topology!r}: expected one of {', '.join(TOPOLOGIES)}")
    check_range("relative_density", target, 0.0, 1.0, lo_open=True, hi_open=True)
    n = check_resolution(n)
    size = np.asarray(size, dtype=float)
    if distances is None:
        sk = SkeletonIndex(seeds, size, metric).distances(voxel_centres(size, n))
        distances = sk.strut if topology == "open" else sk.wall
    d = np.sort(np.asarray(distances, dtype=float).ravel())
    total = d.size
    h = float(np.mean(size)) / n  # mean voxel size [mm]
    # offset = strut radius (open) or half the wall thickness (closed); the thinnest
    # feature is counted in the largest voxel side (the coarsest direction)
    min_offset = 0.5 * min_voxels * float(np.max(size)) / n
    lo = float(np.searchsorted(d, min_offset, side="left")) / total
    hi = float(total - 1) / total  # at least one void voxel
    m = int(round(float(target) * total))
    what = "strut diameter" if topology == "open" else "wall thickness"
    if not (lo <= m / total <= hi) or m < 1:
        raise InfeasibleError(
            f"relative_density: {float(target):g}: unreachable for this {topology}-cell foam at "
            f"resolution {n}: reachable range is [{lo:.4f}, {hi:.4f}] ({what} >= {min_voxels:g} "
            f"voxels = {2 * min_offset:.3g} mm); raise the resolution or the density"
        )
    offset = 0.5 * (d[m - 1] + d[m]) if m < total else d[-1] + h
    offset = max(offset, min_offset)
    achieved = float(np.count_nonzero(d < offset)) / total
    thickness = offset if topology == "open" else 2.0 * offset
    return ThicknessSolution(
        thickness=float(thickness),
        relative_density=achieved,
        volume_estimate=_partial_volume(d, offset, h),
        target=float(target),
        reachable=(lo, hi),
        resolution=n,
    )
