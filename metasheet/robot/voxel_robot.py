"""The printed robot at any motor pose: its two printed sheets as finite-strain voxel bodies
(:mod:`metasheet.sheet.voxel_grips_nonlinear`) held by the rod and the six horns (issue 62).

The robot's geometry is the six-DOF robot's (:func:`metasheet.robot.builder.six_dof_robot`:
its sheet frames ``Q_A``, ``Q_B`` and centres, the servos' axes and pivots, the effector's
reference point), exactly as the linear rest model from condensed sheets uses it
(:mod:`.condensed`), now with finite motions:

* the centre grip of either sheet moves rigidly with the effector: the rod turned by ``R_e``
  (rotation vector ``theta_e``) about its reference point ``o`` and moved by ``dp``;
* arm k's grip moves rigidly with its horn: a rotation by the motor's change ``dphi`` about the
  servo's axis through its pivot (position-controlled servos: the motor angles are given).

Each sheet's grips carry wrenches; the rod is in equilibrium when the two centre grips' wrenches,
taken to the world about the moved ``o``, sum to zero (no gravity: as the linear rest model).
The six unknowns (``dp``, ``theta_e``) are found by a quasi-Newton iteration (Broyden's good
update) started from the rest Schur complement's effector block, the linear condensed model's
(given, or by finite differences). The sheets' voxel solutions warm-start each other pose to
pose.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError, ConvergenceError, check_range
from ..fem.voxel.hyperelastic import NeoHookean
from ..mechanics.rotations import axis_rotation, rotation_matrix
from ..sheet.voxel_grips_nonlinear import GripBody
from .condensed import _check_robot
from .robots import Q_A, Q_B


@dataclass(frozen=True)
class VoxelSheet:
    """One printed sheet as the printed robot holds it: ``phases`` (nx, ny, nz) int (0 void),
    ``size`` (3,) [mm] the grid's edges, ``origin`` (3,) [mm] node (0, 0, 0) in the sheet's frame,
    ``bodies`` (nx + 1, ny + 1, nz + 1) int grip labels (0 free, 1 centre, 2-4 arms 0-2:
    :func:`metasheet.sheet.dns.grip_labels`), ``references`` (4, 3) [mm] the grips' reference
    points in the sheet frame, ``law`` the walls' :class:`NeoHookean`."""

    phases: np.ndarray
    size: np.ndarray
    origin: np.ndarray
    bodies: np.ndarray
    references: np.ndarray
    law: NeoHookean

    @classmethod
    def from_print(cls, spec) -> "VoxelSheet":
        """The printed sheet of a :class:`~metasheet.sheet.dns.SheetPrint` (its foam built as the
        linear DNS builds it), its walls neo-Hookean with the cell design's material (E, nu)."""
        from ..sheet.dns import grip_labels
        from ..sheet.grips import grip_references
        from ..sheet.printed_foam import printed_foam, tripod_region

        foam = printed_foam(tripod_region(spec.params), spec.fields, spec.design, voxel_mm=spec.voxel_mm,
                            gauge=spec.gauge, seed=spec.seed, max_voxels=spec.max_voxels)
        h = np.asarray(foam.voxel_mm, float)
        solid = spec.design.material
        return cls(foam.phases.astype(np.int64), np.asarray(foam.size, float), np.asarray(foam.origin, float),
                   grip_labels(foam.phases.shape, foam.origin, h, spec.params), grip_references(spec.params),
                   NeoHookean(float(solid.E), float(solid.nu)))


@dataclass(frozen=True)
class PrintedPose:
    """The printed robot's equilibrium at ``motors_deg`` (6,): the effector's displacement ``dp``
    (3,) [mm] and rotation vector ``theta`` (3,) [rad] from rest; ``residual`` the rod's
    unbalanced wrench over the grips' wrench scale [-]; ``iterations`` of the rod's quasi-Newton;
    ``wrenches`` (2, 4, 6) each sheet's grip wrenches in its frame [N, N mm]; ``newton`` the
    sheets' Newton iterations in all; ``wall_strain`` each sheet's largest principal
    Green-Lagrange strain in its walls [-]; ``approach`` each sheet's closest approach of two
    formerly separate wall surfaces (:class:`metasheet.fem.voxel.gaps.Approach`: self-contact);
    ``states`` each sheet's displacement field (warm starts); ``stable`` each sheet's stability
    probe at the balance (:attr:`~metasheet.fem.voxel.nonlinear.NonlinearSolution.stable`);
    ``contact`` each sheet's wall pairs in contact (:attr:`~metasheet.fem.voxel.nonlinear.
    NonlinearSolution.contact`; empty without contact); ``rod_step`` (6,) a held rod's step to its
    balance to first order (dp [mm], rotation vector [rad]: the rest model's Jacobian on the
    unbalanced wrench), or a pose balanced to a step tolerance's last predicted step (None: balanced
    to the wrench's)."""

    motors_deg: np.ndarray
    dp: np.ndarray
    theta: np.ndarray
    residual: float
    iterations: int
    wrenches: np.ndarray
    newton: int
    wall_strain: tuple = ()
    approach: tuple = ()
    states: tuple = field(repr=False, default=())
    stable: tuple = ()
    contact: tuple = ()
    rod_step: np.ndarray | None = None


