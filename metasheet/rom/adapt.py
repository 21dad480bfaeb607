"""Growing a reduced model until its certificate is met (issue 41): the round-by-round schedule.

The reduce stage trains on its settings (round 1) and certifies the result on held-out poses
(:mod:`.certificate`). Its defaults must hold on any robot, not only on settings tuned for one,
so when a target is missed the next round trains again with

* more snapshots (``growth`` times as many, at most ``max_snapshots``) and ``tangent_tol``
  halved (more of their static responses in the basis): the held-out error is the basis's
  generalisation between training states. Both levers count, for every measure: on the
  quick robot (whole motor range, within the strain limit) 50 snapshots at 0.01 left 0.17 mm,
  0.13 deg and 5.2 % (every POD mode kept), 98 at 0.01 0.12 mm, 0.036 deg, 3.1 %, and 98 at
  0.005 0.028 mm, 0.013 deg, 0.96 %;
* the element sample's tolerance of a measure halved (``fit_jacobian_tol`` for the Jacobian,
  ``fit_tol_mm`` for positions and orientations) only where that measure missed and the
  sample's own error at the training states took more than a quarter of its target: the
  defaults leave it a fifth (positions) and a half (Jacobian) of the targets, and it reaches
  less (0.2-0.4 % of the 2 %); a tolerance tightened without need grows the sample, or fails
  it (9 halvings of the ECSW tolerance could not hold 0.005 mm on the 15 mm test robot),

until the targets are met or the budget is spent: ``rounds`` rounds, ``max_snapshots``
snapshots, an element sample at its budget (a sample that large hardly reduces the cost), or
the time budget ``seconds`` (issue 59). Every decision but the last depends on the
certificate's figures only (no clock): the same configuration gives the same rounds. The time
budget is checked only where another round would follow (:func:`out_of_time` before it starts,
:func:`deadline` while it solves its snapshots), so a run that stops for any other reason gives
the same result on any machine; one stopped by time (stop code ``"time"``) depends on the
machine's speed and load, and reduce.json and the report say so with the certificate's
shortfall (:func:`shortfall`). The round kept is the one that met the targets, else the one
closest to them (:func:`chosen`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace

from .certificate import TARGETS

#: why the rounds stopped: code -> sentence (reduce.json ``stopped``, the report)
STOP_REASONS = {
    "met": "the certificate's targets are met",
    "no_poses": "no held-out pose lies within the strain limit: there is nothing to certify, more training cannot help",
    "rounds": "the round budget (adapt_rounds) is spent",
    "snapshots": "the snapshot budget (max_snapshots) is spent",
    "elements": "the element sample reached its budget (max_elements_fraction of the mesh's elements)",
    "time": "the time budget (time_budget_s) is spent: this result depends on the machine's speed and load",
    "failed": "the next round's training failed",
}


@dataclass(frozen=True)
class Settings:
    """One round's training settings: ``snapshots`` (Sobol points, besides the box's two
    corners), ``tangent_tol`` [-], ``fit_tol_mm`` [mm], ``fit_jacobian_tol`` [-] (see
    :func:`.training.train`)."""

    snapshots: int
    tangent_tol: float
    fit_tol_mm: float
    fit_jacobian_tol: float


@dataclass(frozen=True)
class Budget:
    """What the rounds may spend: ``rounds`` (1: no adaptation), ``max_snapshots``, the
    snapshots' ``growth`` factor per round (> 1), ``max_elements`` in the element sample,
    ``seconds`` of wall time from the stage's start [s] (None: no time budget)."""

    rounds: int
    max_snapshots: int
    growth: float
    max_elements: int
    seconds: float | None = None


def missed(cert: dict) -> tuple[str, ...]:
    """The :data:`TARGETS` a certificate (:func:`.certificate.summarize`) misses, in their order."""
    return tuple(name for name in TARGETS if not (cert.get(name) or {}).get("met"))


def miss_ratio(cert: dict) -> float:
    """The certificate's distance from its targets: the largest worst / target over the
    measures (<= 1: met; inf: a pose failed or none was compared)."""
    ratios = []
    for name, target in TARGETS.items():
        m = cert.get(name) or {}
        if m.get("worst") is None or m.get("failed"):
            return math.inf
        ratios.append(m["worst"] / target)
    return max(ratios) if ratios and cert.get("poses") else math.inf


def next_round(s: Settings, cert: dict, info: dict, budget: Budget, done: int) -> tuple[Settings | None, str]:
    """The next round's :class:`Settings` after round ``done`` (1-based) trained with ``s``,
    gave the certificate ``cert`` and the training record ``info`` (:func:`.training.train`'s
    ``info``), or ``(None, code)`` with the :data:`STOP_REASONS` code that ends the rounds."""
    if cert.get("met"):
        return None, "met"
    if not cert.get("poses"):
        return None, "no_poses"
    if done >= budget.rounds:
        return None, "rounds"
    if info.get("element_budget_spent") or info.get("elements", 0) >= budget.max_elements:
        return None, "elements"
    n = min(budget.max_snapshots, math.ceil(s.snapshots * budget.growth))
    if n <= s.snapshots:
        return None, "snapshots"
    miss = missed(cert)
    fit_mm, fit_jac = sample_error(info)
    jac = "jacobian_rel" in miss and fit_jac > TARGETS["jacobian_rel"] / 4
    pose = ("position_mm" in miss or "orientation_deg" in miss) and fit_mm > TARGETS["position_mm"] / 4
    return replace(s, snapshots=n, tangent_tol=s.tangent_tol / 2,
                   fit_jacobian_tol=s.fit_jacobian_tol / 2 if jac else s.fit_jacobian_tol,
                   fit_tol_mm=s.fit_tol_mm / 2 if pose else s.fit_tol_mm), ""


