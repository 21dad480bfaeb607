"""Stage ``design``: search and optimise the sheets' fibre field for more rod roll (issue 45).

Reads the orient stage's sheets (mesh, spiral fibres, scene) and the material stage's
constants, and on the robot's linear rest problem (:mod:`metasheet.design.adjoint`)

1. runs a multi-objective parametric search with Optuna (:mod:`metasheet.design.search`:
   the spiral's pitch and ``n_radial`` radial corrections of the fibre angle; maximise
   |rod roll per motor degree| and the smallest singular value of the five other DOF),
   sampler NSGA-II or TPE with a fixed seed, ``batch`` trials at a time through the stage's
   executor, stored in an Optuna journal so a rerun resumes from the stored trials; with
   ``constrain_strain`` the sampler is constrained to trials within ``strain_limit`` at the goals
   and the Pareto front holds those trials only;
2. maximises |rod roll per degree| with the adjoint gradients over a free-form polar B-spline
   field starting from the orient stage's spiral (box bounds +-``coefficient_deg``;
   ``symmetric`` ties it to the sheet's 120 deg symmetry): by SLSQP subject to the goal strain
   (KS aggregate) <= ``strain_limit`` and the other DOF's singular value >= ``other_floor`` x
   the spiral's (``constrain_strain``, :mod:`metasheet.design.constraints`), else by L-BFGS-B
   on the roll alone; with ``strain_front``, again at each of those strain limits;
3. chooses the design of largest |roll| among the spiral, the Pareto trials and the gradient's
   design whose other-DOF singular value is at least ``other_floor`` x the spiral's (and, with
   ``constrain_strain``, whose goal strain is within ``strain_limit``), and
   evaluates the spiral and the chosen design on every objective of issue 45's item 1 (roll,
   six singular values, decoupling, strain at the goals, printability:
   :mod:`metasheet.design.evaluation`) on the pipeline's material and the published constants.

With ``oat_points`` and ``sobol_n`` it also writes the sensitivities of both objectives to the
search's variables (:mod:`metasheet.design.sensitivity`): ``sensitivity.csv`` (one at a time,
about the spiral), Sobol indices in ``design.json`` and ``sensitivity.png``.

Writes ``trials.csv``, ``pareto.csv``, ``pareto.png``, ``field.png`` (spiral | gradient design
| chosen design), ``design.json`` (objectives before and after, iterations, the strain front, the chosen design's
coefficients, the comparison), ``comparison.md`` (the chosen design against the spiral on every
objective, a markdown table), ``chosen.toml`` (a pipeline of material, orient and robot with the chosen
pitch and, for a design with coefficients, ``[orient] fibre_field``: it rebuilds the chosen
design's sheets exactly) and ``study.journal`` (Optuna's journal; it carries times,
so its bytes differ between runs; the tables do not).

Resume: while the stage runs, the journal lives in ``<outputs>/.design.units/`` (outside the
temporary workdir, so a killed run keeps its finished trials); a rerun starts from it, or
else from the last finished run's ``design/study.journal``, when its study is the same
(mesh, material, scene and search settings but ``n_trials``: the study's name hashes them).
"""

from __future__ import annotations

import shutil
import time
from dataclasses import replace
from typing import Literal, NamedTuple

import numpy as np
from pydantic import Field, model_validator

from ...published import paper
from ...design import evaluation as ev
from ...design import outputs as out
from ...design import search as ds
from ...sheet.fibre_field import PolarBSpline
from ...design.optimise import StrainSettings, free_form, reach_at_limit, strain_front
from ...design.optimise import basis_dict as _basis_dict
from ...design.printability import check_settings
from ...errors import ConfigError
from ..artefacts import read_material, read_orient
from ..manifest import read_manifest, write_bytes_atomic, write_json_atomic
from ..registry import Params, Stage, StageContext, register
from ..design_trials import JOURNAL, cache_dir, evaluate_designs, search


class PitchBounds(NamedTuple):
    """``[design] pitch_deg = [lo, hi]``: the search's bounds of the spiral's pitch [deg]."""

    lo: float
    hi: float


