"""Shared plumbing of the study stages (workspace, ranges, anisotropy, maze, report).

Not a stage itself (the leading underscore keeps the stage loader away). It turns the
upstream artefacts (orient's sheet meshes with their fibre field, material.json, and the
robot stage's parameters when it ran) into a picklable :class:`RobotSpec`, the reduced robot
(:class:`~metasheet.studies.reduced_adapter.ReducedSpec`, on the reduce stage's basis) when
``model = "reduced"``, or the analytic stand-in robot when ``model = "standin"``, and gives each
stage a resumable unit cache next to its output directory. For the reduced model it also
records which model ran (:func:`model_record`) and has the full model re-certify the points a
study reports reachable (:func:`certification`).
"""

from __future__ import annotations

import csv
import shutil
import time
from dataclasses import replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import Field, ValidationError, model_validator

from ...published import paper
from ...errors import ConfigError
from ...robot.validity import GRIP_BAND_MM
from ...studies.resume import UnitCache, keep_only_used
from ..artefacts import OrientFile, RobotScene, read_material, read_orient, read_robot_scene
from ..registry import Params, StageContext

#: The scene a study runs on when no robot stage ran (the paper's, :mod:`metasheet.published.paper`).
DEFAULT_SCENE = RobotScene(paper.ROD_LENGTH, paper.REST_ANGLE, paper.HORN_LENGTH, paper.ANGLE_MIN, paper.ANGLE_MAX)


class StudyRobotParams(Params):
    """Which robot the study runs on, and its inverse-model settings."""

    model: Literal["robot", "reduced", "standin"] = Field(
        "robot", description="'robot': the FEM robot from orient + material; 'reduced': its reduced-order model "
        "trained by the reduce stage (which must be in the pipeline, on the same mesh settings); 'standin': the "
        "analytic test robot")
    rod_length: float | None = Field(None, gt=0, le=1000, description="rod length [mm]; None: the robot stage's "
                                     f"or {paper.ROD_LENGTH:g}")
    rest_angle: float | None = Field(None, ge=-180, le=180, description="motor angle of the rest pose [deg]; "
                                     f"None: robot stage's or {paper.REST_ANGLE:g}")
    horn_length: float | None = Field(None, gt=0, le=1000, description="servo horn length [mm]; None: robot "
                                      f"stage's or {paper.HORN_LENGTH:g}")
    motor_min: float | None = Field(None, ge=-180, le=180, description="lower motor limit [deg]; None: robot "
                                    f"stage's or {paper.ANGLE_MIN:g}")
    motor_max: float | None = Field(None, ge=-180, le=180, description="upper motor limit [deg]; None: robot "
                                    f"stage's or {paper.ANGLE_MAX:g}")
    mesh_size: float | None = Field(
        None, ge=0.3, le=50, description="re-mesh the orient sheet at this tet size for this study only "
        "(same geometry and fibre law; per-element constants carried over from the nearest orient "
        "element); None: orient's mesh [mm]")
    layers: int | None = Field(None, ge=0, le=16, description="elements through the thickness of the "
                               "re-meshed sheet; None: orient's")
    grip_size: float | None = Field(None, ge=0, le=50, description="element size at the grip borders of the "
                                    "re-meshed sheet [mm] (0: uniform); None: orient's")
    element: Literal["p1", "p2"] | None = Field(None, description="the study robot's element; None: orient's")
    strain_band_mm: float = Field(GRIP_BAND_MM, ge=0, le=100, description="the strain-validity check leaves out "
                                  "the elements within this distance of a grip's held nodes, where the clamped "
                                  "edge makes the strain singular (metasheet/robot/validity.py; 0: every element) "
                                  "[mm]")
    rot_weight: float = Field(50.0, gt=0, description="inverse QP weight of rotation errors [mm/rad]")
    max_step_deg: float = Field(5.0, gt=0, le=90, description="largest motor change per control step [deg]")
    resume: bool = Field(True, description="keep finished work units so an interrupted run resumes")
    columns: list[Literal["prediction", "reproduction"]] = Field(
        ["prediction"], min_length=1, max_length=2, description="what the study computes: 'prediction' (the "
        "material stage's constants and model, within the strain limit) and/or 'reproduction' (the paper's "
        "published constants under reproduction_model, no strain stop: metasheet/pipeline/column.py); the first "
        "writes into the stage's folder, the second into <stage>/<column>/")
    reproduction_model: Literal["authors", "ours"] = Field(
        "authors", description="the reproduction column's material model: 'authors' (their SOFA force field, "
        "which made the paper's figures) or 'ours' (all five constants)")
    reproduction: dict[str, Any] = Field(
        {}, description="this table's keys changed for the reproduction column (e.g. { tilt_deg = 6 }); "
        "stop_beyond_strain is false there unless given")

    @model_validator(mode="after")
    def _columns_valid(self):
        if len(set(self.columns)) != len(self.columns):
            raise ConfigError(f"columns: {self.columns!r}: a column at most once")
        if self.reproduction:
            self.for_column("reproduction")  # the overrides' own errors, at load time
        return self

    def for_column(self, column: str):
        """These parameters as ``column`` runs them: the column's study defaults
        (:class:`metasheet.pipeline.column.Column`), then the table's ``reproduction`` keys, for
        the column that has defaults (the prediction runs the table as written)."""
        from ..column import column as column_of

        defaults = column_of(column).study_defaults
        if not defaults:
            return self
        bad = sorted(k for k in self.reproduction if k not in type(self).model_fields or k in ("columns", "reproduction"))
        if bad:
            raise ConfigError(f"reproduction: {bad}: not a key of this table that the {column} column can change")
        data = {**self.model_dump(), **{k: v for k, v in defaults.items() if k in type(self).model_fields},
                **self.reproduction, "columns": [column], "reproduction": {}}
        try:
            return type(self).model_validate(data)
        except ValidationError as exc:
            err = exc.errors()[0]
            where = ".".join(str(x) for x in err["loc"])
            raise ConfigError(f"reproduction.{where}: {self.reproduction.get(err['loc'][0])!r}: {err['msg']}") from None

    def check_pipeline(self, table: str, params: dict) -> None:
        """The sheet the study's robot is built on (orient's, or re-meshed) within the size limit."""
        from .orient import check_robot_mesh

        if self.model == "standin" or "orient" not in params:
            return
        changes = {k: getattr(self, k) for k in ("mesh_size", "layers", "grip_size") if getattr(self, k) is not None}
        check_robot_mesh(params["orient"], table if changes else "orient", self.element, **changes)


