"""The equilibrium surface as a robot: the interface the equilibrium solver and the inverse
controller use (:class:`metasheet.robot.robots.Robot`, :class:`metasheet.robot.statics.Linearizer`),
on a :class:`.surface.Surface`.

A state is the effector pose and the motor angles; the sheets are not represented. Its
"residual" is the effector's offset e from the surface at the state's angles, as a force:
``res_e = -S_ee e``, so that one Newton step (:meth:`metasheet.robot.statics.Linearization.newton_step`,
``dq_e = e + J dq_a``) lands on the surface and the control loop's predictor is the surface's
own tangent. Every linearisation is exact and costs one polynomial evaluation: there is no
factorisation to keep, and no tangent refresh lands in a control step.

The surface holds within its motor box only: the robot's motor limits are the box (within
the motors' range), so the inverse QP never leaves it, and :meth:`SurfaceRobot.check` refuses
angles outside it, never extrapolating.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, ConvergenceError
from ..robot.statics import Linearization
from ..mechanics.rotations import rotation_matrix, rotation_vector
from .surface import EquilibriumData, Surface


@dataclass(frozen=True)
class SurfaceState:
    """Effector ``p`` (3,) [mm] and ``R`` (3, 3), motor ``angles`` (na,) [rad]."""

    p: np.ndarray
    R: np.ndarray
    angles: np.ndarray

    @property
    def pose(self) -> np.ndarray:
        """(6,) effector pose: position [mm] and rotation vector [rad]."""
        return np.concatenate([self.p, rotation_vector(self.R)])


class SurfaceRobot:
    """A :class:`.surface.Surface` behind the robot interface (see the module docstring).

    ``robot`` : the full or reduced robot it was fitted on (coupling, name, motor range);
    ``force_scale`` [N]: the rest equilibrium's force scale (:func:`metasheet.robot.statics.force_scale`),
    the reference of the equilibrium tolerance.
    """

    def __init__(self, surface: Surface, robot, force_scale: float):
        if surface.na != robot.coupling.n_act:
            raise ConfigError(f"surface: fitted for {surface.na} motors, the robot has {robot.coupling.n_act}")
        if not force_scale > 0:
            raise ConfigError(f"force_scale: {force_scale!r}: must be > 0 [N]")
        self.surface, self.coupling = surface, robot.coupling
        self.full = getattr(robot, "full", robot)  # the model that solves outside the box
        lo, hi = surface.box
        self.angle_min = np.maximum(np.asarray(robot.angle_min, float), lo)
        self.angle_max = np.minimum(np.asarray(robot.angle_max, float), hi)
        self.name = getattr(robot, "name", "robot") + "_surface"
        self.info = {**getattr(robot, "info", {}), "surface": dict(surface.info)}
        self.gravity, self.axis = getattr(robot, "gravity", None), getattr(robot, "axis", None)
        self.ref = float(force_scale)
        self._last = (None, None)  # (angles' bytes, evaluation): a solve linearises at fixed angles

    def evaluate(self, angles) -> tuple:
        """The surface's (p, R, J, S) at motor ``angles`` (na,) [rad] inside its box
        (:meth:`.surface.Surface.evaluate`); the last one is kept: an equilibrium solve
        and a control step evaluate the same angles several times."""
        a = self.check(angles)
        key = a.tobytes()
        last_key, value = self._last
        if key != last_key:
            value = self.surface.evaluate(a)
            self._last = (key, value)
        return value

    def check(self, angles) -> np.ndarray:
        a = np.asarray(angles, float).reshape(-1)
        if a.shape != (self.coupling.n_act,) or not self.surface.in_box(a, tol=1e-6):
            lo, hi = self.surface.box
            raise ConfigError(f"angles: {np.degrees(a).round(2).tolist()} deg: the surface holds within its box "
                              f"{np.degrees(lo).round(2).tolist()}..{np.degrees(hi).round(2).tolist()} deg")
        return a

    def rest_state(self) -> SurfaceState:
        """The rest equilibrium (motors at their rest angles)."""
        return self.equilibrium(self.coupling.rest_angles)

    def equilibrium(self, angles) -> SurfaceState:
        """The equilibrium at motor ``angles`` (na,) [rad]: the surface itself."""
        p, R, _, _ = self.evaluate(angles)
        return SurfaceState(p, R, np.array(angles, float))

    def linearizer(self, solver: str = "superlu") -> "SurfaceLinearizer":
        return SurfaceLinearizer(self)


class SurfaceLinearizer:
    """The :class:`metasheet.robot.statics.Linearizer` interface on a :class:`SurfaceRobot`: dense, exact, cheap."""

    solver_name = "surface"

    def __init__(self, robot: SurfaceRobot):
        self.robot = robot
        self.factorizations = 0  # stays 0: nothing is factorised, no kept tangent goes stale

    def uses(self, solver: str) -> bool:
        return True

    def linearize(self, state: SurfaceState, *, exact: bool = True) -> Linearization:
        rob = self.robot
        p, R, _, S = rob.evaluate(state.angles)
        e = np.concatenate([p - state.p, rotation_vector(R @ state.R.T)])
        g = -S[:, :6] @ e  # the offset as the forces that pull the effector onto the surface
        return Linearization(state=state, r=g, S=S, Y=np.zeros((0, len(S))), y_r=np.zeros(0),
                             C=np.zeros((len(S), 0)), R_rigid=g, res_e=g[:6], res_f=np.zeros(0), fresh=True,
                             moment_scale=rob.coupling.length_scale, exact=True)

    def update(self, lin: Linearization, state: SurfaceState, f=None) -> Linearization:
        return self.linearize(state)

    def apply(self, state: SurfaceState, dq_e, dx_f, dq_a=None, alpha: float = 1.0) -> SurfaceState:
        p = state.p + alpha * dq_e[:3]
        R = rotation_matrix(alpha * dq_e[3:]) @ state.R
        angles = state.angles if dq_a is None else state.angles + dq_a
        return SurfaceState(p, R, angles)

    def force_scale(self, lin: Linearization) -> float:
        return self.robot.ref

    def residual_floor(self, lin: Linearization) -> float:
        """Round-off of the offset's force: eps times the largest stiffness times the position."""
        eps = np.finfo(float).eps
        return float(10 * eps * np.abs(lin.S[:6, :6]).max() * max(float(np.abs(lin.state.p).max()), 1.0))


