"""Report section: mesh convergence of the robot (``robot/convergence.json``, issue 14).

Shows every mesh level the robot stage measured (P1 and P2, uniform and graded towards the
grips), each family's extrapolated limit with its fitted order, and for the meshes the
pipeline actually runs on (the robot stage's, each study's) their errors against the
reference limit and whether they meet the tolerances (Jacobian 2 %, rod compliance 5 %).
A study whose mesh was not among the measured levels says so: its accuracy is unknown.
Each family's limit is set against the reference's: two families of different elements
agreeing on the limit is what makes it the converged value.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..robot.convergence import TOLERANCES, Level


def _label(m: Mapping) -> str:
    return Level(m["element"], float(m["mesh_size"]), int(m.get("layers", 0)), float(m.get("grip_size", 0.0))).label


def _pct(x: float) -> str:
    return f"{100 * x:.2f} %"


#: the section's heading (also over the line naming the command, when the study is not there)
HEADING = "## Mesh convergence of the robot (issue 14)"

#: the limits' agreement between families asked of the largest singular value (issue 59)
FAMILY_AGREEMENT = 0.02


def family_gaps(conv: Mapping) -> dict[str, dict[str, float]]:
    """Family -> relative gap of its limit to the reference family's [-], for the largest
    singular value (``sv_max``) and the rod compliance (``rod_compliance``)."""
    limits = conv["limits"]
    ref = limits[conv["reference"]]["limits"]
    out = {}
    for fam, lim in limits.items():
        v = lim["limits"]
        out[fam] = {"sv_max": v["singular_values"][0] / ref["singular_values"][0] - 1.0,
                    "rod_compliance": v["rod_compliance_mm_per_N"] / ref["rod_compliance_mm_per_N"] - 1.0}
    return out


def _agreement(conv: Mapping) -> tuple[list[str], list[str]]:
    """A line setting each family's limit against the reference's, and a difference for an
    element (P1 against P2) none of whose families agrees within :data:`FAMILY_AGREEMENT`."""
    ref = conv["reference"]
    gaps = {f: g for f, g in family_gaps(conv).items() if f != ref}
    if not gaps:
        return [], []
    sv = conv["limits"][ref]["limits"]["singular_values"][0]
    parts = [f"{f} {conv['limits'][f]['limits']['singular_values'][0]:.2f} ({100 * g['sv_max']:+.1f} %; rod "
             f"compliance {100 * g['rod_compliance']:+.1f} %)" for f, g in gaps.items()]
    lines = [f"Limits against the reference `{ref}` (largest singular value {sv:.2f}): " + "; ".join(parts) + ".", ""]
    diffs = []
    for element in sorted({f.split("-")[0] for f in gaps} - {ref.split("-")[0]}):
        best = min(abs(g["sv_max"]) for f, g in gaps.items() if f.split("-")[0] == element)
        if best > FAMILY_AGREEMENT:
            diffs.append(f"Mesh convergence: no {element} family's limit of the largest singular value is within "
                         f"{_pct(FAMILY_AGREEMENT)} of the reference `{ref}` (closest {_pct(best)}): the "
                         "converged value has one element behind it.")
    return lines, diffs


def convergence_section(conv: Mapping | None, meshes: Mapping[str, Mapping],
                        preface: list[str] = ()) -> tuple[list[str], list[str]]:
    """(Markdown lines, differences) of the convergence section.

    conv : ``convergence.json`` (None: no study ran, no section).
    meshes : stage name -> its robot mesh {element, mesh_size, layers, grip_size}.
    preface : lines after the heading (where the study came from).
    """
    if not conv:
        return [], []
    ref = conv["reference"]
    lines = [HEADING, "", *preface,
             f"The foam robot of this pipeline (its constants and scene) at the rest equilibrium under "
             f"gravity, on each mesh. Errors against the extrapolated limit of the `{ref}` family "
             f"({', '.join(conv['reference_levels'])}; fit q = q_inf + c h^p, p >= 1, its scatter in "
             f"convergence.json: a limit fitted to coarse levels is indicative only); tolerances: Jacobian "
             f"{_pct(TOLERANCES['jacobian'])} (relative Frobenius), rod compliance "
             f"{_pct(TOLERANCES['rod_compliance'])}.", "",
             "| mesh | tets | dofs | sv max | sv min | rod rotation [deg/deg] | rod compliance [mm/N] | "
             "gravity sag [mm] | error J | error W_rod |", "|---|---|---|---|---|---|---|---|---|---|"]
    by_label = {}
    for row in conv["levels"]:
        lab = _label(row)
        by_label[lab] = row
        e = row["errors"]
        sv = row["singular_values"]
        lines.append(f"| {lab} | {row['tets']} | {row['dofs']} | {sv[0]:.3f} | {sv[-1]:.3f} | "
                     f"{row['rod_rotation_deg_per_deg']:.4f} | {row['rod_compliance_mm_per_N']:.3f} | "
                     f"{row['gravity_sag_mm']:.4f} | {_pct(e['jacobian'])} | {_pct(e['rod_compliance'])} |")
    lines += ["", "| family | fitted from | singular values | rod rotation | rod compliance | orders (J, W_rod) |",
              "|---|---|---|---|---|---|"]
    for fam, lim in conv["limits"].items():
        v, o = lim["limits"], lim["fitted_orders"]
        lines.append(f"| {fam} | {', '.join(lim['from_levels'])} | {np.round(v['singular_values'], 3).tolist()} | "
                     f"{v['rod_rotation_deg_per_deg']:.4f} | {v['rod_compliance_mm_per_N']:.3f} | "
                     f"{o['J']:.2f}, {o['rod_compliance_mm_per_N']:.2f} |")
    agree, diffs = _agreement(conv)
    lines += ["", *agree, "| stage | mesh | error J | error W_rod | within tolerance |", "|---|---|---|---|---|"]
    for stage, mesh in meshes.items():
        lab = _label(mesh)
        row = by_label.get(lab)
        if row is None:
            lines.append(f"| {stage} | {lab} | not measured | not measured | unknown |")
            diffs.append(f"{stage}: its mesh ({lab}) is not among the convergence levels: accuracy unknown")
            continue
        e = row["errors"]
        ok = all(e[k] <= t for k, t in TOLERANCES.items())
        lines.append(f"| {stage} | {lab} | {_pct(e['jacobian'])} | {_pct(e['rod_compliance'])} | "
                     f"{'yes' if ok else 'no'} |")
        if not ok:
            diffs.append(f"{stage} runs on {lab}: Jacobian {_pct(e['jacobian'])}, rod compliance "
                         f"{_pct(e['rod_compliance'])} from the converged limit (tolerances "
                         f"{_pct(TOLERANCES['jacobian'])}, {_pct(TOLERANCES['rod_compliance'])})")
    return lines + [""], diffs
