"""The ``dynamics`` stage's tables and pictures (:mod:`.dynamics`), from its units' results."""

from __future__ import annotations

import numpy as np

from ...robot.kinematics import DOF_NAMES
from ..registry import StageContext


def modes_record(m: dict) -> dict:
    """The modes for ``modes.json``: frequencies [Hz], the rod's motion per mode (mm, rad; the
    shapes mass-normalised), the tangent's relative asymmetry, the masses [g]."""
    return {"frequencies_hz": m["frequencies_hz"].tolist(), "effector": np.round(m["effector"], 9).tolist(),
            "effector_dofs": list(DOF_NAMES), "asymmetry": m["asymmetry"], "sheets_g": m["sheets_g"],
            "maze_and_rod_g": m["maze_g"]}


def steps_rows(m: dict) -> tuple[list, list]:
    """``steps.csv``: per stepped DOF and sample, time [s], the DOF's value (mm or rad) and its
    quasi-static target."""
    header = ["dof", "time_s", "value", "target"]
    rows = [[st["dof"], t, y, st["target"]] for st in m["steps"] for t, y in zip(st["t"], st["y"])]
    return header, rows


def played_rows(r: dict) -> tuple[list, list]:
    """``maze_played.csv``: per robot step, time [s], the rod's pose (mm, deg), the motors
    [deg] and their torques [N mm]."""
    na = r["angles"].shape[1]
    header = (["time_s", "x_mm", "y_mm", "z_mm", "rx_deg", "ry_deg", "rz_deg"] + [f"motor{k}_deg" for k in range(na)]
              + [f"torque{k}_Nmm" for k in range(na)])
    pose = r["pose"].copy()
    pose[:, 3:] = np.degrees(pose[:, 3:])
    rows = np.hstack([r["t"][:, None], pose, np.degrees(r["angles"]), r["torques"]])
    return header, rows.tolist()


def write_pictures(ctx: StageContext, p, foam: dict, modes: dict, sil: dict | None, summary: dict) -> None:
    """modes.png, steps.png, maze_played.png, marble.png and (``p.animation``) maze_played.gif."""
    from ...viz.dynamics import maze_animation, modes_picture, step_picture, tracking_picture
    from ...viz.marble import maze_picture

    col = ctx.column
    ctx.path("modes.png").write_bytes(modes_picture(
        modes["rest_x"], modes["tets"], modes["shapes"], modes["frequencies_hz"],
        title=f"Natural modes at rest, foam sheets [{col}]"))
    steps = modes["steps"]
    ctx.path("steps.png").write_bytes(step_picture(
        steps[0]["t"], np.array([st["y"] for st in steps]), np.array([st["target"] for st in steps]),
        [f"{st['dof']}: {st['size'] if i < 3 else np.degrees(st['size']):g} {'mm' if i < 3 else 'deg'}"
         for i, st in enumerate(steps)],
        [{k: st[k] for k in ("rise_s", "overshoot_pct", "settling_s")} for st in steps],
        title=f"Step responses of the rod's six DOF [{col}]"))
    verdict = summary["maze"]
    ok = np.isfinite(foam["gap_mm"]) & np.isfinite(foam["gap_deg"])  # a sample the path did not solve: a gap
    ctx.path("maze_played.png").write_bytes(tracking_picture(
        foam["t"][ok], foam["gap_mm"][ok], foam["gap_deg"][ok], foam["marble_t"], foam["marble_progress"],
        foam["path_length"], title=f"The maze played on foam sheets [{col}]: "
        f"{'solved' if verdict['solved'] else 'not solved'} ({verdict['vertices']} of {len(foam['geometry'].path) - 1} "
        "corners in order)"))
    geo = foam["geometry"]
    title = f"The marble's track on foam [{col}]"
    if sil is not None:
        title += f"\nsilicone sheets: {sil['vertices']} of {len(geo.path) - 1} corners in order"
    ctx.path("marble.png").write_bytes(maze_picture(geo.path, geo.walls, geo.plate, foam["marble_u"],
                                                    times=foam["marble_t"], title=title))
    if not p.animation or foam["frames_x"] is None:
        return
    every = foam["frames_every"]
    t = foam["t"][::every][:len(foam["frames_x"])]
    pose = foam["pose"][::every][:len(t)]
    from scipy.spatial.transform import Rotation

    R = Rotation.from_rotvec(pose[:, 3:]).as_matrix()
    marble = np.stack([np.interp(t, foam["marble_t"], foam["marble_world"][:, k]) for k in range(3)], axis=1)
    from ...dynamics.maze_geometry import plate_bounds

    lo, hi = plate_bounds(geo)
    ctx.path("maze_played.gif").write_bytes(maze_animation(
        modes["tets"], foam["frames_x"][:len(t)], pose[:, :3], R, t, walls=geo.walls, plate_lo=lo, plate_hi=hi,
        top=p.rod_radius + p.plate_thickness, rod_length=modes["rod_length"],
        rod_radius=p.rod_radius, plate_thickness=p.plate_thickness, wall_height=p.wall_height, marble=marble,
        marble_radius=p.marble_radius, path=geo.path, fps=int(round(1.0 / p.frame_s)),
        title=f"The maze played [{col}]"))