class DesignParams(Params):
    sampler: Literal["nsga2", "tpe"] = Field("nsga2", description="Optuna sampler of the search")
    seed: int = Field(0, ge=0, le=2**31 - 2, description="the search's seed (each trial's sampler is seeded "
                      "with it and the trial's number)")
    n_trials: int = Field(16, ge=1, le=100_000, description="completed trials the search stops at; a rerun "
                          "with more resumes from the stored ones")
    batch: int = Field(4, ge=1, le=1024, description="trials asked at once and evaluated through the executor; "
                       "a resumed search equals an uninterrupted one when the earlier n_trials was a multiple of it")
    population: int = Field(8, ge=2, le=10_000, description="NSGA-II population (TPE: random startup trials, "
                            "at most 10)")
    pitch_deg: PitchBounds = Field(PitchBounds(5.0, 60.0), description="search bounds [lo, hi] of the spiral's "
                                           "pitch [deg], -90 <= lo < hi <= 90")
    n_radial: int = Field(2, ge=0, le=8, description="radial corrections of the fibre angle in the search "
                          "(0: pitch only; else 2-8)")
    radial_deg: float = Field(30.0, gt=0, le=90, description="bound of each radial correction [deg]")
    gradient: bool = Field(True, description="run the free-form gradient optimisation from the spiral")
    field_n_radial: int = Field(4, ge=2, le=32, description="free-form field: B-spline functions along r")
    field_n_angular: int = Field(12, ge=2, le=96, description="free-form field: B-spline functions around "
                                 "(a multiple of 3 when symmetric)")
    field_degree: int = Field(3, ge=1, le=5, description="free-form field: B-spline degree")
    symmetric: bool = Field(True, description="tie the free-form field to the sheet's 120 deg symmetry")
    coefficient_deg: float = Field(45.0, gt=0, le=90, description="box bound of each free-form coefficient [deg]")
    maxiter: int = Field(15, ge=1, le=10_000, description="SLSQP (or L-BFGS-B) iterations per start")
    starts: int = Field(1, ge=1, le=1000, description="SLSQP starts: the spiral, then starts - 1 seeded random "
                        "points (seed: the search's); the best feasible run is kept")
    constrain_strain: bool = Field(True, description="SLSQP under goal strain and other-DOF floor, else L-BFGS-B; "
                                   "the search's sampler and Pareto front keep to the strain limit too")
    constrain_print: bool = Field(True, description="SLSQP (constrain_strain) also keeps sheet A's fibre angle, read "
                                  "back from the print map's 8-bit texture, within 2 deg (linearised; "
                                  "metasheet.design.print_constraint)")
    strain_limit: float = Field(0.3, gt=0, le=10, description="limit of the largest principal strain at the "
                                "goals [-] (the foam's validity limit)")
    ks_rho: float = Field(1000.0, gt=0, le=1e6, description="KS aggregation parameter of the strain [1/strain]")
    strain_front: list[float] = Field(default_factory=list, description="strain limits [-] to optimise at too")
    other_floor: float = Field(1.0, ge=0, le=10, description="the chosen design's other-DOF singular value "
                               "must be at least this times the spiral's [-]")
    length_scale: float = Field(50.0, gt=0, le=1e4, description="rotation -> length for singular values [mm/rad]")
    compare_published: bool = Field(True, description="also evaluate the spiral and the chosen design on the "
                                    "published constants (paper.PAPER_FOAM)")
    goal_deg: float = Field(10.0, gt=0, le=90, description="amplitude of the strain's goals [deg]: all motors "
                            "and motor 0 alone at +-goal_deg (metasheet.design.strain)")
    print_settings: dict[str, float] = Field(default_factory=dict, description="the foam's IceSL settings "
                                             "(infill_percentage [%], kgon_x_shrink [-]), checked against IceSL's range")
    round_trip: bool = Field(True, description="check the spiral's and the chosen design's fibre angle round "
                             "trip through the print map's 8-bit texture")
    oat_points: int = Field(0, ge=0, le=1000, description="one-at-a-time sensitivity: values per variable about "
                            "the spiral (0: none; else >= 2)")
    sobol_n: int = Field(0, ge=0, le=65_536, description="Sobol indices (SALib): base samples, a power of two; "
                         "sobol_n (k + 2) designs for k variables (0: none)")

    @model_validator(mode="after")
    def _check(self):
        ds.SearchSpace(tuple(self.pitch_deg), self.n_radial, self.radial_deg)  # ConfigError names the field
        for i, v in enumerate(self.strain_front):
            try:
                StrainSettings(v, self.goal_deg, self.ks_rho)
            except ConfigError as err:  # it names strain_limit: say which entry of the front
                raise ConfigError(f"strain_front[{i}]: {str(err).split(': ', 1)[1]}") from None
        check_settings(self.print_settings)  # an infeasible print is refused before anything runs
        if self.oat_points == 1:
            raise ConfigError("oat_points: 1: allowed values are 0 (none) or [2, 1000]")
        if self.sobol_n & (self.sobol_n - 1) or self.sobol_n == 1:
            raise ConfigError(f"sobol_n: {self.sobol_n}: expected 0 (none) or a power of two in [2, 65536]")
        try:
            self.field_basis(70.0)
        except ConfigError as err:
            raise ConfigError(f"field_{err}") from None
        return self

    def field_basis(self, r_max: float) -> PolarBSpline:
        return PolarBSpline(n_radial=self.field_n_radial, n_angular=self.field_n_angular, degree=self.field_degree,
                            r_max=r_max, symmetric=self.symmetric)

    def check_pipeline(self, table: str, params: dict) -> None:
        """The rest problem's limits on the orient table: a uniform sheet, fibres in the plane."""
        o = params["orient"]
        if o.element != "p1":
            raise ConfigError(f"orient.element: {o.element!r}: the {table} stage's rest problem is solved on linear "
                              "tetrahedra only; allowed 'p1'")
        g = o.grading
        if g.table or g.density_expr or g.alpha_expr:
            raise ConfigError(f"orient.grading: a graded sheet: the {table} stage supports uniform sheets only")
        if o.tilt_deg != 0:
            raise ConfigError(f"orient.tilt_deg: {o.tilt_deg!r}: the {table} stage turns fibres in the plane; allowed 0")
        if o.fibre_field is not None:  # the search and the gradient start from the law's spiral alone
            raise ConfigError(f"orient.fibre_field: the {table} stage designs the field from the fibre law's "
                              "spiral; allowed: none (leave it out)")


