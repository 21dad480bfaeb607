"""Stage ``reduce``: the reduced-order robot (issue 16), trained and certified against the full one.

Builds the study robot (:func:`._studies.build_spec`: the orient stage's mesh and element,
the robot stage's scene, the material stage's constants), solves full-model equilibria at
motor angles spread over the training box (through the executor: a local pool or
``--scheduler`` on dask; resumable), trains the basis and the element sample by their error
targets (:mod:`metasheet.rom.training`) and certifies the result on held-out angles
(:mod:`metasheet.rom.certificate`). Writes

* ``basis.npz``: the basis, the sampled elements and weights, the training box, the robot's key;
* ``reduce.json``: sizes, targets, training record and the certificate (worst and p95 of the
  position, orientation, Jacobian and inverse-model errors), and the rows of the held-out set;
* ``surface.npz``: the equilibrium surface (:mod:`metasheet.rom.surface`, the real-time
  loop's model), fitted on reduced-model equilibria over its box (``surface_box_deg``, inside
  the training box), its degree chosen on equilibria not fitted, checked on further ones
  (``surface_check``) and certified by that check's bound with the reduced model's own error,
  the held-out full poses inside its box agreeing (``reduce.json`` ``surface``).

The defaults must certify on any robot, not only on tuned settings (issue 41): when the
certificate misses a target the stage trains again, round by round, on more snapshots and
tighter tolerances (:mod:`metasheet.rom.adapt`), until the targets are met or the budget
(``adapt_rounds``, ``max_snapshots``, ``max_elements_fraction``, ``time_budget_s``) is spent.
``reduce.json`` records every round (``adaptation``), the verdict (``certificate_met``), why
the rounds stopped and what the certificate misses (``shortfall``); a budget spent without the
targets is said in the report and in a warning, and the outputs are written all the same (from
the round closest to the targets).

The time budget (issue 59) counts from the stage's start. The first round always completes (no
model without it); another starts only if the time so far plus the last round's would fit
(:func:`metasheet.rom.adapt.out_of_time`), and a later round still solving its snapshots when
the budget runs out is abandoned. The clock is read only where another round would follow, so
a run that stops for any other reason gives the same result on any machine; one stopped by
time says so (``stopped: "time"``).

Training time goes to the manifest (``timings_s``), not to ``reduce.json``.
"""

from __future__ import annotations

import logging
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace

import numpy as np
from pydantic import Field, model_validator

from ...errors import ConfigError, ConvergenceError
from ...robot.equilibrium import solve_equilibrium
from ...robot.kinematics import kinematics
from ...rom.adapt import (Budget, OutOfTime, Settings, chosen, deadline, next_round, out_of_time, round_record,
                          shortfall, shortfall_text, stop_reason)
from ...rom.certificate import (TARGETS, compare, compare_surface, held_out_angles, summarize, surface_check,
                                with_inverse)
from ..manifest import write_json_atomic
from ..registry import Stage, StageContext, register
from ._studies import StudyRobotParams, build_spec, drop_cache, run_columns, unit_cache

log = logging.getLogger(__name__)

#: the default budget: rounds, snapshots (the first round's 16 doubled: 16, 32, 64, 128, then 192)
ADAPT_ROUNDS, MAX_SNAPSHOTS = 5, 192
#: the rounds' default time budget [s]: the first round is small and the budget decides how far
#: it grows (issue 59: docs/performance.md, "The reduce stage's time budget")
TIME_BUDGET_S = 120.0


