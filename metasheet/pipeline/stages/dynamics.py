"""Stage ``dynamics``: the robot in time (issue 64). Its natural modes and step responses at
rest, on foam and silicone sheets; the maze stage's open-loop motor program played on the
robot with a marble rolling on the maze (paper Section V-B3), on foam and, where the maze stage
solved it (``silicone = true``), silicone; the fastest playback that stays within ``fast_tol_mm``
of the quasi-static path.

Writes per column (the first in the stage's folder, the second in ``<column>/``):
``dynamics.json`` (the summary and verdicts), ``modes.json`` and ``modes.png``, ``steps.csv``
and ``steps.png``, ``maze_played.csv`` (the robot in time), ``marble.csv`` (and
``marble_silicone.csv``), ``maze_geometry.json`` (the maze's corridors and walls),
``maze_played.png`` (tracking and the marble's progress), ``marble.png`` (the maze from above
with the marble's track) and ``maze_played.gif`` (the animation; ``animation = false``: none).
"""

from __future__ import annotations

import csv
import json
from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from ...dynamics.marble import MarbleSettings
from ...dynamics.maze_geometry import plate_bounds, to_json
from ...errors import ConfigError
from ...mechanics.material import Isotropic
from ...studies.maze_played import DynamicsSettings, Unit, maze_offset, run_unit
from ..column import column_folder
from ..manifest import write_json_atomic
from ..registry import Stage, StageContext, register
from ._studies import StudyRobotParams, build_spec, drop_cache, run_columns, scene_of, unit_cache, write_csv
from ._dynamics_files import modes_record, played_rows, steps_rows, write_pictures


class DynamicsParams(StudyRobotParams):
    scheme: Literal["implicit_euler", "generalized_alpha"] = Field(
        "generalized_alpha", description="time integration: 'implicit_euler' (SOFA's EulerImplicitSolver) or "
        "'generalized_alpha' (second order, Chung-Hulbert)")
    rho_inf: float = Field(0.8, ge=0, le=1, description="generalized-alpha's spectral radius at infinite frequency [-]")
    dt: float = Field(0.005, gt=0, le=0.05, description="the robot's time step [s]")
    rayleigh_mass: float = Field(0.0, ge=0, description="Rayleigh damping on the mass (SOFA's rayleighMass) [1/s]")
    rayleigh_stiffness: float = Field(0.01, ge=0, description="Rayleigh damping on the stiffness (SOFA's "
                                      "rayleighStiffness; the authors' scenes: 0.01) [s]")
    n_modes: int = Field(10, ge=1, le=50, description="natural modes computed at rest [-]")
    step_mm: float = Field(1.0, gt=0, le=20, description="step of a position goal [mm]")
    step_deg: float = Field(1.0, gt=0, le=20, description="step of a rotation goal [deg]")
    step_s: float = Field(0.4, gt=0, le=10, description="duration of each step response [s]")
    servo_speed: float = Field(600.0, gt=0, description="servo speed (SG90/MG90S datasheets: 0.1 s / 60 deg) [deg/s]")
    marble_radius: float = Field(4.0, gt=0, le=20, description="the marble's radius [mm]")
    marble_mass_g: float = Field(2.1, gt=0, le=100, description="the marble's mass (an 8 mm steel ball: 2.1 g) [g]")
    rolling_resistance: float = Field(0.002, ge=0, le=0.2, description="rolling resistance coefficient [-]")
    restitution: float = Field(0.5, ge=0, le=1, description="the marble's restitution at the walls [-]")
    marble_dt: float = Field(0.001, gt=0, le=0.01, description="the marble's time step [s]")
    corridor: float = Field(12.0, gt=0, le=100, description="the maze corridors' width [mm]")
    wall_height: float = Field(6.0, gt=0, le=50, description="the maze walls' height [mm]")
    plate_thickness: float = Field(3.0, gt=0, le=20, description="the maze plate's thickness (PLA) [mm]")
    rod_radius: float = Field(3.0, gt=0, le=20, description="the rod's radius (PLA) [mm]")
    speeds: list[float] = Field([2.0, 4.0, 8.0, 16.0, 32.0], min_length=0, max_length=8, description="playback speed-ups "
                                "tried for the fastest playback within fast_tol_mm of the quasi-static path [-]")
    fast_tol_mm: float = Field(1.0, gt=0, description="largest distance from the quasi-static path [mm]")
    silicone: bool = Field(True, description="play the maze stage's silicone program too, where it wrote one")
    animation: bool = Field(True, description="write maze_played.gif")
    frame_s: float = Field(0.2, gt=0, le=1, description="the animation's frame period [s]")

    @model_validator(mode="after")
    def _checks(self):
        if self.model != "robot":
            raise ConfigError(f"dynamics.model: {self.model!r}: allowed 'robot' (the full FEM robot; the reduced "
                              "model's dynamics are not built yet)")
        if any(s <= 1 for s in self.speeds) or sorted(self.speeds) != list(self.speeds):
            raise ConfigError(f"dynamics.speeds: {self.speeds!r}: increasing values > 1")
        if self.corridor <= 2 * self.marble_radius:
            raise ConfigError(f"dynamics.corridor: {self.corridor:g} mm: allowed > 2 x marble_radius "
                              f"({2 * self.marble_radius:g} mm)")
        if self.frame_s < self.dt:
            raise ConfigError(f"dynamics.frame_s: {self.frame_s:g} s: allowed >= dt ({self.dt:g} s)")
        return self

    def settings(self) -> DynamicsSettings:
        marble = MarbleSettings(radius=self.marble_radius, mass=self.marble_mass_g * 1e-6,
                                c_rr=self.rolling_resistance, restitution=self.restitution, dt=self.marble_dt)
        return DynamicsSettings(scheme=self.scheme, rho_inf=self.rho_inf, dt=self.dt, alpha=self.rayleigh_mass,
                                beta=self.rayleigh_stiffness, marble=marble, corridor=self.corridor,
                                wall_height=self.wall_height, plate_thickness=self.plate_thickness,
                                rod_radius=self.rod_radius, n_modes=self.n_modes, step_mm=self.step_mm,
                                step_deg=self.step_deg, step_s=self.step_s, servo_speed=self.servo_speed,
                                frame_s=self.frame_s, fast_tol_mm=self.fast_tol_mm, speeds=tuple(self.speeds))


