"""The robot in time: the corotational sheets, the rod (with the maze plate) as a rigid body, the
servo horns as prescribed motions (position-controlled servos), stepped by a scheme of
:mod:`.schemes`.

Each time step is a static problem of the robot's own solver (:mod:`metasheet.robot.statics`:
the effector pose and the free nodes, the motors given) on a *step body*: the sheets' internal
force plus their inertia and Rayleigh damping at the scheme's evaluation point,

    f_step(x_{n+1}) = f(x*) + M a* + C v*,       K_step = c_x K(x*) + c_a M + c_v C,

with ``(x*, v*, a*)`` the scheme's stage of the candidate positions and ``C = alpha M + beta
K`` (SOFA's Rayleigh convention), K the stiffness of the latest fresh tangent (SOFA's is at the
step's start; this one is at most a few steps old: it is refreshed with the chord tangent).
The servo nodes move with their horns; their rows of the residual are the torques the servos
apply (:attr:`DynamicState.torques`). The rod and plate are a rigid body of stated mass and inertia
(:class:`~.mass.RigidInertia`), represented exactly by six point masses on its principal axes
(the same mass, centre and inertia tensor): their positions ``p + R rho_i`` follow the same
scheme as the nodes, so the rigid body's inertia (centripetal and gyroscopic terms included)
is integrated to the scheme's order without a separate rigid-body integrator.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..errors import ConfigError, ConvergenceError, check_range
from ..mechanics.rotations import skew
from ..robot.memo import LinearizationMemo
from ..robot.statics import Linearizer, RobotState, apply_step, rigid_forces
from .mass import RigidInertia, consistent_mass
from .schemes import ImplicitEuler, Kinematics


def point_masses(rigid: RigidInertia) -> tuple[np.ndarray, np.ndarray]:
    """Six point masses with ``rigid``'s mass, centre and inertia tensor: (6, 3) positions [mm]
    in its frame, (6,) masses [t]. On each principal axis e_k, m/6 at com +- s_k e_k with
    ``s_k^2 = 3 S_k / m``, ``S_k = tr(I)/2 - I_k`` the second moment (>= 0 by the triangle
    inequality of the principal moments)."""
    w, E = np.linalg.eigh(0.5 * (rigid.inertia + rigid.inertia.T))
    S = np.clip(0.5 * w.sum() - w, 0.0, None)
    s = np.sqrt(3.0 * S / rigid.mass)
    offsets = np.concatenate([E * s, -(E * s)], axis=1).T  # (6, 3): +s_k e_k then -s_k e_k
    return rigid.com + offsets, np.full(6, rigid.mass / 6.0)


class _StepBody:
    """The body of one time step (module docstring): forces and tangent of the candidate positions."""

    def __init__(self, body, M: sp.csr_matrix, scheme):
        self._body, self.M, self.scheme = body, M, scheme
        self.kin = None
        self.h = None
        self.C = None
        self.last_K = None

    def __getattr__(self, name):  # rest, tets, pattern, stiffness_scale, gravity, mass ...
        return getattr(self._body, name)

    def set_step(self, kin: Kinematics, h: float, C: sp.csr_matrix) -> None:
        self.kin, self.h, self.C = kin, h, C

    def _inertia(self, st) -> np.ndarray:
        return self.M @ st.a.ravel() + self.C @ st.v.ravel()

    def forces(self, x) -> np.ndarray:
        st = self.scheme.stage(np.asarray(x, float).reshape(-1, 3), self.kin, self.h)
        return np.asarray(self._body.forces(st.x)).ravel() + self._inertia(st)

    def forces_and_tangent(self, x, *, symmetric: bool = False):
        st = self.scheme.stage(np.asarray(x, float).reshape(-1, 3), self.kin, self.h)
        f, K = self._body.forces_and_tangent(st.x, symmetric=symmetric)
        self.last_K = K
        data = st.c_x * K.data + st.c_a * self.M.data + st.c_v * self.C.data
        return f + self._inertia(st), self._body.pattern.matrix(data)


class _StepLinearizer(Linearizer):
    """The robot's linearizer with the rigid body's inertia on the effector's six rows."""

    def __init__(self, robot, dyn: "DynamicRobot"):
        super().__init__(robot)
        self.dyn = dyn

    def _linearize(self, state, exact):
        lin = super()._linearize(state, exact)
        g, H = self.dyn.rigid_terms(state)
        S = lin.S.copy()
        S[:6, :6] += H
        R = lin.R_rigid.copy()
        R[:6] += g
        return dataclasses.replace(lin, S=S, R_rigid=R, res_e=lin.res_e + g)

    def update_within(self, lin, state, chord_tol, f=None):
        out = super().update_within(lin, state, None, f)
        g, _ = self.dyn.rigid_terms(state)
        R = out.R_rigid.copy()
        R[:6] += g
        return dataclasses.replace(out, R_rigid=R, res_e=out.res_e + g)