class ReduceParams(StudyRobotParams):
    snapshots: int = Field(16, ge=4, le=2000, description="training equilibria (Sobol points in the box, "
                           "plus its all-low and all-high corners)")
    box_deg: float | None = Field(None, gt=0, le=180, description="training box: the rest angles +- this [deg], "
                                  "cut to the motor range; None: the whole motor range")
    basis_tol_mm: float = Field(0.01, gt=0, le=10, description="POD target: worst nodal projection error of the "
                                "training snapshots [mm]")
    tangent_tol: float = Field(0.01, gt=0, lt=1, description="the snapshots' static responses (the Jacobian's "
                               "data) are captured within this relative nodal error [-]")
    ecsw_tol: float = Field(1e-3, gt=0, lt=1, description="first ECSW relative force tolerance (halved until "
                            "fit_tol_mm and fit_jacobian_tol are met)")
    fit_tol_mm: float = Field(0.02, gt=0, le=10, description="the reduced model must reproduce the training "
                              "equilibria within this [mm]")
    fit_jacobian_tol: float = Field(0.01, gt=0, lt=1, description="... and their Jacobians within this (relative "
                                    "Frobenius) [-]: half the certificate's 2 %")
    held_out: int = Field(8, ge=0, le=1000, description="certificate poses (Sobol, another seed) besides the "
                          "two mixed corners")
    seed: int = Field(0, ge=0, description="Sobol scrambling seed of the training set (held-out: seed + 1)")
    strain_limit: float | None = Field(0.3, gt=0, description="the certificate's targets apply to held-out poses "
                                       "within this max principal strain [-] (the material model's domain; the "
                                       "others are reported apart); None: to all")
    surface_equilibria: int = Field(32, ge=16, le=5000, description="reduced-model equilibria the equilibrium "
                                    "surface (the real-time model) is fitted on; half as many more choose its degree")
    surface_check: int = Field(32, ge=0, le=5000, description="reduced-model equilibria, neither fitted nor used "
                               "for the degree, the surface is checked on (those within the strain limit)")
    surface_box_deg: float | None = Field(None, gt=0, le=180, description="the surface's box: the rest angles +- "
                                          "this [deg], within the training box; None: the training box")
    adapt_rounds: int = Field(ADAPT_ROUNDS, ge=1, le=10, description="training rounds at most: while the certificate "
                              "misses a target, train again on snapshot_growth times the snapshots with tangent_tol "
                              "halved (and the element sample's tolerance of a missed measure, where the sample's own "
                              "error counts: metasheet/rom/adapt.py) (1: one round)")
    snapshot_growth: float = Field(2.0, gt=1, le=8, description="each further round trains on this many times the "
                                   "snapshots of the one before [-]")
    max_snapshots: int = Field(MAX_SNAPSHOTS, ge=4, le=2000, description="the rounds' snapshot budget: no round "
                               "trains on more; at least snapshots")
    max_elements_fraction: float = Field(0.8, gt=0, le=1, description="the element sample's budget, a fraction of "
                                         "the mesh's elements: the ECSW tolerance is not tightened beyond it, and a "
                                         "round that reaches it is the last [-]")
    time_budget_s: float = Field(TIME_BUDGET_S, gt=0, le=86400, description="the rounds' wall-time budget from "
                                 "the stage's start [s]: the first round always completes, another starts if the "
                                 "time so far plus the last round's fits, one still solving snapshots at the end is "
                                 "abandoned; a run it stopped depends on the machine (reduce.json stopped: 'time')")
    ecsw_snapshots: int = Field(48, ge=1, le=2000, description="the element sample is fitted on at most this many "
                                "snapshots (the box's corners and the design's first points) and their pushes: ECSW's "
                                "matrix grows as states x modes x elements (8 bytes each); the basis takes them all")

    @model_validator(mode="after")
    def _budget(self):
        if self.max_snapshots < self.snapshots:
            raise ConfigError(f"max_snapshots: {self.max_snapshots!r}: allowed range [snapshots = {self.snapshots}, "
                              "2000]: the budget starts at the first round's snapshots")
        return self


def _snapshot(unit):
    """Work unit: the full model's equilibrium at motor angles [rad] from rest, compactly
    (p, R, angles, free displacements, and for ``kind`` "training" its static responses
    (3 n_f, 6 + na) float32 and Jacobian (6, na)), or None."""
    from ...rom.training import sensitivity_and_jacobian
    from ...studies.model import MODELS

    spec, angles, kind = unit
    fem = MODELS.get(spec)
    try:
        st = solve_from_rest(fem, np.asarray(angles))
    except ConvergenceError:
        return None
    c = fem.robot.coupling
    u = (st.x[c.free] - c.rest[c.free]).ravel()
    if kind != "training":
        return st.p, st.R, st.angles, u, None, None
    return (st.p, st.R, st.angles, u, *sensitivity_and_jacobian(fem.lz, st))


