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

Training time goes to the manifest (``timings_s``), not to ``reduce.json``.
"""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace

import numpy as np
from pydantic import Field

from ...errors import ConfigError, ConvergenceError
from ...robot.equilibrium import solve_equilibrium
from ...robot.kinematics import kinematics
from ...rom.certificate import TARGETS, compare, compare_surface, held_out_angles, summarize, surface_check
from ..manifest import write_json_atomic
from ..registry import Stage, StageContext, register
from ._studies import StudyRobotParams, build_spec, drop_cache, run_columns, unit_cache


class ReduceParams(StudyRobotParams):
    snapshots: int = Field(48, ge=4, le=2000, description="training equilibria (Sobol points in the box, "
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
    held_out: int = Field(16, ge=0, le=1000, description="certificate poses (Sobol, another seed) besides the "
                          "two mixed corners")
    seed: int = Field(0, ge=0, description="Sobol scrambling seed of the training set (held-out: seed + 1)")
    strain_limit: float | None = Field(0.3, gt=0, description="the certificate's targets apply to held-out poses "
                                       "within this max principal strain [-] (the material model's domain; the "
                                       "others are reported apart); None: to all")
    surface_equilibria: int = Field(64, ge=16, le=5000, description="reduced-model equilibria the equilibrium "
                                    "surface (the real-time model) is fitted on; half as many more choose its degree")
    surface_check: int = Field(64, ge=0, le=5000, description="reduced-model equilibria, neither fitted nor used "
                               "for the degree, the surface is checked on (those within the strain limit)")
    surface_box_deg: float | None = Field(None, gt=0, le=180, description="the surface's box: the rest angles +- "
                                          "this [deg], within the training box; None: the training box")


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


def run(ctx: StageContext) -> dict:
    from ...rom.model import ReducedRobot
    from ...rom.surface import errors
    from ...rom.surface_robot import fit_surface_robot
    from ...rom.training import motor_design, train

    p: ReduceParams = ctx.params
    if p.model != "robot":
        raise ConfigError(f"reduce.model: {p.model!r}: the reduced model is of the FEM robot: use 'robot'")
    spec = build_spec(ctx)
    fem = spec.build()
    rob = fem.robot
    lo, hi = training_box(rob, p.box_deg)
    cache = unit_cache(ctx)
    t0 = time.perf_counter()
    angles = motor_design(lo, hi, p.snapshots, p.seed)
    ctx.progress("training equilibria (full model)", 0, 3)
    rows = cache.map(ctx.executor, _snapshot, [(spec, a, "training") for a in angles],
                     progress=lambda d, n: ctx.progress("training equilibria (full model)", d, n))
    snaps = _states(fem, rows)
    if len(snaps) < max(4, len(angles) // 2):
        raise ConvergenceError(f"reduce: only {len(snaps)} of {len(angles)} training equilibria converged")
    ctx.timings["snapshots"] = time.perf_counter() - t0
    ctx.progress("basis and element sample", 1, 3)
    held_angles = held_out_angles(lo, hi, p.held_out, p.seed + 1)
    with ThreadPoolExecutor(1) as beside:  # the workers' share while this process trains or compares
        # the held-out equilibria need no basis: the workers solve them while the basis trains
        held_job = beside.submit(cache.map, ctx.executor, _snapshot, [(spec, a, "held-out") for a in held_angles],
                                 progress=lambda d, n: ctx.progress("held-out equilibria (full model)", d, n))
        t1 = time.perf_counter()
        sens = np.hstack([r[4] for r in rows if r is not None])
        jacs = [r[5] for r in rows if r is not None]
        basis = train(rob, snaps, fem.rest, sensitivities=sens, jacobians=jacs, basis_tol_mm=p.basis_tol_mm,
                      tangent_tol=p.tangent_tol, ecsw_tol=p.ecsw_tol, fit_tol_mm=p.fit_tol_mm,
                      fit_jacobian_tol=p.fit_jacobian_tol, box=(lo, hi))
        ctx.timings["training"] = time.perf_counter() - t1
        red = ReducedRobot(rob, basis)
        ctx.progress("certificate (held-out poses)", 2, 3)
        t2 = time.perf_counter()
        held_rows = held_job.result()
        # the surface's equilibria (reduced model) go to the workers while the certificate compares
        slo, shi = surface_box(lo, hi, rob.coupling.rest_angles, p)
        surf_job = beside.submit(surface_equilibria, ctx, spec, basis, slo, shi, p)
        held = _states(fem, held_rows)
        rl, fl = red.linearizer(), rob.linearizer()
        full_J = [kinematics(fl.linearize(s)).J for s in held]
        comps = [compare(rob, s, red, rl, fl, fem.strain_elements, full_jacobian=J) for s, J in zip(held, full_J)]
        cert = summarize(comps, p.strain_limit)
        cert["held_out_failed_full"] = int(sum(r is None for r in held_rows))
        ctx.timings["certificate"] = time.perf_counter() - t2
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
    out = {"column": ctx.column, "box_deg": [np.degrees(lo).round(4).tolist(), np.degrees(hi).round(4).tolist()],
           "k": basis.k, "elements": int(len(basis.elements)), "elements_total": int(rob.body.n_elements),
           "free_dofs": int(basis.V.shape[0]), "training": info,
           "snapshots_failed": int(sum(r is None for r in rows)), "targets": TARGETS, "certificate": cert,
           "held_out": [c.__dict__ for c in comps], "strain_band_mm": p.strain_band_mm, "robot_key": basis.robot_key,
           "surface": surface_out}
    write_json_atomic(ctx.path("reduce.json"), out)
    drop_cache(ctx)
    ctx.progress("done", 3, 3)
    return {"k": basis.k, "elements": out["elements"], "certified": cert["met"],
            "surface_degree": surface_out["degree"], "surface_certified": met,
            "position_mm_worst": cert["position_mm"]["worst"], "jacobian_rel_worst": cert["jacobian_rel"]["worst"]}


def run_all(ctx: StageContext) -> dict:
    """One basis per column of ``columns`` (the reproduction's in ``reproduction/``)."""
    return run_columns(ctx, run)


register(Stage(
    name="reduce", params=ReduceParams, run=run_all, requires=("orient", "material"), optional=("robot",),
    outputs=("basis.npz", "reduce.json", "surface.npz"),
    doc="reduced-order robot: POD basis + ECSW element sample, certified on held-out poses",
))
