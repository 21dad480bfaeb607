"""Report section: the design stage's chosen fibre field against the paper's spiral (issue 45).

Reads the ``design`` stage's ``design.json`` (:mod:`metasheet.pipeline.stages.design`): its
``comparison`` (every objective of both designs on the pipeline's material and on the published
constants, :mod:`metasheet.design.evaluation`). Every sentence is computed from it. Returns
Markdown lines and the differences found, as the other sections do.
"""

from __future__ import annotations

from collections.abc import Mapping

#: issue 45's target: the chosen design's rod roll per motor degree over the spiral's
ROLL_TARGET = 1.5


def _rows(table: Mapping) -> dict:
    return {r["objective"]: r for r in table["rows"]}


def targets(table: Mapping, material: str = "pipeline") -> dict:
    """Issue 45's targets on ``material``'s columns of the comparison ``table``: the roll ratio
    [-] (|chosen| / |spiral|), whether each of singular values 2-6 [mm/rad] and the five other
    DOF's smallest is no lower than the spiral's, and whether the chosen design's strain at
    every goal is within the limit."""
    rows = _rows(table)
    roll = rows["rod roll per motor degree"][material]
    ratio = abs(roll["chosen"]) / abs(roll["spiral"])
    others = [rows[f"singular value {i} of 6"][material] for i in range(2, 7)]
    others.append(rows["smallest of the five other DOF"][material])
    strain = [r[material] for k, r in rows.items() if k.startswith("largest principal strain")]
    worst = max(s["chosen"] for s in strain)
    return {"roll_ratio": ratio, "roll_met": ratio >= ROLL_TARGET,
            "others_not_lower": all(o["chosen"] >= o["spiral"] for o in others),
            "strain_max": worst, "spiral_strain_max": max(s["spiral"] for s in strain),
            "strain_within": worst <= table["strain_limit"]}


def trade_off_lines(d: Mapping, limit: float) -> list[str]:
    """Markdown lines on what the roll trades against: the roll reached where the goal strain
    reaches ``limit`` [-] (chosen and spiral, ``design.json``'s ``chosen.reach``) and the
    constrained optimum at each strain limit (``strain_front``); [] when neither was recorded."""
    lines = []
    reach = d["chosen"].get("reach")
    if reach:
        s, c = reach["spiral"], reach["chosen"]
        lines += [(f"Roll reached at the strain limit {limit:g} (the strain is linear in the motor angle): the chosen "
                  f"design {c['roll_deg_at_limit']:.3g} deg of rod roll at {c['motor_deg_at_limit']:.3g} deg of the "
                  f"motors, the spiral {s['roll_deg_at_limit']:.3g} deg at {s['motor_deg_at_limit']:.3g} deg "
                  f"({c['roll_deg_at_limit'] / s['roll_deg_at_limit']:.3g} x)."), ""]
    front = d.get("strain_front")
    if front and front.get("rows"):
        lines += [(f"The constrained optimum at other strain limits (goals at {front['goal_deg']:g} deg; roll at "
                  f"the limit: where its goal strain reaches {front.get('reach_limit', limit):g}):"), "",
                  "| strain limit | roll [deg/deg] | x spiral | goal strain | within | roll at the limit [deg] |",
                  "|---|---|---|---|---|---|"]
        lines += [f"| {r['strain_limit']:g} | {r['roll_deg_per_deg']:.4g} | {r['ratio_abs_roll']:.3g} | "
                  f"{r['goal_strain']:.3g} | {'yes' if r['satisfied'] else 'no'} | {r['roll_deg_at_limit']:.3g} |"
                  for r in front["rows"]]
        lines.append("")
    return lines


def _convergence_lines(g: Mapping) -> list[str]:
    """A line when the gradient optimisation stopped without converging (its message)."""
    if g.get("converged", True):
        return []
    return [f"**The gradient optimisation did not converge** after {g.get('iterations')} iterations: "
            f"{g.get('message')}.", ""]


