"""Report section: the homogenised constants' uncertainty and what it does downstream (issue 43).

Reads what the stages wrote: ``constants.json``'s ``ci95`` and ``ensemble`` blocks, the
homogenize manifest's wall times per realisation (``realisation_s.<n>``), the cell-size study
``convergence.json``, the robot's spread at the constants' bounds, and the print round
trip's ``against_uncertainty``. Every sentence is computed from those numbers.
"""

from __future__ import annotations

from collections.abc import Mapping

from ..published.literature import authors_constants, authors_table
from ..mechanics.material import CONSTANT_NAMES
from ..published.paper import PAPER_FOAM

_UNITS = {"E_t": "MPa", "E_l": "MPa", "nu_t": "-", "nu_tl": "-", "mu_l": "MPa"}


def _pm(mean: float, half: float | None) -> str:
    if half is None:
        return f"{mean:.4g}"
    return f"{mean:.4g} +- {half:.2g} ({100 * half / abs(mean):.0f} %)" if mean else f"{mean:.4g} +- {half:.2g}"


def _beyond(ours: float, half: float | None, ref: float | None) -> str:
    if ref is None or half is None:
        return "-"
    return "yes" if abs(ref - ours) > half else "no: within the interval"


def uncertainty_rows(h: Mapping, timings: Mapping | None) -> tuple[list[str], list[str]]:
    """The constants with their intervals, next to the published set and the authors' table.

    ``h``: constants.json with ``ci95``; ``timings``: the homogenize manifest's ``timings_s``.
    Returns (Markdown lines, differences found).
    """
    ci, ens = h.get("ci95"), h.get("ensemble")
    if not ci or not ens:
        return [], []
    rho = float(h.get("relative_density", float("nan")))
    d = authors_table()["density"]
    lit = authors_constants(rho) if d[0] <= rho <= d[-1] else None
    paper = PAPER_FOAM.to_dict()
    lines = [f"### Constants with 95 % intervals ({ci['k']} realisations of {ci['n_cells']} cells)", "",
             f"Each constant is the mean over {ci['k']} independent seeds ({', '.join(map(str, ens['seeds']))}) of "
             f"the {ci['n_cells']}-cell periodic volume, with the 95 % Student-t half-width of that mean. "
             "Beyond the interval: |reference - mean| > half-width.", "",
             "| constant | mean +- 95 % half-width | published | beyond? | authors' table | beyond? |",
             "|---|---|---|---|---|---|"]
    diffs = []
    for k in CONSTANT_NAMES:
        half = ci["halfwidth"].get(k)
        ref = None if lit is None else float(lit[k])
        lines.append(f"| {k} [{_UNITS[k]}] | {_pm(h[k], half)} | {paper[k]:.4g} | {_beyond(h[k], half, paper[k])} | "
                     f"{'-' if ref is None else f'{ref:.4g}'} | {_beyond(h[k], half, ref)} |")
        if half is not None and abs(paper[k] - h[k]) > half:
            diffs.append(f"{k}: the published {paper[k]:.3g} lies outside our 95 % interval {_pm(h[k], half)}: "
                         "a difference of model, not of sampling.")
    lines += ["", "What a difference beyond the interval points to (infill mapping, walls vs struts, layer "
              "bonding), each assumption changed one at a time and measured: docs/validation.md, \"What the "
              "differences with the published constants point to\" (`benchmarks/assumption_sensitivity.py`).", ""]
    target = float(ens.get("target_rel_halfwidth", 0.05))
    met = [k for k in CONSTANT_NAMES if ens["meets_target"].get(k)]
    missed = [k for k in CONSTANT_NAMES if not ens["meets_target"].get(k)]
    sec = (timings or {}).get(f"realisation_s.{ci['n_cells']}")
    text = f"Target: each half-width <= {100 * target:g} % of its value. Met for {', '.join(met) or 'none'}."
    if missed:
        need = ens["k_required"]
        parts = []
        for k in missed:
            cost = f", about {need[k] * sec / 60:.0f} min of one core at {sec:.0f} s per realisation" if sec else ""
            parts.append(f"{k} ({100 * ci['rel_halfwidth'][k]:.0f} % now) needs {need[k]} realisations{cost}")
        text += " Not met within the stage's budget: " + "; ".join(parts) + "."
        diffs.append(f"Constants' uncertainty: {100 * target:g} % not met for {', '.join(missed)} with "
                     f"{ci['k']} realisations; " + "; ".join(parts) + ".")
    return [*lines, text, ""], diffs


