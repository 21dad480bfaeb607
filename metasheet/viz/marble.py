"""The maze seen from above: the plate, its walls, the path and the marble's track.

Drawn from plain arrays (a ``maze.json``'s path, walls and plate, a run's plate-frame centres),
so the picture can be redrawn from the artefacts alone; matplotlib, Agg.
"""

from __future__ import annotations

import numpy as np

from ..errors import output_error
from . import figure_png, one_at_a_time


@one_at_a_time
def maze_picture(path, walls, plate, marble_u=None, file=None, *, times=None, title: str = "") -> bytes:
    """PNG bytes of the maze from above (maze-plane u, v [mm], equal axes).

    path : (m, 2) [mm] the centre line, dashed; walls : (w, 2, 2) [mm] segments, thick lines;
    plate : (2,) [mm] the plate's outer size, centred on the walls' bounding box (the path's
    without walls), as :func:`metasheet.dynamics.maze_geometry.maze_from_path` lays it;
    marble_u : None or (K, 2) [mm] the marble's centre, coloured by ``times`` (K,) [s] (by
    sample without); file : None or a path the PNG is also written to.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection
    from matplotlib.patches import Rectangle

    P = np.asarray(path, float).reshape(-1, 2)
    W = np.asarray(walls, float).reshape(-1, 2, 2)
    size = np.asarray(plate, float).reshape(2)
    pts = W.reshape(-1, 2) if len(W) else P
    mid = (pts.min(axis=0) + pts.max(axis=0)) / 2
    fig, ax = plt.subplots(figsize=(6.0, 6.0 * size[1] / size[0] + 0.6))
    ax.add_patch(Rectangle(tuple(mid - size / 2), size[0], size[1], facecolor="0.93", edgecolor="0.5"))
    if len(W):
        ax.add_collection(LineCollection(W, colors="0.15", linewidths=3.0, capstyle="round", label="walls"))
    ax.plot(P[:, 0], P[:, 1], "--", color="C0", lw=1.2, label="path")
    ax.plot(*P[0], "o", color="C0", ms=5)
    if marble_u is not None:
        U = np.asarray(marble_u, float).reshape(-1, 2)
        c = np.arange(len(U), dtype=float) if times is None else np.asarray(times, float)
        if len(U) > 1:
            seg = np.stack([U[:-1], U[1:]], axis=1)
            lc = LineCollection(seg, cmap="viridis", linewidths=2.0)
            lc.set_array((c[:-1] + c[1:]) / 2)
            ax.add_collection(lc)
            fig.colorbar(lc, ax=ax, shrink=0.8, label="time [s]" if times is not None else "sample [-]")
        ax.plot(*U[-1], "o", color="C3", ms=6, label="marble (end)")
    ax.set_xlim(mid[0] - size[0] / 2 - 2, mid[0] + size[0] / 2 + 2)
    ax.set_ylim(mid[1] - size[1] / 2 - 2, mid[1] + size[1] / 2 + 2)
    ax.set_aspect("equal")
    ax.set_xlabel("u [mm]")
    ax.set_ylabel("v [mm]")
    ax.legend(loc="upper right", fontsize=7)
    if title:
        ax.set_title(title)
    png = figure_png(fig)
    if file is not None:
        try:
            with open(file, "wb") as fh:
                fh.write(png)
        except OSError as exc:
            raise output_error(exc, str(file)) from exc
    return png
