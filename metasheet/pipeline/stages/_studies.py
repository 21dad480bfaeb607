"""Shared plumbing of the study stages (workspace, ranges, anisotropy, maze, report).

Not a stage itself (the leading underscore keeps the stage loader away). It turns the
upstream artefacts (orient's sheet meshes with their fibre field, material.json, and the
robot stage's parameters when it ran) into a picklable :class:`RobotSpec`, or the analytic
stand-in robot when ``model = "standin"``, and gives each stage a resumable unit cache next
to its output directory.
"""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path
from types import SimpleNamespace
from typing import Literal

import numpy as np
from pydantic import Field

from ...errors import ConfigError
from ...studies.resume import UnitCache
from ..registry import Params, StageContext

ROBOT_KEYS = ("rod_length", "rest_angle", "horn_length", "angle_min", "angle_max")


class StudyRobotParams(Params):
    """Which robot the study runs on, and its inverse-model settings."""

    model: Literal["robot", "standin"] = Field(
        "robot", description="'robot': the FEM robot from orient + material; 'standin': the analytic test robot")
    rod_length: float | None = Field(None, gt=0, le=1000, description="rod length [mm]; None: the robot stage's or 80")
    rest_angle: float | None = Field(None, ge=-180, le=180,
                                     description="motor angle of the rest pose [deg]; None: robot stage's or 60")
    horn_length: float | None = Field(None, gt=0, le=1000, description="servo horn length [mm]; None: robot stage's or 25")
    motor_min: float | None = Field(None, ge=-180, le=180, description="lower motor limit [deg]; None: robot stage's or 0")
    motor_max: float | None = Field(None, ge=-180, le=180, description="upper motor limit [deg]; None: robot stage's or 90")
    mesh_size: float | None = Field(
        None, ge=0.3, le=50, description="re-mesh the orient sheet at this tet size for this study only "
        "(same geometry and fibre law; per-element constants carried over from the nearest orient "
        "element); None: orient's mesh [mm]")
    rot_weight: float = Field(50.0, gt=0, description="inverse QP weight of rotation errors [mm/rad]")
    max_step_deg: float = Field(5.0, gt=0, le=90, description="largest motor change per control step [deg]")
    resume: bool = Field(True, description="keep finished work units so an interrupted run resumes")


def _robot_params(ctx: StageContext) -> dict:
    """rod_length, rest_angle, horn_length, angle_min, angle_max from the robot stage's
    parameters (its manifest; the robot stage writes no file with them) when it ran."""
    out = {}
    if "robot" in ctx.inputs:
        man = ctx.inputs["robot"] / "manifest.json"
        if man.exists():
            params = json.loads(man.read_text()).get("params", {})
            for k in ROBOT_KEYS:
                if isinstance(params.get(k), (int, float)):
                    out[k] = float(params[k])
    return out


def build_spec(ctx: StageContext):
    """The stage's robot recipe (:class:`RobotSpec` or :class:`StandInSpec`)."""
    p = ctx.params
    up = {"rod_length": 80.0, "rest_angle": 60.0, "horn_length": 25.0, "angle_min": 0.0, "angle_max": 90.0,
          **_robot_params(ctx)}
    lo = up["angle_min"] if p.motor_min is None else p.motor_min
    hi = up["angle_max"] if p.motor_max is None else p.motor_max
    if lo >= hi:
        raise ConfigError(f"motor_min/motor_max: ({lo:g}, {hi:g}) deg: need motor_min < motor_max")
    if p.model == "standin":
        from ...studies.standin import StandInSpec

        return StandInSpec(motor_range=(lo, hi), max_step_deg=p.max_step_deg)
    from ...studies.adapter import RobotSpec

    for need in ("orient", "material"):
        if need not in ctx.inputs:
            raise ConfigError(f"{ctx.name}.model: 'robot': the {need!r} stage must be in the pipeline")
    from ...robot.cli_support import read_sheet  # the robot stage's reader: same sheets, same constants

    o = ctx.inputs["orient"]
    a, fa, ca = read_sheet(o / "sheet.vtu")
    b, fb, cb = read_sheet(o / "sheet_mirrored.vtu")
    info = json.loads((o / "sheet.json").read_text())
    mat = json.loads((ctx.inputs["material"] / "material.json").read_text())
    c = mat["constants"]
    consts = tuple(float(c[k]) for k in ("E_t", "E_l", "nu_t", "nu_tl", "mu_l"))
    geo = {k: up[k] for k in ROBOT_KEYS[:3]}
    for k in ROBOT_KEYS[:3]:
        if getattr(p, k) is not None:
            geo[k] = float(getattr(p, k))
    graded = bool(info.get("graded", False)) and ca is not None and cb is not None
    if p.mesh_size is not None:
        a, fa, ca, b, fb, cb = _remesh(info, p.mesh_size, a, ca, b, cb)
    return RobotSpec(a.points, a.tets, a.attach, np.radians(info["arm_angles_deg"]), b.points, b.tets, b.attach,
                     fa, fb, consts, consts, motor_range=(lo, hi), density=float(mat.get("density", 1.785e-10)),
                     rot_weight=p.rot_weight, max_step_deg=p.max_step_deg,
                     consts=ca if graded else None, consts_m=cb if graded else None, **geo)


def _remesh(info: dict, mesh_size: float, a, ca, b, cb):
    """The orient sheet pair re-meshed at ``mesh_size`` [mm] from sheet.json's geometry and fibre
    law; per-element constants (m, 5) or None carried over by nearest element centroid."""
    from scipy.spatial import cKDTree

    from ...sheet.fibers import spiral_fibers
    from ...sheet.geometry import SheetParams, mirror_sheet, tripod_sheet

    g = dict(info["geometry"], mesh_size=float(mesh_size))
    g["tip_box"] = tuple(g["tip_box"])
    fs = {k: info["fibers"][k] for k in ("law", "pitch_deg", "tilt_deg", "r_ref") if k in info.get("fibers", {})}
    s = tripod_sheet(SheetParams(**g))
    m = mirror_sheet(s)
    out = []
    for new, old, consts, mirrored in ((s, a, ca, False), (m, b, cb, True)):
        fib = spiral_fibers(new.centroids(), mirrored=mirrored, **fs)
        if consts is not None:
            old_c = np.asarray(old.points)[np.asarray(old.tets)].mean(axis=1)
            consts = consts[cKDTree(old_c).query(new.centroids())[1]]
        sheet = SimpleNamespace(points=new.points, tets=new.tets, attach=new.attach, arm_angles=new.arm_angles)
        out += [sheet, fib, consts]
    return tuple(out)


def unit_cache(ctx: StageContext) -> UnitCache:
    """Per-unit results in ``<pipeline outputs>/.<stage>.units`` (outside the temporary workdir,
    so they survive an interrupted run); :func:`drop_cache` removes it after success."""
    if not ctx.params.resume:
        return UnitCache(None)
    return UnitCache(ctx.workdir.parent / f".{ctx.name}.units")


def drop_cache(ctx: StageContext) -> None:
    shutil.rmtree(ctx.workdir.parent / f".{ctx.name}.units", ignore_errors=True)


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


class GridParams(StudyRobotParams):
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