def sheet_grip_poses(Q, centre, references, origin, servos, dp, theta, dphi) -> tuple[np.ndarray, np.ndarray]:
    """(rotations (4, 3) [rad], translations (4, 3) [mm]) of one sheet's grips in its own frame.

    Q : (3, 3) the sheet's frame -> world; centre : (3,) its centre in the world [mm];
    references : (4, 3) grip reference points, sheet frame [mm]; origin : (3,) the effector's
    reference point at rest [mm]; servos : arm k's three :class:`~.rigid.Servo`; dp (3,) [mm],
    theta (3,) [rad] the effector's motion; dphi (3,) [rad] the three motors' change from rest."""
    w = np.asarray(references, float) @ Q.T + centre  # world reference points at rest
    rot = np.zeros((4, 3))
    trans = np.zeros((4, 3))
    Re = rotation_matrix(theta)
    moved = np.asarray(origin, float) + dp + Re @ (w[0] - origin)
    rot[0], trans[0] = Q.T @ np.asarray(theta, float), Q.T @ (moved - w[0])
    for k, sv in enumerate(servos):
        a, p = np.asarray(sv.axis, float), np.asarray(sv.pivot, float)
        moved = p + axis_rotation(a, float(dphi[k])) @ (w[k + 1] - p)
        rot[k + 1], trans[k + 1] = Q.T @ (a * float(dphi[k])), Q.T @ (moved - w[k + 1])
    return rot, trans


#: the rod's largest Broyden step: a turn [rad] and a move [share of an arm's reach]
MAX_TURN, MAX_MOVE = 0.1, 0.25


