"""``metasheet robot goto``'s pieces without the command line: which robot it drives, the
pose it parses, the result it prints (:mod:`metasheet.cli` wires them to the command)."""

from __future__ import annotations

import math
from pathlib import Path


def goto_model(orient: Path | None, material_model: str | None) -> str:
    """The material model ``robot goto --orient`` uses: ``material_model`` when given, else
    the material stage's next to the orient stage (``<orient>/../material/material.json``)
    when there is one, else "ours"."""
    from .mechanics.material_model import check_model

    if material_model is not None:
        return check_model(material_model, "--material-model")
    if orient is not None and (Path(orient).parent / "material" / "material.json").is_file():
        from .pipeline.artefacts import read_material

        return read_material(Path(orient).parent / "material").model
    return "ours"


def goto_robot(orient: Path | None = None, mesh_size: float = 8.0, material_model: str | None = None):
    """The 6-DOF robot ``robot goto`` drives without ``--pipeline``: from an orient stage's
    sheets (their own per-element constants), else freshly meshed sheets (``mesh_size``
    [mm]) with the paper's foam along the default spiral; the paper's scene and foam density
    either way (not a pipeline's: use :func:`pipeline_robot`); the material model of
    :func:`goto_model`."""
    from .published import paper
    from .robot.builder import SheetPair, six_dof_robot

    material_model = goto_model(orient, material_model)
    if orient is not None:
        from .pipeline.artefacts import read_orient

        return six_dof_robot(read_orient(Path(orient)).sheets(), density=paper.FOAM_DENSITY, model=material_model)
    from .sheet.outline import SheetParams

    return six_dof_robot(SheetPair.spiral(SheetParams(mesh_size=mesh_size)), paper.PAPER_FOAM,
                         density=paper.FOAM_DENSITY, model=material_model)


def pipeline_robot(pipeline: Path, out: Path | None = None, model: str = "full", material_model: str | None = None,
                   column: str = "prediction"):
    """``(robot, RobotInfo)`` of a pipeline's outputs as ``metasheet serve`` drives it
    (:func:`metasheet.serve.loading.load_robot`: the robot stage's scene, the material
    stage's density and model); ``model`` "full" / "reduced". ``material_model``, when given,
    must be the material stage's (the robot, and a reduced basis, are built with that one).
    ``column`` "reproduction": the same mesh and scene with the published constants under the
    authors' force field (:mod:`metasheet.pipeline.column`)."""
    from .errors import ConfigError
    from .mechanics.material_model import check_model
    from .pipeline.artefacts import read_material
    from .pipeline.column import column as column_of
    from .serve.loading import find_outputs, load_robot

    outputs = find_outputs(pipeline, out)
    robot, info = load_robot(outputs, model, "foam", column)
    if material_model is not None and column_of(column, field="--column").fixes_material:
        raise ConfigError(f"--material-model: the {column} column fixes its material model (the studies' reproduction_model); "
                          "drop --material-model")
    if material_model is not None:
        used = read_material(outputs.directory / "material").model
        if check_model(material_model, "--material-model") != used:
            raise ConfigError(f"--material-model: {material_model!r}: the pipeline's material stage uses {used!r}; "
                              "set [material] model in the pipeline and run it again, or drop --material-model")
    return robot, info


def command_robot(pipeline: Path | None, out: Path | None, model: str, orient: Path | None, mesh_size: float,
                  material_model: str | None, column: str, models: tuple) -> tuple:
    """``(robot, RobotInfo or None)`` the robot commands (``robot goto``, ``robot path``) drive
    for their options: the pipeline's (:func:`pipeline_robot`), else :func:`goto_robot`'s;
    ``models``: the ``--model`` values the command takes. ConfigError naming the option that
    conflicts (a model or a fixed-material column needs the pipeline)."""
    from .errors import ConfigError
    from .pipeline.column import column as column_of

    if model not in models:
        raise ConfigError(f"--model: {model!r}: allowed values are {', '.join(models)}")
    if pipeline is not None:
        if orient is not None:
            raise ConfigError("--orient: give either --pipeline (the pipeline's robot) or --orient, not both")
        return pipeline_robot(pipeline, out, model, material_model, column)
    if model != "full":
        raise ConfigError(f"--model {model}: needs --pipeline (a pipeline with the reduce stage, run first)")
    if column_of(column, field="--column").fixes_material:
        raise ConfigError(f"--column {column}: needs --pipeline (the pipeline's mesh and scene)")
    return goto_robot(orient, mesh_size, material_model), None