#: the cell-size study's heading (also over the line naming the command, when the study is not there)
SIZE_HEADING = "### Cell-size study"


def size_study_rows(conv: Mapping | None, picture: str | None, timings: Mapping | None = None, *,
                    source: str = "homogenize/convergence.json", preface: list[str] = ()) -> list[str]:
    """The cell-size study: per size the means and half-widths, the trend verdicts, and what the
    relative target would cost at each size (``timings``: the homogenize manifest's).
    ``source``: the file it came from; ``preface``: lines after the heading."""
    if not conv or not conv.get("sizes"):
        return []
    names = list(conv["constants"])
    lines = [f"{SIZE_HEADING} ({source})", "", *preface]
    if picture:
        lines += [f"![cell-size study]({picture})", ""]
    lines += ["| cells | k | " + " | ".join(f"{n} [{_UNITS.get(n, '-')}]" for n in names) + " |",
              "|---|---|" + "---|" * len(names)]
    for s in conv["sizes"]:
        cells = [_pm(s["constants"][n]["mean"], s["constants"][n]["halfwidth"]) for n in names]
        lines.append(f"| {s['n_cells']} | {s['k']} | " + " | ".join(cells) + " |")
    lines.append("")
    verdicts = []
    for n, t in (conv.get("trend") or {}).items():
        v = t["verdict"]
        if t.get("extrapolated") is not None:
            v += f", extrapolated to an unbounded foam {t['extrapolated']:.4g} +- {t['halfwidth_a']:.2g}"
        if t.get("chi2_reduced") is not None and t["chi2_reduced"] > 3:
            v += f" (the n^(-1/3) model misses the data: reduced chi-square {t['chi2_reduced']:.1f})"
        verdicts.append(f"{n}: {v}")
    if verdicts:
        fitted = conv.get("trend_sizes") or [z["n_cells"] for z in conv["sizes"]]  # older files: every size
        lines += [f"Trend model {conv['trend_model']}, fitted over {', '.join(map(str, fitted))} cells: "
                  + "; ".join(verdicts) + ".", ""]
    need = conv.get("k_required_per_size") or {}
    costs = []
    for n, req in need.items():
        gov = max(req, key=req.get)
        sec = (timings or {}).get(f"realisation_s.{n}")
        cost = f" (about {req[gov] * sec / 3600:.1f} h of one core)" if sec else ""
        costs.append(f"{n} cells: {req[gov]} realisations, for {gov}{cost}")
    if costs:
        lines += ["Every constant within the target would need, per size: " + "; ".join(costs) +
                  ". A smaller volume needs more realisations and carries the size bias above.", ""]
    return lines


def robot_spread_rows(robot: Mapping | None) -> list[str]:
    """The robot's rod roll and singular values over the constants' 95 % bounds."""
    if not robot or "foam_rod_rotation_range_95" not in robot:
        return []
    lo, hi = robot["foam_rod_rotation_range_95"]
    mean = robot.get("foam", {}).get("rod_rotation_deg_per_deg")
    lines = ["### The robot under the constants' uncertainty", "",
             f"Rod roll per motor degree (all motors together) at the mean constants {mean:.4g} deg/deg; over the "
             f"ten one-at-a-time 95 % bounds {lo:.4g} to {hi:.4g} deg/deg."]
    if "foam_singular_values_range_95" in robot:
        smin, smax = robot["foam_singular_values_range_95"]
        lines.append("Jacobian singular values over the bounds: " +
                     ", ".join(f"{a:.3g}-{b:.3g}" for a, b in zip(smin, smax)) + ".")
    return [*lines, ""]


def print_rows(consistency: Mapping | None) -> list[str]:
    """The print round trip's differences against the constants' own uncertainty."""
    u = (consistency or {}).get("against_uncertainty")
    if not u:
        return []
    rows = [f"{k} {100 * v['max_relative_difference']:.2g} % ({'below' if v['below_uncertainty'] else 'above'} "
            f"its {100 * v['rel_halfwidth_95']:.2g} %)" for k, v in u.items() if isinstance(v, dict)]
    return ["Print round trip against the constants' uncertainty (largest relative difference over both "
            "sheets): " + "; ".join(rows) + ".", ""]
