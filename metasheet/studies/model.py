"""What a study needs from a robot: a small protocol, so the study logic is independent of the FEM.

A study talks to a :class:`RobotModel` (the live robot, with its factorisations) built
from a :class:`ModelSpec` (a small picklable description: mesh arrays and parameters).
Work units sent to other processes carry the spec, never the live model; each process
builds the model once and keeps it in its :class:`ModelCache`, :data:`MODELS`.

Poses are ``(6,)`` arrays ``[x, y, z, rx, ry, rz]``: the effector position [mm] and its
rotation vector relative to the rest orientation [rad]. Motor angles are degrees.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from ..errors import ConfigError
from ..mechanics.rotations import rotation_matrix


@dataclass(frozen=True)
class ReachResult:
    """Outcome of one inverse-model run towards a goal pose.

    Attributes
    ----------
    reached : the model's own verdict for the tolerances it was given.
    pose : (6,) float, final pose [mm, rad].
    motors_deg : (n_motors,) float, final motor angles [deg].
    error_mm : distance between final and goal positions [mm].
    error_deg : angle of the rotation between final and goal orientations [deg].
    steps : control steps used.
    state : opaque model state, to continue from (picklable).
    converged : False when the model's equilibrium solver failed (the pose is then the last
        control state's, and the goal counts as not reached).
    left_domain : True when the reach left the model's domain on the way (past a reduced
        model's training box, the material beyond the strain limit): the pose and state are
        those where it left, and the goal counts as not reached.
    stopped : True when the caller's ``stop`` ended the reach before its goal (the state is
        the last one before ``stop`` fired).
    """

    reached: bool
    pose: np.ndarray
    motors_deg: np.ndarray
    error_mm: float
    error_deg: float
    steps: int
    state: Any = None
    converged: bool = True
    left_domain: bool = False
    stopped: bool = False


@runtime_checkable
class RobotModel(Protocol):
    """A robot as the studies see it (real FEM through :mod:`.adapter`, or :mod:`.standin`)."""

    #: index (0, 1, 2) of the rod axis in the pose's rotation part: rod rotation = pose[3 + rod_axis].
    rod_axis: int
    #: (lo, hi) motor limits [deg].
    motor_range: tuple[float, float]
    #: +1 when "pulling" (paper Fig. 7) raises the motor angles, -1 when it lowers them.
    pull_sign: float

    def rest_pose(self) -> np.ndarray:
        """(6,) effector pose at rest [mm, rad]."""

    def rest_motors(self) -> np.ndarray:
        """(n_motors,) motor angles at rest [deg]."""

    def reach(self, goal, *, state=None, tol_mm: float = 1.0, tol_deg: float | None = None,
              max_steps: int = 50, rot_weight: float | None = None) -> ReachResult:
        """Run the inverse model from ``state`` (rest when None) towards ``goal`` (6,).

        Never raises for an unreachable goal: returns the closest pose it found.
        ``tol_deg`` None means the orientation is not part of the stopping test;
        ``rot_weight`` [mm/rad] overrides the QP's weight of rotation errors (0: position only).
        """

    def equilibrium(self, motors_deg, *, state=None, intermediate: bool = False) -> tuple[np.ndarray, Any]:
        """Forward model: the pose (6,) and the state at equilibrium for ``motors_deg``.
        ``intermediate``: a state that only starts the next solve of a path (a ramp's step),
        converged to the path's looser tolerance (:data:`metasheet.robot.equilibrium.PATH_TOL`)."""

    def max_principal_strain(self, state) -> float:
        """Largest principal (Green-Lagrange or log) strain in the soft parts at ``state`` [-]."""

    def min_singular_value(self, state) -> float:
        """Smallest singular value of the direct Jacobian at ``state`` (loss of control -> 0)."""


class ModelSpec(Protocol):
    """A picklable, hashable recipe for a :class:`RobotModel`."""

    @property
    def key(self) -> str:
        """Stable identity (content hash): equal keys build identical models."""

    @property
    def design_alpha(self) -> float:
        """Anisotropy of the design material, alpha = 100 - 100 E_l / E_t [%]."""

    def build(self) -> RobotModel: ...

    def with_motor_range(self, lo_deg: float, hi_deg: float) -> "ModelSpec": ...

    def with_alpha(self, alpha: float) -> "ModelSpec":
        """The same robot with the sheet material interpolated to ``alpha`` [%] (paper Fig. 7)."""

    def with_material(self, material, density: float | None = None) -> "ModelSpec":
        """The same robot with another sheet material (e.g. silicone) and density [t/mm^3]."""


class ModelCache:
    """Live models by spec, built on first use: one build per process per spec.

    Study work units run in other processes (a process pool, dask workers) and receive a
    picklable :class:`ModelSpec`; each process keeps the models it built in its own cache,
    :data:`MODELS`, so the units that follow on the same spec reuse the model (its
    factorisations, its controller's kept tangent). At most ``max_size`` models are kept; the
    least recently used is dropped first (a robot is big). It was the oldest built: in a
    pipeline run the anisotropy sweep's twelve robots, one per unit, pushed out the models the
    workspace and ranges units use on every ray. ``clear()`` empties it (tests, benchmarks).

    Parameters
    ----------
    max_size : models kept [-], >= 1.
    """

    def __init__(self, max_size: int = 4):
        if int(max_size) < 1:
            raise ConfigError(f"max_size: {max_size!r}: allowed range is [1, inf)")
        self.max_size = int(max_size)
        self._models: dict[str, RobotModel] = {}  # by spec.key, the least recently used first
        self._lock = threading.Lock()  # guards the two dicts: a run's stage threads share the cache
        self._building: dict[str, threading.Lock] = {}  # one lock per spec being built

    def get(self, spec: ModelSpec) -> RobotModel:
        """The model of ``spec``, built on the first call and kept by ``spec.key``. Threads
        asking for the same spec at once wait for one build (two stage threads of a run built
        the same reduced model side by side: 8 CPU s twice); other specs build meanwhile."""
        k = spec.key
        with self._lock:
            m = self._touch(k)
            if m is not None:
                return m
            building = self._building.setdefault(k, threading.Lock())
        with building:
            with self._lock:
                m = self._touch(k)
            if m is not None:  # built by the thread this one waited for
                return m
            m = spec.build()
            with self._lock:
                if len(self._models) >= self.max_size:
                    self._models.pop(next(iter(self._models)))
                self._models[k] = m
                self._building.pop(k, None)
        return m

    def _touch(self, k: str) -> RobotModel | None:
        """The model kept under ``k``, moved to the most recently used end (None: not kept)."""
        m = self._models.pop(k, None)
        if m is not None:
            self._models[k] = m
        return m

    def clear(self) -> None:
        """Drop every model (the next :meth:`get` of each spec builds it again)."""
        with self._lock:
            self._models.clear()

    def __len__(self) -> int:
        return len(self._models)

    def __contains__(self, spec: ModelSpec) -> bool:
        return spec.key in self._models


#: This process's models (a worker process has its own): the studies' work units build
#: through it. A worker may see a few specs (motor ranges, alphas), and a pipeline run's
#: workers serve its stages in turn (:meth:`~metasheet.runtime.executor.Executor.session`), hence 8.
MODELS = ModelCache(max_size=8)


def check_motor_range(field: str, lo: float, hi: float) -> tuple[float, float]:
    """Validate a motor range [deg] inside [0, 360) with lo < hi."""
    lo, hi = float(lo), float(hi)
    if not (-360.0 <= lo < hi <= 360.0):
        raise ConfigError(f"{field}: ({lo:g}, {hi:g}): expected lo < hi within [-360, 360] deg")
    return lo, hi


def rotation_angle_deg(r_goal: np.ndarray, r_pose: np.ndarray) -> float:
    """Angle [deg] of the rotation taking orientation ``r_pose`` to ``r_goal`` (rotation vectors [rad])."""
    Rg = rotation_matrix(np.asarray(r_goal, float))
    Rp = rotation_matrix(np.asarray(r_pose, float))
    c = 0.5 * (np.trace(Rg @ Rp.T) - 1.0)
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def pose_errors(goal: np.ndarray, pose: np.ndarray) -> tuple[float, float]:
    """(position error [mm], orientation error [deg]) between two poses (6,)."""
    goal = np.asarray(goal, float)
    pose = np.asarray(pose, float)
    return float(np.linalg.norm(goal[:3] - pose[:3])), rotation_angle_deg(goal[3:], pose[3:])