class CertifyParams(StudyRobotParams):
    """A study that may run on the reduced model: how many of its reachable points the full model re-solves."""

    certify: int = Field(100, ge=0, le=1_000_000, description="model 'reduced': reachable points re-solved by the "
                         "full model (a seeded random sample; 0: all of them) [-]")
    certify_seed: int = Field(0, ge=0, description="seed of the certified sample [-]")


def build_spec(ctx: StageContext):
    """The stage's robot recipe (:class:`RobotSpec` or :class:`StandInSpec`).

    The scene (rod, servos, stroke, sheet mass, gravity) is the robot stage's, read from its
    ``jacobian.json``, when it is in the pipeline, else the one the orient stage named
    (``sheet.json``), else :data:`DEFAULT_SCENE`; this stage's own parameters override it
    field by field. A scene with a sheet mass sets the density to mass / volume of the
    sheet the study meshes. The material model is the material stage's (material.json).
    """
    p = ctx.params
    up = scene_of(ctx)
    lo = up.angle_min if p.motor_min is None else p.motor_min
    hi = up.angle_max if p.motor_max is None else p.motor_max
    if lo >= hi:
        raise ConfigError(f"motor_min/motor_max: ({lo:g}, {hi:g}) deg: need motor_min < motor_max")
    if p.model == "standin":
        from ...studies.standin import StandInSpec

        return StandInSpec(motor_range=(lo, hi), max_step_deg=p.max_step_deg)
    needs = ("reduce", "orient", "material") if p.model == "reduced" else ("orient", "material")
    for need in needs:
        if need not in ctx.inputs:
            raise ConfigError(f"{ctx.name}.model: {p.model!r}: the {need!r} stage must be in the pipeline")
    from ..column import column, column_robot

    sc = up.with_overrides(rod_length=p.rod_length, rest_angle=p.rest_angle, horn_length=p.horn_length)
    scene = {k: getattr(sc, k) for k in ("rod_length", "rest_angle", "horn_length", "servo_radius", "servo_depth")}
    parts = column_robot(read_orient(ctx.inputs["orient"]), read_material(ctx.inputs["material"]),
                         column(ctx.column, p.reproduction_model), sc.sheet_mass_g, mesh_size=p.mesh_size,
                         layers=p.layers, element=p.element, grip_size=p.grip_size)
    spec = parts.spec(motor_range=(lo, hi), gravity=tuple(sc.gravity), rot_weight=p.rot_weight,
                      max_step_deg=p.max_step_deg, strain_band_mm=p.strain_band_mm, **scene)
    if p.model == "reduced":
        from ...studies.reduced_adapter import ReducedSpec

        return ReducedSpec.from_file(spec, basis_file(ctx.inputs["reduce"], ctx.column, f"{ctx.name}.model"))
    return spec


