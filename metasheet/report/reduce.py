"""Report section: the reduced-order robot and its certificate (``reduce/reduce.json``, issue 16).

The basis and element sample the studies ran on, what training cost, and the certificate:
reduced against full on held-out poses, worst and 95th percentile of each measure against its
target, over the poses within the strain limit (the material model's domain; the others
follow as information, outside every study's domain), and the training rounds that led there
(issue 41: the stage grows the basis and the element sample until the targets are met or its
budget is spent, and a budget spent without them is said here, not hidden). A run whose rounds
the time budget stopped (issue 59) says so in bold, with what the certificate misses: its
result depends on the machine's speed and load.
"""

from __future__ import annotations

from collections.abc import Mapping

MEASURES = (("position_mm", "effector position [mm]"), ("orientation_deg", "effector orientation [deg]"),
            ("jacobian_rel", "Jacobian [relative Frobenius]"), ("inverse_motor_deg", "inverse model's motors [deg]"))


def _g(v) -> str:
    return "-" if v is None else f"{v:.3g}"


def _rows(cert: Mapping, with_target: bool) -> list[str]:
    out = []
    for key, label in MEASURES:
        m = cert.get(key) or {}
        target = m.get("target")
        verdict = "" if target is None else ("met" if m.get("met") else "NOT met")
        cells = [label, _g(m.get("worst")), _g(m.get("p95")), str(m.get("failed", 0))]
        if with_target:
            cells += [_g(target), verdict]
        out.append("| " + " | ".join(cells) + " |")
    return out


def reduce_section(red: Mapping | None, seconds: float | None = None) -> tuple[list[str], list[str]]:
    """(Markdown lines, differences) of the reduced model's section; ``red`` is reduce.json
    (None: no section), ``seconds`` the stage's wall time."""
    if not red:
        return [], []
    cert = red["certificate"]
    lo, hi = red["box_deg"]
    box = f"{min(lo):g} to {max(hi):g} deg" if len(set(lo)) == 1 and len(set(hi)) == 1 else f"{lo} to {hi} deg"
    t = red.get("training", {})
    limit = cert.get("strain_limit")
    where = f"within the strain limit {limit:g}" if limit is not None else "all"
    lines = ["## Reduced-order robot and its certificate (issue 16)", "",
             f"Basis of k = {red['k']} modes ({t.get('static_modes', '?')} static, {t.get('pod_modes', '?')} POD, "
             f"{t.get('sensitivity_modes', '?')} from the static responses) over {red['free_dofs']} free dofs; "
             f"{red['elements']} of {red['elements_total']} elements sampled (ECSW, non-negative weights); "
             f"trained on motor angles {box}"
             + (f" in {seconds:.0f} s." if seconds is not None else "."), "",
             f"Held-out poses (not used in training) {where}: {cert['poses']}"
             + (f"; beyond it: {cert.get('poses_beyond_strain', 0)}." if limit is not None else "."), "",
             "| measure | worst | p95 | failed | target | verdict |", "|---|---|---|---|---|---|",
             *_rows(cert, True), "",
             f"Certificate: **{'met' if cert.get('met') else 'NOT met'}**.", *_rounds(red.get("adaptation"))]
    if cert.get("beyond_strain"):
        lines += ["", f"Beyond the strain limit (outside the homogenised model's domain; information only, "
                  f"{cert['beyond_strain']['poses']} poses, strain up to {_g(cert['beyond_strain'].get('max_strain'))}):",
                  "", "| measure | worst | p95 | failed |", "|---|---|---|---|", *_rows(cert["beyond_strain"], False)]
    ad = red.get("adaptation") or {}
    spent = f", after {len(ad['rounds'])} training round(s): {ad['reason']}" if ad.get("rounds") else ""
    spent += f"; it misses {_misses(ad.get('shortfall'))}" if ad.get("shortfall") else ""
    diffs = [] if cert.get("met") else [
        f"reduced model (issue 16): the certificate is not met on the held-out poses {where}{spent} (see its section)."]
    surf_lines, surf_diffs = _surface(red.get("surface"), where)
    return [*lines, "", *surf_lines], diffs + surf_diffs


