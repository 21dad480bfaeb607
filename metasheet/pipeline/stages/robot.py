"""Stage ``robot``: the paper's 6-DOF robot from the orient sheets, silicone vs foam.

Reads ``orient/sheet.vtu`` and ``sheet_mirrored.vtu`` (fibres and per-element constants) and
``material/material.json`` (density). Builds the robot twice, with the foam (the sheets'
constants along the spiral fibres) and with isotropic silicone, and writes

* ``jacobian.json``: per material the Jacobian J (eq. 7) and compliance W at the rest
  equilibrium, the singular values, per-DOF authority per degree, and the rod rotation per
  degree when all six motors move together (from J and from a finite move);
* ``rest.vtu``: the foam robot at its rest equilibrium under gravity (both sheets, world
  frame), cell data ``sheet`` (0 = A, 1 = B), point data ``attach`` (0 free, k + 1 horn of
  motor k = 0..5, 99 effector) and ``displacement`` from the unloaded rest [mm];
* ``robot.png``: rest vs deformed (all motors by ``delta_deg``) for both materials (Fig. 4/8).
"""

from __future__ import annotations

import json

import numpy as np
from pydantic import Field

from ...material import Isotropic
from ...robot.assemblies import ServoGeometry
from ...robot.cli_support import robot_from_orient
from ...robot.compare import evaluate
from ..registry import Params, Stage, StageContext, register


class RobotParams(Params):
    rod_length: float = Field(80.0, gt=10, le=1000, description="rod joining the sheet centres [mm]")
    rest_angle: float = Field(60.0, ge=-180, le=180, description="motor angle of the undeformed rest pose; places "
                              "the servo pivots (the servo radius is derived and reported) [deg]")
    horn_length: float = Field(25.0, gt=0, le=1000, description="servo horn length [mm]")
    angle_min: float = Field(0.0, ge=-180, le=180, description="motor stroke minimum [deg] (0 = horizontal horn)")
    angle_max: float = Field(90.0, ge=-180, le=180, description="motor stroke maximum [deg] (90 = vertical horn)")
    delta_deg: float = Field(-15.0, ge=-90, le=90, description="all-motors move for the pictures and finite test [deg]")
    silicone_E: float = Field(0.25, gt=0, le=1e4, description="silicone Young's modulus [MPa]")
    silicone_nu: float = Field(0.45, gt=-1, lt=0.5, description="silicone Poisson ratio [-]")
    silicone_density: float = Field(1.07e-9, gt=0, le=1e-7, description="silicone density [t/mm^3]")
    length_scale: float = Field(50.0, gt=0, le=1e4, description="rotation -> length for singular values [mm/rad]")
    picture: bool = Field(True, description="write robot.png")


def _write_rest_vtu(path, robot, state) -> None:
    import meshio

    c = robot.coupling
    tags = np.zeros(len(c.rest), dtype=np.int32)
    tags[c.effector_nodes] = 99
    for k, s in enumerate(c.servos):
        tags[s.nodes] = k + 1
    n_a = robot.info.get("n_tets_per_sheet", [len(robot.body.tets)])[0]
    sheet = (np.arange(len(robot.body.tets)) >= n_a).astype(np.int32)
    meshio.write(path, meshio.Mesh(
        state.x, [("tetra", np.asarray(robot.body.tets))],
        point_data={"attach": tags, "displacement": state.x - c.rest},
        cell_data={"sheet": [sheet]}), binary=True)


def run(ctx: StageContext) -> dict:
    p: RobotParams = ctx.params
    if p.angle_min >= p.angle_max:
        from ...errors import ConfigError

        raise ConfigError(f"robot.angle_min/angle_max: ({p.angle_min:g}, {p.angle_max:g}) deg: need min < max")
    mat = json.loads((ctx.inputs["material"] / "material.json").read_text())
    density = float(mat.get("density", 1.785e-10))
    if not p.angle_min <= p.rest_angle <= p.angle_max:
        from ...errors import ConfigError

        raise ConfigError(f"robot.rest_angle: {p.rest_angle:g} deg: allowed range [angle_min, angle_max] = "
                          f"[{p.angle_min:g}, {p.angle_max:g}] deg")
    geo = ServoGeometry(p.rest_angle, p.horn_length, p.angle_min, p.angle_max)
    orient = ctx.inputs["orient"]
    ctx.progress("building robots", 0, 4)
    robots = {
        "foam": robot_from_orient(orient, rod_length=p.rod_length, geometry=geo, density=density),
        "silicone": robot_from_orient(orient, material=Isotropic(p.silicone_E, p.silicone_nu),
                                      rod_length=p.rod_length, geometry=geo, density=p.silicone_density),
    }
    cases = {}
    for i, (name, rob) in enumerate(robots.items()):
        ctx.progress(f"equilibrium and Jacobian: {name}", 1 + i, 4)
        cases[name] = evaluate(rob, name, delta_deg=p.delta_deg, length_scale=p.length_scale)
    foam = robots["foam"]
    out = {
        "units": {"J": "rows x, y, z [mm/rad], rx, ry, rz [rad/rad]; columns motors 0-5",
                  "per_degree": "mm/deg and deg/deg", "singular_values": "of diag(1,1,1,L,L,L) J, L = length_scale"},
        "frame": "rod along world x, gravity -z, effector = rod centre (origin); motors 0-2 sheet A (x<0), 3-5 B",
        "geometry": foam.info,
        "materials": {name: c.to_dict() for name, c in cases.items()},
    }
    ctx.path("jacobian.json").write_text(json.dumps(out, indent=1, sort_keys=True))
    _write_rest_vtu(ctx.path("rest.vtu"), foam, cases["foam"].rest)
    if p.picture:
        ctx.progress("picture", 3, 4)
        from ...viz.robot import robot_picture

        ctx.path("robot.png").write_bytes(robot_picture(
            [(f"{n} (all motors {c.delta_deg:+.0f} deg)", robots[n], c.rest, c.moved)
             for n, c in (("silicone", cases["silicone"]), ("foam", cases["foam"]))]))
    ctx.progress("done", 4, 4)
    return {
        name: {"singular_values": [round(v, 4) for v in c.kin.singular_values],
               "rod_rotation_deg_per_deg": round(c.rod_rotation_per_degree, 5),
               "rod_rotation_finite_deg_per_deg": round(c.rod_rotation_finite, 5)}
        for name, c in cases.items()
    } | {"n_tets": foam.info["n_tets"], "rest_angles_deg": np.degrees(foam.coupling.rest_angles).round(3).tolist(),
       "servo_radius_mm_derived": foam.info["servo_geometry"]["servo_radius_mm_derived"]}


register(Stage(
    name="robot", params=RobotParams, run=run, requires=("orient", "material"),
    outputs=("jacobian.json", "rest.vtu", "robot.png"),
    doc="6-DOF robot: rest equilibrium, Jacobian, silicone vs foam (jacobian.json, rest.vtu, robot.png)",
))