def out_of_time(budget: Budget, elapsed_s: float, last_round_s: float) -> bool:
    """Whether the time budget forbids another round: ``elapsed_s`` [s] since the stage began
    and ``last_round_s`` [s], the round just done, which the next one costs at least (more
    snapshots, a larger basis; a round under way at the budget's end is abandoned, so the
    estimate need not be an upper bound). Never without a time budget. The stage asks only
    after :func:`next_round` gave another round: the one decision that reads a clock."""
    return budget.seconds is not None and elapsed_s + last_round_s > budget.seconds


class OutOfTime(Exception):
    """The time budget ran out while a later round solved its snapshots (the stage catches it)."""


def deadline(t_start: float, budget: Budget) -> Callable[[], None]:
    """A check that raises :class:`OutOfTime` once ``budget.seconds`` [s] have passed since
    ``t_start`` (``time.perf_counter``), for a round under way; a no-op without a time budget."""
    def check() -> None:
        if budget.seconds is not None and time.perf_counter() - t_start > budget.seconds:
            raise OutOfTime
    return check


def stop_reason(stop: str, detail: str, rounds: int, budget: Budget) -> str:
    """reduce.json ``adaptation.reason``: why ``rounds`` rounds stopped (a :data:`STOP_REASONS`
    code and its ``detail``); for ``"time"`` the budget and that the result depends on the
    machine. No clock value: the seconds go to the manifest."""
    if stop != "time":
        return STOP_REASONS[stop] + (f" ({detail})" if detail else "")
    return (f"time budget spent after {rounds} round(s) (time_budget_s = {budget.seconds:g} s; "
            f"{detail or 'another round would not end within it'}): this result depends on the machine's speed "
            "and load")


def shortfall(cert: dict) -> dict:
    """The measures a certificate (:func:`.certificate.summarize`) misses: name -> its worst
    error, target, worst / target (None: no pose compared) and failed poses; {} when met."""
    out = {}
    for name in missed(cert):
        m, target = cert.get(name) or {}, TARGETS[name]
        worst = m.get("worst")
        out[name] = {"worst": worst, "target": target, "ratio": None if worst is None else worst / target,
                     "failed": int(m.get("failed", 0))}
    return out


def shortfall_text(short: dict) -> str:
    """:func:`shortfall` in words: "position_mm 0.17 against 0.1 (1.7x), ..." ("" when nothing
    is missed; a measure within its target but with failed poses says how many failed)."""
    def one(name, m):
        if m["worst"] is None:
            return f"{name}: no pose compared"
        failed = f", {m['failed']} pose(s) failed" if m["failed"] else ""
        return f"{name} {m['worst']:.3g} against {m['target']:g} ({m['ratio']:.2g}x{failed})"

    return ", ".join(one(n, m) for n, m in short.items())


def sample_error(info: dict) -> tuple[float, float]:
    """The kept element sample's own error at the training states (``info["ecsw_rounds"]``:
    the one marked chosen, else the last): position [mm] against the full model, Jacobian
    [relative] against the basis with every element; (0, 0) when not recorded."""
    rounds = info.get("ecsw_rounds") or []
    if not rounds:
        return 0.0, 0.0
    r = next((r for r in rounds if r.get("chosen")), rounds[-1])
    jac = r.get("fit_jacobian_rel")
    return float(r.get("fit_error_mm") or 0.0), float(0.0 if jac is None or jac != jac else jac)


def chosen(certs: list[dict]) -> int:
    """Index of the round to keep: the first that met its targets, else the one with the
    smallest :func:`miss_ratio` (the earliest of equals: the smaller model)."""
    for i, c in enumerate(certs):
        if c.get("met"):
            return i
    return min(range(len(certs)), key=lambda i: (miss_ratio(certs[i]), i))


def round_record(number: int, s: Settings, info: dict, cert: dict, snapshots_failed: int) -> dict:
    """One round's entry of reduce.json ``rounds``: its settings, basis and sample sizes, and
    the certificate's worst figures (poses within the strain limit) and verdict."""
    return {"round": number, "snapshots": s.snapshots, "snapshots_failed": int(snapshots_failed),
            "tangent_tol": s.tangent_tol, "fit_tol_mm": s.fit_tol_mm, "fit_jacobian_tol": s.fit_jacobian_tol,
            "k": info.get("k"), "static_modes": info.get("static_modes"), "pod_modes": info.get("pod_modes"),
            "sensitivity_modes": info.get("sensitivity_modes"), "elements": info.get("elements"),
            "basis_jacobian_rel": info.get("basis_jacobian_rel"), "fit_jacobian_met": info.get("fit_jacobian_met"),
            **dict(zip(("fit_error_mm", "fit_jacobian_rel"), sample_error(info))),
            "element_budget_spent": bool(info.get("element_budget_spent")), "poses": cert.get("poses"),
            **{name: (cert.get(name) or {}).get("worst") for name in TARGETS},
            "failed_poses": int(sum((cert.get(name) or {}).get("failed", 0) for name in TARGETS)),
            "missed": list(missed(cert)), "met": bool(cert.get("met"))}
