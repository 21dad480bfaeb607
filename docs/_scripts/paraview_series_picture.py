"""The picture of docs/howto/paraview.md: one frame of a ParaView series of the quick robot.

    python docs/_scripts/paraview_series_picture.py OUT      # OUT: the --out of `metasheet run pipelines/quick.toml`

Builds the quick pipeline's robot (:func:`metasheet.goto.pipeline_robot`), solves the rest
equilibrium and two motor commands, writes them as a series
(:func:`metasheet.export.series.write_robot_series`, with the maze study's default path on
the plate) into a temporary folder, reads the last frame back from its ``.vtu`` files (as
ParaView would) and renders it off screen: the sheets coloured by ``max_principal_strain``,
fibre glyphs, the rod, the maze plate and the horns. Writes ``docs/img/paraview_series.png``
atomically and prints the series' size.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
DEST = ROOT / "docs" / "img" / "paraview_series.png"
#: the motor commands of the frames after rest, from the rest angles [deg]
COMMANDS = ([6.0, -4.0, 0.0, -6.0, 4.0, 0.0], [12.0, -8.0, 0.0, -12.0, 8.0, 0.0])


def write_series(out: Path, folder: Path) -> Path:
    """The quick robot's series (rest, then :data:`COMMANDS`) in ``folder``; its .pvd."""
    from metasheet.export.series import MazePlate, write_robot_series
    from metasheet.goto import pipeline_robot
    from metasheet.pipeline.stages.maze import DEFAULT_PATH
    from metasheet.robot.equilibrium import solve_equilibrium

    robot, _ = pipeline_robot(ROOT / "pipelines" / "quick.toml", out)
    th0 = robot.coupling.rest_angles
    states = [solve_equilibrium(robot, th0).state]
    for cmd in COMMANDS:
        states.append(solve_equilibrium(robot, th0 + np.radians(cmd), state=states[-1]).state)
    return write_robot_series(robot, states, np.arange(len(states)) * 0.5, folder,
                              maze=MazePlate(path=tuple(DEFAULT_PATH)))


def render(parts: dict, *, window=(900, 620)) -> bytes:
    """PNG bytes of one frame: ``parts`` {part: .vtu path} as :func:`~metasheet.export.series.read_series` gives."""
    import pyvista as pv

    from metasheet.viz import one_at_a_time

    @one_at_a_time
    def draw() -> bytes:
        sheets, rod, maze, horns = (pv.read(parts[k]) for k in range(4))
        pl = pv.Plotter(off_screen=True, window_size=window)
        pl.set_background("white")
        strain = sheets.cell_data["max_principal_strain"]
        pl.add_mesh(sheets, scalars="max_principal_strain", cmap="viridis", preference="cell",
                    clim=(0.0, float(strain.max())),
                    scalar_bar_args={"title": "max principal strain", "color": "black", "fmt": "%.2f",
                                     "position_x": 0.25, "width": 0.5})
        # the fibres of the surface's faces (a face keeps its element's cell data), lifted off it
        skin = sheets.extract_surface(algorithm="dataset_surface").compute_normals(cell_normals=True,
                                                                                  point_normals=False)
        centres = skin.cell_centers()
        centres.points = centres.points + 0.3 * skin.cell_data["Normals"]
        every = centres.extract_points(np.arange(0, centres.n_points, 13), adjacent_cells=False)
        pl.add_mesh(every.glyph(orient="fiber", scale=False, factor=4.5,
                                geom=pv.Line(pointa=(-0.5, 0, 0), pointb=(0.5, 0, 0))),
                    color="white", line_width=2)
        pl.add_mesh(rod, color="dimgrey")
        pl.add_mesh(maze, color="lightgrey", opacity=0.9)
        lines = maze.extract_cells_by_type(pv.CellType.LINE)
        pl.add_mesh(lines, color="crimson", line_width=4)
        pl.add_mesh(horns, color="darkorange", line_width=6)
        pl.view_vector((0.55, -1.0, 0.6), viewup=(0, 0, 1))
        pl.camera.zoom(1.25)
        img = pl.screenshot(return_img=True)
        pl.close()
        return _png(img)

    return draw()


def _png(img: np.ndarray) -> bytes:
    """PNG bytes of an (h, w, 3) image, palette-quantised (a docs picture under 150 kB)."""
    import io

    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(img).quantize(colors=128, method=Image.Quantize.MEDIANCUT).save(buf, format="PNG", optimize=True)
    return buf.getvalue()


def main(out: Path) -> int:
    from metasheet.export.series import read_series
    from metasheet.pipeline.manifest import write_bytes_atomic

    with tempfile.TemporaryDirectory() as tmp:
        pvd = write_series(out, Path(tmp))
        steps = read_series(pvd)
        files = [p for _, parts in steps for p in parts.values()]
        size = sum(p.stat().st_size for p in files)
        print(f"series: {len(steps)} steps, {len(files)} .vtu files, {size / len(steps) / 1e3:.0f} kB per step "
              f"(sheets {np.mean([s[1][0].stat().st_size for s in steps]) / 1e3:.0f} kB)")
        png = render(steps[-1][1])
    write_bytes_atomic(DEST, png)
    print(f"wrote {DEST.relative_to(ROOT)} ({len(png) / 1e3:.0f} kB)")
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    sys.exit(main(Path(sys.argv[1])))
