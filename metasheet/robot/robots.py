"""Robots built from sheets: a single tripod (3 servos) and the paper's 6-DOF robot.

Geometry decisions (FACTS.md; documented here because the sources do not pin them down):

* Sheet frame: mid-plane z = 0, centre at the origin, arm k along ``arm_angles[k]``,
  nodes tagged ``attach`` = k + 1 (tip box of arm k) or 4 (centre, tied to the effector).
* Servo k sits behind the sheet (on the side of -n, n the sheet normal pointing away from the
  servo base) with its axis ``a_k = n x u_k`` horizontal and perpendicular to the arm
  (``u_k`` the arm's outward radial direction). The horn points from the pivot to the arm's
  tip box: ``h(theta) = -cos(theta) u_k + sin(theta) n``, so motor angle 0 is a horizontal
  horn reaching inwards and 90 degrees a vertical one (the paper's convention).
* The design parameter is the REST ANGLE ``theta_0`` (the motor angle at which the flat,
  unloaded sheet is the rest pose), not the servo position: the pivot is placed at
  ``tip - horn_length * h(theta_0)`` from the centroid of the arm's grip (:func:`grip_centre`), so every mesh of the same
  sheet has the same rest angle (placing the pivot on a fixed servo circle instead made the
  rest angle depend on the mesh's tip-box centroid: ~75 deg on the 5 mm mesh, 84-88 deg on
  coarse ones, leaving almost no pull travel). The servo circle's radius
  ``|pivot| = r_tip + horn cos(theta_0)`` is reported (``info``) as a derived quantity.
  Default ``theta_0 = 60 deg``. The paper's Fig. 7 tests (all motors pull 15 deg -> 75,
  push 35 deg -> 25) both fit with >= 15 deg to spare; any rest angle in [35, 75] would.
  Within that band the workspace decides: on the 6-DOF robot (14 mm mesh, 10 deg rotation
  trials, tests/test_studies_robot.py) the rest pose keeps all six +-10 deg rotations for
  theta_0 >= 60 but only 1-2 of them at 45 and 55, where tilting the rod drives the sheets
  into a near-singular pose (smallest Jacobian singular value 0.34 against 8.3 mm/rad at
  rest) long before a motor limit; above 65 the pull travel (25 deg or less) cuts the
  workspace on the pull side and the rest pose sits near the stiff, stretched-arm end. 60 is
  the lowest (most symmetric stroke: 60 down, 30 up) that gives the paper's "full 6-DOF
  control around the centre". With the paper's sheet (tip box at r ~ 59 mm) and a 25 mm horn
  the servo circle is then r ~ 71.5 mm.
* The alternative placement is the authors' (``servo_radius`` and ``servo_depth``): each pivot
  on the arm's radial line at ``servo_radius`` from the sheet centre, ``servo_depth`` behind
  the sheet's mid-plane. The horn (pivot -> tip-box centre) and the rest angle are then
  derived per servo and reported (``info``); they depend on the mesh's tip-box centroid.
  With the authors' scene (66 mm circle, 30 mm behind the sheet, tip box over the last 18 mm
  of the arm: :mod:`metasheet.robot.scenes`) the rest angle is ~75 deg and the horn ~31 mm.
* 6-DOF robot: the rod runs along world x, gravity along -z. The sheets' mid-planes are at
  x = -L/2 and x = +L/2 (L = ``rod_length``, default 80 mm), normals pointing at each other,
  so the rod joins the two centres; the effector is the rod centre, the origin. Sheet A maps
  local (x, y, z) -> world (-z, y, x); sheet B is the same turned 180 degrees about world z and
  carries the mirrored (y -> -y) sheet and fibre field, which makes B the exact mirror image of
  A through x = 0. FACTS gives "tripods at +-90 mm, rod 80 mm": we read +-90 mm as the servo
  bases; with theta_0 = 60 degrees the pivots are ~22 mm behind each sheet (|x| ~ 62 mm), which
  leaves ~28 mm for the servo body down to the base plate at |x| = 90 mm.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ..published import paper
from ..conventions import GRAVITY, TPU_DENSITY
from ..errors import ConfigError, check_range
from ..mechanics.voigt import MANDEL, mandel_rotation
from .rigid import RigidCoupling, Servo



@dataclass(frozen=True)
class ServoGeometry:
    """Where the servos are: from a rest angle and a horn, or on a given circle.

    Attributes
    ----------
    rest_angle : motor angle of the undeformed rest pose [deg] (0 = horizontal horn, 90 =
        vertical); the pivots are placed from it (see the module docstring). Must lie in
        [angle_min, angle_max]. None with ``servo_radius``.
    horn_length : pivot -> tip-box centre [mm] (unused, and derived, on a given circle).
    angle_min, angle_max : motor stroke [deg], 0 = horizontal horn, 90 = vertical.
    servo_radius, servo_depth : None, or the pivots' distance from the sheet centre in the
        sheet plane [mm] and behind the sheet's mid-plane [mm] (the authors' placement);
        give both, and ``rest_angle`` None: the rest angles and horns are then derived.
    """

    rest_angle: float | None = paper.REST_ANGLE
    horn_length: float = paper.HORN_LENGTH
    angle_min: float = paper.ANGLE_MIN
    angle_max: float = paper.ANGLE_MAX
    servo_radius: float | None = None
    servo_depth: float | None = None

    def __post_init__(self):
        check_range("horn_length", self.horn_length, 0.0, None, lo_open=True)
        check_range("angle_min", self.angle_min, -180.0, 180.0)
        check_range("angle_max", self.angle_max, self.angle_min, 180.0, lo_open=True)
        if self.on_circle:
            if self.rest_angle is not None:
                raise ConfigError(f"rest_angle: {self.rest_angle!r}: must be None when servo_radius/servo_depth "
                                  "place the servos (the rest angle is then derived)")
            if self.servo_radius is None or self.servo_depth is None:
                raise ConfigError(f"servo_radius/servo_depth: ({self.servo_radius!r}, {self.servo_depth!r}): "
                                  "give both or neither")
            check_range("servo_radius", self.servo_radius, 0.0, 1000.0, lo_open=True)
            check_range("servo_depth", self.servo_depth, 0.0, 1000.0, lo_open=True)
            return
        if self.rest_angle is None:
            raise ConfigError("rest_angle: None: give a rest angle [deg] or servo_radius and servo_depth [mm]")
        check_range("rest_angle", self.rest_angle, -180.0, 180.0)
        check_range("rest_angle", self.rest_angle, self.angle_min, self.angle_max)

    @property
    def on_circle(self) -> bool:
        """True when the pivots are given (servo_radius, servo_depth), not the rest angle."""
        return self.servo_radius is not None or self.servo_depth is not None


@dataclass(frozen=True)
class Robot:
    """A soft robot: one elastic body, its rigid couplings and its actuation limits.

    Attributes
    ----------
    name : "tripod" or "six_dof" (or a user's).
    body : the FEM body (:class:`metasheet.robot.body.ElasticBody` or compatible).
    coupling : :class:`RigidCoupling` (effector + servos).
    gravity : (3,) [mm/s^2].
    angle_min, angle_max : (na,) motor limits [rad].
    axis : (3,) the effector axis of interest (rod axis / tripod normal).
    info : JSON-able description of the geometry (pivots, rest angles...).
    f_ext : (n, 3) nodal gravity forces [N] (derived from ``body`` and ``gravity``).
    """

    name: str
    body: object
    coupling: RigidCoupling
    gravity: np.ndarray
    angle_min: np.ndarray
    angle_max: np.ndarray
    axis: np.ndarray
    info: dict = field(default_factory=dict)

    @cached_property
    def f_ext(self) -> np.ndarray:
        """(n, 3) external nodal forces [N]: the lumped weight ``M g`` of eq. (1)."""
        return np.asarray(self.body.gravity(tuple(self.gravity)), float).reshape(-1, 3)

    def rest_state(self):
        """The undeformed configuration (motors at their rest angles, no gravity sag)."""
        from .statics import RobotState

        c = self.coupling
        return RobotState(c.origin.copy(), np.eye(3), c.rest_angles.copy(), c.rest.copy())

    def linearizer(self, solver: str = "superlu"):
        """A fresh :class:`metasheet.robot.statics.Linearizer` for this robot (``solver``: its
        sparse solver, :data:`metasheet.fem.factor.FACTOR_SOLVERS`)."""
        from .statics import Linearizer

        return Linearizer(self, solver=solver)


def _rotate_local(C, Q) -> np.ndarray:
    """(m, 6, 6) or (6, 6) Voigt stiffness in a frame rotated by Q (3, 3) (local -> world)."""
    Qm = mandel_rotation(Q[None])[0]
    Cm = np.asarray(C, float) * MANDEL
    return np.einsum("IK,...KL,JL->...IJ", Qm, Cm, Qm) / MANDEL


def _check_sheet(sheet, stiffness, label):
    pts, tets, att = np.asarray(sheet.points, float), np.asarray(sheet.tets), np.asarray(sheet.attach)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ConfigError(f"{label}.points: shape is {pts.shape} and should be (n, 3)")
    if att.shape != (len(pts),):
        raise ConfigError(f"{label}.attach: shape is {att.shape} and should be ({len(pts)},)")
    for tag in range(1, 5):
        if not np.any(att == tag):
            raise ConfigError(f"{label}.attach: no node tagged {tag} (1-3 arm tips, 4 centre)")
    C = np.asarray(stiffness, float)
    if C.shape not in ((6, 6), (len(tets), 6, 6)):
        raise ConfigError(f"{label} stiffness: shape is {C.shape} and should be (6, 6) or ({len(tets)}, 6, 6)")
    if C.ndim == 2:
        C = np.broadcast_to(C, (len(tets), 6, 6))
    return pts, tets, att, C


def grip_centre(points, tets, attach, tag: int) -> np.ndarray:
    """(3,) volume centroid [mm] of the elements whose vertices all carry ``tag``: the grip
    region's centre. Unlike the mean of its nodes it does not move with how the mesh spreads
    nodes inside the region (on a sheet meshed conforming to the grip, it is the region's
    own centroid on every mesh); falls back to the node mean when no element is inside."""
    v = np.asarray(tets)[:, :4]
    inside = np.all(np.asarray(attach)[v] == tag, axis=1)
    if not np.any(inside):
        return np.asarray(points)[np.asarray(attach) == tag].mean(axis=0)
    X = np.asarray(points)[v[inside]]
    vol = np.abs(np.linalg.det(X[:, 1:] - X[:, :1]))
    return (vol[:, None] * X.mean(axis=1)).sum(axis=0) / vol.sum()


def _servos(pts_world, tets, att, arm_angles, Q, centre, geo: ServoGeometry, offset: int, label):
    """Servos of one sheet placed by Q (local -> world) at ``centre`` (3,) [mm]."""
    n = Q[:, 2]
    servos, info = [], []
    for k, phi in enumerate(arm_angles):
        nodes = np.flatnonzero(att == k + 1)
        u = Q @ np.array([np.cos(phi), np.sin(phi), 0.0])
        tip = grip_centre(pts_world, tets, att, k + 1)
        r_tip = float(np.dot(tip - centre, u))
        if geo.on_circle:  # the pivot is given: horn and rest angle follow from the tip box
            pivot = centre + geo.servo_radius * u - geo.servo_depth * n
            v = tip - pivot
            th0, horn = float(np.arctan2(np.dot(v, n), -np.dot(v, u))), float(np.linalg.norm(v))
        else:
            th0, horn = float(np.radians(geo.rest_angle)), geo.horn_length
            pivot = tip - horn * (-np.cos(th0) * u + np.sin(th0) * n)
        servos.append(Servo(np.cross(n, u), pivot, horn, th0, nodes + offset))
        in_plane = (pivot - centre) - np.dot(pivot - centre, n) * n  # the servo circle's radius
        info.append({"sheet": label, "arm": k, "pivot_mm": pivot.round(3).tolist(),
                     "axis": np.cross(n, u).round(6).tolist(), "rest_angle_deg": round(np.degrees(th0), 3),
                     "horn_length_mm": round(horn, 3), "servo_radius_mm": round(float(np.linalg.norm(in_plane)), 3),
                     "servo_depth_mm": round(float(-np.dot(pivot - centre, n)), 3),
                     "tip_radius_mm": round(r_tip, 3)})
    return servos, info


def _make_robot(name, pts, tets, C, eff_nodes, origin, servos, info, geo, gravity, axis, density, extra=None):
    from .body import ElasticBody

    body = ElasticBody(pts, tets, C, density=density)
    coupling = RigidCoupling(pts, eff_nodes, origin, servos)
    na = len(servos)
    lo, hi = np.full(na, np.radians(geo.angle_min)), np.full(na, np.radians(geo.angle_max))
    th0 = coupling.rest_angles
    if np.any(th0 < lo - 1e-12) or np.any(th0 > hi + 1e-12):
        raise ConfigError(
            f"angle_min/angle_max: [{geo.angle_min}, {geo.angle_max}] deg: must contain the rest angles "
            f"{np.degrees(th0).round(2).tolist()} deg")
    radii = [sv["servo_radius_mm"] for sv in info]
    sg = {"rest_angle_deg": geo.rest_angle, "horn_length_mm": geo.horn_length,
          "angle_min_deg": geo.angle_min, "angle_max_deg": geo.angle_max,
          "servo_radius_mm_derived": round(float(np.mean(radii)), 3)}
    if geo.on_circle:  # the given pivots; the mean derived rest angle and horn
        sg.update({"servo_radius_mm": geo.servo_radius, "servo_depth_mm": geo.servo_depth,
                   "rest_angle_deg": None,
                   "rest_angle_deg_derived": round(float(np.degrees(np.mean(th0))), 3),
                   "horn_length_mm_derived": round(float(np.mean([sv["horn_length_mm"] for sv in info])), 3)})
    info = {"servo_geometry": sg,
            "servos": info, **info_extra(pts, tets, eff_nodes, density), **(extra or {})}
    return Robot(name, body, coupling, np.asarray(gravity, float), lo, hi, np.asarray(axis, float), info)


def info_extra(pts, tets, eff, density) -> dict:
    return {"n_nodes": int(len(pts)), "n_tets": int(len(tets)), "n_effector_nodes": int(len(eff)),
            "density_t_per_mm3": density}


def tripod(sheet, stiffness, *, geometry: ServoGeometry = ServoGeometry(), density: float = TPU_DENSITY,
           gravity=(0.0, 0.0, -GRAVITY)) -> Robot:
    """A single tripod: the sheet horizontal at z = 0, servos below, effector = sheet centre.

    Parameters
    ----------
    sheet : object with ``points`` (n, 3) [mm], ``tets`` (m, 4), ``attach`` (n,), ``arm_angles`` (3,) [rad]
        (a :class:`metasheet.sheet.geometry.SheetMesh`).
    stiffness : (m, 6, 6) or (6, 6) Voigt stiffness in the sheet frame [MPa].
    density : [t/mm^3]. gravity : (3,) [mm/s^2].
    """
    pts, tets, att, C = _check_sheet(sheet, stiffness, "sheet")
    Q = np.eye(3)
    servos, info = _servos(pts, tets, att, sheet.arm_angles, Q, np.zeros(3), geometry, 0, "sheet")
    return _make_robot("tripod", pts, tets, C, np.flatnonzero(att == 4), np.zeros(3), servos, info,
                       geometry, gravity, (0.0, 0.0, 1.0), density)


#: sheet A's local -> world rotation in the 6-DOF robot: (x, y, z) -> (-z, y, x)
Q_A = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
#: sheet B's: A's turned 180 degrees about world z
Q_B = np.diag([-1.0, -1.0, 1.0]) @ Q_A


def six_dof(sheet_a, stiffness_a, sheet_b, stiffness_b, *, rod_length: float = paper.ROD_LENGTH,
            geometry: ServoGeometry = ServoGeometry(), density: float = TPU_DENSITY,
            gravity=(0.0, 0.0, -GRAVITY)) -> Robot:
    """The paper's 6-DOF robot: two tripods facing each other joined by a rigid rod along x.

    ``sheet_b`` should be the mirrored sheet (y -> -y, with the mirrored fibre field in
    ``stiffness_b``); motors 0-2 belong to sheet A (at x = -rod_length/2), 3-5 to sheet B.
    The effector is the rod centre (origin); both sheets' centre nodes belong to it.
    """
    check_range("rod_length", rod_length, 0.0, 1000.0, lo_open=True)
    pa, ta, aa, Ca = _check_sheet(sheet_a, stiffness_a, "sheet_a")
    pb, tb, ab, Cb = _check_sheet(sheet_b, stiffness_b, "sheet_b")
    half = 0.5 * rod_length
    ca, cb = np.array([-half, 0.0, 0.0]), np.array([half, 0.0, 0.0])
    wa, wb = pa @ Q_A.T + ca, pb @ Q_B.T + cb
    if np.max(np.abs(pa[:, 2])) >= half:
        raise ConfigError(f"rod_length: {rod_length!r}: the sheets would overlap; allowed > "
                          f"{2 * np.max(np.abs(pa[:, 2])):.1f} mm")
    sa, ia = _servos(wa, ta, aa, sheet_a.arm_angles, Q_A, ca, geometry, 0, "A")
    sb, ib = _servos(wb, tb, ab, sheet_b.arm_angles, Q_B, cb, geometry, len(pa), "B")
    pts = np.vstack([wa, wb])
    tets = np.vstack([ta, np.asarray(tb) + len(pa)])
    C = np.concatenate([_rotate_local(Ca, Q_A), _rotate_local(Cb, Q_B)])
    eff = np.concatenate([np.flatnonzero(aa == 4), np.flatnonzero(ab == 4) + len(pa)])
    extra = {"rod_length_mm": rod_length, "n_tets_per_sheet": [int(len(ta)), int(len(tb))],
             "sheet_centres_mm": [ca.tolist(), cb.tolist()]}
    return _make_robot("six_dof", pts, tets, C, eff, np.zeros(3), sa + sb, ia + ib, geometry, gravity,
                       (1.0, 0.0, 0.0), density, extra)
