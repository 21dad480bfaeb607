"""Stage ``maze``: a maze path -> tilt commands -> open-loop motor series -> forward replay,
with the paper's foam and again with silicone sheets (which segments become impossible).

Writes ``maze.csv`` (time [s], six motor angles [deg], then segment, command and errors),
``maze_silicone.csv`` (the same with silicone sheets; not with ``silicone = false``, where
``maze.json``'s silicone entries are null), ``maze.png`` and ``maze.json`` (with
which model ran: ``model_info``). On the reduced model (``model = "reduced"``) the foam run
is reduced and its reached samples (``certify`` of them, 0: all) are re-solved by the full
model at their motor angles within ``tol_mm`` and ``tol_deg`` (``certification``); the
silicone run changes the sheet material, which the basis was not trained for: it runs on the
full model (``silicone_model``).
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from ...mechanics.material import Isotropic
from ...studies.maze import MazeSettings, solve_mazes
from ..manifest import write_json_atomic
from ..bounds import MASS_DENSITY, MODULUS
from ..registry import Stage, StageContext, register
from ._studies import (run_columns, CertifyParams, build_spec, certification, drop_cache, model_record, progress, scene_of,
                       study_reads, unit_cache, write_csv)

#: a small maze walked once round and back to the start: along the rod, across it, diagonals
DEFAULT_PATH = [(0.0, 0.0), (30.0, 0.0), (30.0, 25.0), (-20.0, 25.0), (-20.0, -20.0), (15.0, -20.0),
                (0.0, 0.0)]


class MazeParams(CertifyParams):
    path: list[tuple[float, float]] = Field(DEFAULT_PATH, min_length=2,
                                            description="maze polyline (u along the rod, v across) [mm]")
    tilt_deg: float = Field(8.0, gt=0, le=45, description="maze tilt that rolls the marble [deg]")
    speed: float = Field(20.0, gt=0, description="marble speed along the path [mm/s]")
    dt: float = Field(0.2, gt=0, description="command sampling period [s]")
    ramp_s: float = Field(0.6, ge=0, description="time to change tilt between segments [s]")
    tol_mm: float = Field(1.0, gt=0, description="position tolerance of each command [mm]")
    tol_deg: float = Field(1.0, gt=0, description="orientation tolerance of each command [deg]")
    max_steps: int = Field(60, ge=1, description="inverse control steps per command [-]")
    silicone: bool = Field(True, description="solve the maze with silicone sheets too (the paper's comparison)")
    silicone_E: float = Field(0.25, **MODULUS, description="silicone Young's modulus [MPa]")
    silicone_nu: float = Field(0.45, gt=-1, lt=0.5, description="silicone Poisson ratio [-]")
    silicone_density: float = Field(1.07e-9, **MASS_DENSITY, description="silicone density [t/mm^3]")
    strain_limit: float = Field(0.3, gt=0, description="the foam's largest principal strain within which its "
                                "homogenised constants hold [-] (reported: the samples beyond it)")


def _rows(res):
    c = res.commands
    for i, t in enumerate(c.time):
        yield [t, *res.motors_deg[i], c.segment[i], c.hold[i], *np.degrees(c.poses[i, 3:]), res.reached[i],
               res.error_mm[i], res.error_deg[i], res.track_mm[i], res.track_deg[i], res.strain[i]]


def _finite_max(a) -> float | None:
    a = np.asarray(a, float)
    return float(np.nanmax(a)) if np.isfinite(a).any() else None


HEADER = (["time_s"] + [f"motor{k}_deg" for k in range(6)] + ["segment", "hold", "cmd_rx_deg", "cmd_ry_deg",
          "cmd_rz_deg", "reached", "error_mm", "error_deg", "track_mm", "track_deg", "strain"])


def run(ctx: StageContext) -> dict:
    return run_columns(ctx, _run_one)


def _run_one(ctx: StageContext) -> dict:
    p: MazeParams = ctx.params
    spec = build_spec(ctx)
    s = MazeSettings(tilt_deg=p.tilt_deg, speed=p.speed, dt=p.dt, ramp_s=p.ramp_s, tol_mm=p.tol_mm,
                     tol_deg=p.tol_deg, max_steps=p.max_steps)
    specs, sil_spec = [spec], None
    if p.silicone:
        # a scene with a sheet mass (the authors': 32 g) keeps it for the silicone sheets too
        sil_density = None if getattr(scene_of(ctx), "sheet_mass_g", None) else p.silicone_density
        sil_spec = spec.with_material(Isotropic(p.silicone_E, p.silicone_nu), density=sil_density)
        specs = [sil_spec, spec]  # one map, silicone first: its impossible segments are the longest units
    *others, foam = solve_mazes(specs, p.path, s, executor=ctx.executor, progress=progress(ctx),
                                cache=unit_cache(ctx))
    sil = others[0] if others else None
    write_csv(ctx.path("maze.csv"), list(HEADER), _rows(foam))
    if sil is not None:
        write_csv(ctx.path("maze_silicone.csv"), list(HEADER), _rows(sil))
    from ...viz.studies import maze_picture

    ctx.path("maze.png").write_bytes(maze_picture(
        np.asarray(p.path), foam.commands.time, foam.motors_deg, foam.track_mm, foam.track_deg, foam.segment_ok,
        None if sil is None else sil.segment_ok, foam.motor_range,
        title=f"Maze: tilt {p.tilt_deg:g} deg, foam{' vs silicone' if sil is not None else ''} sheets "
              f"[{ctx.column}, {p.model}]", strain=foam.strain,
        strain_limit=p.strain_limit))
    lo, hi = foam.motor_range
    summary = {
        "column": ctx.column, "tilt_deg": p.tilt_deg,
        "segments": int(len(foam.segment_ok)), "samples": int(len(foam.commands.time)),
        "duration_s": float(foam.commands.time[-1]),
        "foam_segments_ok": foam.segment_ok.tolist(),
        "silicone_segments_ok": None if sil is None else sil.segment_ok.tolist(),
        "silicone_impossible_segments": None if sil is None else np.flatnonzero(~sil.segment_ok).tolist(),
        "foam_impossible_segments": np.flatnonzero(~foam.segment_ok).tolist(),
        "motor_min_deg": float(foam.motors_deg.min()), "motor_max_deg": float(foam.motors_deg.max()),
        "within_motor_limits": bool(foam.motors_deg.min() >= lo - 1e-9 and foam.motors_deg.max() <= hi + 1e-9),
        "max_track_mm": float(np.nanmax(foam.track_mm)), "max_track_deg": float(np.nanmax(foam.track_deg)),
        "max_inverse_error_deg": float(np.nanmax(foam.error_deg)),
        "max_strain": _finite_max(foam.strain), "strain_limit": p.strain_limit,
        "samples_beyond_strain": int(np.sum(foam.strain > p.strain_limit)),  # NaN: not solved, not counted
        "silicone_max_strain": None if sil is None else _finite_max(sil.strain), "model": p.model,
        "model_info": model_record(spec), "silicone_model": None if sil_spec is None else model_record(sil_spec)["model"],
    }
    ids = np.flatnonzero(foam.reached)
    cert = certification(ctx, spec, foam.commands.poses[ids], foam.motors_deg[ids], tol_mm=p.tol_mm,
                         tol_deg=p.tol_deg, labels=ids.tolist())
    if cert is not None:
        summary["certification"] = cert
    write_json_atomic(ctx.path("maze.json"), summary)
    drop_cache(ctx)
    return summary


register(Stage(
    name="maze", params=MazeParams, run=run, optional=("orient", "material", "robot", "reduce"),
    reads=study_reads,
    outputs=("maze.csv", "maze.png", "maze.json"),  # maze_silicone.csv with ``silicone``
    doc="maze path solved open loop into motor angles, replayed; foam vs silicone",
))
