"""A reduced-order model of the robot (issue 16): a few coordinates for the sheets, a few elements for their forces.

Coordinates ``q = (q_e (6), q_a (na), a (k))``. The rigid ones are the full model's, exact
(:mod:`metasheet.robot.rigid`: the effector pose and the motor angles place every rigid node); the free nodes
move in a basis, ``x_f = X_f + V a`` with ``V`` (3 n_f, k) orthonormal (:mod:`.basis`).
Eq. (1) projected on these coordinates is the Galerkin residual

    G(q) = (dx/dq)^T (f(x(q)) - f_ext),          dx/dq = T = [J_r 0 ; 0 V]

and its tangent ``T^T K T`` plus the rigid bodies' geometric term (as in :mod:`metasheet.robot.statics`).
Hyper-reduction (energy-conserving sampling and weighting, :mod:`.ecsw`): the internal part is
summed over a sample E of the elements with weights w_e >= 0, ``sum_{e in E} w_e T_e^T f_e``.
A corotational element force is linear in its stiffness tensor, so the weighted sample is
itself an :class:`~metasheet.robot.body.ElasticBody` (the sampled elements, their tensors times w_e, on
their own nodes): the full model's kernel evaluates it. Gravity is exact and closed-form
(each rigid body's first mass moment, the projected free-node weights).

:class:`ReducedRobot` has the interface the solvers use (:meth:`ReducedRobot.linearizer`,
:meth:`~ReducedRobot.rest_state`, ``coupling``, the motor limits), so the equilibrium solver,
the kinematics and the inverse controller run on it unchanged; its linearisations are
:class:`metasheet.robot.statics.Linearization` objects whose "free" part is ``a``. Its states are
:class:`~.coordinates.ReducedState` (no node positions: :meth:`ReducedRobot.positions` reconstructs them).

Training data (basis, sample, weights, the motor box it was trained on) is a
:class:`~.coordinates.ReducedBasis`; :mod:`.training` makes one and :mod:`.certificate`
compares it with the full model.
"""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError
from ..mechanics.rotations import axis_rotation, cross
from .coordinates import ReducedBasis, ReducedState, coordinate_jacobian, projected_state, robot_key
from .linearizer import ReducedLinearizer


