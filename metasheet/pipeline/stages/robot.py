"""Stage ``robot``: the paper's 6-DOF robot from the orient sheets, silicone vs foam.

Reads ``orient/sheet.vtu`` and ``sheet_mirrored.vtu`` (fibres and per-element constants),
the scene ``orient/sheet.json`` names (:mod:`metasheet.robot.scenes`: rod, servos, stroke,
sheet mass, gravity; each overridable here) and ``material/material.json`` (density, unless
the scene gives the sheet's mass). Builds the robot twice, with the foam (the sheets'
constants along the spiral fibres) and with isotropic silicone, and writes

* ``jacobian.json``: per material the Jacobian J (eq. 7) and compliance W at the rest
  equilibrium, the singular values, per-DOF authority per degree, and the rod rotation per
  degree when all six motors move together (from J and from a finite move), and ``geometry``:
  the scene (rod length, servo geometry, counts) the study stages build their robot on;
* ``rest.vtu``: the foam robot at its rest equilibrium under gravity (both sheets, world
  frame), cell data ``sheet`` (0 = A, 1 = B), point data ``attach`` (0 free, k + 1 horn of
  motor k = 0..5, 99 effector) and ``displacement`` from the unloaded rest [mm];
* ``robot.png``: rest vs deformed (all motors by ``delta_deg``) for both materials (Fig. 4/8).

When the sheets' constants are not the paper's published ones (e.g. homogenised from the
printed Polyfoam cell), a third case ``published`` builds the same robot with the paper's
constants (:data:`metasheet.published.paper.PAPER_FOAM`) along the same fibres, so the report can put
the robot's figures for both side by side.

The sheets' tensor follows the material stage's ``model`` (:mod:`metasheet.mechanics.material_model`).
With ``compare_models`` the foam (and published) robots are also built under the other model,
as cases ``foam_<other>`` (and ``published_<other>``), so the report can show which of the
paper's claims depend on the shear modulus mu_l (the authors' force field does not use it).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from typing import Annotated, Literal, NamedTuple

import numpy as np

from pydantic import Field, model_validator

from ...published import paper
from ...errors import ConfigError
from ...mechanics.material import Isotropic
from ...mechanics.material_model import other_model
from ...robot.builder import six_dof_robot
from ...robot.convergence import Level
from ...robot.compare import evaluate
from ..artefacts import OrientFile, read_material, read_orient, write_jacobian, write_rest_vtu
from ..manifest import write_json_atomic
from ..bounds import MASS_DENSITY, MODULUS
from ..registry import Params, Stage, StageContext, register


_SCENE = "; None: the orient stage's scene (sheet.json)"


class ConvergenceLevel(NamedTuple):
    """One ``[robot] convergence`` entry, ``[element, mesh_size, layers, grip_size]``: the
    :class:`~metasheet.robot.convergence.Level` it becomes, with the ranges of
    :class:`~metasheet.sheet.outline.SheetParams`, checked at load (a size of 0 was a
    ZeroDivisionError 30 s into the stage)."""

    element: Literal["p1", "p2"]
    mesh_size: Annotated[float, Field(ge=0.3, le=50)]  # [mm]
    layers: Annotated[int, Field(ge=0, le=16)]
    grip_size: Annotated[float, Field(ge=0, le=50)]  # [mm]; 0: uniform, else within [0.2, mesh_size]


class RobotParams(Params):
    rod_length: float | None = Field(None, gt=10, le=1000, description="rod joining the sheet centres [mm]" + _SCENE)
    rest_angle: float | None = Field(None, ge=-180, le=180, description="motor angle of the undeformed rest "
                                     "pose; places the servo pivots (the servo radius is derived and reported) "
                                     "[deg]" + _SCENE)
    horn_length: float | None = Field(None, gt=0, le=1000, description="servo horn length [mm]" + _SCENE)
    servo_radius: float | None = Field(None, gt=0, le=1000, description="pivots on this circle [mm] (with "
                                       "servo_depth; the rest angle is then derived)" + _SCENE)
    servo_depth: float | None = Field(None, gt=0, le=1000, description="pivots this far behind the sheet's "
                                      "mid-plane [mm] (with servo_radius)" + _SCENE)
    angle_min: float | None = Field(None, ge=-180, le=180, description="motor stroke minimum [deg] "
                                    "(0 = horizontal horn)" + _SCENE)
    angle_max: float | None = Field(None, ge=-180, le=180, description="motor stroke maximum [deg] "
                                    "(90 = vertical horn)" + _SCENE)
    delta_deg: float = Field(-15.0, ge=-90, le=90, description="all-motors move for the pictures and finite test [deg]")
    silicone_E: float = Field(paper.SILICONE.E, **MODULUS, description="silicone Young's modulus [MPa]")
    silicone_nu: float = Field(paper.SILICONE.nu, gt=-1, lt=0.5, description="silicone Poisson ratio [-]")
    silicone_density: float = Field(paper.SILICONE_DENSITY, **MASS_DENSITY, description="silicone density [t/mm^3]")
    length_scale: float = Field(50.0, gt=0, le=1e4, description="rotation -> length for singular values [mm/rad]")
    compare_published: bool = Field(True, description="also evaluate the robot with the paper's published "
                                    "constants when the material differs from them")
    compare_models: bool = Field(True, description="also evaluate the foam (and published) robots under the other "
                                 "material model ('ours' / 'authors'), for the report's mu_l table")
    uncertainty: bool = Field(True, description="when the constants carry 95 % half-widths (homogenize with "
                              "realisations), also evaluate the foam robot's rest Jacobian at each constant's "
                              "bounds (ten one-at-a-time cases): jacobian.json's 'uncertainty'")
    picture: bool = Field(True, description="write robot.png")
    convergence: list[ConvergenceLevel] = Field(
        default_factory=list, description="mesh levels [element, mesh_size [mm], layers, grip_size [mm]] of the "
        "convergence study (convergence.json); the orient mesh is added; empty: no study")

    @model_validator(mode="after")
    def _grips(self):
        for i, lev in enumerate(self.convergence):
            if lev.grip_size and not 0.2 <= lev.grip_size <= lev.mesh_size:
                raise ConfigError(f"convergence[{i}].grip_size: {lev.grip_size!r}: allowed range is "
                                  f"[0.2, mesh_size = {lev.mesh_size:g}], or 0 (uniform)")
        return self

    def check_pipeline(self, table: str, params: dict) -> None:
        """The robot's sheet (orient's) and each convergence level's within the size limit."""
        from .orient import check_robot_mesh

        check_robot_mesh(params["orient"], "orient")
        for i, lev in enumerate(self.convergence):
            check_robot_mesh(params["orient"], f"{table}.convergence[{i}]", lev.element,
                             mesh_size=lev.mesh_size, layers=lev.layers, grip_size=lev.grip_size)


