"""Time series ParaView plays: a robot's states as a ``.pvd`` collection of ``.vtu`` files.

``write_robot_series(robot, states, times, folder, name)`` writes ``<folder>/<name>.pvd``
and ``<folder>/<name>/<name>_<part>_<step:05d>.vtu``, one file per state and part (the
pvd's ``part`` attribute, :data:`PARTS`):

* part 0, ``sheets``: both sheets' elements (P1 as VTK ``tetra``, P2 as ``tetra10``), the
  points at the deformed node positions [mm]. Point data ``displacement`` (n, 3) [mm] from
  the rest positions; cell data ``sheet`` (0: sheet A, 1: sheet B), ``fiber`` (m, 3) [-],
  the element's soft axis l turned with it, and ``max_principal_strain`` (m,) [-], the
  largest principal Green-Lagrange strain over the element's quadrature points (the measure
  of :mod:`metasheet.robot.validity`).
* part 1, ``rod``: a 16-sided cylinder of radius :data:`ROD_RADIUS` between the sheet
  centres, moved rigidly with the effector.
* part 2, ``maze``: the maze plate (:class:`MazePlate`, a box, and its path as a polyline
  on its top face), moved rigidly with the effector.
* part 3, ``horns``: one line per servo, pivot -> the centre of the grip the horn holds;
  cell data ``servo`` (its index) and ``angle_deg`` (its motor angle, 0 = horizontal).

Fibres. A robot carries its sheets' stiffness, not their fibres: each element's rest fibre
is the symmetry axis of its transverse-isotropic tensor (:func:`rest_fibers`; the builder
turns the material's axis 3, the soft axis l, onto the fibre). An isotropic element (the
silicone sheets) has no axis and gets a zero fibre. At a state the fibre is ``R l`` with
``R`` the rotation of the polar decomposition of the element's deformation gradient: for P1
exactly the element rotation of the corotational force (:mod:`metasheet.fem.corotational.p1`);
for P2, whose force turns each quadrature point on its own, the rotation of the
volume-averaged gradient (:func:`element_rotations`). Fibres are axes: their sign is
arbitrary (fixed so that the largest component is positive at rest).

The files are XML ``.vtu`` through meshio (binary, zlib-compressed base64: floats round-trip
bit for bit); the pvd's time steps are written as ``repr`` of the floats [s]. Nothing in the
files depends on the clock: the same inputs give the same bytes. A series is written into a
hidden sibling folder and renamed into place at the end; an existing series of the same name
is replaced whole (no step file of the old one stays behind), and a run cut short leaves the
old series or none, never half of one.
"""

from __future__ import annotations

import os
import re
import shutil
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ConfigError

#: the parts of every time step, by the pvd's ``part`` index
PARTS = ("sheets", "rod", "maze", "horns")
#: the drawn rod's radius [mm] (drawing only: the model's rod is a rigid line)
ROD_RADIUS = 3.0
ROD_SIDES = 16
#: VTK's quadratic tetrahedron lists the midpoints of edges 01, 12, 02, 03, 13, 23; the
#: robot's (:mod:`metasheet.fem.tet10`) 01, 02, 03, 12, 13, 23
TET10_TO_VTK = np.array([0, 1, 2, 3, 4, 7, 5, 6, 8, 9])
#: Voigt index of the tensor pair (i, j): 11, 22, 33, 23, 13, 12
_VOIGT = np.array([[0, 5, 4], [5, 1, 3], [4, 3, 2]])
#: an element whose tensor's axis stands out by less than this (relative) is isotropic
_ISOTROPIC = 1e-9


