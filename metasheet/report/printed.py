"""Report section: the printed robot against the paper's physical robot (issue 62).

Reads the ``printed`` stage's ``printed.json`` (:mod:`metasheet.studies.printed_claims`); every
sentence is computed from it. Returns Markdown lines and the differences found, as the other
sections do.
"""

from __future__ import annotations

from collections.abc import Mapping

#: the paper's physical robot, claim by claim (Section V-B, Fig. 5 and 7)
CLAIMS = {
    "roll": "the rod rolled one way with all six motors pulled by {pull:g} deg and the other way pushed by "
            "{push:g} deg (Fig. 7)",
    "rotations": "at rest, {rot:g} deg about each axis within {tol:g} deg, the other DOF held (Fig. 5)",
}


def _f(v, fmt: str = ".3g") -> str:
    return "-" if v is None else format(v, fmt)


def _span(s: Mapping, fmt: str = ".3g") -> str:
    if not s or s.get("n", 0) == 0:
        return "-"
    if s["min"] == s["max"]:
        return _f(s["mean"], fmt)
    return f"{_f(s['mean'], fmt)} ({_f(s['min'], fmt)} to {_f(s['max'], fmt)})"


def printed_robot_section(d: Mapping | None, pictures: Mapping[str, str] | None = None) -> tuple[list[str], list[str]]:
    """(Markdown lines, differences) of the section; ([], []) without the stage's output."""
    if not d:
        return [], []
    pictures = pictures or {}
    p = d["params"]
    rows = d["realisations"]
    text = {"roll": CLAIMS["roll"].format(pull=p["pull_deg"], push=p["push_deg"]),
            "rotations": CLAIMS["rotations"].format(rot=p["rot_deg"], tol=p["tol_deg"])}
    lines = ["## The printed robot against the paper's robot (issue 62)", "",
             (f"Each print ({len(rows)}: seeds {', '.join(str(r['seed']) for r in rows)}; {d['voxel_mm']} mm voxels, "
              f"gauge `{d['gauge']}`) as a robot of two corotational superelements with its sheets' linear DNS "
              "stiffness on their grips, valid until two of its walls first touch (first order in the motion: the "
              "nonlinear DNS closes the gaps sooner, so these limits are late). docs/printed-sheet.md says what the "
              "model leaves out."), ""]
    if "printed_robot" in pictures:
        lines += [f"![The printed robot's roll and its walls' limits]({pictures['printed_robot']})", ""]
    lines += ["| the paper's robot | printed robot | per print |", "|---|---|---|"]
    for key in ("roll", "rotations"):
        per = ", ".join(f"seed {r['seed']}: {r[key]['status']}" for r in rows)
        lines.append(f"| {text[key]} | **{d['claims'][key]}** | {per} |")
    lines.append("")
    spr = d["spread"]
    lines += [f"- Walls' first contact (the model's limit): {_span(spr['valid_deg'])} deg of motor travel "
              f"(mean, min to max over the prints); searched to {p['search_deg']:g} deg.",
              f"- Rod rotation pulled by {p['pull_deg']:g} deg: {_span(spr['rod_rotation_pull_deg'])} deg; pushed by "
              f"{p['push_deg']:g} deg: {_span(spr['rod_rotation_push_deg'])} deg (the model, walls ignored).",
              f"- Smallest singular value at rest: {_span(spr['smallest_singular_value'])} mm/rad "
              "(diag(1, 1, 1, 50 mm) J)."]
    for r in rows:
        lim = r["limits"]
        if not lim:
            continue
        at = r["roll"]["rod_rotation_within_limits_deg"]
        lines.append(f"- Seed {r['seed']}: walls touch first along \"{lim['binding']}\" at {_f(lim['valid_deg'])} deg; "
                     f"the rod turns {_f(at['pull'])} deg pulled and {_f(at['push'])} deg pushed up to the walls' "
                     "limit.")
    lines.append("")
    diffs = [f"Printed robot: {text[k]}: {d['claims'][k]}." for k in ("roll", "rotations")
             if d["claims"][k] != "predicted"]
    return lines, diffs