def run(ctx: StageContext) -> dict:
    p: RobotParams = ctx.params
    orient = read_orient(ctx.inputs["orient"])
    sc = orient.scene.with_overrides(**{k: getattr(p, k) for k in _SCENE_KEYS})
    if sc.angle_min >= sc.angle_max:
        raise ConfigError(f"robot.angle_min/angle_max: ({sc.angle_min:g}, {sc.angle_max:g}) deg: need min < max")
    material = read_material(ctx.inputs["material"])
    if sc.rest_angle is not None and not sc.angle_min <= sc.rest_angle <= sc.angle_max:
        raise ConfigError(f"robot.rest_angle: {sc.rest_angle:g} deg: allowed range [angle_min, angle_max] = "
                          f"[{sc.angle_min:g}, {sc.angle_max:g}] deg")
    geo = sc.servo_geometry()
    scene = {"rod_length": sc.rod_length, "geometry": geo, "gravity": sc.gravity}
    # a scene with a sheet mass (the authors': 32 g) gives every sheet that mass, whatever its material
    foam_mass = {"sheet_mass_g": sc.sheet_mass_g} if sc.sheet_mass_g else {"density": material.density}
    sil_mass = {"sheet_mass_g": sc.sheet_mass_g} if sc.sheet_mass_g else {"density": p.silicone_density}
    model, other = material.model, other_model(material.model)

    robot_kw = {"foam": {"model": model, **foam_mass, **scene}, "silicone": {**sil_mass, **scene}}
    tasks = {"foam": _CaseTask(orient, None, robot_kw["foam"]),
             "silicone": _CaseTask(orient, Isotropic(p.silicone_E, p.silicone_nu), robot_kw["silicone"])}
    if p.compare_published and not paper.is_published(material.material):
        tasks["published"] = _CaseTask(orient, paper.PAPER_FOAM, robot_kw["foam"])
    if p.compare_models:  # the same robots under the other material model
        for name in ("foam", "published"):
            if name in tasks:
                tasks[f"{name}_{other}"] = replace(tasks[name], robot_kw={**tasks[name].robot_kw, "model": other})
    tasks = {name: replace(t, name=name, delta_deg=p.delta_deg, length_scale=p.length_scale)
             for name, t in tasks.items()}
    bs = []
    if p.uncertainty and material.ci95:  # the foam at its constants' 95 % bounds, one at a time
        from ...robot.uncertainty import bounds

        bs = bounds(material.material.to_dict(), material.ci95["halfwidth"])
        tasks["bound mean"] = replace(tasks["foam"], name="mean", rest_only=True)
        tasks |= {f"bound {b.name}": replace(tasks["foam"], name=b.name, bound=(b.constant, b.factor), rest_only=True)
                  for b in bs}
    # every robot is a unit of the executor (each builds its own); the convergence study's
    # meshes go to the workers too, from a side thread
    with ThreadPoolExecutor(1) as side:
        conv = (side.submit(_convergence, ctx, orient, robot_kw["foam"]) if p.convergence else None)
        names = list(tasks)
        done = dict(zip(names, ctx.executor.map(
            _case_unit, [tasks[n] for n in names],
            progress=lambda d, n: ctx.progress("equilibrium and Jacobian of each robot", d, n))))
        if conv is not None:
            ctx.progress("convergence study", 0, 1)
            conv.result()
    cases, skipped = {}, {}
    for name, result in done.items():
        if name.startswith("bound "):
            continue
        if isinstance(result, ConfigError):
            if name.endswith(f"_{other}"):  # the authors' tensor is indefinite for these constants
                skipped[name] = str(result)
                continue
            raise result
        cases[name] = result
    spread = None
    if bs:
        from ...robot.uncertainty import summarise

        spread = summarise(done["bound mean"], {b.name: done[f"bound {b.name}"] for b in bs}, bs)
        spread["constants_ci95"] = material.ci95
    foam = tasks["foam"].build()  # its mesh and coupling for the files (cheap beside a solve)
    out = {
        "material_model": model,
        "units": {"J": "rows x, y, z [mm/rad], rx, ry, rz [rad/rad]; columns motors 0-5",
                  "per_degree": "mm/deg and deg/deg", "singular_values": "of diag(1,1,1,L,L,L) J, L = length_scale"},
        "frame": "rod along world x, gravity -z, effector = rod centre (origin); motors 0-2 sheet A (x<0), 3-5 B",
        "geometry": {**foam.info, "scene": sc.scene, "sheet_mass_g": sc.sheet_mass_g,
                     "gravity_mm_s2": list(sc.gravity)},
        "materials": {name: c.to_dict() for name, c in cases.items()},
        **({"uncertainty": spread} if spread else {}),
    }
    write_jacobian(ctx.path("jacobian.json"), out)
    write_rest_vtu(ctx.path("rest.vtu"), foam, cases["foam"].rest)
    if p.picture:
        ctx.progress("picture", 1, 2)
        from ...viz.robot import robot_picture

        robots = {"silicone": tasks["silicone"].build(), "foam": foam}
        ctx.path("robot.png").write_bytes(robot_picture(
            [(f"{n} (all motors {c.delta_deg:+.0f} deg)", robots[n], c.rest, c.moved)
             for n, c in (("silicone", cases["silicone"]), ("foam", cases["foam"]))]))
    ctx.progress("done", 2, 2)
    return {
        name: {"singular_values": [round(v, 4) for v in c.kin.singular_values],
               "rod_rotation_deg_per_deg": round(c.rod_rotation_per_degree, 5),
               "rod_rotation_finite_deg_per_deg": round(c.rod_rotation_finite, 5)}
        for name, c in cases.items()
    } | {"material_model": model, "other_model": other if p.compare_models else None, "model_skipped": skipped,
         "n_tets": foam.info["n_tets"], "rest_angles_deg": np.degrees(foam.coupling.rest_angles).round(3).tolist(),
         "servo_radius_mm_derived": foam.info["servo_geometry"]["servo_radius_mm_derived"],
         "scene": sc.scene, "rod_length_mm": sc.rod_length, "sheet_mass_g": sc.sheet_mass_g,
         **({"foam_rod_rotation_range_95": [round(v, 5) for v in spread["rod_rotation_range"]],
             "foam_singular_values_range_95": [[round(v, 4) for v in spread[f"singular_values_{e}"]]
                                               for e in ("min", "max")]} if spread else {})}


