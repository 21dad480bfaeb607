"""Pictures of the tripod sheets: fibre spirals (paper Fig. 3) and IceSL print-map slices.

Functions return PNG bytes (matplotlib, Agg); the stage layer writes them.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from . import figure_png, one_at_a_time


def _figure(ncols: int, nrows: int = 1, size: float = 5.0):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(nrows, ncols, figsize=(size * ncols, size * nrows), squeeze=False)
    return fig, axes



@one_at_a_time
def sheet_picture(
    outline: np.ndarray,
    hole_radius: float,
    panels: Sequence[tuple[str, Callable[[np.ndarray], np.ndarray], np.ndarray]],
) -> bytes:
    """Fibre streaks over the sheet outline, one panel per sheet (Fig. 3 of the paper).

    Parameters
    ----------
    outline : (k, 2) closed outer outline [mm] (the same for both sheets, which are
        reflections of a symmetric shape).
    hole_radius : central hole radius [mm].
    panels : (title, fiber_fn, attach_points) per sheet; ``fiber_fn`` maps points (q, 3)
        [mm] to unit fibres (q, 3); ``attach_points`` (a, 3) [mm] are drawn as grey dots
        (the servo-horn and effector node sets).
    """
    from matplotlib.collections import LineCollection
    from matplotlib.path import Path as MplPath

    from .streaks import streak_lines

    fig, axes = _figure(len(panels))
    path = MplPath(outline)
    lo, hi = outline.min(axis=0) - 3, outline.max(axis=0) + 3
    xs, ys = np.linspace(lo[0], hi[0], 220), np.linspace(lo[1], hi[1], 220)
    X, Y = np.meshgrid(xs, ys)
    P = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], axis=1)
    inside = path.contains_points(P[:, :2]) & (np.hypot(P[:, 0], P[:, 1]) > hole_radius)
    for ax, (title, fn, attach) in zip(axes[0], panels):
        f = fn(P)
        U = np.where(inside, f[:, 0], np.nan).reshape(X.shape)
        V = np.where(inside, f[:, 1], np.nan).reshape(X.shape)
        # colour by the fibre's axis angle (mod 180 deg) with a cyclic map
        ang = np.mod(np.degrees(np.arctan2(f[:, 1], f[:, 0])), 180.0)
        A = np.where(inside, ang, np.nan).reshape(X.shape)
        im = ax.pcolormesh(X, Y, A, cmap="twilight", vmin=0, vmax=180, shading="auto", alpha=0.55)
        spacing = float(np.max(hi - lo)) / 48
        ax.add_collection(LineCollection(streak_lines(xs, ys, U, V, spacing, 0.9 * spacing), colors="k",
                                         linewidths=0.8))
        ax.plot(*np.vstack([outline, outline[:1]]).T, color="k", lw=2)
        t = np.linspace(0, 2 * np.pi, 90)
        ax.plot(hole_radius * np.cos(t), hole_radius * np.sin(t), color="k", lw=2)
        if len(attach):
            ax.plot(attach[:, 0], attach[:, 1], ".", color="0.35", ms=2.5, label="attached nodes")
        ax.set_title(title)
        ax.set_aspect("equal")
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("y [mm]")
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
    cb = fig.colorbar(im, ax=axes[0].tolist(), shrink=0.8, pad=0.02)
    cb.set_label("fibre axis angle [deg] (soft direction l)")
    return figure_png(fig, dpi=110)


@one_at_a_time
def printmap_picture(
    slices: Sequence[tuple[str, dict[str, np.ndarray], np.ndarray, np.ndarray, tuple]],
    values: dict[str, float] | None = None,
) -> bytes:
    """Mid-plane slices of the print-map fields, one row per sheet.

    Parameters
    ----------
    slices : (title, fields, inside, solid, extent) per sheet: ``fields`` name -> (n, n)
        slice in display units (indexed [i, j]): ``infill_percentage`` [%],
        ``kgon_x_shrink`` [-], ``axis angle`` [deg] in [0, 180) (the soft axis, a cyclic
        colour map); ``inside`` (n, n) bool part mask; ``solid`` (n, n) bool, the solid parts
        (brush 1, hatched); ``extent`` (xmin, xmax, ymin, ymax) [mm].
    values : settings written as one exact value rather than a field (name -> value): their
        panel says so, and a constant panel gets a colour range of +-5 % around its value.
    """
    values = values or {}
    names = list(slices[0][1])
    fig, axes = _figure(len(names), len(slices), size=4.2)
    styles = {  # name -> (label, colour map, range or None for the data's)
        "infill_percentage": ("infill percentage [%]", "viridis", None),
        "kgon_x_shrink": ("kgon x shrink [-]", "magma", None),
        "axis angle": ("soft axis angle [deg], mod 180", "twilight", (0.0, 180.0)),
    }
    for row, (title, fields, inside, solid, extent) in zip(axes, slices):
        for ax, name in zip(row, names):
            label, cmap, rng = styles.get(name, (name, "viridis", None))
            val = np.where(inside, fields[name], np.nan)
            if rng is None:
                lo, hi = np.nanmin(val), np.nanmax(val)
                pad = 0.05 * max(abs(hi), 1e-12)
                rng = (lo - pad, hi + pad) if hi - lo < 1e-9 else (lo, hi)
            if name in values:
                label = f"{label} = {values[name]:g} (a value)"
            im = ax.imshow(val.T, origin="lower", extent=extent, vmin=rng[0], vmax=rng[1],
                           cmap=cmap, interpolation="nearest")
            ax.contour(inside.T.astype(float), levels=[0.5], colors="k", linewidths=1.2,
                       extent=extent, origin="lower")
            if solid.any():
                ax.contourf(solid.T.astype(float), levels=[0.5, 1.5], colors="none", hatches=["////"],
                            extent=extent, origin="lower")
                ax.contour(solid.T.astype(float), levels=[0.5], colors="0.3", linewidths=0.8,
                           extent=extent, origin="lower")
            ax.set_title(f"{title}: {label}", fontsize=9)
            ax.set_aspect("equal")
            ax.set_xlabel("x [mm]")
            fig.colorbar(im, ax=ax, shrink=0.75)
        row[0].set_ylabel("y [mm]")
    fig.suptitle("IceSL print map, mid-plane slice (black: part outline; hatched: solid parts, brush 1)")
    return figure_png(fig, dpi=110)
