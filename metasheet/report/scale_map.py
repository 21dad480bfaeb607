"""Report section: where the continuum holds (the ``scalemap`` stage, issue 63).

Reads ``scale_map.json`` (:mod:`metasheet.studies.scale_map`); every sentence is computed from
it. Returns Markdown lines and the differences found, as the other sections do.
"""

from __future__ import annotations

from collections.abc import Mapping

HEADING = "## Where the continuum holds: printed sheets against the continuum (issue 63)"


def _ratio(st: Mapping | None) -> str:
    if not st:
        return "-"
    if st.get("lo") is None:
        return f"{st['mean']:.2f}"
    return f"{st['mean']:.2f} ({st['lo']:.2f}-{st['hi']:.2f})"


def scale_map_section(d: Mapping | None, pictures: Mapping[str, str] | None = None) -> tuple[list[str], list[str]]:
    """(Markdown lines, differences) of the section; ([], []) without the stage's output."""
    if not d:
        return [], []
    pictures = pictures or {}
    pr = d["prints"]
    lines = [HEADING, "", f"**{d['verdict']}.**", "",
             (f"Foams of `{d['design']['file']}` (bead {d['design']['bead_width']} mm) with the infill and the k-gon "
              f"shrink varied, in sheets of {', '.join(f'{t:g}' for t in d['grid']['thickness_mm'])} mm: each printed "
              f"{len(pr['seeds'])} times (seeds {', '.join(map(str, pr['seeds']))}, {pr['voxel_mm']:g} mm voxels) as "
              "the robot's two sheets, solved on their grips, over the robot's sheets made of the cell's bulk "
              "stiffness (its whole C, and the transverse-isotropic fit the robot uses) and of the plate's (the cell "
              "cut at the sheet's faces). Ratios: printed over continuum, "
              "geometric mean of both sheets' 36 grip modes, with the 95 % interval over the prints."), ""]
    if "scale_map" in pictures:
        lines += [f"![the scale-separation map]({pictures['scale_map']})", ""]
    lines += ["| infill [%] | shrink | t [mm] | cell [mm] | cells through t | cells across the arm | against bulk | "
              "against the robot's constants | against plate (membrane) | against plate (bending) | rod roll, against "
              "bulk |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for p in d["points"]:
        s = p["summary"]
        cell = " x ".join(f"{c:.1f}" for c in p["cell_mm"])
        if p.get("falls_apart"):
            lines.append(f"| {p['infill']:g} | {p['shrink']:g} | {p['thickness_mm']:g} | {cell} | "
                         f"{p['cells_through']:.2f} | {p['cells_across']:.2f} | falls apart | | | | |")
            continue
        roll = s["bulk"]["rod_roll"]
        lines.append(f"| {p['infill']:g} | {p['shrink']:g} | {p['thickness_mm']:g} | {cell} | {p['cells_through']:.2f} "
                     f"| {p['cells_across']:.2f} | {_ratio(s['bulk']['modes'])} | {_ratio(s.get('bulk_fit', {}).get('modes'))} "
                     f"| {_ratio(s.get('plate_membrane', {}).get('modes'))} "
                     f"| {_ratio(s.get('plate_bending', {}).get('modes'))} | {roll['mean']:.2f} |")
    lines.append("")
    for model, name in (("bulk", "the bulk continuum (the cell's whole C)"),
                        ("bulk_fit", "the robot's constants (its transverse-isotropic fit)"),
                        ("plate_membrane", "the plate (membrane moduli)")):
        tr = d["trend"].get(model, {})
        if "a" in tr and all(v is not None for v in tr["n_within"].values()):
            w = tr["n_within"]
            lines.append(f"- {name}: |log r| = {tr['a']:.3g} n^-{tr['b']:.2f} over {tr['points']} points (scatter "
                         f"{tr['scatter_log']:.2f} in log): within 10 % from {w['10%']:.2g} cells through the sheet, "
                         f"25 % from {w['25%']:.2g}.")
        elif "none" in tr:
            lines.append(f"- {name}: no trend ({tr['none']}).")
    lines.append("")
    diffs = []
    bulk = [p for p in d["points"] if "bulk" in p["summary"]]
    off = [p for p in bulk if p["summary"]["bulk"]["modes"]["mean"] < 1 / 1.25]
    if off:
        diffs.append(f"Printed sheets: on {len(off)} of {len(bulk)} printed designs of the scale map the bulk "
                     "continuum is more than 25 % stiffer than the prints (scale_map.json).")
    return lines, diffs