@dataclass(frozen=True)
class MazePlate:
    """The maze plate fixed to the effector (the maze study's plane: the rod axis x and y at
    rest, normal z).

    size : (3,) [mm] along x, y, z at rest (the default stays between the sheets at +-40 mm).
    centre : (3,) [mm] the plate's centre from the effector's reference point at rest (the
        default lays it on the drawn rod).
    path : None, or the maze path ((u, v), ...) [mm] in the plate's plane (u along x, v
        along y: the maze study's ``path``), drawn on its top face.
    """

    size: tuple = (70.0, 60.0, 3.0)
    centre: tuple = (0.0, 0.0, ROD_RADIUS + 1.5)
    path: tuple | None = None

    def __post_init__(self):
        size = np.asarray(self.size, float)
        if size.shape != (3,) or not np.all(np.isfinite(size)) or np.any(size <= 0):
            raise ConfigError(f"maze.size: {self.size!r}: should be three positive lengths [mm]")
        centre = np.asarray(self.centre, float)
        if centre.shape != (3,) or not np.all(np.isfinite(centre)):
            raise ConfigError(f"maze.centre: {self.centre!r}: should be a finite 3-vector [mm]")
        if self.path is not None:
            path = np.asarray(self.path, float)
            if path.ndim != 2 or path.shape[1] != 2 or len(path) < 2 or not np.all(np.isfinite(path)):
                raise ConfigError(f"maze.path: shape is {path.shape} and should be (k, 2) with k >= 2, finite [mm]")


# --------------------------------------------------------------------------- per-element fields

def rest_fibers(stiffness: np.ndarray) -> np.ndarray:
    """(m, 3) unit symmetry axis of each transverse-isotropic Voigt tensor ``stiffness``
    (m, 6, 6) [MPa] (engineering shear, global axes); zero rows for isotropic ones.

    The axis is the eigenvector with the distinct eigenvalue of a second-order contraction
    of the tensor, ``C_ijkk`` or ``C_ikjk`` (both are ``a I + b l l^T`` for a material
    symmetric about l), whichever sets it further apart.
    """
    C = np.asarray(stiffness, float)
    dil = C[:, _VOIGT, :3].sum(axis=-1)                                # C_ijkk
    voi = C[:, _VOIGT[:, None, :], _VOIGT[None, :, :]].sum(axis=-1)   # C_ikjk
    best, score = np.zeros((len(C), 3)), np.zeros(len(C))
    for T in (dil, voi):
        w, v = np.linalg.eigh(T)
        top = (w[:, 2] - w[:, 1]) > (w[:, 1] - w[:, 0])  # the distinct one: the largest, else the smallest
        sep = np.where(top, w[:, 2] - w[:, 1], w[:, 1] - w[:, 0]) / np.maximum(np.abs(w).max(axis=1), 1e-300)
        axis = np.where(top[:, None], v[:, :, 2], v[:, :, 0])
        better = sep > score
        best[better], score[better] = axis[better], sep[better]
    best[score < _ISOTROPIC] = 0.0
    big = np.abs(best).argmax(axis=1)
    return best * np.where(best[np.arange(len(best)), big] < 0, -1.0, 1.0)[:, None]


def element_rotations(body, x: np.ndarray) -> np.ndarray:
    """(m, 3, 3) each element's rotation at node positions ``x`` (n, 3) [mm]: the polar
    rotation of its volume-averaged deformation gradient (P1: its one gradient)."""
    from ..fem.corotational.p1 import polar_numpy

    F = body.deformation_gradients(x)                      # (m, nq, 3, 3)
    w = np.asarray(body.quad_weights, float)
    Fbar = np.einsum("mqij,mq->mij", F, w) / w.sum(axis=1)[:, None, None]
    return polar_numpy(Fbar)[0]


# --------------------------------------------------------------------------- the parts at rest