def run(ctx: StageContext) -> dict:
    p: DesignParams = ctx.params
    orient, mat = read_orient(ctx.inputs["orient"]), read_material(ctx.inputs["material"])
    if orient.graded:
        raise ConfigError("orient.grading: a graded sheet: the design stage supports uniform sheets only")
    # linear tetrahedra on the orient mesh whatever orient.element (the rest problem's, P1 only)
    sheets = replace(orient.sheets(need_constants=False), element="p1")
    sc = orient.scene
    kw = {"model": mat.model, "rod_length": sc.rod_length, "geometry": sc.servo_geometry(),
          "length_scale": p.length_scale}
    fs = orient.fiber_settings
    if float(fs.get("tilt_deg", 0.0)) != 0.0:
        raise ConfigError(f"orient.tilt_deg: {fs['tilt_deg']!r}: the design stage turns fibres in the plane; allowed 0")
    spiral_kw = {"law": fs["law"], "r_ref": float(fs["r_ref"])}
    pitch0 = float(fs["pitch_deg"])
    r_max = float(np.hypot(*sheets.sheet.points[:, :2].T).max())
    space = ds.SearchSpace(tuple(p.pitch_deg), p.n_radial, p.radial_deg, r_max)
    cent = sheets.sheet.centroids()
    t0 = time.perf_counter()
    problem = ds.rest_problem(sheets, mat.material, space.basis(), **kw)
    spiral = ds.evaluate_trials(ds.Trials(problem, cent, spiral_kw, ((pitch0,) + (0.0,) * p.n_radial,),
                                          p.goal_deg))[0]
    ctx.timings["rest problem"] = round(time.perf_counter() - t0, 3)

    # 1. the parametric search, resumable through the journal
    t0 = time.perf_counter()
    record, study = search(ctx, space, problem, cent, spiral_kw)
    ctx.timings["search"] = round(time.perf_counter() - t0, 3)
    pareto = ds.pareto_mask(record.objectives, record.feasible)
    names = space.names
    write_bytes_atomic(ctx.path("trials.csv"), out.trials_table(names, record.values, record.roll, record.objectives,
                                                                pareto, dict(zip(ds.EXTRAS, record.extras.T))).encode())
    write_bytes_atomic(ctx.path("pareto.csv"), out.pareto_table(names, record.values, record.roll, record.objectives,
                                                                pareto).encode())

    t0 = time.perf_counter()
    sensitivity = _sensitivities(ctx, space, problem, cent, spiral_kw, pitch0)
    ctx.timings["sensitivity"] = round(time.perf_counter() - t0, 3)

    # 2. the free-form field by L-BFGS-B and the adjoint gradient, from the spiral
    spiral_design = {"pitch_deg": pitch0, "basis": None, "coefficients_rad": []}
    cands = [out.Candidate.of("spiral", spiral, spiral_design)]
    for i in np.flatnonzero(pareto):
        pitch, c = space.split(record.values[i])
        s = _scores_of(record, i, problem, cent, spiral_kw, p.goal_deg)
        cands.append(out.Candidate.of(f"trial {i}", s, {"pitch_deg": pitch, "basis": _basis_dict(space.basis())
                                                        if len(c) else None, "coefficients_rad": c.tolist()}))
    grad, front, strain = None, None, StrainSettings(p.strain_limit, p.goal_deg, p.ks_rho) if p.constrain_strain else None
    if p.gradient:
        t0 = time.perf_counter()
        gp = ds.rest_problem(sheets, mat.material, p.field_basis(r_max), **kw)
        printable = _print_constraint(sheets, orient, p.field_basis(r_max), pitch0, spiral_kw) \
            if strain is not None and p.constrain_print else None
        grad = free_form(None, None, {}, p.field_basis(r_max), pitch0, maxiter=p.maxiter,
                         bound_deg=p.coefficient_deg, strain=strain, floor_ratio=p.other_floor, problem=gp,
                         progress=lambda i: ctx.progress("gradient iterations", i, p.maxiter * p.starts),
                         printable=printable, starts=p.starts, seed=p.seed)
        ctx.timings["gradient"] = round(time.perf_counter() - t0, 3)
        g = grad["scores"]
        cands.append(out.Candidate.of("gradient", g, grad["design"]))
        if strain is not None and p.strain_front:
            t0 = time.perf_counter()
            front = strain_front(gp, pitch0, p.field_basis(r_max), p.strain_front, strain, maxiter=p.maxiter,
                                 bound_deg=p.coefficient_deg, floor_ratio=p.other_floor, printable=printable)
            ctx.timings["strain front"] = round(time.perf_counter() - t0, 3)

    # 3. the chosen design, and every objective of it and of the spiral on both constant sets
    others_floor = [p.other_floor * v for v in spiral.others]
    chosen = out.choose(cands, p.other_floor * spiral.other_min, p.strain_limit if p.constrain_strain else None,
                        others_floor)
    t0 = time.perf_counter()
    mats = {"pipeline": mat.material, **({"published": paper.PAPER_FOAM} if p.compare_published else {})}
    cmp = ev.compare_designs(sheets, mats, {"spiral": spiral_design, "chosen": chosen.design}, spiral_kw, r_max,
                             params=orient.sheet_params, settings=p.print_settings, round_trip=p.round_trip,
                             goal_deg=p.goal_deg, **kw)
    ctx.timings["comparison"] = round(time.perf_counter() - t0, 3)
    e = cmp["evaluations"]
    keys = ("roll_deg_per_deg", "abs_roll_deg_per_deg", "other_min_mm_per_rad", "singular_values_mm_per_rad")
    published = {k: {x: e[k]["published"][x] for x in keys} for k in ("spiral", "chosen")} if p.compare_published else {}
    if published:
        published["ratio_abs_roll"] = round(published["chosen"]["abs_roll_deg_per_deg"]
                                            / published["spiral"]["abs_roll_deg_per_deg"], 6)
    for f, data in out.pictures(orient, record, pareto, cands, chosen, grad, spiral_kw).items():
        ctx.path(f).write_bytes(data)
    summary = {
        "model": "linear rest problem (metasheet.design.adjoint): no gravity preload, motors at rest",
        "units": {"roll": "deg of rod roll per deg of all six motors", "singular values": "mm/rad, of "
                  f"diag(1,1,1,L,L,L) J, L = {p.length_scale:g} mm", "angles": "deg; coefficients rad"},
        "objectives": {"abs_roll": "maximise |rod roll per degree| [deg/deg]",
                       "other_min": "maximise the smallest singular value of the five DOF other than the roll "
                       "[mm/rad]"},
        "material": {**mat.material.to_dict(), "model": mat.model, "source": mat.source},
        "scene": sc.scene, "n_tets_per_sheet": len(sheets.sheet.tets),
        "element": f"p1 (the rest problem's; the orient table's: {orient.element})",
        "spiral": {"pitch_deg": pitch0, **spiral_kw, **out.scores_record(spiral.roll, spiral.other_min,
                                                                         spiral.singular_values)},
        "search": {"study": study, "sampler": p.sampler, "seed": p.seed, "n_trials": len(record.values),
                   "evaluated_this_run": int(record.evaluated), "batch": p.batch, "variables": names,
                   "bounds_deg": space.bounds(), "pareto_trials": np.flatnonzero(pareto).tolist(),
                   "best_abs_roll": _best(record, problem, cent, spiral_kw),
                   "strain_limit": p.strain_limit if p.constrain_strain else None,
                   "feasible_trials": int(record.feasible.sum()),
                   "best_feasible": _best(record, problem, cent, spiral_kw, record.feasible)},
        "sensitivity": sensitivity,
        "gradient": None if grad is None else grad["record"],
        "strain_front": front,
        "chosen": {"name": chosen.name, **out.scores_record(chosen.roll, chosen.other_min, chosen.singular_values),
                   "ratio_abs_roll": round(abs(chosen.roll) / abs(spiral.roll), 6),
                   "goal_strain": out._r(chosen.strain), "strain_limit": p.strain_limit,
                   "strain_constrained": p.constrain_strain, "meets_constraints": bool(
                       chosen.other_min >= p.other_floor * spiral.other_min and chosen.strain <= p.strain_limit
                       and out.meets_floors(chosen.others, others_floor)),
                   "other_singular_values_mm_per_rad": [out._r(v) for v in chosen.others],
                   "other_singular_floors_mm_per_rad": [out._r(v) for v in others_floor],
                   "reach": {k: reach_at_limit(x.roll, x.strain, p.goal_deg, p.strain_limit)
                             for k, x in (("spiral", cands[0]), ("chosen", chosen))},
                   "other_floor_mm_per_rad": round(p.other_floor * spiral.other_min, 6),
                   "design": chosen.design, "chosen_toml_reproduces": True,
                   "chosen_toml": "the chosen design exactly: orient.pitch_deg, and orient.fibre_field for "
                   "design.coefficients_rad on design.basis"},
        "published": published or None,
        "comparison": {"evaluations": e, "printability": cmp["printability"], "table": cmp["table"],
                       "file": "comparison.md"},
    }
    write_json_atomic(ctx.path("design.json"), summary)
    write_bytes_atomic(ctx.path("comparison.md"), ev.comparison_markdown(cmp["table"], ev.TITLES).encode())
    write_bytes_atomic(ctx.path("chosen.toml"), _chosen_toml(ctx, orient, mat, chosen).encode())
    shutil.rmtree(cache_dir(ctx), ignore_errors=True)  # the journal is in the outputs now
    return {"spiral_roll": round(spiral.roll, 6), "chosen": chosen.name, "chosen_roll": round(chosen.roll, 6),
            "ratio_abs_roll": summary["chosen"]["ratio_abs_roll"], "trials": len(record.values),
            "evaluated_this_run": int(record.evaluated),
            "gradient_roll": None if grad is None else grad["record"]["after"]["roll_deg_per_deg"]}


