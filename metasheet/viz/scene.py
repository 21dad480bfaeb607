"""A picture of an exported robot scene: what SOFA will load, to check before running it.

Both sheets (sheet A blue, B orange) with a fibre streak per element of their outer halves, each
servo's pivot, axis (red) and horn to its grip (black), the rod and the maze plate; side and
end views. Off-screen pyvista.
"""

from __future__ import annotations

import numpy as np

from . import image_png, one_at_a_time


@one_at_a_time
def scene_picture(points, tets, sheet, fibers, pivots, axes, grips, rod_ends, maze_corners, *,
                  window=(1400, 700)) -> bytes:
    """PNG bytes of the scene.

    points (n, 3) [mm], tets (m, 4), sheet (m,) 0/1, fibers (m, 3) unit; pivots, axes, grips
    (6, 3): servo pivots [mm], unit axes, grip centres [mm]; rod_ends (2, 3) [mm];
    maze_corners (8, 3) [mm] of the maze plate.
    """
    import pyvista as pv

    tets = np.asarray(tets)
    cells = np.hstack([np.full((len(tets), 1), 4), tets]).ravel()
    grid = pv.UnstructuredGrid(cells, np.full(len(tets), 10, dtype=np.uint8), np.asarray(points, float))
    grid.cell_data["sheet"] = np.asarray(sheet, float)
    centres = np.asarray(points)[tets].mean(axis=1)
    # the streaks of the elements in each sheet's outer half (those an end view sees), 5 mm each
    ends = np.asarray(rod_ends, float)[:, 0]
    outer = np.where(np.asarray(sheet) == 0, centres[:, 0] < ends[0], centres[:, 0] > ends[1])
    centres = centres[outer]
    half = 2.5 * np.asarray(fibers, float)[outer]
    m = len(centres)
    streaks = pv.PolyData(np.vstack([centres - half, centres + half]),  # lines only: no vertex cells
                          lines=np.column_stack([np.full(m, 2), np.arange(m), np.arange(m) + m]).ravel())
    pl = pv.Plotter(off_screen=True, shape=(1, 2), window_size=window, border=False)
    for j, view in enumerate(("xz", "yz")):
        pl.subplot(0, j)
        pl.add_mesh(grid, scalars="sheet", cmap=["#4c72b0", "#dd8452"], show_scalar_bar=False, opacity=0.35)
        pl.add_mesh(streaks, color="black", line_width=1)
        for p, a, g in zip(pivots, axes, grips):
            pl.add_mesh(pv.Line(np.asarray(p) - 8 * np.asarray(a), np.asarray(p) + 8 * np.asarray(a)), color="red",
                        line_width=4)
            pl.add_mesh(pv.Line(p, g), color="black", line_width=4)
            pl.add_mesh(pv.Sphere(radius=2.0, center=p), color="red")
        pl.add_mesh(pv.Line(*rod_ends), color="dimgray", line_width=8)
        c = np.asarray(maze_corners, float)
        pl.add_mesh(pv.Box(bounds=(c[:, 0].min(), c[:, 0].max(), c[:, 1].min(), c[:, 1].max(), c[:, 2].min(),
                                   c[:, 2].max())), color="lightgray", opacity=0.6)
        pl.add_text(("side view (rod along x)", "end view (along the rod)")[j], font_size=11)
        getattr(pl, f"view_{view}")()
    image = pl.screenshot(return_img=True)
    pl.close()
    return image_png(image)