def rod_rest(robot) -> tuple[np.ndarray, np.ndarray]:
    """The drawn rod at rest: points (2 + 2 S, 3) [mm] and (S, 6) wedges, S = :data:`ROD_SIDES`,
    a cylinder of radius :data:`ROD_RADIUS` from sheet A's centre to sheet B's."""
    centres = robot.info.get("sheet_centres_mm")
    if centres is None or "rod_length_mm" not in robot.info:
        raise ConfigError(f"robot: {robot.name!r} has no rod (info has no sheet_centres_mm, rod_length_mm): "
                          "a series needs the 6-DOF robot")
    a, b = np.asarray(centres, float)
    d = (b - a) / np.linalg.norm(b - a)
    e1 = np.cross(d, [0.0, 0.0, 1.0] if abs(d[2]) < 0.9 else [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(d, e1)
    phi = 2 * np.pi * np.arange(ROD_SIDES) / ROD_SIDES
    ring = ROD_RADIUS * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)
    pts = np.vstack([a, b, a + ring, b + ring])
    s = np.arange(ROD_SIDES)
    s1 = (s + 1) % ROD_SIDES
    # VTK wedge: each triangle's right-hand normal points away from the other one
    wedges = np.stack([np.zeros_like(s), 2 + s1, 2 + s, np.ones_like(s), 2 + ROD_SIDES + s1, 2 + ROD_SIDES + s], 1)
    return pts, wedges


def maze_rest(robot, maze: MazePlate) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The maze plate at rest: points (8 + k, 3) [mm], its (1, 8) hexahedron and the path's
    (k - 1, 2) lines (k = 0 without a path), on the top face."""
    h = 0.5 * np.asarray(maze.size, float)
    centre = np.asarray(robot.coupling.origin, float) + np.asarray(maze.centre, float)
    corners = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                        [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], float) * h
    path = np.zeros((0, 2)) if maze.path is None else np.asarray(maze.path, float)
    on_top = np.column_stack([path, np.full(len(path), h[2])])
    pts = centre + np.vstack([corners, on_top])
    lines = 8 + np.column_stack([np.arange(len(path) - 1), np.arange(1, len(path))]) if len(path) else np.zeros((0, 2))
    return pts, np.arange(8)[None, :], lines.astype(np.int64)


def horn_tips_rest(robot) -> np.ndarray:
    """(na, 3) [mm] each horn's tip at rest: the centre of the grip it holds, as the robot
    builder placed the pivot from it (:func:`metasheet.robot.robots.grip_centre`)."""
    from ..robot.robots import grip_centre

    body, tips = robot.body, []
    for s in robot.coupling.servos:
        tag = np.zeros(body.n_nodes, int)
        tag[np.asarray(s.nodes)] = 1
        tips.append(grip_centre(body.rest, body.tets, tag, 1))
    return np.array(tips)


def rigid(points: np.ndarray, origin: np.ndarray, p: np.ndarray, R: np.ndarray) -> np.ndarray:
    """(k, 3) [mm] ``points`` fixed to the effector, moved from its rest (``origin``, I) to
    (``p`` [mm], ``R``): ``p + R (X - origin)`` (eq. 2's effector map)."""
    return np.asarray(p, float) + (np.asarray(points, float) - origin) @ np.asarray(R, float).T


def horn_tips(robot, tips0: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """(na, 3) [mm] the horn tips at motor ``angles`` (na,) [rad]: each turned about its
    servo's axis through the pivot by the angle from rest (:mod:`metasheet.robot.rigid`)."""
    from ..mechanics.rotations import axis_rotation

    out = []
    for s, tip, th in zip(robot.coupling.servos, tips0, angles):
        out.append(s.pivot + axis_rotation(s.axis, th - s.rest_angle) @ (tip - s.pivot))
    return np.array(out)


# --------------------------------------------------------------------------- one time step

def step_meshes(robot, x: np.ndarray, p, R, angles, *, fibers0, rod, maze, tips0) -> list:
    """The four meshio meshes (:data:`PARTS`) of one state: node positions ``x`` (n, 3) [mm],
    effector (``p`` [mm], ``R``), motor ``angles`` (na,) [rad]; the rest geometry precomputed
    (``fibers0`` (m, 3), ``rod`` and ``maze`` as their ``*_rest`` functions return them,
    ``tips0`` (na, 3))."""
    import meshio

    body, c = robot.body, robot.coupling
    tets = np.asarray(body.tets)
    p2 = tets.shape[1] == 10
    n_a = int(robot.info["n_tets_per_sheet"][0])
    fiber = np.einsum("mij,mj->mi", element_rotations(body, x), fibers0)
    sheets = meshio.Mesh(
        np.asarray(x, float), [("tetra10" if p2 else "tetra", tets[:, TET10_TO_VTK] if p2 else tets)],
        point_data={"displacement": x - np.asarray(c.rest, float)},
        cell_data={"sheet": [(np.arange(len(tets)) >= n_a).astype(np.int32)], "fiber": [fiber],
                   "max_principal_strain": [np.asarray(body.max_principal_strain(x), float)]})
    rod_mesh = meshio.Mesh(rigid(rod[0], c.origin, p, R), [("wedge", rod[1])])
    blocks = [("hexahedron", maze[1])] + ([("line", maze[2])] if len(maze[2]) else [])
    maze_mesh = meshio.Mesh(rigid(maze[0], c.origin, p, R), blocks)
    pivots = np.array([s.pivot for s in c.servos], float)
    na = len(pivots)
    horn_pts = np.stack([pivots, horn_tips(robot, tips0, angles)], 1).reshape(-1, 3)
    horns = meshio.Mesh(horn_pts, [("line", np.arange(2 * na).reshape(na, 2))],
                        cell_data={"servo": [np.arange(na, dtype=np.int32)],
                                   "angle_deg": [np.degrees(np.asarray(angles, float))]})
    return [sheets, rod_mesh, maze_mesh, horns]


# --------------------------------------------------------------------------- the series

def _check_inputs(robot, states: list, times, name: str) -> tuple[np.ndarray, list[np.ndarray]]:
    from ..serve.models import positions

    if not isinstance(name, str) or not re.fullmatch(r"[A-Za-z0-9_][A-Za-z0-9._-]*", name):
        raise ConfigError(f"name: {name!r}: should be a plain file name of letters, digits, '.', '_', '-' "
                          "(no folder, not hidden: it names files in the .pvd)")
    if not states:
        raise ConfigError("states: empty: a series needs at least one state")
    t = np.asarray(times, float)
    if t.shape != (len(states),):
        raise ConfigError(f"times: shape is {t.shape} and should be ({len(states)},), one per state")
    if not np.all(np.isfinite(t)):
        raise ConfigError(f"times[{int(np.flatnonzero(~np.isfinite(t))[0])}]: not finite")
    if np.any(np.diff(t) <= 0):
        i = int(np.flatnonzero(np.diff(t) <= 0)[0])
        raise ConfigError(f"times[{i + 1}]: {t[i + 1]!r} s after {t[i]!r} s: times must increase strictly")
    n, na = robot.body.n_nodes, robot.coupling.n_act
    xs = []
    for i, st in enumerate(states):
        if getattr(st, "x", None) is None and not hasattr(robot, "positions"):
            raise ConfigError(f"states[{i}]: {type(st).__name__} has no node positions x, and the robot "
                              "gives none (a reduced state needs its reduced robot)")
        x = np.asarray(positions(robot, st), float)
        if x.shape != (n, 3):
            raise ConfigError(f"states[{i}]: node positions of shape {x.shape}; the robot has ({n}, 3)")
        if not np.all(np.isfinite(x)):
            raise ConfigError(f"states[{i}]: non-finite node positions")
        if np.shape(st.p) != (3,) or np.shape(st.R) != (3, 3) or np.shape(st.angles) != (na,):
            raise ConfigError(f"states[{i}]: p, R, angles of shapes {np.shape(st.p)}, {np.shape(st.R)}, "
                              f"{np.shape(st.angles)}; expected (3,), (3, 3), ({na},)")
        xs.append(x)
    return t, xs


def pvd_text(entries) -> str:
    """The ``.pvd`` collection: ``entries`` = ((time [s], part, relative file), ...)."""
    lines = ['<?xml version="1.0"?>',
             '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
             "  <!-- metasheet robot series: parts " + ", ".join(f"{k} {p}" for k, p in enumerate(PARTS))
             + "; times [s], lengths [mm] -->",
             "  <Collection>"]
    lines += [f'    <DataSet timestep="{t!r}" group="" part="{k}" file="{f}"/>' for t, k, f in entries]
    return "\n".join(lines + ["  </Collection>", "</VTKFile>", ""])


def write_robot_series(robot, states, times, folder, name: str = "path", *, maze=None) -> Path:
    """Write <folder>/<name>.pvd and <folder>/<name>/ with one .vtu per state and part; return the .pvd path.

    robot : a 6-DOF robot (:func:`metasheet.robot.builder.six_dof_robot`) or its
        :class:`~metasheet.rom.model.ReducedRobot`; states : T states of it (full ones with
        node positions ``x``, or reduced ones); times : (T,) [s], finite, strictly
        increasing; maze : a :class:`MazePlate`, None for the default one. The parts and
        arrays: the module docstring. Raises :class:`ConfigError` naming the field.
    """
    import meshio

    maze = MazePlate() if maze is None else maze
    if not isinstance(maze, MazePlate):
        raise ConfigError(f"maze: {type(maze).__name__}: expected a MazePlate or None")
    states = list(states)
    t, xs = _check_inputs(robot, states, times, name)
    fibers0 = rest_fibers(robot.body.stiffness)
    rod, plate, tips0 = rod_rest(robot), maze_rest(robot, maze), horn_tips_rest(robot)
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    work = folder / f".{name}.tmp-{os.getpid()}"
    shutil.rmtree(work, ignore_errors=True)
    try:
        (work / name).mkdir(parents=True)
        entries = []
        for i, (ti, st, x) in enumerate(zip(t, states, xs)):
            meshes = step_meshes(robot, x, st.p, st.R, st.angles, fibers0=fibers0, rod=rod, maze=plate, tips0=tips0)
            for k, mesh in enumerate(meshes):
                rel = f"{name}/{name}_{k}_{i:05d}.vtu"
                meshio.write(work / rel, mesh, file_format="vtu")
                entries.append((float(ti), k, rel))
        (work / f"{name}.pvd").write_text(pvd_text(entries))
        _swap_in(work, folder, name)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return folder / f"{name}.pvd"


def _swap_in(work: Path, folder: Path, name: str) -> None:
    """Replace ``folder``'s series ``name`` (pvd and step folder) by ``work``'s with renames:
    the old pvd goes first and the new one comes last, so a reader finds the old series, no
    pvd, or the new series."""
    old = folder / f".{name}.old-{os.getpid()}"
    shutil.rmtree(old, ignore_errors=True)
    old.mkdir()
    pvd, data = folder / f"{name}.pvd", folder / name
    moved = []
    try:
        for path in (pvd, data):
            if path.exists():
                os.replace(path, old / path.name)
                moved.append(path)
        os.replace(work / name, data)
        os.replace(work / f"{name}.pvd", pvd)
    except OSError:
        for path in moved:  # put the old series back
            if path.is_dir():
                shutil.rmtree(path, ignore_errors=True)
            os.replace(old / path.name, path)
        raise
    finally:
        shutil.rmtree(old, ignore_errors=True)


def read_series(pvd_path) -> list[tuple[float, dict[int, Path]]]:
    """The time steps of a ``.pvd`` collection in file order: ``[(time [s], {part: file}), ...]``
    with the files resolved from the pvd's folder (part k is :data:`PARTS` [k] for a
    metasheet series)."""
    pvd_path = Path(pvd_path)
    try:
        root = ET.parse(pvd_path).getroot()
    except (OSError, ET.ParseError) as err:
        raise ConfigError(f"{pvd_path}: not a readable .pvd collection ({err})") from None
    steps: dict[float, dict[int, Path]] = {}
    for ds in root.iter("DataSet"):
        try:
            t, k, f = float(ds.attrib["timestep"]), int(ds.attrib.get("part", 0)), ds.attrib["file"]
        except (KeyError, ValueError) as err:
            raise ConfigError(f"{pvd_path}: a DataSet without a valid timestep or file ({err})") from None
        steps.setdefault(t, {})[k] = pvd_path.parent / f
    return list(steps.items())