def goto_tolerances(column: str, tol_mm: float | None, tol_deg: float | None) -> tuple[float, float]:
    """The position [mm] and rotation [deg] tolerances of a goto: those given, else the column's
    (:class:`metasheet.pipeline.column.Column`; the reproduction's are the paper's test, Section
    IV-B: +-10 deg "within 2 deg", the position within 1 mm)."""
    from .pipeline.column import column as column_of

    mm, deg = column_of(column, field="--column").tolerances
    return (mm if tol_mm is None else tol_mm), (deg if tol_deg is None else tol_deg)


def pose_text(pose) -> str:
    return ("X Y Z [mm] " + " ".join(f"{v:.3f}" for v in pose[:3])
            + " | RX RY RZ [deg] " + " ".join(f"{v:.3f}" for v in pose[3:]))


def format_result(res) -> str:
    """Human-readable lines of an :class:`~metasheet.robot.inverse.InverseResult`."""
    lines = [f"status: {res.status} after {res.steps} control steps",
             "motor angles [deg]: " + " ".join(f"{a:.2f}" for a in res.angles_deg),
             "pose reached: " + pose_text(res.pose),
             f"remaining error: {res.pos_error:.3f} mm, {res.rot_error:.3f} deg",
             f"equilibrium: residual {res.residual:.2e} N = {res.residual / max(res.reference, 1e-300):.1e} x "
             f"force scale (certified by {res.certified or '-'})"]
    return "\n".join(lines)


#: The six pose components ``robot goto`` takes, in order, with their units.
POSE_COMPONENTS = ("X [mm]", "Y [mm]", "Z [mm]", "RX [deg]", "RY [deg]", "RZ [deg]")
#: Largest |component| of a goal: 1000 mm, the longest sheet reach, rod and horn a pipeline allows
#: (no robot moves its effector farther; 1e308 overflowed to inf mm and nan deg); 180 deg, as every
#: rotation is a rotation vector of length <= 180 deg, so its components are within it.
POSE_BOUNDS = (1000.0,) * 3 + (180.0,) * 3


def parse_pose(values: list[str]) -> list[float]:
    """Six finite numbers within :data:`POSE_BOUNDS` from the command line; a bad one is named with
    its position and unit."""
    from .errors import ConfigError

    if len(values) != 6:
        raise ConfigError(f"pose: {len(values)} numbers given: expected 6 (X Y Z [mm] RX RY RZ [deg])")
    pose = []
    for i, (text, name) in enumerate(zip(values, POSE_COMPONENTS), 1):
        try:
            v = float(text)
        except ValueError:
            raise ConfigError(f"pose component {i} of 6 ({name}): {text!r}: expected a number") from None
        if not math.isfinite(v):
            raise ConfigError(f"pose component {i} of 6 ({name}): {text!r}: expected a finite number")
        bound = POSE_BOUNDS[i - 1]
        if abs(v) > bound:
            raise ConfigError(f"pose component {i} of 6 ({name}): {text!r}: allowed range is [{-bound:g}, {bound:g}]")
        pose.append(v)
    return pose


def stall_text(robot, res) -> str:
    """``limited by: ...`` lines naming why ``res`` (an unreached goal) stopped, the primary
    cause first (:func:`metasheet.robot.stall.diagnose`)."""
    from .robot.stall import diagnose

    return "\n".join(f"limited by: {line}" for line in diagnose(robot, res).text().splitlines())
