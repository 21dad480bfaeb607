"""The robot ``metasheet serve`` drives: the one the robot stage built from a pipeline's outputs.

The page shows the robot as the pipeline built it, so it is rebuilt here from the same
artefacts the robot stage read, in the same way (:mod:`metasheet.pipeline.stages.robot`):

* the orient stage's sheets (``orient/sheet.vtu``, ``sheet_mirrored.vtu``) with their fibres
  and per-element constants;
* the scene the robot stage recorded in ``robot/jacobian.json`` (rod length, servo geometry,
  stroke, gravity, sheet mass: the orient stage's scene with the robot stage's overrides);
* the material stage's density and material model (``material/material.json``); a scene with
  a sheet mass gives every sheet that mass instead, as in the robot stage.

The "silicone" robot is the robot stage's silicone case: the same sheets, isotropic silicone
(the pipeline's ``[robot]`` silicone constants, else :data:`metasheet.published.paper.SILICONE`), the
silicone density or the scene's sheet mass.

Every robot is built by :func:`load_robot`, the one place a robot model is chosen (the page
and ``metasheet robot goto --pipeline``): ``"full"`` is the FEM robot; ``"reduced"`` the
reduce stage's reduced-order robot (:class:`~metasheet.rom.model.ReducedRobot`) on that
same FEM robot. The reduce stage trains on the robot of
:func:`metasheet.pipeline.stages._studies.build_spec` (orient's sheets, the robot stage's
scene, the material stage's constants and density): without ``[reduce]`` overrides of the
mesh or the scene that is the robot built here, and the basis's robot key proves it (a
basis trained on another robot is a clear error, never a silent misfit). The basis is
trained on the foam: ``"reduced"`` with silicone gives the full silicone robot, with a note
saying so. Missing outputs are a :class:`~metasheet.errors.ConfigError` naming the file and
the command that writes it; nothing falls back to a default robot. Nor do outputs the
pipeline file no longer matches (edited since its run, under the same ``name``: the cache
keys in their manifests differ) drive anything (:func:`check_fresh`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import ConfigError

#: the robot models ``--model`` accepts
MODELS = ("full", "reduced")
#: the models ``robot goto`` accepts: the page's, and the equilibrium surface (it has no
#: sheets to draw: the page cannot show it)
GOTO_MODELS = MODELS + ("surface",)
#: the sheet materials the page switches between
MATERIALS = ("foam", "silicone")
#: the artefacts the page needs, per stage
REQUIRED = {
    "orient": ("sheet.json", "sheet.vtu", "sheet_mirrored.vtu"),
    "material": ("material.json",),
    "robot": ("jacobian.json",),
}


@dataclass(frozen=True)
class Outputs:
    """Where a pipeline's outputs are: ``directory`` = ``<out root>/<pipeline name>``;
    ``run_command``: the command that writes them (for error messages); ``silicone``: the
    pipeline's silicone (E [MPa], nu [-], density [t/mm^3]) for the material switch."""

    directory: Path
    run_command: str
    silicone: tuple[float, float, float]
    stages: tuple[str, ...] = ()


def find_outputs(pipeline: str | Path, out: str | Path | None = None) -> Outputs:
    """The output folder of ``pipeline`` (a TOML file) as ``metasheet run`` writes it:
    ``<out>/<name>`` with ``out`` the ``--out`` root, default ``outputs/`` of the project.

    Raises :class:`ConfigError` when the outputs the page reads were written by another
    version of the file (:func:`check_fresh`)."""
    from ..published import paper
    from ..pipeline.config import load_pipeline

    p = load_pipeline(pipeline)
    root = Path(out) if out is not None else p.root / "outputs"
    command = f"metasheet run {pipeline}" + (f" --out {out}" if out is not None else "")
    check_fresh(p, root / p.name, command)
    rp = p.params.get("robot")
    silicone = ((rp.silicone_E, rp.silicone_nu, rp.silicone_density) if rp is not None
                else (paper.SILICONE.E, paper.SILICONE.nu, paper.SILICONE_DENSITY))
    return Outputs(root / p.name, command, tuple(float(v) for v in silicone), tuple(p.order))


