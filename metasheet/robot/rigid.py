"""Rigid couplings of the FEM nodes (paper eq. 2): an effector body and revolute servo horns.

The node positions are split into ``x_e`` (nodes rigidly tied to the effector), ``x_a``
(nodes tied to the servo horns) and ``x_f`` (free nodes), and

    x = x(q_e, q_a, x_f),        dx = [J_e dq_e ; J_a dq_a ; dx_f]            (eq. 2)

* Effector (6 DOF): position ``p`` [mm] and orientation ``R`` (3, 3). A node with rest
  offset ``rho_i = X_i - p_0`` sits at ``x_i = p + R rho_i``. Increments are spatial,
  ``dq_e = (dp [mm], dtheta [rad])`` with ``R <- exp([dtheta]x) R``, so the rows of ``J_e``
  for node i are ``[I, -[R rho_i]x]``.
* Servo k (1 DOF): horn angle ``theta_k`` [rad] about the unit axis ``a_k`` through the
  pivot ``c_k``; its nodes sit at ``x_i = c_k + Rot(a_k, theta_k - theta0_k) (X_i - c_k)``,
  so ``dx_i/dtheta_k = a_k x (x_i - c_k)``.

The transposed Jacobians turn nodal forces into the rigid bodies' force/torque; their
derivatives give the geometric stiffness terms (:func:`geometric_effector`,
:func:`geometric_servo`) that make Newton's tangent exact for the rigid coordinates.
Rotation vectors and matrices: :mod:`metasheet.mechanics.rotations`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..mechanics.rotations import axis_rotation, cross, skew


@dataclass(frozen=True)
class Servo:
    """A servo horn: a 1-DOF revolute joint that owns some FEM nodes.

    Attributes
    ----------
    axis : (3,) unit rotation axis (world).
    pivot : (3,) a point of the axis [mm].
    horn_length : distance pivot -> attached node box centre [mm] (documentation, drawing).
    rest_angle : motor angle at which the nodes are at their rest positions [rad].
    nodes : (k,) int node indices the horn owns.
    """

    axis: np.ndarray
    pivot: np.ndarray
    horn_length: float
    rest_angle: float
    nodes: np.ndarray


class RigidCoupling:
    """The map x = x(q_e, q_a, x_f) of eq. (2) and its Jacobians.

    Parameters
    ----------
    rest : (n, 3) float [mm] rest node positions.
    effector_nodes : (ne,) int nodes tied to the effector.
    effector_origin : (3,) [mm] the effector's reference point at rest (q_e measures it).
    servos : the actuators; their node sets must be disjoint from each other and the effector's.
    """

    def __init__(self, rest, effector_nodes, effector_origin, servos):
        self.rest = np.asarray(rest, dtype=float)
        n = len(self.rest)
        self.effector_nodes = np.asarray(effector_nodes, dtype=np.int64)
        self.origin = np.asarray(effector_origin, dtype=float).reshape(3)
        self.servos = tuple(servos)
        if len(self.effector_nodes) < 3:
            raise ConfigError(f"effector_nodes: {len(self.effector_nodes)} nodes: need >= 3")
        owner = np.full(n, -1)
        owner[self.effector_nodes] = 0
        for k, s in enumerate(self.servos):
            if len(s.nodes) == 0:
                raise ConfigError(f"servos[{k}].nodes: empty: each horn must own nodes")
            if np.any(owner[s.nodes] >= 0):
                raise ConfigError(f"servos[{k}].nodes: overlap another rigid body's nodes")
            owner[s.nodes] = k + 1
            if abs(np.linalg.norm(s.axis) - 1.0) > 1e-9:
                raise ConfigError(f"servos[{k}].axis: {s.axis}: must be a unit vector")
        self.free = np.flatnonzero(owner < 0)
        #: rigid nodes: effector's first, then each servo's, in servo order
        self.rigid_nodes = np.concatenate([self.effector_nodes] + [s.nodes for s in self.servos])
        self.n_act = len(self.servos)
        self.n_rigid_dof = 6 + self.n_act
        self.rho = self.rest[self.effector_nodes] - self.origin  # body-frame offsets [mm]
        self.rest_angles = np.array([s.rest_angle for s in self.servos])
        #: rms distance of the effector nodes from its reference point [mm] (>= 1): turns the
        #: effector's moments into forces when residuals are compared
        self.length_scale = max(float(np.sqrt(np.mean(np.sum(self.rho**2, axis=1)))), 1.0)
        # slices of the rigid-node list per body
        sizes = [len(self.effector_nodes)] + [len(s.nodes) for s in self.servos]
        self._bounds = np.concatenate([[0], np.cumsum(sizes)])

    # -- positions -----------------------------------------------------------------------
    def effector_positions(self, p, R) -> np.ndarray:
        """(ne, 3) [mm] effector node positions for pose (p, R)."""
        return p + self.rho @ R.T

    def servo_positions(self, angles) -> list[np.ndarray]:
        """Per servo, (k, 3) [mm] node positions at motor angles (na,) [rad]."""
        out = []
        for s, th in zip(self.servos, angles):
            Q = axis_rotation(s.axis, th - s.rest_angle)
            out.append(s.pivot + (self.rest[s.nodes] - s.pivot) @ Q.T)
        return out

    def positions(self, p, R, angles, x_free) -> np.ndarray:
        """Full (n, 3) [mm] node positions x(q_e, q_a, x_f)."""
        x = np.empty_like(self.rest)
        x[self.effector_nodes] = self.effector_positions(p, R)
        for s, xs in zip(self.servos, self.servo_positions(angles)):
            x[s.nodes] = xs
        x[self.free] = x_free
        return x

    # -- Jacobians ----------------------------------------------------------------------
    def rigid_jacobian(self, x, p) -> np.ndarray:
        """Dense (3 nr, 6 + na) Jacobian of the rigid nodes' positions w.r.t. (dq_e, dq_a).

        Rows follow :attr:`rigid_nodes` (x, y, z per node); columns are
        (dp [mm], dtheta [rad], dtheta_servo_k [rad]). ``x`` (n, 3) current positions.
        """
        nr = len(self.rigid_nodes)
        J = np.zeros((nr, 3, self.n_rigid_dof))
        b = self._bounds
        arm = x[self.effector_nodes] - p  # R rho_i [mm]
        J[b[0] : b[1], :, 0:3] = np.eye(3)
        J[b[0] : b[1], :, 3:6] = -skew(arm)
        for k, s in enumerate(self.servos):
            J[b[k + 1] : b[k + 2], :, 6 + k] = cross(s.axis, x[s.nodes] - s.pivot)
        return J.reshape(3 * nr, self.n_rigid_dof)

    def rigid_geometric(self, x, p, r) -> np.ndarray:
        """(6 + na, 6 + na) geometric stiffness d(J_r^T r)/dq_r at fixed nodal vector r.

        ``r`` (n, 3) [N] nodal residual forces f(x) - f_ext. Effector block:
        ``sum_i (a_i r_i^T - (a_i . r_i) I)`` with ``a_i = x_i - p`` (symmetric when the
        torque vanishes, i.e. at equilibrium); servo k: ``sum_i r_i . (a x (a x (x_i - c)))``.
        """
        G = np.zeros((self.n_rigid_dof, self.n_rigid_dof))
        e = self.effector_nodes
        a, re = x[e] - p, r[e]
        G[3:6, 3:6] = a.T @ re - np.sum(a * re) * np.eye(3)
        for k, s in enumerate(self.servos):
            d = x[s.nodes] - s.pivot
            G[6 + k, 6 + k] = np.sum(r[s.nodes] * cross(s.axis, cross(s.axis, d)))
        return G