def solve_from_rest(fem, angles):
    return solve_equilibrium(fem.robot, angles, state=fem.rest, linearizer=fem.lz).state


def _states(fem, rows):
    """Full :class:`RobotState` s from the units' compact results (failures skipped)."""
    from ...robot.statics import RobotState

    c = fem.robot.coupling
    out = []
    for r in rows:
        if r is not None:
            p, R, ang, u = r[:4]
            out.append(RobotState(p, R, ang, c.positions(p, R, ang, c.rest[c.free] + u.reshape(-1, 3))))
    return out


def _surface_unit(unit):
    """Work unit: the reduced model's equilibria (:class:`~metasheet.rom.surface.
    EquilibriumData`) at motor angles (s, na) [rad], by continuation from its rest equilibrium."""
    from ...rom.model import ReducedRobot
    from ...rom.surface_robot import equilibrium_data
    from ...robot.validity import validity_strain
    from ...studies.model import MODELS

    spec, basis, angles = unit
    fem = MODELS.get(spec)
    red = ReducedRobot(fem.robot, basis)
    lz = red.linearizer()
    rest = solve_equilibrium(red, red.coupling.rest_angles, linearizer=lz).state
    return equilibrium_data(red, angles, linearizer=lz, start=rest,
                            strain=lambda s: validity_strain(fem.robot.body, red.positions(s), fem.strain_elements))


