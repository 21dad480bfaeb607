"""The coupled robot's state and its linearisation (paper eq. 1 and 6), with the force scale and
round-off floor its residual is judged against; the Newton solve of eq. 1 is in :mod:`.equilibrium`.

Unknowns are the effector's 6 rigid DOFs and the free nodes, ``y = (q_e, x_f)``; the motor
angles ``q_a`` are given. With ``r(x) = f(x) - f_ext`` (internal minus gravity/loads,
``f_ext = M g``) the reduced residual is ``R(y) = [J_e^T r ; r_f]`` (eq. 1 projected by
eq. 2) and the reduced tangent is the e/f part of the paper's matrix ``A`` (eq. 6),
``J^T K J`` plus the rigid bodies' geometric term (see :mod:`.rigid`).

The linear algebra is shared with the kinematics (:mod:`.kinematics`): the free block
``K_ff`` is extracted from the body's CSR tangent through cached index maps, factorised
once (:mod:`metasheet.fem.solvers`: CHOLMOD of its symmetric part plus iterative refinement when
scikit-sparse is installed, else SuperLU), and solved exactly with all rigid columns
(6 + n_act) and the residual at once; everything else is a small dense Schur complement
``S = A_rr - C K_ff^-1 B``. Chord updates reuse the factor (for CHOLMOD: of the symmetric
part, a modified Newton) and are always judged on the true residual.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp

from ..fem.assembly import submatrix_map
from ..fem.factor import SparseSolver
from .memo import LinearizationMemo, factor_bytes, state_key
from ..mechanics.rotations import cross, rotation_matrix, rotation_vector


@dataclass(frozen=True)
class RobotState:
    """A configuration of the robot.

    Attributes
    ----------
    p : (3,) effector reference point [mm].
    R : (3, 3) effector orientation.
    angles : (na,) motor angles [rad].
    x : (n, 3) all node positions [mm] (consistent with p, R, angles).
    """

    p: np.ndarray
    R: np.ndarray
    angles: np.ndarray
    x: np.ndarray

    @property
    def pose(self) -> np.ndarray:
        """(6,) effector pose: position [mm] and rotation vector [rad]."""
        return np.concatenate([self.p, rotation_vector(self.R)])


class Linearizer:
    """Linearisation of a robot about a state, reusing index maps (and optionally LU).

    Built once per robot; :meth:`linearize` returns a :class:`Linearization`.
    ``solver`` : "auto" | "cholmod" | "superlu" (:mod:`metasheet.fem.solvers`); :attr:`solver_name` is
    what runs and ``self.solver.stats`` counts factorisations, fallbacks and refinement sweeps.
    """

    def __init__(self, robot, solver: str = "superlu"):
        self.robot = robot
        c = robot.coupling
        self.dof_r = (3 * c.rigid_nodes[:, None] + np.arange(3)).ravel()
        self.dof_f = (3 * c.free[:, None] + np.arange(3)).ravel()
        self._maps = None
        self._pattern = None
        self.solver = SparseSolver(solver)
        self.factor = None
        self.factorizations = 0
        self.memo = LinearizationMemo()  # repeated states: the same bits without a factorisation

    @property
    def solver_name(self) -> str:
        """The sparse solver in use: "cholmod" or "superlu"."""
        return self.solver.name

    @property
    def lu(self):
        """The current factor of K_ff (kept for callers of the SuperLU-only version)."""
        return self.factor

    def uses(self, solver: str) -> bool:
        """Whether this linearizer factorises with ``solver`` (a name :func:`~metasheet.fem.factor.resolve` knows)."""
        from ..fem.factor import resolve

        return resolve(solver) == self.solver_name

    # -- the model interface the solvers use (a reduced model's linearizer has the same) -----
    def apply(self, state: RobotState, dq_e, dx_f, dq_a=None, alpha: float = 1.0) -> RobotState:
        """The state after the increment (:func:`apply_step`)."""
        return apply_step(self.robot, state, dq_e, dx_f, dq_a, alpha)

    def force_scale(self, lin: "Linearization") -> float:
        """Force scale [N] of the equilibrium tolerances (:func:`force_scale`)."""
        return force_scale(self.robot, lin)

    def residual_floor(self, lin: "Linearization") -> float:
        """Round-off floor [N] of the residual norm (:func:`residual_floor`)."""
        return residual_floor(self.robot, lin)

    def _blocks(self, K):
        if self._maps is None or K.nnz != self._pattern[0] or not np.array_equal(K.indptr, self._pattern[1]):
            r, f = self.dof_r, self.dof_f
            self._maps = {k: submatrix_map(K, a, b) for k, (a, b) in
                          {"rr": (r, r), "rf": (r, f), "fr": (f, r), "ff": (f, f)}.items()}
            self._pattern = (K.nnz, K.indptr.copy())
        out = {}
        for k, (sub, take) in self._maps.items():
            out[k] = sp.csr_matrix((K.data[take], sub.indices, sub.indptr), shape=sub.shape)
        return out

    def _solve(self, rhs: np.ndarray) -> np.ndarray:
        """Chord solve with the current factor (exact for SuperLU, symmetric part for CHOLMOD)."""
        return self.factor.solve(rhs)

    def linearize(self, state: RobotState, *, exact: bool = True) -> "Linearization":
        """Fresh tangent, factor of K_ff, residual and Schur complement at ``state``.

        ``exact`` (default) solves with K_ff itself (refined or SuperLU, see :mod:`metasheet.fem.solvers`):
        S and Y are then the true eq. (6) condensation, as the kinematics need. ``exact=False``
        uses the factor as it is: with CHOLMOD, the symmetric part of K_ff, which makes the
        Newton step a modified one (the control loop's choice: it checks the true residual
        and the pending correction every step); with SuperLU nothing changes.

        A state equal (array for array) to one of the last few linearised gets their result
        back, factor included (:mod:`.memo`): the same bits, counted as a factorisation.
        """
        key = state_key(state, exact)
        hit = self.memo.get(key)
        if hit is not None:
            lin, self.factor = hit
            self.factorizations += 1
            return replace(lin, state=state)
        lin = self._linearize(state, exact)
        self.memo.put(key, (lin, self.factor), factor_bytes(self.factor) + lin.Y.nbytes)
        return lin

    def _linearize(self, state: RobotState, exact: bool) -> "Linearization":
        rob = self.robot
        c = rob.coupling
        f, K = rob.body.forces_and_tangent(state.x)
        r = f.reshape(-1, 3) - rob.f_ext
        B = self._blocks(K.tocsr() if not sp.isspmatrix_csr(K) else K)
        Jr = c.rigid_jacobian(state.x, state.p)
        A = Jr.T @ (B["rr"] @ Jr) + c.rigid_geometric(state.x, state.p, r)
        Bfr = B["fr"] @ Jr  # (3nf, nr)
        Crf = (B["rf"].T @ Jr).T  # (nr, 3nf)
        self.factor = self.solver.factorize(B["ff"])
        self.factorizations += 1
        rf = r[c.free].ravel()
        rhs = np.column_stack([Bfr, rf])
        if exact:
            Y, self.factor = self.solver.solve_exact(self.factor, B["ff"], rhs)
        else:
            Y = self.factor.solve(rhs)
        nr = Jr.shape[1]
        S = A - Crf @ Y[:, :nr]
        Rr = Jr.T @ r[c.rigid_nodes].ravel()  # generalised forces on the rigid DOFs
        return Linearization(state=state, r=r, S=S, Y=Y[:, :nr], y_r=Y[:, nr], C=Crf,
                             R_rigid=Rr - Crf @ Y[:, nr], res_e=Rr[:6], res_f=rf, fresh=True,
                             moment_scale=c.length_scale, exact=exact or not self.factor.symmetric)

    def update(self, lin: "Linearization", state: RobotState, f=None) -> "Linearization":
        """Fresh residual at ``state`` on ``lin``'s (stale) tangent: a chord / modified-Newton step.

        Costs one force evaluation and one solve with the cached factor. ``f`` (n, 3) [N] the
        internal forces at ``state`` if already known.
        """
        return self.update_within(lin, state, None, f)

    def update_within(self, lin: "Linearization", state: RobotState, chord_tol: float | None,
                      f=None) -> "Linearization | None":
        """:meth:`update`, or None when the reduced residual at ``state`` exceeds ``chord_tol``
        times the force scale (:meth:`force_scale`; None: no test): the test needs the forces
        only, so a chord update the control loop would drop for its residual
        (:class:`.tangent.TangentCache`) costs no solve with the kept factor."""
        rob = self.robot
        c = rob.coupling
        f = rob.body.forces(state.x) if f is None else f
        r = np.asarray(f).reshape(-1, 3) - rob.f_ext
        rf = r[c.free].ravel()
        Rr = rigid_forces(c, state.x, state.p, r)
        out = Linearization(state=state, r=r, S=lin.S, Y=lin.Y, y_r=None, C=lin.C, R_rigid=None, res_e=Rr[:6],
                            res_f=rf, fresh=False, moment_scale=c.length_scale, exact=False)
        if chord_tol is not None and not out.residual_norm <= chord_tol * max(self.force_scale(out), 1e-300):
            return None
        y_r = self._solve(rf)
        return replace(out, y_r=y_r, R_rigid=Rr - lin.C @ y_r)


def rigid_forces(coupling, x, p, r) -> np.ndarray:
    """``J_r^T r`` (6 + na,) without forming J_r: effector force [N] and moment about ``p``
    [N mm], then each servo's torque about its axis [N mm]. ``x`` (n, 3) [mm], ``r`` (n, 3) [N].
    """
    c = coupling
    xr, rr = x[c.rigid_nodes], r[c.rigid_nodes]
    arm = xr.copy()  # lever arm of each rigid node about its body's reference point
    b = c._bounds
    arm[b[0]:b[1]] -= p
    for k, sv in enumerate(c.servos):
        arm[b[k + 1]:b[k + 2]] -= sv.pivot
    mom = cross(arm, rr)  # one cross product for all rigid nodes
    out = np.empty(c.n_rigid_dof)
    out[:3] = rr[b[0]:b[1]].sum(axis=0)
    out[3:6] = mom[b[0]:b[1]].sum(axis=0)
    for k, sv in enumerate(c.servos):
        out[6 + k] = sv.axis @ mom[b[k + 1]:b[k + 2]].sum(axis=0)
    return out


@dataclass(frozen=True)
class Linearization:
    """Everything eq. (6) needs at one state.

    Attributes
    ----------
    state : where it was taken.
    r : (n, 3) nodal residual f(x) - f_ext [N].
    S : (6 + na, 6 + na) Schur complement of the free nodes in eq. (6)'s matrix A
        (units mixed: N/mm, N, N mm per mm / rad).
    Y : (3nf, 6 + na) K_ff^-1 B (free-node motion per unit rigid DOF).
    y_r : (3nf,) K_ff^-1 r_f.
    C : (6 + na, 3nf) coupling block J_r^T K_rf.
    R_rigid : (6 + na,) condensed rigid residual J_r^T r - C K_ff^-1 r_f.
    fresh : False when S, Y, C come from an earlier state (:meth:`Linearizer.update`).
    moment_scale : [mm] the effector's size; moments / moment_scale count as forces in the norm.
    res_e, res_f : (6,), (3nf,) reduced residual [N, N mm].
    exact : True when S, Y, y_r solve with the true tangent at ``state`` (fresh and exact).
    """

    state: RobotState
    r: np.ndarray
    S: np.ndarray
    Y: np.ndarray
    y_r: np.ndarray
    C: np.ndarray
    R_rigid: np.ndarray
    res_e: np.ndarray
    res_f: np.ndarray
    fresh: bool = True

    moment_scale: float = 1.0
    exact: bool = True

    @property
    def residual_norm(self) -> float:
        """Norm of the reduced residual [J_e^T r ; r_f] [N], moments divided by ``moment_scale`` [mm]."""
        m = self.res_e[3:] / self.moment_scale
        return float(np.sqrt(self.res_e[:3] @ self.res_e[:3] + m @ m + self.res_f @ self.res_f))

    def newton_step(self, dq_a=None) -> tuple[np.ndarray, np.ndarray]:
        """Linearised step (dq_e (6,), dx_f (3nf,)) for a motor increment dq_a (na,) [rad]."""
        S = self.S
        rhs = -self.R_rigid[:6].copy()
        dx_f = -self.y_r.copy()
        if dq_a is not None and np.any(dq_a):
            rhs -= S[:6, 6:] @ dq_a
            dx_f -= self.Y[:, 6:] @ dq_a
        dq_e = np.linalg.solve(S[:6, :6], rhs)
        dx_f -= self.Y[:, :6] @ dq_e
        return dq_e, dx_f


def force_scale(robot, lin: Linearization) -> float:
    """Force scale [N] the equilibrium tolerances are relative to: the norm of the forces on
    the rigid nodes plus that of the external loads (gravity) at ``lin``'s state."""
    f = lin.r + robot.f_ext
    return float(np.linalg.norm(f[robot.coupling.rigid_nodes]) + np.linalg.norm(robot.f_ext))