def read_program(path, rest_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray, tuple]:
    """A maze stage's CSV as a program from rest: times (T + 1,) [s] (0 first), angles (T + 1,
    na) [rad] with the rest angles ``rest_deg`` [deg] at 0 s, and each segment's hold end [s]
    (its last held sample: where the program turns to the next corridor)."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        raise ConfigError(f"{path}: no samples")
    na = len(rest_deg)
    t = np.array([0.0] + [float(r["time_s"]) for r in rows])
    a = np.array([rest_deg] + [[float(r[f"motor{k}_deg"]) for k in range(na)] for r in rows])
    ends: dict[int, float] = {}
    for r in rows:
        if r["hold"] == "1":
            ends[int(r["segment"])] = float(r["time_s"])
    return t, np.radians(a), tuple(ends[k] for k in sorted(ends))


def run(ctx: StageContext) -> dict:
    return run_columns(ctx, _run_one)


def _run_one(ctx: StageContext) -> dict:
    p: DynamicsParams = ctx.params
    s = p.settings()
    spec = build_spec(ctx)
    maze_dir = column_folder(ctx.inputs["maze"], ctx.column, "maze")
    maze_params = json.loads((ctx.inputs["maze"] / "manifest.json").read_text())["params"]
    path = tuple(tuple(map(float, v)) for v in maze_params["path"])
    rest_deg = np.full(6, scene_of(ctx).rest_angle if p.rest_angle is None else p.rest_angle)
    times, angles, ends = read_program(maze_dir / "maze.csv", rest_deg)
    sil_file = maze_dir / "maze_silicone.csv"
    sil_spec = None
    if p.silicone and sil_file.is_file():
        sil_density = None if getattr(scene_of(ctx), "sheet_mass_g", None) else maze_params["silicone_density"]
        sil_spec = spec.with_material(Isotropic(maze_params["silicone_E"], maze_params["silicone_nu"]),
                                      density=sil_density)
    program = (tuple(times), tuple(map(tuple, angles)))
    # the step responses on the foam only: silicone's rod roll needs motors far beyond the stroke (the
    # rest Jacobian's inverse of a robot that cannot roll), and the paper compares their mazes
    units = [Unit("maze", spec, s, path, *program, 1.0, p.animation, ends, main=True),
             Unit("modes", spec, s, path, main=True)]
    if sil_spec is not None:
        st, sa, sends = read_program(sil_file, rest_deg)
        units += [Unit("maze", sil_spec, s, path, tuple(st), tuple(map(tuple, sa)), 1.0, False, sends),
                  Unit("modes", sil_spec, s, path)]
    units += [Unit("maze", spec, s, path, *program, v, False, ends) for v in p.speeds]
    # finished units are kept (resume = true): an interrupted run picks up where it stopped
    out = unit_cache(ctx).map(ctx.executor, run_unit, units, progress=lambda d, n: ctx.progress("dynamics units", d, n))
    foam, modes = out[0], out[1]
    sil, sil_modes = (out[2], out[3]) if sil_spec is not None else (None, None)
    fast = out[4 if sil_spec is not None else 2:]
    return _write(ctx, p, foam, modes, sil, sil_modes, fast)


def _fastest(foam: dict, fast: list[dict], tol: float, servo_speed: float) -> dict:
    """The largest speed-up, among those tried in order, up to which the rod stays within ``tol``
    [mm] of the quasi-static path; each tried speed's gap, the motors' speed it asks for (against
    the servos' ``servo_speed`` [deg/s]) and the marble's verdict."""
    tried = [foam] + list(fast)
    best = None
    for r in tried:
        if not (_nanmax(r["gap_mm"]) or 0.0) <= tol:
            break
        best = r["speed"]
    duration = float(foam["quasi_t"][-1])
    return {"speed": best, "tol_mm": tol, "duration_s": None if best is None else duration / best,
            "servo_speed_deg_s": servo_speed,
            "tried": [{"speed": r["speed"], "gap_mm": _nanmax(r["gap_mm"]), "gap_deg": _nanmax(r["gap_deg"]),
                       "motor_speed_deg_s": r["motor_speed_deg_s"],
                       "within_servo_speed": bool(r["motor_speed_deg_s"] <= servo_speed),
                       "solved": bool(r["solved"]), "vertices": int(r["vertices"])} for r in tried]}


def _write(ctx: StageContext, p: DynamicsParams, foam, modes, sil, sil_modes, fast) -> dict:
    geo = foam["geometry"]
    write_json_atomic(ctx.path("maze_geometry.json"), {**to_json(geo), "plate_bounds": plate_bounds(geo).tolist(),
                                                       "top_mm": p.rod_radius + p.plate_thickness,
                                                       "offset_mm": maze_offset(np.asarray(foam["path_in"])).tolist()})
    write_json_atomic(ctx.path("modes.json"), {"foam": modes_record(modes),
                                               "silicone": None if sil_modes is None else modes_record(sil_modes)})
    write_csv(ctx.path("steps.csv"), *steps_rows(modes))
    write_csv(ctx.path("maze_played.csv"), *played_rows(foam))
    marble_header = ["time_s", "u_mm", "v_mm", "progress_mm", "normal_force_N"]
    for name, run_ in (("marble.csv", foam), ("marble_silicone.csv", sil)):
        if run_ is not None:
            k = max(1, int(round(0.01 / p.marble_dt)))  # every 10 ms
            write_csv(ctx.path(name), marble_header,
                      zip(run_["marble_t"][::k], run_["marble_u"][::k, 0], run_["marble_u"][::k, 1],
                          run_["marble_progress"][::k], run_["normal_force"][::k]))
    fastest = _fastest(foam, fast, p.fast_tol_mm, p.servo_speed)
    modal = None if foam["modal"] is None else dict(foam["modal"])
    if modal is not None:  # a clock: the manifest's timings, never the result's (the same run, the same bytes)
        ctx.timings["modal.s_per_playback"] = modal.pop("seconds_per_playback")
    summary = {
        "column": ctx.column, "scheme": p.scheme, "dt_s": p.dt, "rayleigh": [p.rayleigh_mass, p.rayleigh_stiffness],
        "sheets_g": modes["sheets_g"], "maze_and_rod_g": modes["maze_g"], "marble_g": p.marble_mass_g,
        "frequencies_hz": modes["frequencies_hz"].tolist(),
        "silicone_frequencies_hz": None if sil_modes is None else sil_modes["frequencies_hz"].tolist(),
        "steps": [{k: st[k] for k in ("dof", "size", "final", "rise_s", "overshoot_pct", "settling_s")}
                  for st in modes["steps"]],
        "maze": _verdict(foam), "silicone": None if sil is None else _verdict(sil),
        "fastest": fastest, "modal": modal, "duration_s": float(foam["quasi_t"][-1]),
    }
    write_pictures(ctx, p, foam, modes, sil, summary)
    write_json_atomic(ctx.path("dynamics.json"), summary)
    drop_cache(ctx)
    return summary


def _nanmax(a) -> float | None:
    """The largest finite value of ``a``, None when there is none (JSON has no NaN)."""
    a = np.asarray(a, float)
    return float(np.nanmax(a)) if np.isfinite(a).any() else None


def _verdict(r: dict) -> dict:
    return {"solved": bool(r["solved"]), "vertices": int(r["vertices"]), "arrivals": r["arrivals"],
            "path_length_mm": r["path_length"],
            "final_progress_mm": float(r["marble_progress"][-1]), "impacts": len(r["contacts"]),
            "lifted_off": bool(r["lifted_off"]), "max_gap_mm": _nanmax(r["gap_mm"]),
            "max_gap_deg": _nanmax(r["gap_deg"]), "quasi_static_unsolved": int(r["quasi_unsolved"]),
            "max_torque_Nmm": float(np.abs(r["torques"]).max()),
            "newton_per_step": float(np.mean(r["newton"][1:])), "duration_s": float(r["t"][-1])}


register(Stage(
    name="dynamics", params=DynamicsParams, run=run, requires=("orient", "material", "maze"), optional=("robot",),
    outputs=("dynamics.json", "modes.json", "steps.csv", "maze_played.csv", "marble.csv", "maze_geometry.json",
             "modes.png", "steps.png", "maze_played.png", "marble.png"),
    doc="the robot in time: modes, step responses, the maze played with a marble on foam and silicone",
))