def check_fresh(pipeline, directory: Path, run_command: str) -> None:
    """ConfigError naming the stages whose outputs in ``directory`` the pipeline file would
    not reuse (their manifests' cache keys differ from the ones it computes now: a scene, a
    mesh, a material edited under the same ``name``) among those the page and ``goto`` read
    and their upstream stages; a damaged manifest counts as stale. Outputs without manifests
    (written by hand) are not judged."""
    from ..pipeline.staleness import stale_stages

    stale = stale_stages(pipeline, directory, (*REQUIRED, "reduce", "maze"))
    if stale:
        raise ConfigError(f"{directory}: the outputs of stage(s) {', '.join(stale)} do not match {pipeline.path} "
                          f"(edited since they were written, or a manifest damaged): run `{run_command}` first")


def check_outputs(outputs: Outputs) -> None:
    """Raise a one-line :class:`ConfigError` naming the first missing artefact and the
    command that writes it (or the stage the pipeline lacks)."""
    for stage, files in REQUIRED.items():
        if outputs.stages and stage not in outputs.stages:
            raise ConfigError(f"the pipeline has no {stage!r} stage, whose outputs the page needs: "
                              f"add {stage!r} to [pipeline] stages and run `{outputs.run_command}`")
        for name in files:
            path = outputs.directory / stage / name
            if not path.is_file():
                raise ConfigError(f"{path}: missing (the {stage} stage's output): run `{outputs.run_command}` first")


@dataclass(frozen=True)
class RobotGeometry:
    """What the page draws of a robot, in the world frame at rest.

    Attributes
    ----------
    rest : (n, 3) float, node positions [mm] (the robot's ``coupling.rest``).
    tets : (m, 4) or (m, 10) int, the elements (both sheets, sheet A's first).
    sheet : (m,) int, 0 for sheet A's elements, 1 for sheet B's.
    fibers : (m, 3) float, unit fibre direction (the soft axis l) of each element at rest.
    fiber_angle : (m,) float, the fibre's axis angle in its sheet's own frame [deg], in [0, 180).
    pivots : (na, 3) float, the servo pivots [mm]; horn_nodes : per servo, the (k,) int
        nodes its horn holds.
    axis : (3,) the rod's direction at rest; rod_length : [mm].
    """

    rest: np.ndarray
    tets: np.ndarray
    sheet: np.ndarray
    fibers: np.ndarray
    fiber_angle: np.ndarray
    pivots: np.ndarray
    horn_nodes: tuple
    axis: np.ndarray
    rod_length: float


@dataclass(frozen=True)
class RobotInfo:
    """A loaded robot's description: ``model`` ("full" / "reduced": the robot returned),
    ``material`` ("foam" / "silicone"), what it is made of (``description``, for the page),
    its :class:`RobotGeometry`, ``note``: why the model differs from the one asked for
    ("" when it does not), and the study ``column`` whose foam it is
    (:mod:`metasheet.pipeline.column`)."""

    model: str
    material: str
    description: str
    geometry: RobotGeometry
    note: str = ""
    column: str = "prediction"


def robot_geometry(robot, fibers_local: tuple[np.ndarray, np.ndarray]) -> RobotGeometry:
    """The :class:`RobotGeometry` of a 6-DOF robot built by :func:`~metasheet.robot.builder.
    six_dof_robot`; ``fibers_local``: each sheet's (m_s, 3) fibres in its own sheet frame."""
    from ..robot.robots import Q_A, Q_B

    fa, fb = (np.asarray(f, float) for f in fibers_local)
    tets = np.asarray(robot.body.tets)
    if len(fa) + len(fb) != len(tets):
        raise ConfigError(f"fibers: {len(fa)} + {len(fb)} elements: the robot has {len(tets)}")
    sheet = np.repeat([0, 1], [len(fa), len(fb)])
    world = np.vstack([fa @ Q_A.T, fb @ Q_B.T])  # sheet frame -> world, as the robot's stiffness
    world /= np.linalg.norm(world, axis=1, keepdims=True)
    local = np.vstack([fa, fb])
    angle = np.mod(np.degrees(np.arctan2(local[:, 1], local[:, 0])), 180.0)  # an axis: period 180
    c = robot.coupling
    centres = np.asarray(robot.info["sheet_centres_mm"], float)
    return RobotGeometry(np.asarray(c.rest, float), tets, sheet, world, angle,
                         np.array([s.pivot for s in c.servos], float), tuple(np.asarray(s.nodes) for s in c.servos),
                         np.asarray(robot.axis, float) / np.linalg.norm(robot.axis),
                         float(np.linalg.norm(centres[1] - centres[0])))