def residual_floor(robot, lin: Linearization) -> float:
    """Round-off floor [N] of the reduced residual norm (:attr:`Linearization.residual_norm`)
    at ``lin``'s state: no residual below it can be told from zero, and Newton stalls there.

    Each entry of the internal force carries an error of order ``eps |K_e| |x|``: the element
    force ``R K_e (R^T x_e - X_e)`` (:mod:`.kernels`; at a quadrature point, the strain from
    ``F = sum_a x_a g_a^T``) cancels positions of size ``|x|`` [mm] down to a displacement,
    and the positions themselves are only known to ``eps |x|``. It is not ``eps`` times the
    forces: at the light foam robot's equilibria (nodal forces <= 0.64 N) the residual stalls
    at 2e-12 N, and one-ulp changes of the free positions move it by 5e-12 N, a thousand times
    ``eps |f|_max sqrt(dofs)`` = 6e-15 N. With the body's per-entry bound
    ``delta = 10 eps |K_e|_max max|x|`` (``|K_e|_max`` the body's ``stiffness_scale``; as
    :attr:`~.body.ElasticBody.force_floor`, but at the current positions) and errors summing
    in quadrature, the reduced residual ``[J_e^T r ; r_f]`` has 3 n_f free entries, 3 n_e in
    the effector's force sum and 3 n_e in its moment divided by ``moment_scale`` (the rms
    lever arm, so these count about once each):

        floor = delta sqrt(3 n_f + 6 n_e) + eps (sum_i |r_i| + sum_i |a_i| |r_i| / L)

    the last term the round-off of summing the effector nodes' (large, cancelling) forces
    r_i and moments about the reference point, a_i = x_i - p, L = ``moment_scale`` [mm].
    On the foam robot this is 9e-11 N, some 40 times the stall level measured above.
    """
    c = robot.coupling
    eps = np.finfo(float).eps
    body = robot.body
    k = getattr(body, "stiffness_scale", None)  # [N/mm]; P1-only bodies carry K_e instead
    k = float(np.abs(body.Ke).max()) if k is None else float(k)
    delta = 10 * eps * k * float(np.abs(lin.state.x).max())  # [N]
    e = c.effector_nodes
    r_e = np.linalg.norm(lin.r[e], axis=1)  # [N]
    a_e = np.linalg.norm(lin.state.x[e] - lin.state.p, axis=1)  # [mm]
    summed = eps * float(r_e.sum() + (a_e * r_e).sum() / lin.moment_scale)
    return float(delta * np.sqrt(3 * len(c.free) + 6 * len(e)) + summed)


def apply_step(robot, state: RobotState, dq_e, dx_f, dq_a=None, alpha: float = 1.0) -> RobotState:
    """New :class:`RobotState` after the increment alpha * (dq_e, dq_a, dx_f)."""
    c = robot.coupling
    p = state.p + alpha * dq_e[:3]
    R = rotation_matrix(alpha * dq_e[3:]) @ state.R
    angles = state.angles if dq_a is None else state.angles + dq_a
    x_f = state.x[c.free] + alpha * dx_f.reshape(-1, 3)
    return RobotState(p, R, angles, c.positions(p, R, angles, x_f))
