"""``metasheet export sofa``: a pipeline's robot as a SOFA scene folder, and that folder read back.

The folder holds the scene (:mod:`.sofa_scene`, copied as ``scene.py``), ``sheets.vtk`` (both
sheets, linear tetrahedra in the robot's world frame [mm], legacy ASCII VTK: SOFA's
``MeshVTKLoader`` and ParaView read it), ``elements.txt`` (per element: the sheet, the fibre
direction in the world frame, E_t, E_l, nu_t, nu_tl, mu_l in kPa), ``maze.obj`` (the maze plate
the rod carries) and ``robot.json`` (servos, grips, rod, masses, units, what the export came
from). SOFA's units are mm, kg and s, so its stresses are kPa: metasheet's MPa times 1,000, its
masses (tonnes) times 1,000. SOFA's tetrahedra are linear: a robot meshed with quadratic
elements is exported on its own linear tetrahedra (the same mesh, coarser in effect), or
re-meshed with ``mesh_size``.

The authors' force field makes its own tensor from the five constants (metasheet's material
model "authors", :mod:`metasheet.mechanics.material_model`): it is metasheet's robot with
``model="authors"`` that the scene reproduces; a pipeline whose material model is "ours"
runs in SOFA with another longitudinal shear and c13 (``robot.json`` says so).
:func:`read_sofa_robot` builds metasheet's robot from the folder's files alone.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from ..robot.robots import Q_A, Q_B

#: SOFA's stress unit (kPa) per metasheet's (MPa), and its mass unit (kg) per metasheet's (t)
KPA_PER_MPA = 1000.0
KG_PER_T = 1000.0
#: the five constants' columns in elements.txt, after the sheet and the fibre
CONSTANTS = ("E_t", "E_l", "nu_t", "nu_tl", "mu_l")
_STRESS = (True, True, False, False, True)
#: what the scene targets (the docs' "Run your design in SOFA")
SOFA_TARGET = "SOFA v24.06 with SofaPython3, SoftRobots, SoftRobots.Inverse, ArticulatedSystemPlugin, Anisotropy"


def quaternion(R: np.ndarray) -> list[float]:
    """[qx, qy, qz, qw] of the rotation matrix ``R`` (3, 3) (SOFA's Rigid3 order)."""
    from scipy.spatial.transform import Rotation

    return [float(v) for v in Rotation.from_matrix(np.asarray(R, float)).as_quat()]


def servo_frame(Q: np.ndarray, arm_angle: float) -> np.ndarray:
    """(3, 3) the axes of the servo of the arm at ``arm_angle`` [rad] of a sheet placed by
    ``Q`` (local -> world): x the servo axis ``a = n x u``, y the horn at 0 deg (``-u``), z the
    horn at 90 deg (``n``), so that turning y by the motor angle about x gives the horn
    (``h(theta) = -cos(theta) u + sin(theta) n``, :mod:`metasheet.robot.robots`)."""
    n = Q[:, 2]
    u = Q @ np.array([np.cos(arm_angle), np.sin(arm_angle), 0.0])
    return np.column_stack([np.cross(n, u), -u, n])


def _rx(theta: float) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def write_vtk(path: Path, points: np.ndarray, tets: np.ndarray, sheet: np.ndarray, fibers: np.ndarray,
              attach: np.ndarray) -> None:
    """Legacy ASCII VTK of linear tetrahedra (repr-exact floats): point data ``attach``, cell
    data ``sheet`` and ``fiber``."""
    f = "%.17g"
    lines = ["# vtk DataFile Version 3.0", "metasheet robot sheets [mm]", "ASCII", "DATASET UNSTRUCTURED_GRID",
             f"POINTS {len(points)} double"]
    lines += [" ".join(f % v for v in p) for p in points]
    lines += [f"CELLS {len(tets)} {5 * len(tets)}"] + [f"4 {a} {b} {c} {d}" for a, b, c, d in tets]
    lines += [f"CELL_TYPES {len(tets)}"] + ["10"] * len(tets)
    lines += [f"POINT_DATA {len(points)}", "SCALARS attach int 1", "LOOKUP_TABLE default"]
    lines += [str(int(a)) for a in attach]
    lines += [f"CELL_DATA {len(tets)}", "SCALARS sheet int 1", "LOOKUP_TABLE default"] + [str(int(s)) for s in sheet]
    lines += ["VECTORS fiber double"] + [" ".join(f % v for v in d) for d in fibers]
    path.write_text("\n".join(lines) + "\n")


def maze_corners(plate=None) -> np.ndarray:
    """(8, 3) [mm] the corners of the maze plate (:class:`.series.MazePlate`, default the
    ParaView series' plate) in the rod's frame."""
    from .series import MazePlate

    plate = plate or MazePlate()
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    return signs * 0.5 * np.asarray(plate.size, float) + np.asarray(plate.centre, float)


def maze_obj(corners: np.ndarray) -> str:
    """An OBJ box of the 8 ``corners`` (in :func:`maze_corners`' order) [mm]."""
    v = [tuple(c) for c in corners]
    faces = [(1, 2, 4, 3), (5, 7, 8, 6), (1, 5, 6, 2), (3, 4, 8, 7), (1, 3, 7, 5), (2, 6, 8, 4)]
    return "".join(f"v {x:g} {y:g} {z:g}\n" for x, y, z in v) + "".join(f"f {a} {b} {c} {d}\n" for a, b, c, d in faces)


def check_program_file(path: Path) -> None:
    """ConfigError unless ``path`` is a CSV whose header has ``time_s`` and ``motor0_deg`` to ``motor5_deg``."""
    try:
        header = path.read_text().splitlines()[0].split(",")
    except (OSError, IndexError) as exc:
        raise ConfigError(f"--program: {path}: cannot read a header ({exc})") from exc
    missing = [c for c in ["time_s"] + [f"motor{k}_deg" for k in range(6)] if c not in header]
    if missing:
        raise ConfigError(f"--program: {path}: columns {missing} missing (a `metasheet robot path` program.csv has them)")


def scene_text(text: str, anisotropic: bool, inverse: bool, program: str | None) -> str:
    """The scene file with its three switches set (:mod:`.sofa_scene`)."""
    for key, value in (("ANISOTROPIC", anisotropic), ("INVERSE", inverse),
                       ("PROGRAM", None if program is None else f"os.path.join(HERE, {program!r})")):
        line = f"{key} = {'True' if key != 'PROGRAM' else 'None'}\n"
        if line not in text:
            raise RuntimeError(f"the scene template lost its line {line!r}")
        text = text.replace(line, f"{key} = {value}\n", 1)
    return text


def export_robot(robot, sheets, material, model: str, to: Path, *, source: dict | None = None,
                 rod_mass_g: float = 10.0, horn_mass_g: float = 10.0, dt_s: float = 0.01,
                 rayleigh_stiffness: float = 0.01, max_step_deg: float = 5.0, anisotropic: bool = True,
                 inverse: bool = True, program: Path | None = None, picture: bool = False,
                 notes: dict | None = None) -> Path:
    """Write the scene folder ``to`` for ``robot`` (built by :func:`~metasheet.robot.builder.
    six_dof_robot` from the P1 ``sheets``; ``material`` None: the sheets' own constants) and
    return it. Written beside ``to`` under a temporary name and renamed: an interrupted export
    leaves no folder. ``rod_mass_g``, ``horn_mass_g``: the rod-and-maze's and each horn's mass
    [g] (metasheet's statics carry neither; SOFA's dynamics need one); ``dt_s``, the Rayleigh
    stiffness and the QP's motor step limit [deg] go to the scene as they are; ``anisotropic``
    False: the scene's isotropic fallback (no Anisotropy plugin); ``inverse`` False: the servos
    follow ``program`` (a ``metasheet robot path`` program.csv, copied in) or hold rest;
    ``picture``: also ``scene.png`` (:func:`metasheet.viz.scene.scene_picture`); ``notes``:
    more entries for ``robot.json`` (:func:`model_gap`'s)."""
    from ..version import __version__
    from .sofa_scene import __file__ as scene_file

    if program is not None:
        check_program_file(Path(program))
        if inverse:
            raise ConfigError("program: a motor program plays in the direct scene (servos commanded), not the inverse one")
    if sheets.element != "p1":
        raise ConfigError(f"element: {sheets.element!r}: SOFA's tetrahedra are linear; export the sheets as 'p1'")
    if robot.body.tets.shape[1] != 4:
        raise ConfigError("robot: built on quadratic elements; export the robot of the sheets' linear tetrahedra")
    tets_a = len(sheets.sheet.tets)
    fibers = np.vstack([sheets.fibers @ Q_A.T, sheets.fibers_mirrored @ Q_B.T])
    if material is None:
        consts = np.vstack([sheets.constants, sheets.constants_mirrored])
    else:  # an isotropic material as the degenerate transverse-isotropic one (E_l = E_t, ...)
        five = material.as_transverse() if hasattr(material, "as_transverse") else material
        consts = np.broadcast_to([getattr(five, n) for n in CONSTANTS], (len(fibers), 5))
    consts = consts * np.where(_STRESS, KPA_PER_MPA, 1.0)
    sheet_id = np.repeat([0, 1], [tets_a, len(fibers) - tets_a])
    attach = np.concatenate([sheets.sheet.attach, sheets.mirrored.attach])
    c = robot.coupling
    arms = [(Q_A, a) for a in sheets.sheet.arm_angles] + [(Q_B, a) for a in sheets.mirrored.arm_angles]
    servos = []
    for k, s in enumerate(c.servos):
        F = servo_frame(*arms[k])
        servos.append({"sheet": "AB"[k // 3], "arm": k % 3, "pivot_mm": s.pivot.tolist(),
                       "axis": np.asarray(s.axis, float).tolist(),
                       "horn_length_mm": float(s.horn_length), "rest_angle_rad": float(s.rest_angle),
                       "angle_min_rad": float(robot.angle_min[k]), "angle_max_rad": float(robot.angle_max[k]),
                       "max_step_rad": float(np.radians(max_step_deg)), "horn_mass_kg": horn_mass_g / 1000.0,
                       "frame": [*s.pivot.tolist(), *quaternion(F)],
                       "grip_frame": [*s.pivot.tolist(), *quaternion(F @ _rx(s.rest_angle))],
                       "grip_nodes": [int(i) for i in s.nodes]})
    data = {
        "format": "metasheet SOFA export 1", "sofa": SOFA_TARGET, "metasheet": __version__,
        "units": {"length": "mm", "mass": "kg", "time": "s", "stress": "kPa", "angle": "rad",
                  "conversion": "stress kPa = MPa x 1000; mass kg = t x 1000 (metasheet: mm, t, s, MPa)"},
        "mesh": "sheets.vtk", "elements": "elements.txt", "n_tets_per_sheet": [tets_a, len(fibers) - tets_a],
        "n_nodes_per_sheet": [len(sheets.sheet.points), len(sheets.mirrored.points)],
        "arm_angles_rad": [np.asarray(sheets.sheet.arm_angles, float).tolist(),
                           np.asarray(sheets.mirrored.arm_angles, float).tolist()],
        "servo_geometry": robot.info["servo_geometry"],
        "material_model": model,
        "material_model_note": ("the authors' force field makes the tensor of metasheet's 'authors' model from these "
                                "constants" + ("" if model == "authors" else "; this robot was modelled with "
                                               f"{model!r} (another longitudinal shear and c13): SOFA will differ")),
        "density_kg_per_mm3": robot.body.density * KG_PER_T,
        "sheets_mass_kg": float(robot.body.mass.sum()) * KG_PER_T,
        "gravity_mm_s2": [float(g) for g in robot.gravity], "dt_s": dt_s,
        "rayleigh_stiffness": rayleigh_stiffness, "rayleigh_mass": 0.0, "qp_epsilon": 1e-3,
        "rod": {"frame": [*c.origin.tolist(), 0.0, 0.0, 0.0, 1.0], "length_mm": float(robot.info["rod_length_mm"]),
                "grip_nodes": [int(i) for i in c.effector_nodes], "mass_kg": rod_mass_g / 1000.0,
                "maze_mesh": "maze.obj"},
        "servos": servos, "servo_convention": "angle 0 = horn horizontal reaching inwards, pi/2 = vertical",
        "source": source or {}, **(notes or {}),
    }
    to = Path(to)
    tmp = to.with_name(to.name + ".partial")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    try:
        write_vtk(tmp / "sheets.vtk", robot.body.rest, robot.body.tets, sheet_id, fibers, attach)
        rows = np.column_stack([sheet_id, fibers, consts])
        np.savetxt(tmp / "elements.txt", rows, fmt=["%d"] + ["%.17g"] * 8,
                   header="sheet dx dy dz E_t_kPa E_l_kPa nu_t nu_tl mu_l_kPa (fibre: the soft axis l, world frame)")
        (tmp / "maze.obj").write_text(maze_obj(maze_corners()))
        (tmp / "robot.json").write_text(json.dumps(data, indent=1, sort_keys=True) + "\n")
        if picture:
            (tmp / "scene.png").write_bytes(_picture(robot, sheet_id, fibers, servos))
        if program is not None:
            shutil.copyfile(program, tmp / "program.csv")
        (tmp / "scene.py").write_text(scene_text(Path(scene_file).read_text(), anisotropic, inverse,
                                                 None if program is None else "program.csv"))
        if to.exists():
            shutil.rmtree(to)
        tmp.rename(to)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return to


def _picture(robot, sheet_id, fibers, servos) -> bytes:
    """``scene.png``: the sheets, fibres, servo axes and horns, rod and maze as exported."""
    from scipy.spatial.transform import Rotation

    from ..viz.scene import scene_picture

    pivots = np.array([s["pivot_mm"] for s in servos])
    horns = np.array([Rotation.from_quat(s["grip_frame"][3:]).as_matrix()[:, 1] * s["horn_length_mm"] for s in servos])
    half = 0.5 * robot.info["rod_length_mm"]
    corners = maze_corners()
    return scene_picture(robot.body.rest, robot.body.tets, sheet_id, fibers, pivots,
                         np.array([s["axis"] for s in servos]), pivots + horns, np.array([[-half, 0, 0], [half, 0, 0]]),
                         corners)


def _servo_geometry(sg: dict):
    """The :class:`~metasheet.robot.robots.ServoGeometry` recorded in ``robot.json``."""
    from ..robot.robots import ServoGeometry

    on_circle = sg.get("servo_radius_mm") is not None
    return ServoGeometry(None if on_circle else sg["rest_angle_deg"], sg["horn_length_mm"], sg["angle_min_deg"],
                         sg["angle_max_deg"], servo_radius=sg.get("servo_radius_mm"),
                         servo_depth=sg.get("servo_depth_mm"))


def read_sofa_robot(folder: Path, model: str = "authors"):
    """metasheet's robot from an export's files alone: the sheets' nodes and tetrahedra back
    in each sheet's own frame, their fibres and constants per element (kPa back to MPa), the
    servo geometry, rod, density and gravity; ``model`` the material model ("authors": the
    tensor SOFA's force field makes). ConfigError naming a missing or inconsistent file."""
    import meshio

    from ..robot.builder import SheetPair, six_dof_robot
    from ..sheet.geometry import SheetMesh

    folder = Path(folder)
    try:
        data = json.loads((folder / "robot.json").read_text())
        mesh = meshio.read(folder / data["mesh"])
        rows = np.atleast_2d(np.loadtxt(folder / data["elements"]))
    except (OSError, ValueError, KeyError) as exc:
        raise ConfigError(f"{folder}: not a metasheet SOFA export ({exc})") from exc
    tets = mesh.cells_dict["tetra"]
    attach = np.asarray(mesh.point_data["attach"]).reshape(-1).astype(int)
    if len(rows) != len(tets) or rows.shape[1] != 9:
        raise ConfigError(f"{folder / data['elements']}: {rows.shape} rows and columns; expected ({len(tets)}, 9)")
    (ta, _), (na, _) = data["n_tets_per_sheet"], data["n_nodes_per_sheet"]
    half = 0.5 * data["rod"]["length_mm"]
    consts = rows[:, 4:] / np.where(_STRESS, KPA_PER_MPA, 1.0)
    parts = []
    for Q, c, nodes, elems, angles in ((Q_A, -half, slice(0, na), slice(0, ta), data["arm_angles_rad"][0]),
                                       (Q_B, half, slice(na, None), slice(ta, None), data["arm_angles_rad"][1])):
        local = (mesh.points[nodes] - np.array([c, 0.0, 0.0])) @ Q  # world = local Q^T + centre
        sheet = SheetMesh(local, tets[elems] - nodes.start, attach[nodes], np.asarray(angles, float))
        parts.append((sheet, rows[elems, 1:4] @ Q, consts[elems]))
    (sa, fa, ca), (sb, fb, cb) = parts
    sheets = SheetPair(sa, sb, fa, fb, ca, cb, "p1")
    return six_dof_robot(sheets, None, density=data["density_kg_per_mm3"] / KG_PER_T,
                         rod_length=data["rod"]["length_mm"], geometry=_servo_geometry(data["servo_geometry"]),
                         gravity=tuple(data["gravity_mm_s2"]), model=model)


def export_sofa(outputs: Path, to: Path, *, column: str = "prediction", mesh_size: float | None = None,
                **options) -> Path:
    """The SOFA scene folder ``to`` of a pipeline's outputs ``outputs`` (the folder holding its
    ``orient``, ``material`` and ``robot`` stages): the ``column``'s robot (prediction: the
    material stage's constants; reproduction: the published foam) on the orient stage's
    tetrahedra, linear, or re-meshed at ``mesh_size`` [mm]; ``options``: :func:`export_robot`'s."""
    from dataclasses import replace

    from ..pipeline.artefacts import read_material, read_orient, read_robot_scene
    from ..pipeline.column import column as column_of, column_robot

    outputs = Path(outputs)
    for stage, name in (("orient", "sheet.json"), ("material", "material.json"), ("robot", "jacobian.json")):
        if not (outputs / stage / name).is_file():
            raise ConfigError(f"{outputs / stage / name}: missing: give the output folder of a pipeline run with the "
                              "orient, material and robot stages (e.g. outputs/quick after `metasheet run "
                              "pipelines/quick.toml`)")
    orient, mat, sc = read_orient(outputs / "orient"), read_material(outputs / "material"), read_robot_scene(outputs / "robot")
    col = column_of(column, field="--column")
    mesh = {} if mesh_size is None else {"mesh_size": float(mesh_size), "element": "p1"}
    if col.fixes_material and mesh_size is not None:
        col = replace(col, mesh={**col.mesh, **mesh})
        mesh = {}
    parts = column_robot(orient, mat, col, sc.sheet_mass_g, **mesh)
    sheets = replace(parts.sheets, element="p1")
    material = None if sheets.has_constants else parts.material
    robot = six_dof_robot_of(sheets, material, parts, sc)
    notes = {} if parts.model == "authors" else {"model_gap": model_gap(robot, six_dof_robot_of(
        sheets, material, replace(parts, model="authors"), sc), parts.model)}
    source = {"outputs": str(outputs.resolve()), "column": column, "mesh_size_mm": mesh_size,
              "element": "p1", "orient_element": orient.element}
    return export_robot(robot, sheets, material, parts.model, to, source=source, notes=notes, **options)


def model_gap(robot, authors, model: str) -> dict:
    """How far the scene's robot (``authors``: the same sheets under the authors' force field)
    is from metasheet's (``robot``, material model ``model``) at rest: the singular values of
    the direct Jacobian [mm/rad] (:mod:`metasheet.robot.kinematics`) of both, and their largest
    relative difference."""
    from ..robot.kinematics import kinematics_at

    s_m = kinematics_at(robot, robot.rest_state()).singular_values
    s_a = kinematics_at(authors, authors.rest_state()).singular_values
    return {"what": f"rest Jacobian's singular values [mm/rad]: metasheet's model {model!r} against the authors' "
                    "force field (the scene's) on the exported sheets",
            f"singular_values_{model}": s_m.tolist(), "singular_values_authors": s_a.tolist(),
            "largest_relative_difference": float(np.max(np.abs(s_a - s_m) / s_m))}


def six_dof_robot_of(sheets, material, parts, scene):
    """The robot of ``sheets`` with a column's material, model and density and a robot stage's scene."""
    from ..robot.builder import six_dof_robot

    return six_dof_robot(sheets, material, density=parts.density, model=parts.model, rod_length=scene.rod_length,
                         geometry=scene.servo_geometry(), gravity=scene.gravity)
