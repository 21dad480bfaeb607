"""The report's section on the robot in time (issue 64): the maze played with a marble, beside
the paper's claim (Section V-B3: "we put a marble on the maze and we were able ... to make the
marble follow the whole path of the maze and come back at the initial position"; silicone
sheets could not roll the rod, so their maze fails), the modes and the step responses."""

from __future__ import annotations

from collections.abc import Mapping

HEADING = "## The maze, played (paper Section V-B3, in time)"
COPIED = ("maze_played.png", "marble.png", "steps.png", "modes.png", "maze_played.gif")


def _f(v, digits: int = 3) -> str:
    return "-" if v is None else f"{v:.{digits}g}"


def _corners(v: Mapping | None) -> str:
    if v is None:
        return "not played"
    n = len(v["arrivals"]) if v.get("arrivals") is not None else None
    word = "solved: every corner in order" if v["solved"] else "not solved"
    where = ""
    if v.get("arrivals") is not None and not all(v["arrivals"]):
        where = f"; at the end of segment(s) {[i for i, ok in enumerate(v['arrivals']) if not ok]} the marble was not at its corner"
    return f"{word} ({v['vertices']} of {n if n is not None else '?'} corners{where})"


def _steps(steps: list) -> str:
    slow = max(steps, key=lambda s: s["settling_s"] if s["settling_s"] is not None else float("inf"))
    over = max(steps, key=lambda s: s["overshoot_pct"])
    return (f"slowest to settle: {slow['dof']} ({_f(slow['settling_s'] and slow['settling_s'] * 1000)} ms); "
            f"largest overshoot: {over['dof']} ({over['overshoot_pct']:.3g} %)")


def _fastest(f: Mapping) -> str:
    if f["speed"] is None:
        return f"no playback stays within {f['tol_mm']:g} mm of the quasi-static path"
    tried = {t["speed"]: t for t in f["tried"]}
    t = tried[f["speed"]]
    last = max(tried)
    servo = "within" if t["within_servo_speed"] else "beyond"
    more = "" if f["speed"] < last else f" (the fastest tried: {last:g}x)"
    solved = [f"{x['speed']:g}x" for x in f["tried"] if x["solved"]]
    return (f"{f['speed']:g}x ({_f(f['duration_s'])} s) within {f['tol_mm']:g} mm{more}; the motors then turn at "
            f"{t['motor_speed_deg_s']:.3g} deg/s, {servo} the servos' {f['servo_speed_deg_s']:g} deg/s; the marble "
            f"solves the maze at {', '.join(solved) if solved else 'none of the speeds tried'}")


def _modal(m: Mapping | None, tol: float) -> str:
    if not m:
        return "-"
    f = m["fastest"]
    if f["speed"] is None:
        return f"no playback within {tol:g} mm"
    limit = m["servo_limited_speed"]
    bound = ("the servos' speed, not the sheets, bounds it" if f["speed"] >= limit * (1 - 1e-9)
             else f"beyond it the rod lags more than {tol:g} mm")
    return (f"{f['speed']:.3g}x within {tol:g} mm (gap {f['gap_mm']:.3g} mm; the servos allow {limit:.3g}x): {bound}; "
            f"{m['modes']} modes")


def dynamics_section(columns: Mapping[str, Mapping], pictures: Mapping[str, str]) -> tuple[list[str], list[str]]:
    """(Markdown lines, differences from the paper) for the dynamics stage's summaries per column."""
    if not columns:
        return [], []
    lines = [HEADING, "",
             "The maze study's open-loop motor program played on the robot in time (the sheets' consistent mass, "
             "the rod and maze plate as a rigid body of PLA, Rayleigh damping as SOFA's, position-controlled "
             "servos), with a marble rolling without slipping on the moving plate between the maze's walls "
             "(`pipelines/maze-dynamics.toml`; docs: The maze, played).", ""]
    diffs = []
    for col, z in columns.items():
        rows = [("sheets / maze and rod / marble [g]", f"{z['sheets_g']:.3g} / {z['maze_and_rod_g']:.3g} / {z['marble_g']:.3g}"),
                ("first natural frequencies, foam [Hz]", ", ".join(f"{v:.3g}" for v in z["frequencies_hz"][:3])),
                ("first natural frequencies, silicone [Hz]", "-" if not z.get("silicone_frequencies_hz") else
                 ", ".join(f"{v:.3g}" for v in z["silicone_frequencies_hz"][:3])),
                ("step responses (1 mm, 1 deg)", _steps(z["steps"])),
                ("the maze on foam", _corners(z["maze"])),
                ("the maze on silicone", _corners(z.get("silicone"))),
                ("largest distance from the quasi-static path [mm]", _f(z["maze"]["max_gap_mm"])),
                ("largest servo torque [N mm]", _f(z["maze"]["max_torque_Nmm"])),
                ("fastest playback, full model", _fastest(z["fastest"])),
                ("fastest playback, modal model", _modal(z.get("modal"), z["fastest"]["tol_mm"]))]
        lines += [f"### {col.capitalize()} column", "", "| quantity | value |", "|---|---|"]
        lines += [f"| {a} | {b} |" for a, b in rows] + [""]
        for name in COPIED:
            key = f"dynamics/{col}/{name}"
            if key in pictures:
                lines += [f"![{name}]({pictures[key]})", ""]
        if not z["maze"]["solved"]:
            diffs.append(f"The maze, played ({col}): the marble did not follow the whole path on foam sheets "
                         f"({z['maze']['vertices']} corners in order); the paper's did.")
        sil = z.get("silicone")
        if sil is not None and sil["solved"]:
            diffs.append(f"The maze, played ({col}): the marble solved the maze on silicone sheets too; the paper's "
                         "silicone robot could not roll the rod.")
    return lines, diffs