@dataclass(frozen=True)
class DynamicState:
    """A state of the robot in time: ``state`` (:class:`~metasheet.robot.statics.RobotState`),
    ``kin`` the node and rigid-point kinematics ((n + 6, 3) x [mm], v [mm/s], a [mm/s^2], t [s]),
    ``torques`` (na,) the servos' torques [N mm] at it (zero at the start); ``newton`` the
    iterations and ``tangents`` the fresh tangents its step took."""

    state: RobotState
    kin: Kinematics
    torques: np.ndarray
    newton: int = 0
    tangents: int = 0


def lumped_mass(body) -> sp.csr_matrix:
    """The body's lumped (row-sum) mass on its pattern: (3n, 3n) [t]."""
    return _on_pattern(body.pattern, sp.diags(np.repeat(body.mass, 3)).tocsr())


def _on_pattern(pattern, A: sp.csr_matrix) -> sp.csr_matrix:
    """``A`` (its entries inside ``pattern``) as a matrix with exactly ``pattern``'s structure."""
    P = pattern.matrix(np.arange(1, pattern.nnz + 1, dtype=float))
    coo = A.tocoo()
    pos = np.asarray(P[coo.row, coo.col]).ravel().astype(np.int64) - 1
    if np.any(pos < 0):
        raise ConfigError("mass: entries outside the body's sparsity pattern")
    data = np.zeros(pattern.nnz)
    np.add.at(data, pos, coo.data)
    return pattern.matrix(data)