def design_section(d: Mapping | None, pictures: Mapping[str, str] | None = None) -> tuple[list[str], list[str]]:
    """(Markdown lines, differences) of the section; ([], []) without the design stage's output
    (or with one from before the comparison was recorded)."""
    if not d or not d.get("comparison"):
        return [], []
    from ..design.evaluation import TITLES, comparison_markdown

    pictures = pictures or {}
    table = d["comparison"]["table"]
    mats = table["materials"]
    t = {m: targets(table, m) for m in mats}
    p = t["pipeline"]
    verdict = (f"rod roll per motor degree {p['roll_ratio']:.3g} x the spiral's (target {ROLL_TARGET:g}: "
               f"{'met' if p['roll_met'] else 'not met'}); the other singular values "
               f"{'no lower than' if p['others_not_lower'] else 'partly below'} the spiral's; the largest strain at "
               f"the goals {p['strain_max']:.3g} ({'within' if p['strain_within'] else 'beyond'} the limit "
               f"{table['strain_limit']:g}; the spiral's {p['spiral_strain_max']:.3g})")
    c = d["chosen"]
    met = p["roll_met"] and p["others_not_lower"] and p["strain_within"]
    how = ("optimised subject to the strain limit at the goals (SLSQP, KS aggregate) and chosen among the designs "
           "within it" if c.get("strain_constrained") else "optimised for the roll alone, the strain only measured")
    lines = ["## Design: the chosen fibre field against the paper's spiral (issue 45)", "",
             (f"**Chosen design: {c['name']}, on the pipeline's material: {verdict}. Issue 45's target "
             f"(all three together): {'met' if met else 'not met'}.**"), "", f"The design was {how}.", "",
             *_convergence_lines(d.get("gradient") or {}),
             *trade_off_lines(d, table["strain_limit"]),
             (f"Model: {d['model']}; {d['n_tets_per_sheet']} tetrahedra a sheet ({d['element']}); the numbers "
              "show the direction of the gain, not the converged robot's values. Strain: the linear problem's "
              f"small strain at the motors {d['comparison']['evaluations']['spiral']['pipeline']['strain']['goal_deg']:g}"
              " deg from rest (all together, and motor 0 alone)."), ""]
    for key, what in (("design_field", "fibre fields"), ("design_pareto", "the search's Pareto front")):
        if key in pictures:
            lines += [f"![{what}]({pictures[key]})", ""]
    lines += [comparison_markdown(table, TITLES), ""]
    diffs = []
    if "published" in t:
        q = t["published"]
        diffs.append(f"Design (beyond the paper): on the published constants the chosen design's roll is "
                     f"{q['roll_ratio']:.3g} x the spiral's (pipeline's material: {p['roll_ratio']:.3g} x).")
    if not p["roll_met"] and c.get("strain_constrained"):
        diffs.append(f"Design: within the strain limit {table['strain_limit']:g} the chosen design rolls "
                     f"{p['roll_ratio']:.3g} x the spiral per motor degree, short of issue 45's {ROLL_TARGET:g} x: "
                     "the roll trades against the strain at the goals (the section's strain front).")
    if not p["strain_within"]:
        diffs.append(f"Design: the chosen design's linearised strain at the goals reaches {p['strain_max']:.3g}, "
                     f"beyond the validity limit {table['strain_limit']:g}.")
    return lines, diffs


def print_check_section(d: Mapping | None) -> tuple[list[str], list[str]]:
    """(Markdown lines, differences): the chosen design printed against its model (the
    ``printcheck`` stage's ``print_check.json``); ([], []) without it."""
    if not d:
        return [], []
    f = d["print_design"]
    lines = ["### The chosen design printed (issue 63)", "", f"**{d['verdict']}.**", "",
             (f"Printed in `{f['file']}` (infill {f['infill_percentage']:g} %, shrink {f['kgon_x_shrink']:g}, bead "
              f"{f['bead_width']:g} mm; seeds {', '.join(map(str, d['seeds']))}, {d['voxel_mm']:g} mm voxels), both "
              "sheets solved on the robot's grips, against the design's continuum on the same grips "
              f"({d['material']['source']} constants, model {d['material']['model']})."), "",
             *([f"The foam in this sheet (scale map): {d['continuum']['message']}.", ""] if d.get("continuum") else []),
             "| design | model's rod roll [deg/deg] | printed [deg/deg] | printed / model |", "|---|---|---|---|"]
    for k in ("spiral", "chosen"):
        if k in d:
            rolls = ", ".join(f"{p['rod_rotation_deg_per_deg']:+.3f}" for p in d[k]["prints"])
            r = d[k]["roll_ratio"]
            span = f"{r['min']:.2f}" if r["min"] == r["max"] else f"{r['min']:.2f} to {r['max']:.2f}"
            lines.append(f"| {k} | {d[k]['model']['rod_rotation_deg_per_deg']:+.3f} | {rolls} | {span} |")
    lines.append("")
    diffs = [] if d["chosen"]["meets"] else [
        f"Design: printed, the chosen design's rod roll per degree misses its model by {d['chosen']['misses_by']:.0%} "
        "(print_check.json)."]
    return lines, diffs
