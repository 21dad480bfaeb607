"""Report section: the homogenised foam next to the published constants and the literature.

Three sources side by side, each named: the pipeline's homogenised cell (``homogenize``),
the paper's published constants (:data:`metasheet.published.paper.PAPER_FOAM`) and the authors'
homogenised IceSL foam table (:mod:`metasheet.published.literature`), at the cell's density and over
the design chart's density sweep; then the robot's figures for both constant sets. The
differences listed are computed from these numbers.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..published.literature import E_S, G_S, SOURCE, authors_constants, authors_table
from ..mechanics.material import CONSTANT_NAMES
from ..published.paper import PAPER_FOAM

_UNITS = {"E_t": "MPa", "E_l": "MPa", "nu_t": "-", "nu_tl": "-", "mu_l": "MPa"}


def _in_table(rho: float, kind: str = "transverse") -> bool:
    d = authors_table(kind)["density"]
    return bool(d[0] <= rho <= d[-1])


def cell_rows(h: Mapping) -> tuple[list[str], list[str]]:
    """Markdown lines and differences for the homogenised cell vs published vs literature."""
    rho = float(h.get("relative_density", float("nan")))
    paper = PAPER_FOAM.to_dict()
    lit = authors_constants(rho) if _in_table(rho) else None
    head = "| constant | homogenised | published (paper) | authors' table at this density | homogenised / published |"
    lines = [head, "|---|---|---|---|---|"]
    for k in CONSTANT_NAMES:
        if k not in h:
            continue
        at = f"{float(lit[k]):.4g}" if lit is not None else "outside its density range"
        lines.append(f"| {k} [{_UNITS[k]}] | {h[k]:.4g} | {paper[k]:.4g} | {at} | {h[k] / paper[k]:.2f} |")
    lines += ["", f"relative density of the cell {rho:.3f} (the paper's foam: 0.15); E_t / E_s = "
              f"{h['E_t'] / E_S:.4f}, E_l / E_s = {h['E_l'] / E_S:.4f}, mu_l / G_s = {h['mu_l'] / G_S:.4f} "
              f"(E_s = {E_S:g} MPa, G_s = E_s / 2.6). Literature: {SOURCE}.", ""]
    diffs = []
    for k in ("E_t", "E_l", "mu_l"):
        r = h[k] / paper[k]
        if abs(r - 1) > 0.2:
            diffs.append(f"Homogenised {k} = {h[k]:.3g} MPa is {r:.2f} x the published {paper[k]:.3g} MPa.")
    return lines, diffs


def _pick(rows, column: str, target: float):
    vals = sorted({float(r[column]) for r in rows})
    return min(vals, key=lambda v: abs(v - target)) if vals else None


def _halfwidths(chart_rows: list[Mapping]) -> tuple[dict, str]:
    """((constant, infill, shrink) -> the chart's 95 % half-width there, the seeds per point as
    text); empty with one seed per point."""
    from ..homogenize.chart_bars import chart_bars

    out, seeds = {}, ""
    for k in CONSTANT_NAMES:
        b = chart_bars(chart_rows, k, "infill_percentage", "kgon_x_shrink")
        if b.k.max() < 2:
            return {}, ""
        out.update({(k, float(p), float(q)): float(h) for (p, q), h in zip(b.points, b.halfwidths)})
        seeds = " or ".join(str(v) for v in sorted(set(b.k.tolist())))
    return out, seeds


def sweep_rows(chart_rows: list[Mapping], shrink: float | None) -> tuple[list[str], list[str]]:
    """Density sweep of the chart (Polyfoam) next to the authors' table; fitted power laws."""
    if not chart_rows or "infill_percentage" not in chart_rows[0]:
        return [], []
    lines, diffs = [], []
    hw, seeds = _halfwidths(chart_rows)
    cases = [("transverse", _pick(chart_rows, "kgon_x_shrink", shrink if shrink is not None else 0.2)),
             ("isotropic", _pick(chart_rows, "kgon_x_shrink", 1.0))]
    for kind, s in cases:
        if s is None or (kind == "isotropic" and s != 1.0):
            continue
        sel = [r for r in chart_rows if float(r["kgon_x_shrink"]) == s]
        by_p: dict[float, list] = {}
        for r in sel:
            by_p.setdefault(float(r["infill_percentage"]), []).append(r)
        lines += [f"**kgon_x_shrink {s:g}** against the authors' {kind} foam:", "",
                  "| infill [%] | rho | E_t / E_s | authors | E_l / E_s | authors | nu_t | authors | nu_tl | authors "
                  "| mu_l / G_s | authors |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
        rho, e_t, e_l = [], [], []
        for p, rs in sorted(by_p.items()):
            m = {k: float(np.mean([float(r[k]) for r in rs])) for k in ("relative_density", *CONSTANT_NAMES)}
            a = authors_constants(m["relative_density"], kind) if _in_table(m["relative_density"], kind) else None

            def cell(k, ref, scale=1.0):
                h = hw.get((k, p, s))
                return (f"{m[k] / scale:.4g}" + (f" +- {h / scale:.2g}" if h else "") + " | "
                        + (f"{float(ref) / scale:.4g}" if ref is not None else "-"))
            lines.append(f"| {p:g} | {m['relative_density']:.3f} | {cell('E_t', a and a['E_t'], E_S)} | "
                         f"{cell('E_l', a and a['E_l'], E_S)} | {cell('nu_t', a and a['nu_t'])} | "
                         f"{cell('nu_tl', a and a['nu_tl'])} | {cell('mu_l', a and a['mu_l'], G_S)} |")
            rho.append(m["relative_density"])
            e_t.append(m["E_t"])
            e_l.append(m["E_l"])
        if hw:
            lines.append(f"+- : the 95 % interval of the mean over the chart's seeds ({seeds} per point; "
                         "bars as in chart.png, metasheet.homogenize.chart_bars).")
        lines.append("")
        if len(rho) >= 2:
            t = authors_table(kind)
            ref = {"E_t": 0.5 * (t["E_y"] + t["E_z"]) if kind == "transverse" else (t["E_x"] + t["E_y"] + t["E_z"]) / 3,
                   "E_l": t["E_x"] if kind == "transverse" else (t["E_x"] + t["E_y"] + t["E_z"]) / 3}
            laws = []
            for name, ours in (("E_t", e_t), ("E_l", e_l)):
                n, c = np.polyfit(np.log(rho), np.log(np.array(ours) / E_S), 1)
                n_ref, c_ref = np.polyfit(np.log(t["density"]), np.log(ref[name]), 1)
                laws.append(f"{name} / E_s = {np.exp(c):.3g} rho^{n:.2f} (authors: {np.exp(c_ref):.3g} rho^{n_ref:.2f})")
            lines += ["Fitted power laws: " + "; ".join(laws) + ".", ""]
            diffs.append(f"Density sweep, shrink {s:g} vs the authors' {kind} foam: " + "; ".join(laws) + ".")
    return lines, diffs


def robot_rows(robot: Mapping | None, anisotropy: Mapping | None) -> list[str]:
    """The robot's figures with the pipeline's constants and with the published ones."""
    lines = []
    if robot and "published" in robot:
        lines += ["| robot figure | this pipeline's foam | published constants |", "|---|---|---|"]
        for key, label in (("singular_values", "Jacobian singular values"),
                           ("rod_rotation_deg_per_deg", "rod rotation per motor degree [deg/deg]"),
                           ("rod_rotation_finite_deg_per_deg", "rod rotation, finite move [deg/deg]")):
            a, b = robot["foam"].get(key), robot["published"].get(key)
            if a is None or b is None:
                continue
            fmt = (lambda v: ", ".join(f"{x:.4g}" for x in v)) if isinstance(a, list) else (lambda v: f"{v:.4g}")
            lines.append(f"| {label} | {fmt(a)} | {fmt(b)} |")
    if anisotropy and "published_end_point" in anisotropy:
        e = anisotropy["published_end_point"]
        rot = anisotropy["rod_rotation_deg"]
        if not lines:
            lines += ["| robot figure | this pipeline's foam | published constants |", "|---|---|---|"]
        lines.append(f"| Fig. 7 end point: alpha [%] | {anisotropy['alpha_percent'][-1]:.4g} | {e['alpha_percent']:.4g} |")
        for case in ("pull", "push"):
            a, b = rot[case][-1], e["rod_rotation_deg"][case]
            lines.append(f"| Fig. 7 end point: rod rotation, {case} [deg] | "
                         f"{'not converged' if a is None else f'{a:.4g}'} | {'not converged' if b is None else f'{b:.4g}'} |")
    return [*lines, ""] if lines else []


def scale_rows(cell: Mapping | None, thickness: float | None) -> tuple[list[str], list[str]]:
    """The cell's size against the sheet's thickness: does the sheet hold many cells?

    Homogenised constants describe a foam with many cells across every dimension of the
    part; the mean void chord along z (the build axis, the sheet's thickness) measures how
    many the printed sheet really holds.
    """
    if not cell or not thickness or "mean_void_chord_mm" not in cell:
        return [], []
    ch = [float(v) for v in cell["mean_void_chord_mm"]]
    cells_through = float(thickness) / ch[2] if ch[2] > 0 else float("inf")
    lines = [f"Cell scale: mean void chords along x, y, z = {ch[0]:.3g}, {ch[1]:.3g}, {ch[2]:.3g} mm "
             f"(periodic box {', '.join(f'{v:.3g}' for v in cell.get('size_mm', []))} mm, "
             f"{cell.get('seed_count', '?')} cells) against the sheet thickness {float(thickness):g} mm along z: "
             f"{cells_through:.2g} cell(s) through the thickness.", ""]
    diffs = []
    if cells_through < 3:
        diffs.append(f"Scale separation fails: the cell's mean void chord along the build axis is {ch[2]:.3g} mm "
                     f"for a {float(thickness):g} mm sheet ({cells_through:.2g} cells through it); the homogenised "
                     "constants are those of an unbounded foam, not of this sheet.")
    return lines, diffs


def constants_section(homogenize: Mapping | None, chart_rows: list[Mapping] | None, material: Mapping | None,
                      robot: Mapping | None, anisotropy: Mapping | None,
                      shrink: float | None = None, *, cell: Mapping | None = None,
                      thickness: float | None = None, chart_note: list[str] = ()) -> tuple[list[str], list[str]]:
    """The whole section: (Markdown lines, differences found); ``chart_note``: lines before the
    design chart's sweep (where the chart came from, or the command that makes it)."""
    if not homogenize:
        return [], []
    lines = ["## Printed foam: homogenised vs published vs literature (paper Section III-A)", ""]
    src = (material or {}).get("source")
    if src:
        lines += [f"The robot runs on the **{src}** constants" + (
            " (the printed cell's homogenised constants)." if src == "homogenize" else " (the published set)."), ""]
    cl, diffs = cell_rows(homogenize)
    kl, kd = scale_rows(cell, thickness)
    sl, sd = sweep_rows(chart_rows or [], shrink)
    lines += cl + kl + [*chart_note] + sl + robot_rows(robot, anisotropy)
    return lines, diffs + kd + sd
