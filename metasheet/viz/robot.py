"""Pictures of the robot (like the paper's Fig. 4 and Fig. 8): rest vs deformed, per material.

Off-screen pyvista. Each material gets two panels: a side view (rod horizontal, as in Fig. 4)
and an end view along the rod (the rod rotation of the 6th DOF shows as the turn of the
"maze" plate fixed at the rod centre). Rest in translucent grey, deformed coloured by the
displacement magnitude [mm].
"""

from __future__ import annotations

import io

import numpy as np

from ..mechanics.rotations import rotation_vector
from . import one_at_a_time


def _grid(points, tets, disp=None):
    import pyvista as pv

    tets = np.asarray(tets)[:, :4]  # the vertices: a quadratic mesh drawn by its straight edges
    cells = np.hstack([np.full((len(tets), 1), 4), tets]).ravel()
    g = pv.UnstructuredGrid(cells, np.full(len(tets), 10, dtype=np.uint8), np.asarray(points, float))
    if disp is not None:
        g.point_data["|u| [mm]"] = np.linalg.norm(disp, axis=1)
    return g.extract_surface(algorithm="dataset_surface")


def _maze(p, R, axis, size=36.0, thick=2.0):
    """A thin square plate at p, normal to the rod, rotated by R (the maze of Fig. 2)."""
    import pyvista as pv

    box = pv.Box(bounds=(-thick / 2, thick / 2, -size / 2, size / 2, -size / 2, size / 2))
    # plate in the local y-z plane with a long pointer along +z, which points between the
    # upper arms so the end view shows its turn beyond the sheets' hubs
    marker = pv.Box(bounds=(-thick, thick, -1.5, 1.5, 0.0, 95.0))
    out = []
    for m in (box, marker):
        pts = np.asarray(m.points) @ R.T + p
        m = m.copy()
        m.points = pts
        out.append(m)
    return out


@one_at_a_time
def robot_picture(cases, *, window=(1600, 1200)) -> bytes:
    """PNG bytes: for each ``(title, robot, rest_state, moved_state)`` a side and an end view."""
    import pyvista as pv

    n = len(cases)
    pl = pv.Plotter(off_screen=True, shape=(2, n), window_size=window, border=False)
    clim_max = max(float(np.linalg.norm(c[3].x - c[2].x, axis=1).max()) for c in cases)
    for j, (title, robot, rest, moved) in enumerate(cases):
        tets = robot.body.tets
        ax = robot.axis / np.linalg.norm(robot.axis)
        rot = float(np.degrees(rotation_vector(moved.R @ rest.R.T)) @ ax)
        dp = moved.p - rest.p
        lateral = float(np.linalg.norm(dp - dp @ ax * ax))
        for i, view in enumerate(("side", "end")):
            pl.subplot(i, j)
            pl.set_background("white")
            pl.add_mesh(_grid(rest.x, tets), color="lightgrey", opacity=0.35)
            pl.add_mesh(_grid(moved.x, tets, moved.x - rest.x), scalars="|u| [mm]", cmap="viridis",
                        clim=(0.0, clim_max), show_edges=False,
                        scalar_bar_args={"title": "|u| [mm]", "color": "black", "vertical": True,
                                         "position_x": 0.88, "position_y": 0.1, "height": 0.6})
            for m in _maze(rest.p, rest.R, ax):
                pl.add_mesh(m, color="grey", opacity=0.5)
            for m in _maze(moved.p, moved.R, ax):
                pl.add_mesh(m, color="crimson")
            a, b = moved.p - 45 * (moved.R @ ax), moved.p + 45 * (moved.R @ ax)
            pl.add_mesh(pv.Tube(pointa=a, pointb=b, radius=2.0), color="black")
            for s in robot.coupling.servos:  # horn: pivot -> centre of the tip box it holds
                tip = moved.x[s.nodes].mean(axis=0)
                pl.add_mesh(pv.Tube(pointa=s.pivot, pointb=tip, radius=1.5), color="orange")
                pl.add_mesh(pv.Sphere(radius=3.0, center=s.pivot), color="darkorange")
            if view == "side":
                pl.view_vector((0.0, -1.0, 0.25), viewup=(0, 0, 1))
                pl.add_text(f"{title}: side view", font_size=11, color="black")
            else:
                pl.view_vector(tuple(ax), viewup=(0, 0, 1))
                pl.add_text(f"{title}: along the rod\nrod rotation {rot:+.2f} deg, lateral {lateral:.2f} mm",
                            font_size=11, color="black")
            pl.reset_camera()
            pl.camera.zoom(1.15)
    img = pl.screenshot(return_img=True)
    pl.close()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    plt.imsave(buf, img, format="png")
    return buf.getvalue()