def surface_equilibria(ctx, spec, basis, lo, hi, p):
    """(fit, choose, check) :class:`~metasheet.rom.surface.EquilibriumData` of the
    reduced model for the equilibrium surface on the box [lo, hi]: ``p.surface_equilibria``
    Sobol points (seed + 2) to fit, half as many (seed + 3) to choose the degree on and
    ``p.surface_check`` (seed + 4) to check it on (those within the strain limit), solved
    through the executor in chunks of about 24."""
    from ...rom.surface import EquilibriumData
    from ...rom.training import motor_design

    sets = [motor_design(lo, hi, p.surface_equilibria, p.seed + 2),
            motor_design(lo, hi, p.surface_equilibria // 2, p.seed + 3, corners=False)]
    if p.surface_check:
        sets.append(motor_design(lo, hi, p.surface_check, p.seed + 4, corners=False))
    angles = np.vstack(sets)
    chunks = np.array_split(angles, max(4, len(angles) // 24))
    parts = unit_cache(ctx).map(ctx.executor, _surface_unit, [(spec, basis, c) for c in chunks if len(c)],
                                progress=lambda d, n: ctx.progress("surface equilibria (reduced model)", d, n))
    data = EquilibriumData.concat(parts)
    ends = np.cumsum([len(a) for a in sets])
    out = [data.take(slice(a, b)) for a, b in zip([0, *ends[:-1]], ends)]
    return out[0], out[1], (out[2] if p.surface_check else None)


def surface_box(lo, hi, rest_angles, p) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) (na,) [rad] of the surface: the training box [lo, hi], or the rest angles +-
    ``p.surface_box_deg`` inside it."""
    if p.surface_box_deg is None:
        return lo, hi
    if p.box_deg is not None and p.surface_box_deg > p.box_deg:
        raise ConfigError(f"reduce.surface_box_deg: {p.surface_box_deg!r}: allowed range (0, box_deg = {p.box_deg!r}]"
                          " deg: the surface is fitted on the reduced model, which holds in its training box")
    d = np.radians(p.surface_box_deg)
    return np.maximum(lo, rest_angles - d), np.minimum(hi, rest_angles + d)


def training_box(robot, box_deg: float | None):
    """(lo, hi) (na,) [rad]: the motor range, or the rest angles +- ``box_deg`` inside it."""
    lo, hi = robot.angle_min, robot.angle_max
    if box_deg is None:
        return lo.copy(), hi.copy()
    th0 = robot.coupling.rest_angles
    return np.maximum(lo, th0 - np.radians(box_deg)), np.minimum(hi, th0 + np.radians(box_deg))


def training_equilibria(ctx, spec, fem, lo, hi, n: int, seed: int, label: str = "", check=None):
    """(rows, states): the full model's equilibria at ``n`` Sobol points in the box [lo, hi]
    (na,) [rad] and its two corners (:func:`_snapshot`'s rows, None where one failed; the
    converged ones as states), through the executor. A later round's design begins with the
    earlier one's points (the same scrambled sequence), which the unit cache holds.
    ``check()`` runs after each solved unit (it may raise, which cancels the rest: the solved
    ones stay in the unit cache)."""
    from ...rom.training import motor_design

    angles = motor_design(lo, hi, n, seed)
    desc = f"training equilibria (full model{label})"

    def progress(done, total):
        ctx.progress(desc, done, total)
        if check is not None:
            check()

    rows = unit_cache(ctx).map(ctx.executor, _snapshot, [(spec, a, "training") for a in angles], progress=progress)
    snaps = _states(fem, rows)
    if len(snaps) < max(4, len(angles) // 2):
        raise ConvergenceError(f"reduce: only {len(snaps)} of {len(angles)} training equilibria converged")
    return rows, snaps


def _round_line(rec: dict, rounds: int) -> str:
    """A round in a few words (its progress line)."""
    figs = ", ".join(f"{n} {'-' if rec[n] is None else format(rec[n], '.3g')}" for n in TARGETS)
    verdict = "met" if rec["met"] else "missed " + ", ".join(rec["missed"])
    return (f"round {rec['round']} (of at most {rounds}): {rec['snapshots']} snapshots, k {rec['k']}, "
            f"{rec['elements']} elements; worst {figs}: {verdict}")


def adapt(ctx, spec, fem, lo, hi, start_held, t_start: float) -> dict:
    """The training rounds (:mod:`metasheet.rom.adapt`): train, certify on the held-out poses
    (without the inverse model, which has no target) and grow until the targets are met or
    the budget is spent; the time budget counts from ``t_start`` (``time.perf_counter``, the
    stage's start). ``start_held()`` submits the held-out equilibria (a future of their rows),
    called once the first round's snapshots are in. Returns the rounds' records, the chosen
    round's basis, model, comparisons and snapshot rows, the held-out rows, states and full
    Jacobians, the budget, the stop code and its detail."""
    from ...rom.model import ReducedRobot
    from ...rom.training import train

    p: ReduceParams = ctx.params
    rob = fem.robot
    budget = Budget(p.adapt_rounds, p.max_snapshots, p.snapshot_growth,
                    max(1, int(p.max_elements_fraction * rob.body.n_elements)), p.time_budget_s)
    settings = Settings(p.snapshots, p.tangent_tol, p.fit_tol_mm, p.fit_jacobian_tol)
    trials, held_job, held, stop, detail = [], None, None, "", ""
    for key in ("snapshots", "training", "certificate"):
        ctx.timings[key] = 0.0
    while settings is not None:
        number = len(trials) + 1
        t0 = time.perf_counter()
        # the first round always completes; a later one is abandoned while it solves snapshots
        check = deadline(t_start, budget) if number > 1 else None
        try:
            rows, snaps = training_equilibria(ctx, spec, fem, lo, hi, settings.snapshots, p.seed,
                                              "" if number == 1 else f", round {number}", check)
            # the held-out equilibria need no basis: the workers solve them while round 1 trains
            held_job = held_job or start_held()
            if check is not None:
                check()
            t1 = time.perf_counter()
            ctx.timings["snapshots"] += t1 - t0
            basis = train(rob, snaps, fem.rest, sensitivities=np.hstack([r[4] for r in rows if r is not None]),
                          jacobians=[r[5] for r in rows if r is not None], basis_tol_mm=p.basis_tol_mm,
                          tangent_tol=settings.tangent_tol, ecsw_tol=p.ecsw_tol, fit_tol_mm=settings.fit_tol_mm,
                          fit_jacobian_tol=settings.fit_jacobian_tol, box=(lo, hi), max_elements=budget.max_elements,
                          ecsw_snapshots=p.ecsw_snapshots + 2)  # + the box's two corners
        except ConvergenceError as exc:
            if not trials:
                raise
            stop, detail = "failed", f"round {number}: {exc}"  # the rounds before stand
            break
        except OutOfTime:
            ctx.timings[f"round_{number}_abandoned"] = time.perf_counter() - t0
            stop, detail = "time", f"round {number} abandoned while it solved its snapshots"
            break
        t2 = time.perf_counter()
        ctx.timings["training"] += t2 - t1
        if held is None:
            held_rows = held_job.result()
            held, fl = _states(fem, held_rows), rob.linearizer()
            full_J = [kinematics(fl.linearize(s)).J for s in held]
        red = ReducedRobot(rob, basis)
        rl = red.linearizer()
        comps = [compare(rob, s, red, rl, fl, fem.strain_elements, full_jacobian=J, inverse=False)
                 for s, J in zip(held, full_J)]
        cert = summarize(comps, p.strain_limit)
        ctx.timings["certificate"] += time.perf_counter() - t2
        rec = round_record(number, settings, basis.info, cert, sum(r is None for r in rows))
        trials.append({"record": rec, "basis": basis, "red": red, "comps": comps, "rows": rows, "cert": cert})
        ctx.timings[f"round_{number}"] = time.perf_counter() - t0
        ctx.progress(_round_line(rec, budget.rounds), number, number)
        settings, stop = next_round(settings, cert, basis.info, budget, number)
        now = time.perf_counter()
        if settings is not None and out_of_time(budget, now - t_start, now - t0):
            settings, stop = None, "time"
    best = chosen([t["cert"] for t in trials])
    return {**trials[best], "records": [t["record"] for t in trials], "best": best, "held_rows": held_rows,
            "held": held, "full_J": full_J, "budget": budget, "stop": stop, "detail": detail}


def _adaptation(a: dict, p: ReduceParams) -> dict:
    """reduce.json ``adaptation``: the budget, every round, the round kept, why the rounds
    stopped (``reason``: a sentence) and what the kept round's certificate misses
    (``shortfall``, :func:`metasheet.rom.adapt.shortfall`). No clock value: a run stopped by
    time says so (``stopped: "time"``), its seconds are in the manifest (``timings_s``)."""
    b = a["budget"]
    return {"budget": {"rounds": b.rounds, "max_snapshots": b.max_snapshots, "snapshot_growth": b.growth,
                       "max_elements": b.max_elements, "max_elements_fraction": p.max_elements_fraction,
                       "time_budget_s": b.seconds},
            "rounds": a["records"], "chosen_round": a["best"] + 1, "stopped": a["stop"],
            "reason": stop_reason(a["stop"], a["detail"], len(a["records"]), b), "shortfall": shortfall(a["cert"])}


def run(ctx: StageContext) -> dict:
    from ...rom.surface import errors
    from ...rom.surface_robot import fit_surface_robot

    p: ReduceParams = ctx.params
    t_start = time.perf_counter()  # the time budget's start
    if p.model != "robot":
        raise ConfigError(f"reduce.model: {p.model!r}: the reduced model is of the FEM robot: use 'robot'")
    spec = build_spec(ctx)
    fem = spec.build()
    rob = fem.robot
    lo, hi = training_box(rob, p.box_deg)
    cache = unit_cache(ctx)
    ctx.progress("training rounds (basis, element sample, certificate)", 0, 3)
    held_angles = held_out_angles(lo, hi, p.held_out, p.seed + 1)
    with ThreadPoolExecutor(1) as beside:  # the workers' share while this process trains or compares
        a = adapt(ctx, spec, fem, lo, hi, lambda: beside.submit(
            cache.map, ctx.executor, _snapshot, [(spec, q, "held-out") for q in held_angles],
            progress=lambda d, n: ctx.progress("held-out equilibria (full model)", d, n)), t_start)
        basis, red, held, full_J = a["basis"], a["red"], a["held"], a["full_J"]
        ctx.progress("inverse model and surface (the round kept)", 2, 3)
        t2 = time.perf_counter()
        # the surface's equilibria (reduced model) go to the workers while the inverse model is compared
        slo, shi = surface_box(lo, hi, rob.coupling.rest_angles, p)
        surf_job = beside.submit(surface_equilibria, ctx, spec, basis, slo, shi, p)
        comps = [with_inverse(c, red, s) for c, s in zip(a["comps"], held)]
        cert = summarize(comps, p.strain_limit)
        cert["held_out_failed_full"] = int(sum(r is None for r in a["held_rows"]))
        ctx.timings["certificate_inverse"] = time.perf_counter() - t2
        t3 = time.perf_counter()
        fit, choose, check = surf_job.result()
        surf = fit_surface_robot(red, fit, choose, slo, shi, TARGETS, strain_limit=p.strain_limit)
    inside = [i for i, s in enumerate(held) if surf.surface.in_box(s.angles, tol=1e-6)]
    surf_comps = [compare_surface(surf, held[i], full_J[i], comps[i].strain) for i in inside]
    direct = summarize(surf_comps, p.strain_limit)
    checked = None if check is None else surface_check(errors(surf.surface, check), check.strain, p.strain_limit, cert)
    # certified: the many reduced-model checks bound it within the targets, and the few
    # held-out full poses inside its box (if any is within the strain limit) agree
    met = bool(checked is not None and checked["met"] and (direct["poses"] == 0 or direct["met"]))
    surface_out = {**surf.surface.info, "box_deg": [np.degrees(slo).round(4).tolist(), np.degrees(shi).round(4).tolist()],
                   "certified": met, "certificate": direct, "held_out_outside_box": len(held) - len(inside),
                   "check": checked, "held_out": [c.__dict__ for c in surf_comps]}
    ctx.timings["surface"] = time.perf_counter() - t3
    surf.surface.save(ctx.path("surface.npz"))
    # the training's own timings go to the manifest: in basis.npz they changed its bytes, so its
    # hash (the studies' model key) from run to run of the same config
    info = {k: v for k, v in basis.info.items() if k != "seconds"}
    ctx.timings.update({f"training_{k}": v for k, v in basis.info.get("seconds", {}).items()})
    replace(basis, info=info).save(ctx.path("basis.npz"))
    adaptation = _adaptation(a, p)
    out = {"column": ctx.column, "box_deg": [np.degrees(lo).round(4).tolist(), np.degrees(hi).round(4).tolist()],
           "k": basis.k, "elements": int(len(basis.elements)), "elements_total": int(rob.body.n_elements),
           "free_dofs": int(basis.V.shape[0]), "training": info,
           "snapshots_failed": int(sum(r is None for r in a["rows"])), "targets": TARGETS,
           "certificate_met": bool(cert["met"]), "adaptation": adaptation, "certificate": cert,
           "held_out": [c.__dict__ for c in comps], "strain_band_mm": p.strain_band_mm, "robot_key": basis.robot_key,
           "surface": surface_out}
    write_json_atomic(ctx.path("reduce.json"), out)
    drop_cache(ctx)
    if not cert["met"]:  # said loudly: the outputs stand, but the studies run on a model outside its targets
        msg = (f"WARNING: certificate NOT met after {len(a['records'])} round(s): {adaptation['reason']}; "
               f"it misses {shortfall_text(adaptation['shortfall'])}; "
               f"outputs written from round {adaptation['chosen_round']}")
        log.warning("reduce: %s", msg)
        ctx.progress(msg, 3, 3)
    ctx.progress("done", 3, 3)
    return {"k": basis.k, "elements": out["elements"], "certified": cert["met"], "rounds": len(a["records"]),
            "stopped": adaptation["stopped"], "surface_degree": surface_out["degree"], "surface_certified": met,
            "position_mm_worst": cert["position_mm"]["worst"], "jacobian_rel_worst": cert["jacobian_rel"]["worst"]}


def run_all(ctx: StageContext) -> dict:
    """One basis per column of ``columns`` (the reproduction's in ``reproduction/``)."""
    return run_columns(ctx, run)


register(Stage(
    name="reduce", params=ReduceParams, run=run_all, requires=("orient", "material"), optional=("robot",),
    outputs=("basis.npz", "reduce.json", "surface.npz"),
    doc="reduced-order robot: POD basis + ECSW element sample, certified on held-out poses",
))