def basis_file(reduce_dir: Path, column: str, key: str) -> Path:
    """The reduce stage's basis for ``column``; a :class:`ConfigError` naming ``key`` when the
    reduce stage did not train it."""
    from ..column import column_folder

    path = column_folder(reduce_dir, column, "reduce") / "basis.npz"
    if not path.is_file():
        raise ConfigError(f"{key}: 'reduced': the reduce stage trained no basis for the {column} column "
                          f"(add {column!r} to [reduce] columns)")
    return path


def run_columns(ctx: StageContext, run_one) -> dict:
    """Run a study stage's ``run_one(ctx)`` once per column of ``ctx.params.columns``: the first
    writes into the stage's folder, the next into ``<column>/``, each with its parameters
    (:meth:`StudyRobotParams.for_column`). Returns the first column's summary, with
    ``"columns"``: {column: its summary} when there are two. With two, the manifest's timings
    are each column's, prefixed ``<column>.``, its wall time ``<column>`` and its CPU time
    ``<column>.cpu`` [s]: the stage thread's and its units' in local worker processes (the
    columns run one after the other; on a dask cluster the stage thread's only)."""
    p = ctx.params
    if len(p.columns) == 1:
        return run_one(replace(ctx, params=p.for_column(p.columns[0]), column=p.columns[0]))
    out = {}
    meter = ctx.executor.meter
    for i, col in enumerate(p.columns):
        say = lambda d, k, n, col=col: ctx.progress(f"{col}: {d}", k, n)  # noqa: E731
        sub = replace(ctx, params=p.for_column(col), column=col, subdir="" if i == 0 else col, progress=say,
                      timings={})
        t0, cpu0, units0 = time.perf_counter(), time.thread_time(), meter.seconds if meter is not None else 0.0
        out[col] = run_one(sub)
        ctx.timings.update({f"{col}.{k}": v for k, v in sub.timings.items()})
        ctx.timings[col] = time.perf_counter() - t0
        units = meter.seconds - units0 if meter is not None else 0.0
        ctx.timings[f"{col}.cpu"] = time.thread_time() - cpu0 + units
    return {**out[p.columns[0]], "columns": out}


def study_reads(params) -> tuple[str, ...]:
    """The upstream stages a study reads: the reduce stage's basis only on the reduced model."""
    return ("orient", "material", "robot", "reduce") if params.model == "reduced" else ("orient", "material", "robot")


def model_record(spec) -> dict:
    """Which model a study ran on, for its JSON: {"model": "reduced", k, elements (sampled of
    total), basis_key (basis.npz's hash), robot_key, box_deg (the training box, lo and hi)},
    or {"model": "robot"} / {"model": "standin"}."""
    from ...studies.reduced_adapter import ReducedSpec

    if not isinstance(spec, ReducedSpec):
        return {"model": "standin" if type(spec).__name__ == "StandInSpec" else "robot"}
    from ...rom.coordinates import ReducedBasis

    b = ReducedBasis.load(Path(spec.basis_path))
    return {"model": "reduced", "k": b.k, "elements": int(len(b.elements)), "basis_key": spec.basis_hash,
            "robot_key": b.robot_key, "spec_key": spec.key,
            "box_deg": [np.degrees(b.box_lo).round(4).tolist(), np.degrees(b.box_hi).round(4).tolist()]}


def certification(ctx: StageContext, spec, goals, motors_deg, *, tol_mm: float, tol_deg: float | None = None,
                  labels=None, desc: str = "") -> dict | None:
    """The full model's verdict on the reduced model's reachable points ``goals`` (n, 6) [mm, rad]
    with motors ``motors_deg`` (n, na) [deg] (:func:`metasheet.studies.certify.certify_study`,
    ``ctx.params.certify`` of them, seeded by ``certify_seed``) as a dict; None unless the
    study ran on the reduced model."""
    from ...studies.certify import certify_study
    from ...studies.reduced_adapter import ReducedSpec

    if not isinstance(spec, ReducedSpec):
        return None
    p = ctx.params
    cert = certify_study(spec, goals, motors_deg, tol_mm=tol_mm, tol_deg=tol_deg, size=p.certify,
                         seed=p.certify_seed, executor=ctx.executor, cache=unit_cache(ctx), labels=labels,
                         progress=lambda d, i, n: ctx.progress(f"certify {desc}".strip(), i, n))
    return {**cert.to_dict(), "tol_mm": tol_mm, "tol_deg": tol_deg}