def load_robot(outputs: Outputs, model: str = "full", material: str = "foam", column: str = "prediction"):
    """The robot of ``outputs`` as the robot stage built it: ``(robot, RobotInfo)``.

    ``model`` : "full" (the FEM robot), "reduced" (the reduce stage's
    :class:`~metasheet.rom.model.ReducedRobot` on it) or "surface" (the reduce stage's
    :class:`~metasheet.rom.surface_robot.SurfaceRobot`); silicone: the full robot, with
    ``info.note`` saying why; ``material`` : "foam" (the sheets' own constants) or
    "silicone" (the robot stage's silicone case); ``column`` : "prediction" (the pipeline's
    foam) or "reproduction" (the paper's published foam under the authors' force field, on the
    authors' kind of mesh: :mod:`metasheet.pipeline.column`). Raises :class:`ConfigError` for
    a missing artefact (see :func:`check_outputs`), an unknown model, material or column, a
    basis trained on another robot.
    """
    if model not in GOTO_MODELS:
        raise ConfigError(f"--model: {model!r}: allowed values are {', '.join(GOTO_MODELS)}")
    if material not in MATERIALS:
        raise ConfigError(f"material: {material!r}: allowed values are {', '.join(MATERIALS)}")
    from ..pipeline.column import COLUMNS, column as column_of, column_folder

    if column_of(column, field="--column").fixes_material and material != "foam":
        raise ConfigError(f"material: {material!r}: the {column} column is the paper's published foam; "
                          "silicone is the prediction column's comparison")
    check_outputs(outputs)
    basis_file = column_folder(outputs.directory / "reduce", column, "reduce") / "basis.npz"
    needs = {"reduced": basis_file, "surface": basis_file.with_name("surface.npz")}.get(model)
    if needs is not None and not needs.is_file():
        fix = (f"add {column!r} to [reduce] columns and run the pipeline again" if column != COLUMNS[0]
               else "run a pipeline with the reduce stage")
        raise ConfigError(f"--model {model}: needs the reduce stage's outputs for the {column} column ({needs}), "
                          f"which are missing: {fix}, or use --model full")
    robot, info = _full_robot(outputs, material, column)
    if model == "full":
        return robot, info
    if material == "silicone":
        note = (f"the {model} model was trained on the foam and does not fit silicone: "
                "silicone runs on the full model")
        return robot, replace(info, note=note)
    red, info = reduced_robot(robot, info, basis_file, outputs.run_command)
    if model == "reduced":
        return red, info
    return surface_robot(red, info, needs)


def surface_robot(red, info: RobotInfo, surface_file: Path):
    """``(SurfaceRobot, RobotInfo)`` of the reduce stage's ``surface.npz`` on its reduced robot."""
    import json

    from ..rom.surface_robot import load_surface

    surf = load_surface(surface_file, red)
    cert = ""
    try:
        s = json.loads(surface_file.with_name("reduce.json").read_text())["surface"]
        met, check = s.get("certified", s["certificate"]["met"]), s.get("check")
        if check:  # the bound over its box's check equilibria: more of the box than the held-out poses
            pos, jac = check["position_mm"]["bound_with_reduced"], check["jacobian_rel"]["bound_with_reduced"]
            what = "errors against the full model bounded by"
        else:
            pos, jac = s["certificate"]["position_mm"]["worst"], s["certificate"]["jacobian_rel"]["worst"]
            what = "held-out errors up to"
        cert = f"; certificate {'met' if met else 'NOT met'}: {what} {pos:.2g} mm, Jacobian {100 * jac:.2g} %"
    except (OSError, ValueError, KeyError, TypeError):
        pass
    what = (f"equilibrium surface: degree {surf.surface.info.get('degree')} in the motor angles, fitted on "
            f"{surf.surface.info.get('equilibria')} reduced equilibria{cert}; ")
    return surf, replace(info, model="surface", description=what + info.description)