def _rounds(ad: Mapping | None) -> list[str]:
    """The training rounds (``reduce.json`` ``adaptation``): one row each, the verdict, why
    they stopped; nothing for an older reduce.json without them."""
    if not ad or not ad.get("rounds"):
        return []
    rows = [f"| {r['round']} | {r['snapshots']} | {r['k']} | {r['elements']} | {_g(r['tangent_tol'])} | "
            f"{_g(r['fit_jacobian_tol'])} | {_g(r['position_mm'])} | {_g(r['orientation_deg'])} | "
            f"{_g(r['jacobian_rel'])} | {'met' if r['met'] else 'NOT met'} |" for r in ad["rounds"]]
    b, n, kept = ad.get("budget", {}), len(ad["rounds"]), ad.get("chosen_round")
    met = any(r["met"] for r in ad["rounds"])
    verdict = (f"the targets were met in round {kept}" if met else
               f"**the targets were NOT met within the budget**; the model kept is round {kept}'s, the closest "
               "to them")
    seconds = b.get("time_budget_s")
    timed = f", {seconds:g} s" if seconds is not None else ""
    return ["", f"Training rounds: {n} (budget: {b.get('rounds')} rounds, {b.get('max_snapshots')} snapshots, "
            f"{b.get('max_elements')} elements{timed}); {verdict}. Stopped: {ad.get('reason')}.",
            *_time_spent(ad), "", "Worst errors over the held-out poses within the strain limit:", "",
            "| round | snapshots | k | elements | tangent_tol | fit_jacobian_tol | position [mm] | orientation [deg] "
            "| Jacobian | certificate |", "|---|---|---|---|---|---|---|---|---|---|", *rows]


def _time_spent(ad: Mapping) -> list[str]:
    """The time budget's stop in bold, and the certificate's shortfall (``adaptation``
    ``shortfall``); nothing when the rounds stopped otherwise."""
    if ad.get("stopped") != "time":
        return []
    misses = _misses(ad.get("shortfall"))
    return ["", f"**The time budget stopped the rounds after {len(ad['rounds'])}: this model depends on the "
            "machine's speed and load** (a quieter or faster machine, or a larger `[reduce] time_budget_s`, may "
            "train further). " + (f"The certificate misses: {misses}." if misses else "The certificate is met.")]


def _misses(short: Mapping | None) -> str:
    """``adaptation`` ``shortfall`` in words: "effector position [mm] worst 0.17 against 0.1
    (1.7 times); ..." ("" for none, or an older reduce.json without it)."""
    return "; ".join(f"{label} worst {_g(m['worst'])} against {_g(m['target'])}"
                     + (f" ({m['ratio']:.2g} times)" if m.get("ratio") is not None else "")
                     for key, label in MEASURES if (m := (short or {}).get(key)))


def _surface(surf: Mapping | None, where: str) -> tuple[list[str], list[str]]:
    """The equilibrium surface's subsection (``reduce.json`` ``surface``), or nothing."""
    if not surf or "certificate" not in surf:
        return [], []
    cert, check = surf["certificate"], surf.get("check")
    met = surf.get("certified", cert.get("met"))
    lo, hi = surf.get("box_deg", (None, None))
    box = f" over motor angles {min(lo):.4g} to {max(hi):.4g} deg" if lo else ""
    lines = ["### Equilibrium surface (the real-time model)", "",
             f"Polynomials of degree {surf.get('degree')} in the motor angles ({surf.get('coefficients')} "
             f"coefficients){box}, fitted on {surf.get('equilibria')} reduced-model equilibria, the degree chosen "
             f"on {surf.get('check_equilibria')} others."]
    if check:
        rows = [f"| {label} | {_g(m['worst'])} | {_g(m['p95'])} | {_g(m['bound_with_reduced'])} | "
                f"{_g(m['target'])} | {'met' if m['met'] else 'NOT met'} |"
                for key, label in MEASURES if (m := check.get(key))]
        lines += ["", f"Against the reduced model on {check['within_strain']} further equilibria within the strain "
                  f"limit (of {check['equilibria']}; neither fitted nor used for the degree); the bound adds the "
                  "reduced model's worst error against the full model:", "",
                  "| measure | worst | p95 | bound against the full model | target | verdict |",
                  "|---|---|---|---|---|---|", *rows]
    outside = surf.get("held_out_outside_box", 0)
    lines += ["", f"Against the full model on the held-out poses inside its box ({where}: {cert['poses']}"
              + (f"; {outside} outside its box" if outside else "") + "):", "",
              "| measure | worst | p95 | failed | target | verdict |", "|---|---|---|---|---|---|",
              *_rows(cert, True), "", f"Certificate: **{'met' if met else 'NOT met'}**.", ""]
    diffs = [] if met else [
        f"equilibrium surface (issue 16): the certificate is not met {where} (see its section)."]
    return lines, diffs
