"""Helpers behind ``metasheet robot goto X Y Z RX RY RZ``: build the 6-DOF robot from the
orient/material artefacts (or a plain config) and run the inverse model to a pose."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from ..errors import ConfigError
from ..material import TransverseIsotropic
from .assemblies import Robot, ServoGeometry, six_dof
from .compare import PAPER_FOAM, build_six_dof
from .inverse import InverseController, InverseResult, InverseSettings

CONSTANTS = ("E_t", "E_l", "nu_t", "nu_tl", "mu_l")


def read_sheet(path) -> tuple[SimpleNamespace, np.ndarray, np.ndarray]:
    """(sheet (points, tets, attach, arm_angles), fibres (m, 3), constants (m, 5) [MPa]) from an orient VTU."""
    import meshio

    m = meshio.read(path)
    tets = np.asarray(m.cells_dict.get("tetra", np.zeros((0, 4))), dtype=np.int64)
    if len(tets) == 0:
        raise ConfigError(f"{path}: no tetra cells")
    cd = {k: np.asarray(v[0]) for k, v in m.cell_data.items()}
    if "fiber" not in cd or "attach" not in m.point_data:
        raise ConfigError(f"{path}: needs cell data 'fiber' and point data 'attach' (the orient stage's sheet)")
    consts = np.column_stack([cd[k] for k in CONSTANTS]) if all(k in cd for k in CONSTANTS) else None
    sheet = SimpleNamespace(points=np.asarray(m.points, float), tets=tets,
                            attach=np.asarray(m.point_data["attach"]).astype(int).ravel(),
                            arm_angles=np.radians([0.0, 120.0, 240.0]))
    return sheet, np.asarray(cd["fiber"], float), consts


def element_stiffness(fibers: np.ndarray, consts: np.ndarray) -> np.ndarray:
    """(m, 6, 6) stiffness [MPa] in the sheet frame: per-element constants (m, 5), axis 3 along fibres."""
    from ..material import stiffness_along

    uniq, inv = np.unique(np.round(consts, 12), axis=0, return_inverse=True)
    C = np.empty((len(fibers), 6, 6))
    for i, row in enumerate(uniq):
        sel = np.flatnonzero(inv.ravel() == i)
        C[sel] = stiffness_along(TransverseIsotropic(*row).stiffness(), fibers[sel])
    return C


def robot_from_orient(orient_dir, *, material=None, rod_length=80.0, geometry=ServoGeometry(),
                      density=1.785e-10) -> Robot:
    """The 6-DOF robot from ``orient_dir`` (sheet.vtu, sheet_mirrored.vtu, sheet.json).

    ``material`` None: the per-element constants stored in the VTUs; otherwise that material
    everywhere (an :class:`~metasheet.material.Isotropic` ignores the fibres).
    """
    import json

    d = Path(orient_dir)
    a, fa, ca = read_sheet(d / "sheet.vtu")
    b, fb, cb = read_sheet(d / "sheet_mirrored.vtu")
    info = d / "sheet.json"
    if info.exists():
        ang = np.radians(json.loads(info.read_text()).get("arm_angles_deg", [0.0, 120.0, 240.0]))
        a.arm_angles = b.arm_angles = ang
    if material is not None or ca is None or cb is None:
        return build_six_dof(a, b, material or PAPER_FOAM, fibers=fa, fibers_mirrored=fb, rod_length=rod_length,
                             geometry=geometry, density=density)
    return six_dof(a, element_stiffness(fa, ca), b, element_stiffness(fb, cb), rod_length=rod_length,
                   geometry=geometry, density=density)


@dataclass(frozen=True)
class GotoConfig:
    """How ``goto`` builds its robot when not given one: an orient output directory, or a
    freshly meshed sheet (``mesh_size`` [mm]) with the paper's foam and spiral fibres."""

    orient_dir: str | None = None
    mesh_size: float = 8.0
    rod_length: float = 80.0
    rest_angle: float = 60.0  # [deg] motor angle of the rest pose (places the servos)
    horn_length: float = 25.0
    density: float = 1.785e-10


def _default_robot(cfg: GotoConfig) -> Robot:
    geo = ServoGeometry(rest_angle=cfg.rest_angle, horn_length=cfg.horn_length)
    if cfg.orient_dir is not None:
        return robot_from_orient(cfg.orient_dir, rod_length=cfg.rod_length, geometry=geo, density=cfg.density)
    from ..sheet.fibers import spiral_fibers
    from ..sheet.geometry import SheetParams, mirror_sheet, tripod_sheet

    s = tripod_sheet(SheetParams(mesh_size=cfg.mesh_size))
    m = mirror_sheet(s)
    return build_six_dof(s, m, PAPER_FOAM, fibers=spiral_fibers(s.centroids()),
                         fibers_mirrored=spiral_fibers(m.centroids(), mirrored=True), rod_length=cfg.rod_length,
                         geometry=geo, density=cfg.density)


def goto(config_or_robot, pose, *, settings: InverseSettings = InverseSettings()) -> InverseResult:
    """Solve the inverse model (eq. 8) from the rest equilibrium to ``pose``.

    Parameters
    ----------
    config_or_robot : a :class:`Robot`, a :class:`GotoConfig`, or a path to an orient output
        directory.
    pose : (6,) X, Y, Z [mm] of the rod centre and RX, RY, RZ [deg] (rotation vector) in the
        world frame (rod along x, gravity -z); the rest pose is ~(0, 0, 0, 0, 0, 0).

    Returns an :class:`InverseResult`: ``status`` reached / stalled / max_steps, the motor
    angles [deg], the reached pose and the remaining errors; never raises for an
    unreachable goal.
    """
    if isinstance(config_or_robot, Robot):
        robot = config_or_robot
    elif isinstance(config_or_robot, GotoConfig):
        robot = _default_robot(config_or_robot)
    elif isinstance(config_or_robot, (str, Path)):
        robot = _default_robot(GotoConfig(orient_dir=str(config_or_robot)))
    else:
        raise ConfigError(f"config_or_robot: {type(config_or_robot).__name__}: expected Robot, GotoConfig or a path")
    return InverseController(robot, settings=settings).goto(pose)


def format_result(res: InverseResult) -> str:
    """Human-readable lines for the CLI."""
    lines = [f"status: {res.status} after {res.steps} control steps",
             "motor angles [deg]: " + " ".join(f"{a:.2f}" for a in res.angles_deg),
             "pose reached: X Y Z [mm] " + " ".join(f"{v:.3f}" for v in res.pose[:3])
             + " | RX RY RZ [deg] " + " ".join(f"{v:.3f}" for v in res.pose[3:]),
             f"remaining error: {res.pos_error:.3f} mm, {res.rot_error:.3f} deg",
             f"equilibrium: residual {res.residual:.2e} N = {res.residual / max(res.reference, 1e-300):.1e} x "
             f"force scale (certified by {res.certified or '-'})"]
    return "\n".join(lines)