def _print_constraint(sheets, orient, basis: PolarBSpline, pitch0: float, spiral_kw: dict):
    """The free-form designs' print round trip on sheet A, linear in the coefficients."""
    from ...design.print_constraint import print_constraint

    return print_constraint(sheets.sheet.points, sheets.sheet.tets, orient.sheet_params,
                            lambda q: ds.spiral_angles(q, pitch_deg=pitch0, **spiral_kw), basis.design_matrix)


def _best(record, problem, cent, spiral_kw, among=None) -> dict | None:
    """The trial of largest |roll| (the first such; among the ``among`` (n,) bool trials) and its
    objectives; None when ``among`` holds none."""
    ok = np.ones(len(record.objectives), bool) if among is None else np.asarray(among, bool)
    if not ok.any():
        return None
    i = int(np.argmax(np.where(ok, record.objectives[:, 0], -np.inf)))
    s = _scores_of(record, i, problem, cent, spiral_kw)
    return {"trial": i, "values_deg": [float(v) for v in record.values[i]],
            **out.scores_record(s.roll, s.other_min, s.singular_values)}


def _scores_of(record, i, problem, cent, spiral_kw, goal_deg=None):
    """A stored trial's scores, re-evaluated (the journal keeps only its two objectives)."""
    return ds.evaluate_trials(ds.Trials(problem, cent, spiral_kw, (tuple(record.values[i]),), goal_deg))[0]


