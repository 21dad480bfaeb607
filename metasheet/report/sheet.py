"""Report section: the printed sheet against the homogenised sheet (issue 44).

Reads the ``sheet`` stage's ``sheet_dns.json`` (:mod:`metasheet.studies.sheet_dns`); every
sentence is computed from it. Returns Markdown lines and the differences found, as the other
sections do.
"""

from __future__ import annotations

from collections.abc import Mapping

from ..mechanics.material import CONSTANT_NAMES
from ..published.paper import PAPER_FOAM


def _f(v, nd: int = 3) -> str:
    return "-" if v is None else f"{v:.{nd}g}"


def _range(s: Mapping, nd: int = 3) -> str:
    if s["min"] == s["max"]:
        return _f(s["mean"], nd)
    return f"{_f(s['mean'], nd)} ({_f(s['min'], nd)} to {_f(s['max'], nd)})"


def sheet_dns_section(d: Mapping | None, pictures: Mapping[str, str] | None = None,
                      material: Mapping | None = None) -> tuple[list[str], list[str]]:
    """(Markdown lines, differences) of the section; ([], []) without the stage's output."""
    if not d:
        return [], []
    pictures = pictures or {}
    rows = d["realisations"]
    hom, spr = d["homogenised_robot"], d["spread"]
    n = len(rows)
    first = rows[0]["sheets"]["normal"]
    lines = ["## The printed sheet against the homogenised sheet (issue 44)", "",
             f"**Verdict: {d['verdict']}.**", "",
             (f"The print maps' foam built voxel by voxel ({d['voxel_mm']} mm, gauge `{d['gauge']}`, seeds "
             f"{', '.join(str(s) for s in d['seeds'])}), solved with the robot's four grips rigid and condensed on "
             "their 24 rigid DOF; the robot's homogenised sheets (its mesh, element, fibres and constants) condensed "
             "the same way. Both robots are the linear rest model without gravity (sheet_dns.json)."), ""]
    for key in ("printed_sheet", "sheet_dns"):
        if key in pictures:
            lines += [f"![{key}]({pictures[key]})", ""]
    lines += ["| | homogenised robot | printed robot | printed / homogenised |", "|---|---|---|---|"]
    roll = spr["rod_rotation_deg_per_deg"]
    lines.append(f"| rod roll per degree, all motors [deg/deg] | {hom['rod_rotation_deg_per_deg']:+.4f} | "
                 f"{_range(roll, 4)} | {_range(spr['rod_roll_ratio'])} |")
    sv_h, sv = hom["singular_values"], spr["singular_values"]
    for k in range(len(sv_h)):
        one = {"mean": sv["mean"][k], "min": sv["min"][k], "max": sv["max"][k]}
        ratio = {q: one[q] / sv_h[k] for q in one}
        lines.append(f"| singular value {k + 1} [mm/rad] | {sv_h[k]:.4g} | {_range(one, 4)} | {_range(ratio)} |")
    lines += ["", ("Each sheet on its grips (centre held; 18 modes): the generalised eigenvalues are each mode's "
              "stiffness, printed over homogenised; the compliances are the centre's with the arm tabs clamped."), "",
              ("| seed | sheet | eigen-ratios (min, geometric mean, max) | normal | roll | tilt x | tilt y | "
              "solid kept | unknowns | CG iterations |"), "|---|---|---|---|---|---|---|---|---|---|"]
    for row in rows:
        for label, s in row["sheets"].items():
            lam, c = s["eigen_ratios"], s["compliance_ratio"]
            lines.append(f"| {row['seed']} | {label} | {min(lam):.3g}, {s['geometric_mean_ratio']:.3g}, {max(lam):.3g} "
                         f"| {c['normal_mm_per_N']:.3g} | {c['roll_rad_per_Nmm']:.3g} | {c['tilt_x_rad_per_Nmm']:.3g} "
                         f"| {c['tilt_y_rad_per_Nmm']:.3g} | {s['kept_share']:.3f} | {s['n_dof']:,} "
                         f"| {max(s['iterations'])} |")
    lines += ["", "(compliance columns: printed over homogenised; > 1, the print is softer)", ""]
    found = []
    if "apparent" in spr:
        app = spr["apparent"]
        bulk = (material or {})
        lines += [("Apparent constants: the five constants that make the homogenised sheet FEM (same mesh and fibres) "
                  "reproduce the printed sheets' grip stiffness best (both sheets, log eigen-ratio norm); "
                  "`[material] source = \"sheet\"` drives the robot with them."), "",
                  "| constant | bulk homogenised | apparent (printed sheet) | published |", "|---|---|---|---|"]
        for k in CONSTANT_NAMES:
            lines.append(f"| {k} | {_f(bulk.get(k), 4)} | {_range(app[k], 4)} | {getattr(PAPER_FOAM, k):.4g} |")
        res = [r["apparent"] for r in rows]
        worst = max(r["rms_log_ratio"] for r in res)
        lines += ["", f"Fit residual (rms of log eigen-ratios): up to {worst:.3f}"
                  + ("" if all(r["converged"] for r in res) else "; not converged for some realisation "
                     "(a constant at its positive-definite limit)") + ". A residual this large says no single "
                  "transverse-isotropic material describes the print: read the constants as a diagnostic.", ""]
    lines += _plate_lines(d.get("plate"), rows, spr)
    if n > 1:
        lines += [(f"Print to print ({n} seeds): rod roll {_f(roll['min'], 4)} to {_f(roll['max'], 4)} deg/deg "
                  f"(sd {_f(roll['std'], 2)}); geometric mean stiffness ratio "
                  f"{_range(spr['geometric_mean_ratio_normal'])} (normal sheet)."), ""]
    if first["kept_share"] < 0.99:
        found.append(f"only {first['kept_share']:.1%} of the printed sheet's solid is held by its grips at "
                     f"{d['voxel_mm']} mm: the rest floats (thin walls break into pieces on the voxel grid)")
    if d["verdict"].startswith("differs"):
        found.append("the printed sheet: " + d["verdict"])
    return lines, found


def _plate_lines(plate: Mapping | None, rows, spr: Mapping) -> list[str]:
    """The sheet-scale (plate) continuum against the prints, when the homogenize stage wrote plate.json."""
    if not plate:
        return []
    out = [(f"The sheet cut from the foam ({plate['thickness_mm']:.2f} mm slabs of the cell, free faces: "
            "homogenize's plate.json, docs/plate.md) as the robot's constants, its stretching's or its bending's; "
            "printed over model, as above (`[material] source = \"plate\"` drives the robot with them):"), "",
           "| the robot's sheets from | geometric mean ratio, normal | mirrored | rms log ratio, normal | mirrored |",
           "|---|---|---|---|---|"]
    rms = {k: max(r["sheets"][k]["log_ratio_rms"] for r in rows) for k in ("normal", "mirrored")}
    out.append(f"| the bulk constants | {_range(spr['geometric_mean_ratio_normal'])} | "
               f"{_range(spr['geometric_mean_ratio_mirrored'])} | {_f(rms['normal'])} | {_f(rms['mirrored'])} |")
    for variant in ("membrane", "bending"):
        v = plate[variant]["spread"]
        out.append(f"| the plate's {variant} moduli | {_range(v['geometric_mean_ratio_normal'])} | "
                   f"{_range(v['geometric_mean_ratio_mirrored'])} | {_f(v['log_ratio_rms_normal']['max'])} | "
                   f"{_f(v['log_ratio_rms_mirrored']['max'])} |")
    return out + ["", "(rms log ratio: the worst print; 0 when the model is the print mode by mode)", ""]
