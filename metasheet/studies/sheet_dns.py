"""Is the homogenised sheet the printed sheet? The DNS against the homogenised robot (issue 44).

Given the printed sheets' grip stiffnesses (:mod:`metasheet.sheet.dns`, one pair per
realisation: the normal and the mirrored print) and the homogenised sheets' (the robot's own
mesh, element, fibres and constants, :func:`metasheet.sheet.grips.fem_condensed`), this module
compares them sheet by sheet (:func:`metasheet.sheet.dns.compare`), builds the robot's linear
rest model from each pair (:mod:`metasheet.robot.condensed`: Jacobian singular values, rod roll
per motor degree), fits the apparent constants (:mod:`metasheet.sheet.apparent`, both sheets
at once) and states the spread over realisations: what two prints of one design differ by.

Everything here is the linear rest model without gravity, for both columns alike, so the
printed-over-homogenised ratios compare like with like; the robot stage's own numbers (with the
gravity sag) are quoted beside them.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..mechanics.material import CONSTANT_NAMES
from ..robot.builder import SheetPair, element_stiffness
from ..robot.condensed import rest_numbers_condensed
from ..sheet.dns import DnsSheet, compare
from ..sheet.grips import fem_condensed, grip_references

#: the rod roll of the printed robot within this fraction of the homogenised one: "agrees"
ROLL_AGREES = 0.10


def homogenised_grips(pair: SheetPair, model: str) -> tuple[np.ndarray, np.ndarray]:
    """(K_A, K_B), each (24, 24): the robot's homogenised sheets condensed on their grips
    (per-element constants along the fibres under ``model``, the pair's element)."""
    out = []
    for mesh, fib, con in ((pair.sheet, pair.fibers, pair.constants),
                           (pair.mirrored, pair.fibers_mirrored, pair.constants_mirrored)):
        out.append(fem_condensed(mesh, element_stiffness(fib, con, model), pair.element).K)
    return out[0], out[1]


def _pairs(sheets: Sequence[DnsSheet]) -> list[tuple[DnsSheet, DnsSheet]]:
    """The (normal, mirrored) DNS sheets of each realisation, in seed order."""
    by = {(s.seed, s.label): s for s in sheets}
    seeds = sorted({s.seed for s in sheets})
    return [(by[(s, "normal")], by[(s, "mirrored")]) for s in seeds]


def _spread(values) -> dict:
    v = np.asarray(values, float)
    return {"mean": float(v.mean(axis=0)) if v.ndim == 1 else v.mean(axis=0).tolist(),
            "min": float(v.min()) if v.ndim == 1 else v.min(axis=0).tolist(),
            "max": float(v.max()) if v.ndim == 1 else v.max(axis=0).tolist(),
            "std": float(v.std(ddof=1)) if v.ndim == 1 and len(v) > 1 else None}


def dns_study(sheets: Sequence[DnsSheet], homogenised: tuple[np.ndarray, np.ndarray], robot, params, *,
              length_scale: float, fits: Sequence | None = None) -> dict:
    """The comparison ``sheet_dns.json`` holds (module docstring).

    sheets : every realisation's normal and mirrored :class:`~metasheet.sheet.dns.DnsSheet`;
    homogenised : (K_A, K_B) of :func:`homogenised_grips`; robot : the six-DOF robot whose servos
    place the grips (the robot stage's scene); params : the sheets' SheetParams;
    fits : per realisation an :class:`~metasheet.sheet.apparent.ApparentFit` (or None).
    """
    refs = grip_references(params)
    Ka, Kb = homogenised
    hom = rest_numbers_condensed(Ka, Kb, robot, refs, length_scale=length_scale)
    rows = []
    for i, (a, b) in enumerate(_pairs(sheets)):
        dns = rest_numbers_condensed(a.K, b.K, robot, refs, length_scale=length_scale)
        row = {"seed": a.seed,
               # wall times go to the manifest only: the same config and seed give the same bytes
               "sheets": {s.label: {**{k: v for k, v in s.to_dict().items() if k not in ("build_s", "solve_s")},
                                    **compare(s.K, K, params)}
                          for s, K in ((a, Ka), (b, Kb))},
               "robot": {**dns, "rod_roll_ratio": dns["rod_rotation_deg_per_deg"] / hom["rod_rotation_deg_per_deg"],
                         "singular_value_ratios": (np.asarray(dns["singular_values"])
                                                   / np.asarray(hom["singular_values"])).tolist()}}
        if fits is not None and fits[i] is not None:
            f = fits[i]
            row["apparent"] = {"constants": f.constants, "rms_log_ratio": f.rms_log, "max_log_ratio": f.max_log,
                               "converged": f.converged, "evaluations": f.evaluations, "message": f.message}
        rows.append(row)
    roll = [r["robot"]["rod_rotation_deg_per_deg"] for r in rows]
    out = {"homogenised_robot": hom, "realisations": rows,
           "spread": {"rod_rotation_deg_per_deg": _spread(roll),
                      "rod_roll_ratio": _spread([r["robot"]["rod_roll_ratio"] for r in rows]),
                      "singular_values": _spread([r["robot"]["singular_values"] for r in rows]),
                      **{f"geometric_mean_ratio_{lab}": _spread([r["sheets"][lab]["geometric_mean_ratio"]
                                                                 for r in rows]) for lab in ("normal", "mirrored")}}}
    if all("apparent" in r for r in rows):
        out["spread"]["apparent"] = {k: _spread([r["apparent"]["constants"][k] for r in rows])
                                     for k in CONSTANT_NAMES}
    out["verdict"] = verdict(out)
    return out


def _span(r: dict) -> str:
    return f"{r['min']:.2f}" if r["min"] == r["max"] else f"{r['min']:.2f} to {r['max']:.2f}"


def verdict(study: dict) -> str:
    """One line: does the printed sheet give the 6th DOF the homogenised model predicts? "agrees"
    when the printed robot's rod roll per degree is within :data:`ROLL_AGREES` of the
    homogenised robot's in every realisation; the singular values and the sheets' stiffness
    follow."""
    hom = study["homogenised_robot"]["rod_rotation_deg_per_deg"]
    r = study["spread"]["rod_roll_ratio"]
    n = len(study["realisations"])
    within = max(abs(r["min"] - 1.0), abs(r["max"] - 1.0)) <= ROLL_AGREES
    sv = np.asarray([row["robot"]["singular_value_ratios"] for row in study["realisations"]])
    g = study["spread"]["geometric_mean_ratio_normal"]
    head = "agrees" if within else "differs"
    return (f"{head}: the printed robot's rod roll per degree is {_span(r)} x the homogenised robot's "
            f"({hom:+.3f} deg/deg) over {n} realisation{'s' if n > 1 else ''}, {'within' if within else 'beyond'} "
            f"{ROLL_AGREES:.0%}; its singular values {sv.min():.2f} to {sv.max():.2f} x; the printed sheet is "
            f"{_span(g)} x as stiff as the homogenised one (geometric mean of its 18 modes)")
