"""Pictures and the voxel file of the Polyfoam printed in the sheet (:mod:`metasheet.sheet.printed_foam`).

:func:`printed_foam_picture` returns PNG bytes (matplotlib, Agg): the sheet's mid-plane
slice (the walls a horizontal cut shows, the spiral of the paper's Fig. 3) and a top view
(the solid's share along each vertical line through the sheet), with a second build's
slice beside it if asked (the two gauges). :func:`voxel_npz_bytes`
is the voxel file's bytes, the same arrays giving the same bytes; the caller writes them
(:func:`write_voxel_npz` does, for scripts).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..runtime.npz import npz_bytes
from . import figure_png, one_at_a_time

# phase colours: outside, foam void, foam wall, solid brush (RGBA)
_OUTSIDE = (1.0, 1.0, 1.0, 0.0)
_VOID = (0.97, 0.95, 0.90, 1.0)
_WALL = (0.10, 0.22, 0.45, 1.0)
_BRUSH = (0.55, 0.55, 0.55, 1.0)


def _slice_rgba(phases: np.ndarray, region: np.ndarray) -> np.ndarray:
    """(nx, ny, 4) colours of one z slice (phases, region (nx, ny) uint8)."""
    out = np.empty(phases.shape + (4,))
    out[:] = _OUTSIDE
    foam = region == 1
    out[foam & (phases == 0)] = _VOID
    out[foam & (phases == 1)] = _WALL
    out[region == 2] = _BRUSH
    return out


@one_at_a_time
def printed_foam_picture(phases: np.ndarray, region: np.ndarray, origin, voxel_mm, *, title: str = "",
                         layer: int | None = None, label: str = "",
                         other: tuple[str, np.ndarray] | None = None) -> bytes:
    """The slice at ``layer`` (default the mid-plane) and the top view; with ``other``, a second
    build's slice between them (the other gauge, say).

    Parameters
    ----------
    phases, region : (nx, ny, nz) uint8 (0 void, 1 solid; 0 outside, 1 foam, 2 solid brush).
    origin : (3,) [mm] the grid's low corner; voxel_mm : (3,) [mm] its voxel edges.
    title : a line above the panels; label : what ``phases`` is (in its slice's title).
    layer : the z index of the slice.
    other : (label, phases (nx, ny, nz)) of another build on the same grid and region.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    phases, region = np.asarray(phases), np.asarray(region)
    origin, h = np.asarray(origin, float), np.asarray(voxel_mm, float)
    nx, ny, nz = phases.shape
    k = nz // 2 if layer is None else int(layer)
    extent = (origin[0], origin[0] + nx * h[0], origin[1], origin[1] + ny * h[1])
    slices = [(label, phases)] + ([other] if other is not None else [])
    fig, axes = plt.subplots(1, len(slices) + 1, figsize=(6.25 * (len(slices) + 1), 6.0), squeeze=False)
    z = origin[2] + (k + 0.5) * h[2]
    for ax, (name, ph) in zip(axes[0], slices):
        ax.imshow(np.transpose(_slice_rgba(np.asarray(ph)[:, :, k], region[:, :, k]), (1, 0, 2)), origin="lower",
                  extent=extent, interpolation="nearest")
        head = f"{name}: " if name else ""
        ax.set_title(f"{head}slice z = {z:.2f} mm: walls (blue), solid brush (grey)", fontsize=10)
    # top view: the share of the part's voxels along z that are solid (foam walls and brush)
    part = region > 0
    n_part = part.sum(axis=2)
    share = np.where(n_part > 0, (phases.astype(np.int32) * part).sum(axis=2) / np.maximum(n_part, 1), np.nan)
    ax = axes[0, -1]
    im = ax.imshow(share.T, origin="lower", extent=extent, cmap="Blues", vmin=0.0, vmax=1.0,
                   interpolation="nearest")
    ax.set_title(f"{label + ': ' if label else ''}top view: solid share through the thickness", fontsize=10)
    cb = fig.colorbar(im, ax=ax, shrink=0.8, pad=0.02)
    cb.set_label("solid voxels / part voxels along z [-]")
    for a in axes[0]:
        a.set_aspect("equal")
        a.set_xlabel("x [mm]")
        a.set_ylabel("y [mm]")
    if title:
        fig.suptitle(title, fontsize=11)
    return figure_png(fig, dpi=110)


def voxel_npz_bytes(**arrays: np.ndarray) -> bytes:
    """The printed foam's byte-stable ``.npz`` (:func:`metasheet.runtime.npz.npz_bytes`): ``phases``
    (nx, ny, nz) uint8, ``region`` (nx, ny, nz) uint8, ``size`` (3,) [mm], ``origin`` (3,) [mm]
    and ``voxel_mm`` (3,) [mm]."""
    return npz_bytes(**arrays)


def printed_foam_npz(foam) -> bytes:
    """The voxel file of a :class:`~metasheet.sheet.printed_foam.PrintedFoam` (see :func:`voxel_npz_bytes`)."""
    return voxel_npz_bytes(phases=foam.phases.astype(np.uint8), region=foam.region.astype(np.uint8),
                           size=np.asarray(foam.size, float), origin=np.asarray(foam.origin, float),
                           voxel_mm=np.asarray(foam.voxel_mm, float))


def write_voxel_npz(path, foam) -> None:
    """Write :func:`printed_foam_npz` to ``path`` through a temporary name (never half-written)."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    tmp.write_bytes(printed_foam_npz(foam))
    os.replace(tmp, path)
