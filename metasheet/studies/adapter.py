"""The real 6-DOF robot (:mod:`metasheet.robot`) as a :class:`~.model.RobotModel`.

:class:`RobotSpec` is the picklable recipe (sheet meshes as arrays, fibre fields, the
material's five constants, servo geometry, inverse settings); :class:`FemRobot` is the live
robot built from it in each worker: the FEM body, one linearizer (cached factorisation
pattern) and the eq. (8) controller. States are :class:`metasheet.robot.statics.RobotState`.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from ..published import paper
from ..conventions import GRAVITY
from ..errors import ConfigError, ConvergenceError
from ..mechanics.material import Isotropic, TransverseIsotropic, interpolate
from ..mechanics.material_model import check_model
from ..robot.builder import SheetPair
from ..robot.validity import GRIP_BAND_MM
from ..sheet.geometry import SheetMesh
from .model import ReachResult, check_motor_range, pose_errors


@dataclass(frozen=True, eq=False)
class RobotSpec:
    """Recipe of the 6-DOF robot.

    Attributes
    ----------
    points, tets, attach : the sheet mesh ((n, 3) [mm], (m, 4), (n,) tags 0-4); arm_angles (3,) [rad].
    element : "p1" or "p2", the robot's element on that mesh (:class:`~metasheet.robot.builder.SheetPair`).
    points_m, tets_m, attach_m : the mirrored sheet.
    fibers, fibers_m : (m, 3) unit fibre directions of each sheet (local axis 3).
    material : (E_t, E_l, nu_t, nu_tl, mu_l) [MPa, -] of the sheets (transverse isotropic).
    design : the design material's constants (the anisotropy sweep interpolates from it).
    rod_length [mm]; rest_angle [deg] (places the servos, see :mod:`metasheet.robot.robots`);
    horn_length [mm]; or servo_radius, servo_depth [mm] (pivots given, rest_angle None);
    motor_range (lo, hi) [deg]; density [t/mm^3]; gravity (3,) [mm/s^2].
    consts, consts_m : optional (m, 5) per-element constants of a graded design (the orient
    stage's); when given they replace ``material`` until ``with_alpha``/``with_material``.
    model : the material model, "ours" or "authors" (:mod:`metasheet.mechanics.material_model`).
    strain_band_mm : the band along the grips the strain-validity check leaves out [mm]
    (:mod:`metasheet.robot.validity`; 0: every element).
    rot_weight [mm/rad], max_step_deg [deg], stall_steps, refresh_angle_deg [deg]: inverse-loop
    settings. A goal counts as unreachable after ``stall_steps`` steps without progress (the
    controller's default 15 makes every unreachable workspace point cost 15+ FEM steps). The
    kept tangent is refreshed after ``refresh_angle_deg`` of motor motion (controller default
    8): a fresh one costs ~20 chord steps on the paper's mesh, and the loop's residual and
    drift tests still guard every kept step. Measured on the 14 mm mesh, 24 workspace points
    with rotations: (stall 6, refresh 8) -> (4, 15) took 42 -> 36 fresh linearisations per
    point, and 23 instead of 21 of the 72 rotation axes passed (different paths, same tolerances).
    ``chord_tol`` (controller default 1.0): a kept step's residual may reach this fraction of the
    force scale; at 1.0 the failed (stalled) trials end far from equilibrium and their
    certification falls back to the line-searched Newton solve (~11 fresh tangents each on the
    paper's mesh); 0.3 took the paper mesh from 55 to 48 fresh linearisations per point
    (Newton fallbacks 54 -> 22 on 24 points; 22 instead of 24 of 72 axes passed).
    """

    points: np.ndarray
    tets: np.ndarray
    attach: np.ndarray
    arm_angles: np.ndarray
    points_m: np.ndarray
    tets_m: np.ndarray
    attach_m: np.ndarray
    fibers: np.ndarray
    fibers_m: np.ndarray
    material: tuple
    design: tuple
    rod_length: float = paper.ROD_LENGTH
    rest_angle: float | None = paper.REST_ANGLE
    horn_length: float = paper.HORN_LENGTH
    servo_radius: float | None = None
    servo_depth: float | None = None
    gravity: tuple = (0.0, 0.0, -GRAVITY)
    motor_range: tuple = (paper.ANGLE_MIN, paper.ANGLE_MAX)
    density: float = paper.FOAM_DENSITY
    rot_weight: float = 50.0
    max_step_deg: float = 5.0
    stall_steps: int = 4
    refresh_angle_deg: float = 15.0
    chord_tol: float = 0.3
    consts: np.ndarray | None = None
    consts_m: np.ndarray | None = None
    element: str = "p1"
    model: str = "ours"
    strain_band_mm: float = GRIP_BAND_MM

    def __post_init__(self):
        check_motor_range("motor_range", *self.motor_range)
        check_model(self.model, "model")
        for name in ("material", "design"):
            if len(getattr(self, name)) != 5:
                raise ConfigError(f"{name}: {getattr(self, name)!r}: expected (E_t, E_l, nu_t, nu_tl, mu_l)")
        TransverseIsotropic(*self.material)  # validates the constants

    @property
    def key(self) -> str:
        h = hashlib.sha256()
        for a in (self.points, self.tets, self.attach, self.arm_angles, self.points_m, self.tets_m,
                  self.attach_m, self.fibers, self.fibers_m):
            h.update(np.ascontiguousarray(a).tobytes())
        for a in (self.consts, self.consts_m):
            h.update(b"-" if a is None else np.ascontiguousarray(a).tobytes())
        h.update(repr((self.material, self.design, self.rod_length, self.rest_angle, self.horn_length,
                       self.servo_radius, self.servo_depth, tuple(self.gravity), self.motor_range, self.density,
                       self.rot_weight, self.max_step_deg, self.stall_steps, self.refresh_angle_deg, self.chord_tol,
                       self.element, self.model, self.strain_band_mm)).encode())
        return "fem-" + h.hexdigest()[:24]

    @property
    def design_alpha(self) -> float:
        return TransverseIsotropic(*self.design).alpha

    def build(self) -> "FemRobot":
        return FemRobot(self)

    def with_motor_range(self, lo_deg: float, hi_deg: float) -> "RobotSpec":
        return replace(self, motor_range=(float(lo_deg), float(hi_deg)))

    def with_alpha(self, alpha: float) -> "RobotSpec":
        m = interpolate(TransverseIsotropic(*self.design), float(alpha))
        return replace(self, material=m.as_tuple(), consts=None, consts_m=None)

    def with_material(self, material, density: float | None = None) -> "RobotSpec":
        """Another sheet material (and density [t/mm^3], default unchanged)."""
        if isinstance(material, Isotropic):
            material = material.as_transverse()
        return replace(self, material=material.as_tuple(), consts=None, consts_m=None,
                       density=self.density if density is None else float(density))

    @classmethod
    def from_sheets(cls, sheets: SheetPair, material, **kw) -> "RobotSpec":
        """From a :class:`~metasheet.robot.builder.SheetPair` and the design ``material``; the
        pair's per-element constants (a graded design), when it has them, drive the robot."""
        if isinstance(material, Isotropic):
            material = material.as_transverse()
        c = material.as_tuple()
        a, b = sheets.sheet, sheets.mirrored
        return cls(np.asarray(a.points, float), np.asarray(a.tets), np.asarray(a.attach),
                   np.asarray(a.arm_angles, float), np.asarray(b.points, float), np.asarray(b.tets),
                   np.asarray(b.attach), np.asarray(sheets.fibers, float), np.asarray(sheets.fibers_mirrored, float),
                   c, kw.pop("design", c), consts=sheets.constants, consts_m=sheets.constants_mirrored,
                   element=sheets.element, **kw)

    def sheets(self) -> SheetPair:
        """The sheet pair again (per-element constants only when they drive the robot)."""
        graded = self.consts is not None and self.consts_m is not None
        return SheetPair(SheetMesh(self.points, self.tets, self.attach, self.arm_angles),
                         SheetMesh(self.points_m, self.tets_m, self.attach_m, self.arm_angles),
                         self.fibers, self.fibers_m, self.consts if graded else None,
                         self.consts_m if graded else None, self.element)


class FemRobot:
    """The FEM robot of a :class:`RobotSpec` behind the study protocol."""

    pull_sign = 1.0  # towards 90 deg the horn lifts the arm tip outwards: it stretches the arm
    _last_equilibrium = None  # the last :meth:`equilibrium`'s solve (its state's linearisation)

    def __init__(self, spec: RobotSpec):
        from ..robot.builder import six_dof_robot
        from ..robot.inverse import InverseController
        from ..robot.inverse_settings import InverseSettings
        from ..robot.robots import ServoGeometry

        self.spec = spec
        sheets = spec.sheets()
        # graded: the sheets' per-element constants; else the spec's material
        mat = None if sheets.has_constants else TransverseIsotropic(*spec.material)
        if spec.servo_radius is not None:  # pivots given: the rest angles follow (limits set below)
            geo = ServoGeometry(None, spec.horn_length, -180.0, 180.0, servo_radius=spec.servo_radius,
                                servo_depth=spec.servo_depth)
        else:
            geo = ServoGeometry(spec.rest_angle, spec.horn_length, min(paper.ANGLE_MIN, spec.rest_angle),
                                max(paper.ANGLE_MAX, spec.rest_angle))
        self.robot = six_dof_robot(sheets, mat, rod_length=spec.rod_length, geometry=geo, density=spec.density,
                                   gravity=spec.gravity, model=spec.model)
        # the limits may exclude the rest angles (the motor-range study): set them after the build
        na = len(self.robot.angle_min)
        self.robot = replace(self.robot, angle_min=np.full(na, np.radians(spec.motor_range[0])),
                             angle_max=np.full(na, np.radians(spec.motor_range[1])))
        self.settings = InverseSettings(rot_weight=spec.rot_weight, max_step_deg=spec.max_step_deg,
                                        stall_steps=spec.stall_steps, refresh_angle_deg=spec.refresh_angle_deg,
                                        chord_tol=spec.chord_tol)
        self.ctrl = InverseController(self.robot, settings=self.settings)
        self.lz = self.ctrl.linearizer
        self.rest = self.ctrl.state
        self.motor_range = tuple(spec.motor_range)
        ax = np.abs(self.robot.axis)
        self.rod_axis = int(np.argmax(ax))

    def rest_pose(self) -> np.ndarray:
        return self.rest.pose.copy()

    def rest_motors(self) -> np.ndarray:
        return np.degrees(self.rest.angles)

    def reach(self, goal, *, state=None, tol_mm=1.0, tol_deg=None, max_steps=50, rot_weight=None,
              stop=None, certify_stop: bool = True) -> ReachResult:
        """The inverse controller's run towards ``goal`` (6,) [mm, rad] from ``state`` (None: rest);
        ``stop(state) -> bool`` ends it before a step that makes it True (``stopped``; its state
        certified as an equilibrium unless ``certify_stop`` is False)."""
        goal = np.asarray(goal, float)
        # rot_weight 0 (position only) becomes a tiny weight: the controller needs w > 0
        rw = self.settings.rot_weight if rot_weight is None else max(float(rot_weight), 1e-6)
        # a little inside the tolerance: the loop stops on its one-Newton-step state
        settings = replace(self.settings, rot_weight=rw, pos_tol=0.9 * tol_mm,
                           rot_tol_deg=180.0 if tol_deg is None else 0.9 * tol_deg, max_steps=int(max_steps))
        goal_deg = np.concatenate([goal[:3], np.degrees(goal[3:])])
        converged = True
        steps0 = self.ctrl.total_steps
        try:
            # continuation: a state this controller produced (the previous point on a ray, the
            # point a rotation is tried from) keeps its tangent; the loop still checks it
            r = self.ctrl.goto(goal_deg, state=self.rest if state is None else state, settings=settings, stop=stop,
                               certify_stop=certify_stop)
            st, steps, stopped = r.state, r.steps, r.status == "stopped"
        except ConvergenceError:  # the final equilibrium failed: report the last control state
            st, steps, converged, stopped = self.ctrl.state, self.ctrl.total_steps - steps0, False, False
        pose = st.pose
        e_mm, e_deg = pose_errors(goal, pose)
        # a stopped run's uncertified control state is not an equilibrium: never reached
        ok = converged and not (stopped and not certify_stop) and e_mm <= tol_mm and (tol_deg is None or e_deg <= tol_deg)
        return ReachResult(ok, pose, np.degrees(st.angles), e_mm, e_deg, int(steps), st, converged, stopped=stopped)

    def equilibrium(self, motors_deg, *, state=None, intermediate: bool = False):
        from ..robot.equilibrium import PATH_TOL, solve_equilibrium

        tol = {"tol": PATH_TOL} if intermediate else {}
        start = self.rest if state is None else state
        last = self._last_equilibrium  # a path's next step starts on the tangent its last one ended on
        carried = last.linearization if last is not None and last.state is start else None
        eq = solve_equilibrium(self.robot, np.radians(np.asarray(motors_deg, float)), state=start,
                               linearizer=self.lz, start=carried, **tol)
        self._last_equilibrium = eq
        return eq.state.pose, eq.state

    @cached_property
    def strain_elements(self) -> np.ndarray:
        """(m,) bool: the elements the strain-validity check counts (:mod:`metasheet.robot.validity`)."""
        from ..robot.validity import validity_elements

        return validity_elements(self.robot, self.spec.strain_band_mm)

    def max_principal_strain(self, state) -> float:
        """Largest principal Green-Lagrange strain over the sheets' quadrature points [-], away
        from the grips' clamped edges (``spec.strain_band_mm``, :mod:`metasheet.robot.validity`).
        An equal state's strain (the study asks again for the state a reach stopped at) is kept."""
        from ..robot.validity import validity_strain

        return remembered_strain(self._strains, state, lambda: validity_strain(self.robot.body, state.x,
                                                                               self.strain_elements))

    @cached_property
    def _strains(self):
        """The strains [-] of the last 8 states, by their arrays' digest (:mod:`metasheet.robot.memo`)."""
        from ..robot.memo import LinearizationMemo

        return LinearizationMemo(size=8)

    def min_singular_value(self, state) -> float:
        """Smallest singular value of the Jacobian scaled by diag(1, 1, 1, 50 mm) [mm/rad].

        The fresh linearisation it needs is handed to the controller, so the goals tried next
        from ``state`` (the rotations at a workspace point) start on it.
        """
        from ..robot.kinematics import kinematics

        lin = self.ctrl.refresh(state)
        if not lin.exact:  # a modified-Newton factor (CHOLMOD): the Jacobian needs the exact one
            lin = self.lz.linearize(state)
        return float(kinematics(lin).singular_values.min())


def remembered_strain(memo, state, compute) -> float:
    """``compute()``, the strain [-] at ``state``, or the one ``memo`` (a
    :class:`~metasheet.robot.memo.LinearizationMemo`) kept for an equal state (a pure function
    of the state's arrays: the same value)."""
    from ..robot.memo import state_key

    key = state_key(state, True)
    got = memo.get(key)
    if got is None:
        got = float(compute())
        memo.put(key, got)
    return got


def paper_robot_spec(*, mesh_size: float = 5.0, rest_angle: float = paper.REST_ANGLE, material=None,
                     pitch_deg: float = 45.0, layers: int = 0, element: str = "p1", **kw) -> RobotSpec:
    """The paper's robot built in memory (no pipeline): default sheet, spiral fibres, the
    paper's foam (or ``material``), motors at rest at ``rest_angle`` [deg] on every mesh.
    For tests and benchmarks; the stages build their spec from the orient stage's sheets.
    """
    from ..sheet.outline import SheetParams

    sheets = SheetPair.spiral(SheetParams(mesh_size=mesh_size, layers=layers), element, pitch_deg=pitch_deg)
    return RobotSpec.from_sheets(sheets, material or paper.PAPER_FOAM, rest_angle=float(rest_angle), **kw)