class DynamicRobot:
    """A :class:`~metasheet.robot.robots.Robot` in time (module docstring).

    Parameters
    ----------
    robot : the static robot (its body's density gives the sheets' mass).
    rigid : the rod and plate's :class:`~.mass.RigidInertia` in the effector's frame at rest
        (centre relative to world origin at rest, as the robot's nodes), or None (massless rod).
    alpha, beta : Rayleigh damping, mass [1/s] and stiffness [s] (SOFA's rayleighMass and
        rayleighStiffness; the authors' scenes: 0 and 0.01).
    scheme : :class:`.schemes.ImplicitEuler` (default, SOFA's) or :class:`.schemes.GeneralizedAlpha`.
    mass : "consistent" or "lumped".
    """

    def __init__(self, robot, rigid: RigidInertia | None = None, *, alpha: float = 0.0, beta: float = 0.01,
                 scheme=None, mass: str = "consistent"):
        check_range("alpha", alpha, 0.0, None)
        check_range("beta", beta, 0.0, None)
        if mass not in ("consistent", "lumped"):
            raise ConfigError(f"mass: {mass!r}: allowed 'consistent' or 'lumped'")
        self.robot, self.alpha, self.beta = robot, float(alpha), float(beta)
        self.scheme = scheme or ImplicitEuler()
        body = robot.body
        if mass == "lumped" and np.any(body.mass < 0):
            raise ConfigError("mass: 'lumped': the body's nodal masses are negative at some nodes (P2's vertices "
                              "carry -1/20 of an element's mass); allowed 'consistent' for quadratic sheets")
        self.M = consistent_mass(body) if mass == "consistent" else lumped_mass(body)
        c = robot.coupling
        if rigid is None:
            self.rho, self.m_pts = np.zeros((6, 3)), np.zeros(6)
        else:
            pts, self.m_pts = point_masses(rigid)
            self.rho = pts - c.origin  # [mm] offsets from the effector's reference point at rest
        self.rigid = rigid
        self.step_body = _StepBody(body, self.M, self.scheme)
        self.step_robot = dataclasses.replace(robot, body=self.step_body)
        self.linearizer = _StepLinearizer(self.step_robot, self)
        self.g = np.asarray(robot.gravity, float)
        self._pts_kin = None
        self._h = None
        self._lin = None  # the chord tangent carried from step to step (reset by :meth:`start`)
        self._K = None

    # -- the rigid body's six points -----------------------------------------------------------
    def points(self, p, R) -> np.ndarray:
        """(6, 3) [mm] the rigid body's point masses at effector pose (p, R)."""
        return p + self.rho @ R.T

    def rigid_terms(self, state: RobotState) -> tuple[np.ndarray, np.ndarray]:
        """The rigid body's generalised inertial force minus weight on the effector's (dp, dtheta)
        (6,) [N, N mm] at ``state`` (the current step's candidate) and its tangent (6, 6)."""
        if not self.m_pts.any():
            return np.zeros(6), np.zeros((6, 6))
        x = self.points(state.p, state.R)
        st = self.scheme.stage(x, self._pts_kin, self._h)
        m = self.m_pts[:, None]
        r = m * (st.a + self.alpha * st.v - self.g)  # (6, 3) [N]
        arm = x - state.p
        g = np.concatenate([r.sum(axis=0), np.cross(arm, r).sum(axis=0)])
        c = st.c_a + self.alpha * st.c_v
        J = np.zeros((6, 3, 6))
        J[:, :, :3] = np.eye(3)
        J[:, :, 3:] = -skew(arm)
        H = c * np.einsum("pia,p,pib->ab", J, self.m_pts, J)
        H[3:, 3:] += arm.T @ r - np.sum(arm * r) * np.eye(3)  # as rigid.rigid_geometric
        return g, H

    def _predict_pose(self, st: RobotState, pts: Kinematics, h: float):
        """The rod's pose carried on at its current velocity for ``h`` [s] (the scheme's predictor
        for the free nodes, the rigid motion's for the rod): the six points' velocities give the
        rod's translational and angular velocity exactly (they sit in +- pairs about its centre)."""
        if not self.m_pts.any() or not np.any(pts.v):
            return st.p, st.R
        from ..mechanics.rotations import rotation_matrix

        com = pts.x.mean(axis=0)
        v_c = pts.v.mean(axis=0)
        arm = pts.x - com
        # v_i - v_c = w x arm_i = -[arm_i]x w: least squares over the six points
        w = np.linalg.lstsq(-skew(arm).reshape(-1, 3), (pts.v - v_c).ravel(), rcond=None)[0]
        p = st.p + h * (v_c + np.cross(w, st.p - com))
        return p, rotation_matrix(h * w) @ st.R

    def reset(self) -> None:
        """Forget the chord tangent and the damping's stiffness carried between steps: a run
        from a given state then gives the same bits whatever ran on this robot before."""
        self._lin, self._K = None, None

    # -- time --------------------------------------------------------------------------------
    def start(self, state: RobotState, t: float = 0.0) -> DynamicState:
        """A state at rest in time (zero velocity and, for generalised-alpha, the acceleration of
        that state's force imbalance: zero at an equilibrium) at ``state``."""
        self.reset()
        x = np.vstack([state.x, self.points(state.p, state.R)])
        zero = np.zeros_like(x)
        return DynamicState(state, Kinematics(x, zero, zero.copy(), float(t)), np.zeros(self.robot.coupling.n_act))

    def step(self, ds: DynamicState, angles, h: float, *, tol: float = 1e-6, max_iter: int = 30,
             max_halvings: int = 5) -> DynamicState:
        """One time step of ``h`` [s] to motor ``angles`` (na,) [rad] (:meth:`_step`); when its
        Newton solve fails, two half steps (the motors at their midpoint between), up to
        ``max_halvings`` times deep: a fast motor move on soft sheets (silicone's impossible
        maze segments) can snap them within one step. ConvergenceError when even the smallest
        step fails."""
        try:
            return self._step(ds, angles, h, tol=tol, max_iter=max_iter)
        except ConvergenceError:
            if max_halvings <= 0:
                raise
        self._lin, self._K = None, None  # the failed solve's tangent is no guide
        a = np.asarray(angles, float)
        mid = self.step(ds, 0.5 * (ds.state.angles + a), 0.5 * h, tol=tol, max_iter=max_iter,
                        max_halvings=max_halvings - 1)
        return self.step(mid, a, 0.5 * h, tol=tol, max_iter=max_iter, max_halvings=max_halvings - 1)

    def _step(self, ds: DynamicState, angles, h: float, *, tol: float, max_iter: int) -> DynamicState:
        """One time step of ``h`` [s] to motor ``angles`` (na,) [rad] at ``t + h`` (the horns'
        prescribed positions). Newton on the step body, the tangent kept while each iteration
        cuts the residual at least fourfold (from one step to the next too), each step halved
        until the residual falls (at most five times); ConvergenceError with the time and the residual
        when ``max_iter`` iterations do not reach ``tol`` times the force scale."""
        check_range("h", h, 0.0, None, lo_open=True)
        robot, L, n = self.robot, self.linearizer, self.robot.body.n_nodes
        c = robot.coupling
        kin = ds.kin
        node_kin = Kinematics(kin.x[:n], kin.v[:n], kin.a[:n], kin.t)
        self._pts_kin = Kinematics(kin.x[n:], kin.v[n:], kin.a[n:], kin.t)
        self._h = h
        if self._K is None:  # damping with the stiffness of the latest fresh tangent (SOFA: at x_n)
            self._K = robot.body.forces_and_tangent(ds.state.x)[1]
        K0 = self._K if len(self._K.data) == robot.body.pattern.nnz else _on_pattern(robot.body.pattern, self._K.tocsr())
        C = robot.body.pattern.matrix(self.alpha * self.M.data + self.beta * K0.data)
        self.step_body.set_step(node_kin, h, C)
        L.memo = LinearizationMemo()  # the step body changed: no linearisation of an earlier step holds
        st0 = ds.state
        guess = self.scheme.predict(node_kin, h)
        p, R = self._predict_pose(st0, self._pts_kin, h)
        state = RobotState(p, R, np.asarray(angles, float), c.positions(p, R, angles, guess[c.free]))
        # the previous step's tangent as a chord (the inertia term c_a M dominates it and does not
        # change): a fresh one only when an iteration cuts the residual less than fourfold
        lin = L.linearize(state) if self._lin is None else L.update(self._lin, state)
        scale = max(L.force_scale(lin), 1e-300)
        floor = L.residual_floor(lin)
        last = np.inf
        fresh = 0
        for it in range(max_iter + 1):
            res = lin.residual_norm
            if res <= max(tol * scale, 2 * floor):
                break
            if it == max_iter:
                raise ConvergenceError(f"dynamic step at t = {kin.t + h:.6g} s: residual {res:.3g} N after "
                                       f"{max_iter} Newton iterations (tolerance {tol * scale:.3g} N)")
            if res > 0.25 * last and not lin.fresh:
                lin = L.linearize(state)
                fresh += 1
                self._K = self.step_body.last_K
            last = res
            dq_e, dx_f = lin.newton_step()
            for alpha in 0.5 ** np.arange(6):  # backtracking: a large motor move from a far predictor
                trial = apply_step(self.step_robot, state, dq_e, dx_f, alpha=alpha)
                new_lin = L.update(lin, trial)
                if new_lin.residual_norm < res:
                    break
            state, lin = trial, new_lin
        self._lin = lin
        x_all = np.vstack([state.x, self.points(state.p, state.R)])
        new = self.scheme.finish(x_all, kin, h)
        r = lin.r  # step body's residual: internal + inertia + damping - weight [N]
        torques = rigid_forces(c, state.x, state.p, r)[6:]
        return DynamicState(state, new, torques, it, fresh)