class ReducedRobot:
    """The robot on a :class:`ReducedBasis` (see the module docstring).

    Parameters
    ----------
    full : the full :class:`~metasheet.robot.robots.Robot` the basis was trained on (checked by key).
    basis : the trained basis, sample and weights.
    tangent_dtype : precision of the tangent's projection ``T^T K T`` (:meth:`evaluate`):
        float32 (default) or float64 (every result to double round-off).

    Attributes
    ----------
    full, basis, coupling, body (the full body: strains on reconstructed positions),
    angle_min, angle_max (the full robot's motor limits [rad]), gravity, axis, name, info.
    sub : the weighted sampled elements as an :class:`~metasheet.robot.body.ElasticBody`.
    """

    def __init__(self, full, basis: ReducedBasis, *, check_key: bool = True, tangent_dtype=np.float32):
        from ..robot.body import ElasticBody

        if np.dtype(tangent_dtype) not in (np.float32, np.float64):
            raise ConfigError(f"tangent_dtype: {tangent_dtype!r}: allowed float32 or float64")

        c = full.coupling
        if basis.V.shape[0] != 3 * len(c.free):
            raise ConfigError(f"basis.V: {basis.V.shape[0]} rows: the robot has {3 * len(c.free)} free dofs")
        if check_key and basis.robot_key != robot_key(full):
            raise ConfigError("reduced model: trained on another robot (mesh, material or scene differ); "
                              "run the 'reduce' stage again")
        if np.any(basis.weights <= 0):
            raise ConfigError("basis.weights: must be > 0")
        self.full, self.basis, self.coupling, self.body = full, basis, c, full.body
        self.angle_min, self.angle_max = full.angle_min, full.angle_max
        self.gravity, self.axis, self.name = full.gravity, full.axis, full.name + "_reduced"
        self.info = {**full.info, "reduced": {"k": basis.k, "elements": int(len(basis.elements))}}
        self.k, self.na = basis.k, c.n_act
        self.background_tangents = False
        self.tangent_dtype = np.dtype(tangent_dtype)
        self.nq = 6 + self.na + self.k
        tets = full.body.tets[basis.elements]
        nodes, inv = np.unique(tets, return_inverse=True)
        C = full.body.stiffness[basis.elements] * basis.weights[:, None, None]
        self.sub = ElasticBody(full.body.rest[nodes], inv.reshape(tets.shape), C, density=full.body.density)
        self.sub_nodes = nodes
        owner = np.full(full.body.n_nodes, -1)
        owner[c.effector_nodes] = 0
        for k, s in enumerate(c.servos):
            owner[s.nodes] = k + 1
        own = owner[nodes]
        free_index = np.full(full.body.n_nodes, -1)
        free_index[c.free] = np.arange(len(c.free))
        self._free = np.flatnonzero(own < 0)  # sub-node positions of free nodes
        rows = (3 * free_index[nodes[self._free]][:, None] + np.arange(3)).ravel()
        self._V = np.ascontiguousarray(basis.V[rows])  # (3 n_sf, k)
        self._X = full.body.rest[nodes]
        self._eff = np.flatnonzero(own == 0)
        self._rho = self._X[self._eff] - c.origin
        self._servo = [np.flatnonzero(own == k + 1) for k in range(self.na)]
        # gravity, exactly: each rigid body's first mass moment, the free nodes' projected weights
        f_ext = full.f_ext
        self._F_e = f_ext[c.effector_nodes].sum(axis=0)  # [N]
        g = np.asarray(full.gravity, float)
        m = full.body.mass
        self._g = g
        self._s_e = (m[c.effector_nodes, None] * c.rho).sum(axis=0)  # [t mm]
        self._s_k = [(m[s.nodes, None] * (c.rest[s.nodes] - s.pivot)).sum(axis=0) for s in c.servos]
        self._ext_a = basis.V.T @ f_ext[c.free].ravel()  # (k,) [N]
        self.f_ext_norm = float(np.linalg.norm(f_ext))
        self._free_rest = c.rest[c.free]

    # -- the interface of :class:`~metasheet.robot.robots.Robot` ---------------------------------------------
    def rest_state(self) -> ReducedState:
        """The undeformed configuration (a = 0, motors at their rest angles, no sag)."""
        c = self.coupling
        return ReducedState(c.origin.copy(), np.eye(3), c.rest_angles.copy(), np.zeros(self.k))

    def linearizer(self, solver: str = "superlu"):
        """A :class:`.linearizer.ReducedLinearizer` (dense: ``solver`` is accepted for the interface);
        its tangent library computes in the background when :attr:`background_tangents`
        (real-time use; off by default, so the same calls give the same results)."""
        return ReducedLinearizer(self, background=self.background_tangents)

    def with_limits(self, lo, hi) -> "ReducedRobot":
        """The same model with motor limits ``lo``, ``hi`` (na,) [rad] (shares the sample)."""
        out = object.__new__(ReducedRobot)
        out.__dict__.update(self.__dict__)
        out.angle_min, out.angle_max = np.asarray(lo, float), np.asarray(hi, float)
        return out

    def in_box(self, angles, tol: float = 1e-9) -> bool:
        """Whether motor ``angles`` (na,) [rad] lie in the training box."""
        a = np.asarray(angles, float)
        return bool(np.all(a >= self.basis.box_lo - tol) and np.all(a <= self.basis.box_hi + tol))

    # -- positions ------------------------------------------------------------------------
    def positions(self, st: ReducedState) -> np.ndarray:
        """(n, 3) [mm] every node of the full mesh at ``st`` (for strains, pictures, a full solve)."""
        c = self.coupling
        x_f = self._free_rest + (self.basis.V @ st.a).reshape(-1, 3)
        return c.positions(st.p, st.R, st.angles, x_f)

    def full_state(self, st: ReducedState):
        """The full model's :class:`~metasheet.robot.statics.RobotState` with these positions (a Newton start)."""
        from ..robot.statics import RobotState

        return RobotState(st.p, st.R, st.angles, self.positions(st))

    def project(self, state) -> ReducedState:
        """The reduced state closest to a full :class:`~metasheet.robot.statics.RobotState` (rigid coordinates
        as they are, ``a = V^T (x_f - X_f)``): a Newton start when a solve changes model."""
        return projected_state(self.full, self.basis.V, state)

    def sub_positions(self, st: ReducedState) -> np.ndarray:
        """(n_s, 3) [mm] the sampled elements' nodes at ``st``."""
        x = np.empty_like(self._X)
        x[self._free] = self._X[self._free] + (self._V @ st.a).reshape(-1, 3)
        x[self._eff] = st.p + self._rho @ st.R.T
        for s, idx, th in zip(self.coupling.servos, self._servo, st.angles):
            Q = axis_rotation(s.axis, th - s.rest_angle)
            x[idx] = s.pivot + (self._X[idx] - s.pivot) @ Q.T
        return x

    def jacobian(self, x: np.ndarray, st: ReducedState, dtype=np.float64) -> np.ndarray:
        """(3 n_s, nq) T = dx_s / dq at sub-node positions ``x`` (n_s, 3) [mm]."""
        T = coordinate_jacobian(self.coupling, x, st.p, self._eff, self._servo, self._free, self._V,
                                node_major=True, dtype=dtype)
        return T.reshape(-1, self.nq)

    # -- generalised forces ---------------------------------------------------------------
    def _project(self, x: np.ndarray, st: ReducedState, f: np.ndarray) -> np.ndarray:
        """(nq,) ``T^T f`` for nodal forces ``f`` (n_s, 3) [N] at sub-node positions ``x``
        [mm], without forming T: effector force and moment [N, N mm], servo torques [N mm],
        ``V^T f`` [N]."""
        g = np.empty(self.nq)
        fe = f[self._eff]
        g[:3] = fe.sum(axis=0)
        g[3:6] = cross(x[self._eff] - st.p, fe).sum(axis=0)
        for k, (s, idx) in enumerate(zip(self.coupling.servos, self._servo)):
            g[6 + k] = s.axis @ cross(x[idx] - s.pivot, f[idx]).sum(axis=0)
        g[6 + self.na:] = f[self._free].ravel() @ self._V
        return g

    def _gravity(self, st: ReducedState) -> np.ndarray:
        """(nq,) generalised external forces: effector force [N], moment [N mm], servo torques [N mm], V^T f_ext [N]."""
        g = np.zeros(self.nq)
        g[:3] = self._F_e
        g[3:6] = cross(st.R @ self._s_e, self._g)
        for k, (s, sk, th) in enumerate(zip(self.coupling.servos, self._s_k, st.angles)):
            Q = axis_rotation(s.axis, th - s.rest_angle)
            g[6 + k] = s.axis @ cross(Q @ sk, self._g)
        g[6 + self.na:] = self._ext_a
        return g

    def _gravity_geometric(self, st: ReducedState) -> np.ndarray:
        """(6 + na, 6 + na) the rigid geometric term of the gravity loads
        (:meth:`metasheet.robot.rigid.RigidCoupling.rigid_geometric`)."""
        G = np.zeros((6 + self.na, 6 + self.na))
        a = st.R @ self._s_e
        G[3:6, 3:6] = np.outer(a, self._g) - (a @ self._g) * np.eye(3)
        for k, (s, sk, th) in enumerate(zip(self.coupling.servos, self._s_k, st.angles)):
            d = axis_rotation(s.axis, th - s.rest_angle) @ sk
            G[6 + k, 6 + k] = self._g @ cross(s.axis, cross(s.axis, d))
        return G

    def _internal_geometric(self, x: np.ndarray, st: ReducedState, f: np.ndarray) -> np.ndarray:
        G = np.zeros((6 + self.na, 6 + self.na))
        a, fe = x[self._eff] - st.p, f[self._eff]
        G[3:6, 3:6] = a.T @ fe - np.sum(a * fe) * np.eye(3)
        for k, (s, idx) in enumerate(zip(self.coupling.servos, self._servo)):
            G[6 + k, 6 + k] = np.sum(f[idx] * cross(s.axis, cross(s.axis, x[idx] - s.pivot)))
        return G

    def evaluate(self, st: ReducedState, tangent: bool = True):
        """Hyper-reduced internal forces ``g_int`` (nq,) [N, N mm], external ``g_ext`` (nq,), and
        the tangent dG/dq (nq, nq) (None unless ``tangent``) at ``st``.

        The tangent's projection ``T^T K T`` runs in :attr:`tangent_dtype`. In single precision
        the evaluation takes 0.59 of double's time (53 against 89 ms on the paper's sample of
        1,842 P2 elements, ``benchmarks/bench_reduced_tangent.py``; the sparse ``K T`` 21
        against 43 ms) for a relative error of ~3e-8 in the tangent, which the condensation
        onto the rigid coordinates amplifies to 1-9e-4 in the Jacobian (5 poses in the box; the
        certificate's target is 2e-2). The forces, which decide convergence, stay double
        (``T^T f`` without T): the equilibria are double precision's to the solver's tolerance."""
        x = self.sub_positions(st)
        f, data = self.sub.evaluate(x, tangent)
        g_ext = self._gravity(st)
        r = f.reshape(-1, 3)
        g_int = self._project(x, st, r)
        if not tangent:
            return g_int, g_ext, None
        T = self.jacobian(x, st, dtype=self.tangent_dtype)
        K = self.sub.pattern.matrix(data.astype(self.tangent_dtype, copy=False))
        A = (T.T @ (K @ T)).astype(np.float64)
        nr = 6 + self.na
        A[:nr, :nr] += self._internal_geometric(x, st, r) - self._gravity_geometric(st)
        return g_int, g_ext, A