def reduced_robot(full, info: RobotInfo, basis_file: Path, run_command: str):
    """``(ReducedRobot, RobotInfo)`` of the basis in ``basis_file`` on the full robot ``full``;
    ConfigError naming the file when it was trained on another robot."""
    from ..rom.coordinates import ReducedBasis, robot_key
    from ..rom.model import ReducedRobot

    basis = ReducedBasis.load(basis_file)
    if basis.robot_key != robot_key(full):
        raise ConfigError(f"--model reduced: {basis_file} was trained on another robot than the robot stage's "
                          "(its [reduce] mesh or scene overrides, or outputs of another run): run "
                          f"`{run_command}` again without them, or use --model full")
    red = ReducedRobot(full, basis)
    lo, hi = np.degrees(basis.box_lo), np.degrees(basis.box_hi)
    box = (f"[{lo.min():g}, {hi.max():g}]" if np.ptp(lo) < 1e-9 and np.ptp(hi) < 1e-9
           else f"[{', '.join(f'{a:.4g}' for a in lo)}] to [{', '.join(f'{b:.4g}' for b in hi)}]")
    what = (f"reduced model: {basis.k} modes, {len(basis.elements)} of {full.body.n_elements} elements, "
            f"trained on motor angles in {box} deg (outside: the full model){certificate(basis_file.parent)}; ")
    return red, replace(info, model="reduced", description=what + info.description)


def certificate(reduce_dir: Path) -> str:
    """The reduce stage's certificate in a few words (from ``reduce.json``), or ""."""
    import json

    try:
        c = json.loads((reduce_dir / "reduce.json").read_text())["certificate"]
        pos, jac = c["position_mm"]["worst"], c["jacobian_rel"]["worst"]
    except (OSError, ValueError, KeyError, TypeError):
        return ""
    where = f" (strain <= {c['strain_limit']:g})" if c.get("strain_limit") is not None else ""
    if pos is None or jac is None:
        return f"; certificate NOT met: no held-out pose{where} solved"
    return (f"; certificate {'met' if c.get('met') else 'NOT met'}: held-out errors{where} up to {pos:.2g} mm, "
            f"Jacobian {100 * jac:.2g} %")


def _full_robot(outputs: Outputs, material: str, column: str):
    """The FEM robot of ``outputs`` for ``material`` in ``column`` and its :class:`RobotInfo`."""
    from ..mechanics.material import Isotropic
    from ..pipeline.artefacts import read_material, read_orient, read_robot_scene
    from ..pipeline.column import column as column_of, column_robot
    from ..robot.builder import six_dof_robot

    d = outputs.directory
    orient, mat, sc = read_orient(d / "orient"), read_material(d / "material"), read_robot_scene(d / "robot")
    scene = {"rod_length": sc.rod_length, "geometry": sc.servo_geometry(), "gravity": sc.gravity}
    if material == "foam":
        parts = column_robot(orient, mat, column_of(column), sc.sheet_mass_g)
        robot = parts.robot(**scene)
        if parts.column.fixes_material:
            m = parts.column.mesh
            what = (f"published constants (the paper's), model {parts.model}, {m['element']} {m['mesh_size']:g} mm "
                    "sheets: the reproduction column")
        else:
            whose = "the graded sheets' own constants" if parts.sheets.has_constants else "the material's constants"
            what = f"foam: {whose} along the fibres ({mat.source or 'material stage'}, model {mat.model})"
        fibers, element = (parts.sheets.fibers, parts.sheets.fibers_mirrored), parts.sheets.element
    else:
        E, nu, density = outputs.silicone
        mass = {"sheet_mass_g": sc.sheet_mass_g} if sc.sheet_mass_g else {"density": density}
        robot = six_dof_robot(orient.sheets(need_constants=False), Isotropic(E, nu), **mass, **scene)
        what = f"silicone: isotropic E = {E:g} MPa, nu = {nu:g}"
        fibers, element = (orient.normal.fibers, orient.mirrored.fibers), orient.element
    geometry = robot_geometry(robot, fibers)
    description = (f"{what}; scene {sc.scene}, rod {sc.rod_length:g} mm, stroke "
                   f"[{sc.angle_min:g}, {sc.angle_max:g}] deg; {len(geometry.tets)} {element} elements")
    return robot, RobotInfo("full", material, description, geometry, column=column)