class PrintedRobot:
    """The two printed sheets on the six-DOF ``robot``'s rod and horns (module docstring).

    ``sheets``: (sheet A, sheet B) :class:`VoxelSheet` (A on servos 0-2, B on 3-5);
    ``S_rest``: the rest Schur complement (12, 12) of the linear condensed model
    (:func:`metasheet.robot.condensed.condensed_robot_S` of the sheets' linear grip stiffness),
    the rod iteration's first Jacobian; None: by finite differences at the first pose.
    ``progress``: called as ``progress(desc, done, total)`` by each sheet's solve (long on a print).
    ``contact``: the walls' penalty contact in each sheet (None: they pass through each other,
    True: :meth:`metasheet.fem.voxel.contact.Contact.default`, or a Contact).
    ``processes``: each sheet in a process of its own (:mod:`.sheet_process`), the two solved at once
    on two cores (the same bits; ``progress`` then reports the rod's iterations only); False: both in
    this process, one after the other. :meth:`close` stops them (so does the object's collection).
    """

    def __init__(self, robot, sheets, S_rest=None, rtol: float = 1e-8, progress=None, contact=None,
                 processes: bool = False):
        c, centres = _check_robot(robot)
        if len(sheets) != 2 or not all(isinstance(s, VoxelSheet) for s in sheets):
            raise ConfigError("sheets: expected (sheet A, sheet B), two VoxelSheet")
        self.robot, self.sheets, self.rtol, self.progress = robot, tuple(sheets), float(rtol), progress
        self.frames = ((Q_A, centres[0], list(c.servos[:3])), (Q_B, centres[1], list(c.servos[3:])))
        self.origin = np.asarray(c.origin, float)
        self.rest_angles = np.asarray([s.rest_angle for s in c.servos], float)
        self.J0 = None if S_rest is None else np.asarray(S_rest, float)[:6, :6].copy()
        if processes:
            from .sheet_process import SheetProcess

            self.bodies = tuple(SheetProcess(s, contact) for s in self.sheets)
        else:  # each sheet's multigrid built once
            self.bodies = tuple(GripBody(s.phases, s.size, s.law, bodies=s.bodies,
                                         references=s.references - s.origin, contact=contact) for s in self.sheets)
        self.states = [None, None]
        self.last = [None, None]
        self.newton = 0

    def rod_wrench(self, q, motors_rad, probe: bool = False) -> tuple[np.ndarray, np.ndarray, float]:
        """(the rod's unbalanced wrench (6,) [N, N mm about the moved effector point], the grips'
        wrenches (2, 4, 6), their scale [N]) at effector motion ``q`` = (dp, theta) and motor angles;
        ``probe``: each sheet's equilibrium checked for stability (its solve's last step)."""
        dphi = np.asarray(motors_rad, float) - self.rest_angles
        dp, theta = q[:3], q[3:]
        o = self.origin + dp
        total, per, scale = np.zeros(6), np.zeros((2, 4, 6)), 0.0
        poses = []
        for s, (sheet, (Q, centre, servos)) in enumerate(zip(self.sheets, self.frames)):
            rot, trans = sheet_grip_poses(Q, centre, sheet.references, self.origin, servos, dp, theta,
                                          dphi[3 * s:3 * s + 3])
            say = None if self.progress is None else \
                (lambda d, k, n, s=s: self.progress(f"sheet {'AB'[s]}: {d}", k, n))
            self.bodies[s].submit(rot, trans, self.states[s], self.rtol, probe=probe, progress=say)
            poses.append(trans)
        for s, (sheet, (Q, centre, servos)) in enumerate(zip(self.sheets, self.frames)):
            trans = poses[s]
            g = self.bodies[s].result()  # in this process: solved now; in a sheet's process: waited for
            self.states[s] = g.solution.full(g.solution.u)
            self.last[s] = g
            self.newton += g.solution.newton
            per[s] = g.wrenches
            F, M = Q @ g.wrenches[0, :3], Q @ g.wrenches[0, 3:]
            r0 = Q @ (sheet.references[0] + trans[0]) + centre  # the moved centre reference, world
            total += np.concatenate([F, M + np.cross(r0 - o, F)])
            scale = max(scale, float(np.abs(g.wrenches[:, :3]).max()))
        return total, per, scale

    def equilibrium(self, motors_deg, q0=None, max_iterations: int = 40, step_tol: float | None = None
                    ) -> PrintedPose:
        """The rod's equilibrium at ``motors_deg`` (6,) [deg], from the effector motion ``q0`` (6,)
        (None: rest); the sheets start from the last pose's solution, the rod's Jacobian is the last
        pose's Broyden update (the first: the linear rest model's). Balanced where the rod's
        wrench is within ten times the sheets' ``rtol`` of the grips' scale, or, with ``step_tol``
        [mm], where the step to the balance that the Jacobian predicts moves the rod and an arm's
        end by under it (the stiffly held rod's wrench falls slowly in its last digits: each rod
        iteration is a solve of both sheets; the pose's ``rod_step`` is that last step)."""
        motors = np.radians(np.asarray(motors_deg, float))
        if motors.shape != (6,) or not np.all(np.isfinite(motors)):
            raise ConfigError(f"motors_deg: {np.asarray(motors_deg).tolist()}: six finite angles [deg]")
        if step_tol is not None:
            check_range("step_tol", step_tol, 0.0, None, lo_open=True)
        q = np.zeros(6) if q0 is None else np.asarray(q0, float).copy()
        r, per, scale = self.rod_wrench(q, motors)
        J = self.J0 if self.J0 is not None else self._fd_jacobian(q, motors, r)
        hist = []
        length = self._reach()
        w = self._weights()
        probes = 0

        def balance(r, scale):  # (relative wrench, the predicted step, balanced?)
            rel = float(np.linalg.norm(w * r)) / max(scale, 1e-300)
            # the sheets' force round-off bounds what the rod can balance (a pose at rest: no force at all)
            floor = sum(b.floor(self.states[k].reshape(-1, 3)) for k, b in enumerate(self.bodies))
            step = np.linalg.solve(J, -r)
            near = step_tol is not None and max(float(np.linalg.norm(step[:3])),
                                                length * float(np.linalg.norm(step[3:]))) <= step_tol
            return rel, step, rel <= 10 * self.rtol or float(np.linalg.norm(w * r)) <= floor or near

        for it in range(max_iterations + 1):
            rel, step, balanced = balance(r, scale)
            hist.append(rel)
            if balanced and probes < 2:
                # the sheets' stability checked once the rod balances (a probe per rod iteration would
                # cost a CG solve each); a sheet that leaves a saddle moves the balance on
                probes += 1
                r, per, scale = self.rod_wrench(q, motors, probe=True)
                rel, step, balanced = balance(r, scale)
            if balanced:
                self.J0 = J
                strain, approach = self._walls()
                return PrintedPose(np.degrees(motors), q[:3].copy(), q[3:].copy(), rel, it, per, self.newton,
                                   strain, approach, tuple(self.states),
                                   tuple(g.solution.stable for g in self.last),
                                   tuple(g.solution.contact for g in self.last if g.solution.contact is not None),
                                   None if step_tol is None else step)
            # a Jacobian carried from another pose can be poor in the directions that pose never
            # explored (all six motors alike move the rod along one axis only): a full step from
            # it turned the rod by more than a half turn; Broyden learns from the shorter step too
            step = step * min(1.0, MAX_TURN / max(float(np.linalg.norm(step[3:])), 1e-300),
                              MAX_MOVE * length / max(float(np.linalg.norm(step[:3])), 1e-300))
            q_new = q + step
            r_new, per, scale = self.rod_wrench(q_new, motors)
            y = r_new - r
            J = J + np.outer(y - J @ step, step) / float(step @ step)  # Broyden's good update
            q, r = q_new, r_new
        raise ConvergenceError(f"printed robot: the rod's equilibrium at motors {np.degrees(motors).round(3).tolist()} "
                               f"deg reached {hist[-1]:.2e} after {max_iterations} iterations", history=hist)

    def held(self, motors_deg, q, from_rest: bool = False) -> PrintedPose:
        """Both sheets at ``motors_deg`` (6,) [deg] with the rod held at the effector motion ``q``
        (6,) (dp [mm], rotation vector [rad]: a faster model's balance, say) instead of balanced:
        one solve per sheet, each one's stability probed. ``residual`` is the rod's unbalanced
        wrench over the grips' scale there, ``rod_step`` the step to the balance to first order
        (how far ``q`` is from it), ``iterations`` 0. ``from_rest``: the sheets solved from rest,
        not from the last pose (the pose then a function of ``motors_deg`` and ``q`` alone, to
        the bit, whatever was solved before)."""
        motors = np.radians(np.asarray(motors_deg, float))
        q = np.asarray(q, float)
        if motors.shape != (6,) or q.shape != (6,) or not (np.all(np.isfinite(motors)) and np.all(np.isfinite(q))):
            raise ConfigError(f"motors_deg, q: shapes {motors.shape}, {q.shape}: six finite angles [deg] and a "
                              "finite effector motion (dp [mm], rotation vector [rad])")
        if from_rest:
            self.states = [None, None]
        r, per, scale = self.rod_wrench(q, motors, probe=True)
        strain, approach = self._walls()
        # a stiffly held rod leaves a large wrench for a small miss: the step says the miss
        step = None if self.J0 is None else -np.linalg.solve(self.J0, r)
        return PrintedPose(np.degrees(motors), q[:3].copy(), q[3:].copy(),
                           float(np.linalg.norm(self._weights() * r)) / max(scale, 1e-300), 0, per, self.newton,
                           strain, approach, tuple(self.states), tuple(g.solution.stable for g in self.last),
                           tuple(g.solution.contact for g in self.last if g.solution.contact is not None), step)

    def _reach(self) -> float:
        """An arm's reach [mm] (at least 1): the rod's moments' and moves' length scale."""
        return max(float(np.linalg.norm(self.sheets[0].references[1])), 1.0)

    def _weights(self) -> np.ndarray:
        """The rod's wrench components' weights: forces as they are, moments over an arm's reach."""
        length = self._reach()
        return np.array([1, 1, 1, 1 / length, 1 / length, 1 / length])

    def close(self) -> None:
        """Stop the sheets' processes (``processes=True``; nothing otherwise)."""
        for b in self.bodies:
            if hasattr(b, "close"):
                b.close()

    def _walls(self) -> tuple[tuple, tuple]:
        """Each sheet's largest wall strain and closest approach at the last solved pose."""
        from ..fem.voxel.gaps import closest_approach

        strain, approach = [], []
        for g, u in zip(self.last, self.states):
            sol = g.solution
            kept = ~np.isnan(sol.strain)
            strain.append(float(np.nanmax(sol.strain)))
            approach.append(closest_approach(kept, sol.h, u))
        return tuple(strain), tuple(approach)

    def _fd_jacobian(self, q, motors, r0, h: float = 1e-4) -> np.ndarray:
        J = np.zeros((6, 6))
        for k in range(6):
            e = np.zeros(6)
            e[k] = h
            J[:, k] = (self.rod_wrench(q + e, motors)[0] - r0) / h
        self.rod_wrench(q, motors)  # the warm starts back at q
        return J

