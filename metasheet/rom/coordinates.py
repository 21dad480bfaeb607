"""The reduced model's coordinates and the data that defines them (issue 16).

``q = (q_e (6), q_a (na), a (k))``: the effector pose, the motor angles and the sheets'
free nodes in the basis, ``x_f = X_f + V a``. Here are the state (:class:`ReducedState`),
the trained data that fixes ``V`` and the element sample (:class:`ReducedBasis`, the
``reduce`` stage's ``basis.npz``), the full robot's identity a basis is tied to
(:func:`robot_key`), a full state's projection (:func:`projected_state`) and the map
``T = dx/dq`` (:func:`coordinate_jacobian`). The model on them is :mod:`.model`; these
types sit apart so the model's linearizer (:mod:`.linearizer`) and the training
(:mod:`.training`) use them without importing the model back.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from ..mechanics.rotations import cross, rotation_vector, skew


@dataclass(frozen=True)
class ReducedBasis:
    """What training produced (:mod:`.training`).

    Attributes
    ----------
    V : (3 n_f, k) orthonormal basis of the free nodes' displacements from rest [-] (free
        nodes in :attr:`metasheet.robot.rigid.RigidCoupling.free` order, node-major).
    elements : (s,) int sampled elements of the full body; weights : (s,) float > 0 [-].
    box_lo, box_hi : (na,) the motor box trained on [rad]: outside it the model extrapolates.
    robot_key : identity of the full robot it was trained on (:func:`robot_key`).
    info : JSON-able training record (sizes, tolerances, errors).
    """

    V: np.ndarray
    elements: np.ndarray
    weights: np.ndarray
    box_lo: np.ndarray
    box_hi: np.ndarray
    robot_key: str
    info: dict = field(default_factory=dict)

    @property
    def k(self) -> int:
        return int(self.V.shape[1])

    def save(self, path: Path) -> None:
        """Write ``path`` (.npz) atomically."""
        path = Path(path)
        tmp = path.with_name(path.name + ".tmp.npz")
        np.savez(tmp, V=self.V, elements=self.elements, weights=self.weights, box_lo=self.box_lo,
                 box_hi=self.box_hi, robot_key=np.array(self.robot_key), info=np.array(json.dumps(self.info)))
        tmp.replace(path)

    @classmethod
    def load(cls, path: Path) -> "ReducedBasis":
        path = Path(path)
        if not path.is_file():
            raise ConfigError(f"reduced model: {path} is missing; run the 'reduce' stage")
        with np.load(path) as z:
            return cls(z["V"], z["elements"], z["weights"], z["box_lo"], z["box_hi"], str(z["robot_key"]),
                       json.loads(str(z["info"])))


def robot_key(robot) -> str:
    """A content hash of the full robot's mesh, tensors, couplings and loads: a basis only
    fits the robot it was trained on."""
    import hashlib

    h = hashlib.sha256()
    b, c = robot.body, robot.coupling
    for a in (b.rest, b.tets, b.stiffness, b.mass, c.effector_nodes, robot.gravity):
        h.update(np.ascontiguousarray(a).tobytes())
    for s in c.servos:
        h.update(np.ascontiguousarray(np.concatenate([s.axis, s.pivot, [s.rest_angle]])).tobytes())
        h.update(np.ascontiguousarray(s.nodes).tobytes())
    return h.hexdigest()[:24]


@dataclass(frozen=True)
class ReducedState:
    """A configuration of the reduced robot: effector ``p`` (3,) [mm] and ``R`` (3, 3), motor
    ``angles`` (na,) [rad], and the sheets' reduced coordinates ``a`` (k,) [mm]."""

    p: np.ndarray
    R: np.ndarray
    angles: np.ndarray
    a: np.ndarray

    @property
    def pose(self) -> np.ndarray:
        """(6,) effector pose: position [mm] and rotation vector [rad]."""
        return np.concatenate([self.p, rotation_vector(self.R)])


def projected_state(robot, V: np.ndarray, state) -> ReducedState:
    """The reduced state closest to a full :class:`~metasheet.robot.statics.RobotState` on the
    basis ``V`` (rigid coordinates as they are, ``a = V^T (x_f - X_f)``) of the full ``robot``."""
    c = robot.coupling
    u = (state.x[c.free] - c.rest[c.free]).ravel()
    return ReducedState(state.p, state.R, state.angles, V.T @ u)


def coordinate_jacobian(coupling, x, p, eff, servo, free, V, *, node_major: bool = False,
                        dtype=np.float64) -> np.ndarray:
    """(len(x), 3, 6 + na + k) dx / dq of the nodes at positions ``x`` [mm]: rows ``eff`` move
    with the effector (reference point ``p`` [mm]), ``servo[k]`` with horn k, ``free`` with the
    basis rows ``V`` (3 len(free), k) (any other row is zero).

    Stored coordinate-major (``T.reshape(-1, nq)`` a Fortran-ordered view), or with
    ``node_major`` C-ordered: the same numbers, filled 3x faster, and a sparse stiffness times
    it runs ~15 % faster with bit-identical results (the reduced tangent's ``K T``: 42 against
    50 ms on the paper's sample, scipy 1.17). The training keeps the coordinate-major layout:
    its element sample is sensitive to round-off, and a gemv on the other layout (``T^T f``)
    sums in another order. ``dtype`` (node-major only): the array's type."""
    na = coupling.n_act
    if node_major:
        T = np.zeros((len(x), 3, 6 + na + V.shape[1]), dtype)
        T[eff, :, 0:3] = np.eye(3)
        T[eff, :, 3:6] = -skew(x[eff] - p)
        for k, (s, idx) in enumerate(zip(coupling.servos, servo)):
            T[idx, :, 6 + k] = cross(s.axis, x[idx] - s.pivot)
        T[free, :, 6 + na:] = V.reshape(len(free), 3, -1)
        return T
    Tt = np.zeros((6 + na + V.shape[1], len(x), 3))
    Tt[0:3, eff, :] = np.eye(3)[:, None, :]
    Tt[3:6, eff, :] = -skew(x[eff] - p).transpose(2, 0, 1)
    for k, (s, idx) in enumerate(zip(coupling.servos, servo)):
        Tt[6 + k, idx, :] = cross(s.axis, x[idx] - s.pivot)
    Tt[6 + na:, free, :] = V.reshape(len(free), 3, -1).transpose(2, 0, 1)
    return Tt.transpose(1, 2, 0)