_SCENE_KEYS = ("rod_length", "rest_angle", "horn_length", "servo_radius", "servo_depth", "angle_min", "angle_max")


def _convergence(ctx: StageContext, orient, robot_kw: dict) -> None:
    """``convergence.json``: the foam robot over the mesh levels of ``convergence`` (and the
    orient mesh, checked against the tolerances), one work unit per level on the stage's
    executor; each level's seconds go to the manifest."""
    from ...robot.convergence import convergence_summary, cost_order

    sp = orient.sheet_params
    own = Level(orient.element, float(sp.mesh_size), int(sp.layers), float(sp.grip_size))
    levels = list(dict.fromkeys([Level(e, float(h), int(n), float(g)) for e, h, n, g in ctx.params.convergence]
                                + [own]))
    order = cost_order(levels)
    done = ctx.executor.map(_level_unit, [_LevelTask(orient, levels[i], levels[i] == own, robot_kw) for i in order],
                            progress=lambda d, n: ctx.progress("convergence study", d, n))
    results = [None] * len(levels)
    for i, r in zip(order, done):
        results[i] = r
    for r in results:
        ctx.timings[f"convergence {r.level.label}"] = round(r.seconds, 3)
    write_json_atomic(ctx.path("convergence.json"), convergence_summary(results, {"robot": own}))