def _sensitivities(ctx: StageContext, space, problem, cent, spiral_kw, pitch0: float) -> dict | None:
    """One-at-a-time curves about the spiral (``sensitivity.csv``) and Sobol indices of both
    objectives; ``sensitivity.png``. None when neither is asked for."""
    from ...design import sensitivity as sens

    p: DesignParams = ctx.params
    if not (p.oat_points or p.sobol_n):
        return None
    rec, curves, sobol = {}, [], None
    if p.oat_points:
        lo, hi = space.bounds()[0]
        base = np.array([min(max(pitch0, lo), hi)] + [0.0] * space.n_radial)
        X, which = sens.oat_designs(space, base, p.oat_points)
        S = evaluate_designs(ctx, problem, cent, spiral_kw, list(X), "one-at-a-time designs")
        rows = [[space.names[w], *x, s.roll, *s.objectives] for w, x, s in zip(which, X, S)]
        text = out.csv_text(["variable", *space.names, "roll_deg_per_deg", "abs_roll_deg_per_deg",
                             "other_min_mm_per_rad"], rows)
        write_bytes_atomic(ctx.path("sensitivity.csv"), text.encode())
        for i, name in enumerate(space.names):
            m = which == i
            curves.append((name, X[m, i], np.array([s.objectives[0] for s, k in zip(S, m) if k]),
                           np.array([s.objectives[1] for s, k in zip(S, m) if k])))
        rec["one_at_a_time"] = {"base_deg": base.tolist(), "points": p.oat_points, "file": "sensitivity.csv",
                                "range_abs_roll": {c[0]: out._r(np.ptp(c[2])) for c in curves},
                                "range_other_min": {c[0]: out._r(np.ptp(c[3])) for c in curves}}
    if p.sobol_n:
        X = sens.sobol_designs(space, p.sobol_n, p.seed)
        F = np.array([s.objectives for s in evaluate_designs(ctx, problem, cent, spiral_kw, list(X), "Sobol designs")])
        sobol = {o: sens.sobol_indices(space, F[:, j], p.seed).to_dict() for j, o in enumerate(ds.OBJECTIVES)}
        rec["sobol"] = {"method": "SALib Saltelli / Sobol, first-order and total, bootstrap 95 %", "n": p.sobol_n,
                        "designs": len(X), "indices": sobol}
    from ...viz.design import sensitivity_picture

    ctx.path("sensitivity.png").write_bytes(sensitivity_picture(curves, sobol))
    return rec


def _chosen_toml(ctx: StageContext, orient, mat, chosen) -> str:
    """``chosen.toml`` (:func:`metasheet.design.outputs.chosen_pipeline`): the material's
    constants as given, the orient stage's table with the chosen pitch and field."""
    man = read_manifest(ctx.inputs["orient"]) or {}
    o = dict(man.get("params") or {"scene": orient.scene.scene, "element": orient.element,
                                   "mesh_size": orient.sheet_params.mesh_size, **orient.fiber_settings})
    m = {"source": "config", "kind": "transverse", **mat.material.to_dict(), "density": mat.density, "model": mat.model}
    return out.chosen_pipeline(f"{man.get('pipeline', 'design')}_chosen", m, o, chosen)


register(Stage(
    name="design", params=DesignParams, run=run, requires=("orient", "material"),
    outputs=("trials.csv", "pareto.csv", "pareto.png", "field.png", "design.json", "comparison.md", "chosen.toml",
             JOURNAL),
    doc="fibre design: Optuna search (pitch, radial field) and adjoint L-BFGS-B (free-form field) for more rod roll",
))