def scene_of(ctx: StageContext) -> RobotScene:
    """The robot scene of a study stage's pipeline: the robot stage's, else the orient
    stage's, else :data:`DEFAULT_SCENE` (without this stage's overrides)."""
    if "robot" in ctx.inputs:
        return read_robot_scene(ctx.inputs["robot"])
    if "orient" in ctx.inputs:
        return read_orient(ctx.inputs["orient"]).scene
    return DEFAULT_SCENE


def unit_cache(ctx: StageContext) -> UnitCache:
    """Per-unit results in ``<pipeline outputs>/.<stage>.units`` (``.<stage>-<column>.units`` for
    a second column; outside the temporary workdir, so they survive an interrupted run);
    :func:`drop_cache` removes or prunes it after success."""
    if not ctx.params.resume:
        return UnitCache(None)
    return UnitCache(_cache_dir(ctx))


def _cache_dir(ctx: StageContext) -> Path:
    return ctx.workdir.parent / (f".{ctx.name}.units" if not ctx.subdir else f".{ctx.name}-{ctx.subdir}.units")


def drop_cache(ctx: StageContext) -> None:
    """After the stage (column) succeeded: the reproduction column keeps the units this run used
    (its robot is the published foam's, whatever the pipeline's cell: a rerun after another cell
    reuses them; ``metasheet run --force`` removes them first); another column's are removed."""
    from ..column import column

    if column(ctx.column).keeps_units and ctx.params.resume:
        keep_only_used(_cache_dir(ctx))
    else:
        shutil.rmtree(_cache_dir(ctx), ignore_errors=True)


def progress(ctx: StageContext):
    return lambda desc, done, total: ctx.progress(desc, done, total)


def write_csv(path: Path, header: list[str], rows) -> None:
    """CSV with fixed float formatting (same results -> same bytes)."""
    with open(path, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(header)
        for r in rows:
            w.writerow([_fmt(v) for v in r])


def _fmt(v) -> str:
    if isinstance(v, (bool, np.bool_)):
        return str(int(v))
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return "nan" if not np.isfinite(v) else f"{float(v):.6g}"
    return str(v)


def grid_from(p):
    from ...studies.grid import star_grid

    return star_grid(n_azimuth=p.n_azimuth, n_elevation=p.n_elevation, max_elevation_deg=p.max_elevation_deg,
                     n_steps=p.n_steps, extent_axial=p.extent_axial, extent_lateral=p.extent_lateral,
                     thin_below=p.thin_below, thin_every=p.thin_every)


class GridParams(CertifyParams):
    """The star grid of goal points (see :mod:`metasheet.studies.grid`)."""

    n_azimuth: int = Field(12, ge=2, le=720, description="ray directions around the rod [-]")
    n_elevation: int = Field(5, ge=1, le=181, description="elevation rings towards the rod axis [-]")
    max_elevation_deg: float = Field(60.0, ge=0, lt=90, description="largest ring elevation [deg]")
    n_steps: int = Field(37, ge=1, le=10000, description="points per ray before thinning [-]")
    extent_axial: float = Field(20.0, gt=0, description="grid reach along the rod [mm]")
    extent_lateral: float = Field(20.0, gt=0, description="grid reach across the rod [mm]")
    thin_below: float = Field(0.35, ge=0, le=1, description="fraction of the reach below which points are thinned [-]")
    thin_every: int = Field(3, ge=1, description="keep every n-th point in the thinned centre [-]")
    tol_mm: float = Field(1.0, gt=0, description="reach tolerance [mm]")
    max_steps: int = Field(60, ge=1, le=100000, description="inverse control steps per goal [-]")
    stop_after: int = Field(2, ge=0, description="failures in a row before a ray's outer points are left untried (0: try all) [-]")
    strain_limit: float = Field(0.3, gt=0, description="max principal strain of the homogenisation's validity [-]")
    stop_beyond_strain: bool = Field(False, description="a ray ends at its first reached point beyond "
                                     "strain_limit (its outer points are not tried: outside the material model)")
    past_box: Literal["reduced", "full"] = Field(
        "reduced", description="model 'reduced' within the strain limit: which model carries a reach on past "
        "the training box ('reduced': the reduced model, its successes confirmed by the full model; 'full': "
        "the full model from the box's edge)")