@dataclass(frozen=True)
class _LevelTask:
    """One level of the convergence study: the orient sheets, the level, whether it is the
    orient mesh itself (its sheets as they are) and the robot's keywords."""

    orient: OrientFile
    level: Level
    own: bool
    robot_kw: dict


@dataclass(frozen=True)
class _CaseTask:
    """One robot of the stage: the orient sheets under ``material`` (None: the sheets' own
    per-element constants, the foam), ``robot_kw`` for :func:`six_dof_robot`; ``bound`` scales one
    constant of the sheets' own (``(name, factor)``, the uncertainty's cases); ``rest_only``:
    the rest numbers only (:func:`~metasheet.robot.uncertainty.rest_numbers`), else the full
    :func:`~metasheet.robot.compare.evaluate`."""

    orient: OrientFile
    material: object | None
    robot_kw: dict
    name: str = ""
    bound: tuple[str, float] | None = None
    rest_only: bool = False
    delta_deg: float = 0.0
    length_scale: float = 1.0

    def build(self):
        if self.material is not None:
            return six_dof_robot(self.orient.sheets(need_constants=False), self.material, **self.robot_kw)
        sheets = self.orient.sheets()
        if self.bound is not None:
            from ...robot.uncertainty import scaled_sheets

            sheets = scaled_sheets(sheets, *self.bound)
        return six_dof_robot(sheets, **self.robot_kw)


def _case_unit(task: _CaseTask):
    """Work unit: the robot of ``task`` built and evaluated; a ConfigError it raised (a tensor
    that is not positive definite) is returned, for the stage to skip or raise."""
    from ...robot.uncertainty import rest_numbers

    try:
        robot = task.build()
    except ConfigError as exc:
        return exc
    if task.rest_only:
        return rest_numbers(robot, length_scale=task.length_scale)
    return evaluate(robot, task.name, delta_deg=task.delta_deg, length_scale=task.length_scale)


def _level_unit(task: _LevelTask):
    """Work unit: the :class:`~metasheet.robot.convergence.LevelResult` of one level."""
    from ...robot.convergence import build_and_measure
    from ..remesh import remesh

    def build(lev):
        sheets = task.orient.sheets() if task.own else remesh(task.orient, lev.mesh_size, lev.layers, lev.element,
                                                               lev.grip_size)
        return six_dof_robot(sheets, **task.robot_kw)

    return build_and_measure(build, task.level)


register(Stage(
    name="robot", params=RobotParams, run=run, requires=("orient", "material"),
    outputs=("jacobian.json", "rest.vtu"),  # robot.png only with picture = true
    doc="6-DOF robot: rest equilibrium, Jacobian, silicone vs foam (jacobian.json, rest.vtu, robot.png)",
))
