"""A tiny workspace exploration of the foam robot (paper Fig. 5, on a handful of goals).

Goal points lie on rays from the rest pose (a star grid: rays across the rod in the plane
normal to it, and two along it). Each ray is reached outwards by continuation with the
inverse model (position only, within 1 mm); at every reached point the rod is then asked to
rotate +-10 deg about x, y and z from there, each within 2 deg: the point's class is how
many axes pass both signs. Each reached point also records the largest principal strain
beyond the grips' band (the homogenised foam holds up to 0.3) and the Jacobian's smallest
singular value (control authority), and neighbouring rays are walked between to find
the connected workspace. Small case: 3 rays across and 2 along the rod, 2 steps each, on
the linear 14 mm robot (about 15 s); full case: 8 x 3 rays of 5 steps on 8 mm sheets, on
two worker processes (about a minute).

Run: python examples/small_workspace.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import metasheet  # first: pins numpy's code path, so the numbers repeat on any x86-64 CPU)
import matplotlib

matplotlib.use("Agg")  # off screen: no display needed
import matplotlib.pyplot as plt
import numpy as np

from metasheet.runtime.executor import Executor
from metasheet.studies.adapter import paper_robot_spec
from metasheet.studies.grid import star_grid
from metasheet.studies.workspace import WorkspaceSettings, explore_workspace
from metasheet.viz import figure_png

ROOT = Path(__file__).resolve().parents[1]


def main(small: bool = False, out: Path | None = None) -> dict:
    # the recipe of the robot (picklable: each worker builds its own FEM robot from it)
    spec = paper_robot_spec(mesh_size=14.0 if small else 8.0)  # paper's foam on spiral fibres, P1
    if small:
        # 3 rays across the rod, 120 deg apart like the tripod's arms, and the 2 along it
        grid = star_grid(n_azimuth=3, n_elevation=1, n_steps=2, extent_axial=6.0, extent_lateral=8.0, thin_below=0.0)
        settings, workers = WorkspaceSettings(max_steps=30, substeps=1), 1
    else:
        grid = star_grid(n_azimuth=8, n_elevation=3, n_steps=5, extent_axial=15.0, extent_lateral=20.0,
                         thin_below=0.0)
        settings, workers = WorkspaceSettings(), 2
    ws = explore_workspace(spec, grid, settings, executor=Executor(workers=workers))  # one unit per ray

    r = ws.records
    counts = ws.counts()
    numbers = {"goals": len(grid), "reached": int(r.reached.sum()), **counts,
               "components": ws.n_components, "paths_tested": ws.edges_tested, "paths_passed": ws.edges_passed,
               "max_strain": float(np.nanmax(r.strain)), "min_sigma": float(np.nanmin(r.sigma_min)),
               "valid": int(ws.valid.sum())}
    print(f"{len(grid)} goals on {len(grid.directions)} rays; {numbers['reached']} reached "
          f"({numbers['valid']} with strain <= {settings.strain_limit})")
    for name, n in counts.items():
        print(f"  {name:16s} {n:3d}")
    print(f"  connected components {ws.n_components} (paths between neighbouring rays: "
          f"{ws.edges_passed} of {ws.edges_tested} walked)")
    print(f"  strain of reached points {np.nanmin(r.strain):.3f} .. {numbers['max_strain']:.3f}; "
          f"smallest singular value {numbers['min_sigma']:.2f} .. {np.nanmax(r.sigma_min):.2f} mm/rad")

    out = Path(out) if out is not None else ROOT / "outputs" / "examples" / "small_workspace.png"
    picture(ws, grid, settings.strain_limit, out)
    return numbers


def picture(ws, grid, strain_limit: float, out: Path) -> None:
    """The goals seen along the rod and from the top, coloured by class, rays from rest."""
    from metasheet.viz.studies import CLASS_COLOURS, CLASS_LABELS  # the study stage's colours

    rest = ws.goals[0] - grid.points[0]  # goals are rest + offsets
    fig, axes = plt.subplots(1, 2, figsize=(12, 5.5))
    for ax, (h, v, view) in zip(axes, ((1, 2, "along the rod (x)"), (0, 1, "from the top (z)"))):
        for ray in range(len(grid.directions)):  # each ray was reached outwards from rest
            path = np.vstack([rest, ws.goals[grid.ray_points(ray)]])
            ax.plot(path[:, h], path[:, v], "-", color="0.8", zorder=0)
        for c in sorted(set(ws.cls.tolist())):
            sel = ws.cls == c
            ax.scatter(ws.goals[sel, h], ws.goals[sel, v], s=90, color=CLASS_COLOURS[c],
                       label=f"{CLASS_LABELS[c]} ({sel.sum()})", edgecolors="k", zorder=2)
        beyond = ws.records.reached & ~ws.valid  # the homogenised foam does not hold there
        ax.scatter(ws.goals[beyond, h], ws.goals[beyond, v], s=260, facecolors="none", edgecolors="crimson",
                   linewidths=1.5, label=f"strain > {strain_limit:g} ({beyond.sum()})", zorder=1)
        ax.plot(rest[h], rest[v], "k+", ms=14, label="rest")
        ax.set(xlabel=f"{'xyz'[h]} [mm]", ylabel=f"{'xyz'[v]} [mm]", title=f"goals seen {view}", aspect="equal")
        ax.margins(0.15)
    axes[1].legend(loc="center left", bbox_to_anchor=(1.02, 0.5))
    fig.suptitle("workspace of the foam robot: rotations +-10 deg passed at each reached point")
    metasheet.write_file(out, figure_png(fig))  # never half a file


if __name__ == "__main__":  # python examples/NAME.py [PICTURE] (default: outputs/examples/NAME.png)
    main(out=Path(sys.argv[1]) if len(sys.argv) > 1 else None)