def equilibrium_data(robot, angles: np.ndarray, *, linearizer=None, start=None, strain=None) -> EquilibriumData:
    """Equilibria of ``robot`` at motor ``angles`` (s, na) [rad], each solved by continuation
    from the nearest one already solved (the first from ``start``, default the rest state),
    with its Jacobian, condensed tangent and, given ``strain`` (state -> [-]), strain. Raises :class:`~metasheet.errors.ConvergenceError`
    naming the angles where no equilibrium is found."""
    from ..robot.equilibrium import solve_equilibrium
    from ..robot.kinematics import jacobian_from_schur

    lz = linearizer or robot.linearizer()
    angles = np.atleast_2d(np.asarray(angles, float))
    states, lins, poses, Js, Ss = [], [], [], [], []
    for q in angles:
        st, lin = start, None
        if states:
            near = int(np.argmin([np.abs(s.angles - q).max() for s in states]))
            st, lin = states[near], lins[near]  # its fresh linearisation starts the predictor
        try:
            eq = solve_equilibrium(robot, q, state=st, linearizer=lz, start=lin)
        except ConvergenceError as err:
            raise ConvergenceError(f"surface training: no equilibrium at motors {np.degrees(q).round(2).tolist()} "
                                   f"deg: {err}", err.history) from err
        lin = eq.linearization
        if lin is None or not (lin.fresh and lin.exact):  # the solve ended on a chord step
            lin = lz.linearize(eq.state)
        states.append(eq.state)
        lins.append(lin)
        poses.append(eq.state.pose)
        Js.append(jacobian_from_schur(lin.S)[1])
        Ss.append(lin.S)
    strains = None if strain is None else np.array([strain(s) for s in states])
    return EquilibriumData(angles, np.array(poses), np.array(Js), np.array(Ss), strains)


def fit_surface_robot(robot, train: EquilibriumData, check: EquilibriumData, box_lo, box_hi, targets: dict, *,
                      strain_limit: float | None = None) -> SurfaceRobot:
    """The :class:`SurfaceRobot` of ``robot`` fitted on ``train``, its degree chosen on ``check``
    (:func:`.surface.choose_degree`) over the box [lo, hi] (na,) [rad]; its rest equilibrium's
    force scale, the equilibrium tolerance's reference, goes into the surface's record."""
    from dataclasses import replace

    from ..robot.equilibrium import solve_equilibrium
    from .surface import choose_degree

    lz = robot.linearizer()
    rest = solve_equilibrium(robot, robot.coupling.rest_angles, linearizer=lz).state
    rest_data = equilibrium_data(robot, robot.coupling.rest_angles[None], linearizer=lz, start=rest)
    surface = choose_degree(train, check, rest_data, box_lo, box_hi, targets, strain_limit=strain_limit)
    ref = lz.force_scale(lz.linearize(rest))
    return SurfaceRobot(replace(surface, info={**surface.info, "force_scale_N": ref}), robot, force_scale=ref)


def load_surface(path, robot) -> SurfaceRobot:
    """The :class:`SurfaceRobot` of a reduce stage's ``surface.npz`` on ``robot`` (the robot it
    was fitted for: its coupling and motor range)."""
    from pathlib import Path

    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{path}: missing: run the pipeline's reduce stage")
    surface = Surface.load(path)
    return SurfaceRobot(surface, robot, force_scale=float(surface.info.get("force_scale_N", 0.0)))
