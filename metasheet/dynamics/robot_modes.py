"""The robot's natural modes at an equilibrium: the sheets, the rod (and plate) with the servo
horns held, linearised in the robot's own coordinates ``y = (q_e (6), x_f (3 n_f))``.

With ``T = dx/dy`` (the effector nodes' rows ``[I, -[x_i - p]x]``, the free nodes' the
identity, the horn nodes' zero: the servos hold them) the stiffness and mass seen by ``y`` are

    K_y = T^T K T + G,      M_y = T^T M T + sum_i m_i J_i^T J_i,

``G`` the rigid body's geometric term at the equilibrium's forces (:meth:`RigidCoupling.rigid_geometric`,
and the rod's weight on its six point masses) and the last sum the rod and plate's inertia
(:func:`.robot.point_masses`). ``K_y`` is symmetrised: the corotational tangent of an
anisotropic sheet is not exactly symmetric away from rest (:meth:`ElasticBody.forces_and_tangent`);
its skew part is reported (``asymmetry``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..mechanics.rotations import skew
from .modes import natural_modes


@dataclass(frozen=True)
class RobotModes:
    """frequencies_hz (k,); shapes (k, n, 3) the nodes' motion per mode (M-normalised in y,
    [mm / sqrt(t)]); effector (k, 6) the rod's (mm, rad) per mode; asymmetry: |K_y - K_y^T| / |K_y|."""

    frequencies_hz: np.ndarray
    shapes: np.ndarray
    effector: np.ndarray
    asymmetry: float


def coordinate_map(robot, state) -> sp.csr_matrix:
    """T = dx/dy, sparse (3 n, 6 + 3 n_f) at ``state`` (module docstring)."""
    c = robot.coupling
    n, nf = robot.body.n_nodes, len(c.free)
    e = c.effector_nodes
    arm = state.x[e] - state.p
    blocks = np.zeros((len(e), 3, 6))
    blocks[:, :, :3] = np.eye(3)
    blocks[:, :, 3:] = -skew(arm)
    rows_e = np.repeat((3 * e[:, None] + np.arange(3)).ravel(), 6)
    cols_e = np.tile(np.arange(6), 3 * len(e))
    rows_f = (3 * c.free[:, None] + np.arange(3)).ravel()
    cols_f = 6 + np.arange(3 * nf)
    rows = np.concatenate([rows_e, rows_f])
    cols = np.concatenate([cols_e, cols_f])
    vals = np.concatenate([blocks.ravel(), np.ones(3 * nf)])
    return sp.csr_matrix((vals, (rows, cols)), shape=(3 * n, 6 + 3 * nf))


def condensed_matrices(dyn, state) -> tuple[np.ndarray | sp.csr_matrix, sp.csr_matrix, sp.csr_matrix, float]:
    """(K_y, M_y, T, asymmetry) of :class:`.robot.DynamicRobot` ``dyn`` at ``state`` (module docstring)."""
    robot = dyn.robot
    c = robot.coupling
    f, K = robot.body.forces_and_tangent(state.x)
    r = f.reshape(-1, 3) - robot.f_ext
    T = coordinate_map(robot, state)
    Ky = (T.T @ K @ T).tocsr()
    G = c.rigid_geometric(state.x, state.p, r)[:6, :6]
    x = dyn.points(state.p, state.R)
    arm = x - state.p
    w = -dyn.m_pts[:, None] * dyn.g  # the rod's weight as a residual (internal minus external)
    G[3:, 3:] += arm.T @ w - np.sum(arm * w) * np.eye(3)
    J = np.zeros((6, 3, 6))
    J[:, :, :3] = np.eye(3)
    J[:, :, 3:] = -skew(arm)
    Mr = np.einsum("pia,p,pib->ab", J, dyn.m_pts, J)
    pad = sp.csr_matrix((np.ones(6), (np.arange(6), np.arange(6))), shape=(Ky.shape[0], 6))
    Ky = Ky + pad @ sp.csr_matrix(G) @ pad.T
    My = (T.T @ dyn.M @ T).tocsr() + pad @ sp.csr_matrix(Mr) @ pad.T
    skew_part = 0.5 * (Ky - Ky.T)
    asym = float(abs(skew_part).max() / max(abs(Ky).max(), 1e-300))
    return (0.5 * (Ky + Ky.T)).tocsr(), My.tocsr(), T, asym


def robot_modes(dyn, state, n: int = 10) -> RobotModes:
    """The first ``n`` natural modes of ``dyn`` (:class:`.robot.DynamicRobot`) at the equilibrium ``state``."""
    Ky, My, T, asym = condensed_matrices(dyn, state)
    modes = natural_modes(Ky, My, n=n)
    phi = np.asarray(modes.shapes)  # (ny, n)
    x = (T @ phi).T.reshape(n, -1, 3)
    return RobotModes(np.asarray(modes.frequencies_hz), x, phi[:6].T.copy(), asym)
