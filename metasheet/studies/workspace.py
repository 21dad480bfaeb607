"""Workspace exploration (paper Fig. 5) with validity, loss of control and continuity.

Each ray of a :class:`~.grid.StarGrid` is one work unit: its goals are reached by
continuation outwards from the rest pose (each reach starts from the last reached state),
within ``tol_mm`` (position only, as in the paper, unless ``hold_orientation``); at every
reached point the six rotations +-``rot_deg`` about x, y and z of the orientation reached
there are tried from that point's state, each within ``tol_rot_deg`` (and ``tol_mm``). An axis
counts when both signs succeed (the second sign is skipped, NaN, when the first fails). Classes: 3, 2, 1 axes, 0 = reachable only, -1 = unreachable.
With ``rot_stop_after`` = n, once n rotation-tested points in a row on a ray pass no axis, the
ray's outer points are still reached (the continuation is the same) but not rotation-tested:
they count as reachable only (:attr:`PointRecords.rot_tried` False), as the reach's own
``stop_after`` leaves a ray's outer points untried.

Two rotation tests (:data:`ROTATION_TESTS`, ``WorkspaceSettings.test``): ``"paper"`` (the
default) as the paper describes it, +-10 deg about x, y and z, each within 2 deg, each tried
from the point's state; ``"authors_code"`` as the authors' controller ran it
(VannesteFelix/anisotropy, ``examples/Tripod/inverse_simu/utility/tripodcontroller.py``:
``stepAngle = 5`` line 55, ``angle_offset = 3`` and ``pos_offset = 1`` lines 166-167, +5 deg
then -10 deg about the goal's local y only, lines 202 and 214, the x and z tries commented
out, lines 225-237; a point fails when the centre is more than 1 mm from the goal or moved
more than 1 mm since two animation steps earlier, lines 173-189 and 249-251): +-5 deg about y
in sequence (the -5 deg goal starts from the +5 deg state), within 3 deg and ``tol_mm``, and no
jump of more than ``jump_mm`` = 1 mm in any coordinate of the effector between successive test
states (point, +5, -5): the quasi-static reading of their settling check. In their scene the
goal's local y is perpendicular to the rod, like our y (rod along x). Their controller then
draws a point that passes as "3T + 3R" (line 272); here it counts one axis (class 1).

Beyond the paper: the largest principal strain at each reached point against a limit
(the homogenisation's domain of validity; with ``stop_beyond_strain`` a ray ends at its first
point beyond it, so the study stays where the material model holds and a reduced model trained
there suffices; that point is not rotation-tested and its outer points count as not tried; and
a rotation try fails when it meets its tolerances only beyond the limit, or its reach leaves the
model's domain on the way: :attr:`PointRecords.rot_beyond`), the smallest Jacobian singular value (loss of
control), and continuity: a graph whose nodes are the reached points (and the rest pose),
with an edge along each ray where continuation went, and an edge between points at the same
step of neighbouring rays when the inverse model walks from one to the other through
``substeps`` intermediate goals, each reached (:mod:`.continuity`). Its connected components are reported.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError, check_range
from ..runtime.executor import Executor
from .continuity import continuity
from .grid import StarGrid
from .model import MODELS, ModelSpec, pose_errors
from .reduced_adapter import PAST_BOX
from .resume import UnitCache

CLASS_NAMES = {3: "3 rotations", 2: "2 rotations", 1: "1 rotation", 0: "reachable only", -1: "unreachable"}

#: The rotation tests (see the module docstring): rotation [deg], its tolerance [deg], the axes,
#: the largest jump between successive test states [mm] (None: not checked), sequential tries.
ROTATION_TESTS = {
    "paper": {"rot_deg": 10.0, "tol_rot_deg": 2.0, "rot_axes": "xyz", "jump_mm": None, "sequential": False},
    "authors_code": {"rot_deg": 5.0, "tol_rot_deg": 3.0, "rot_axes": "y", "jump_mm": 1.0, "sequential": True},
}


@dataclass(frozen=True)
class WorkspaceSettings:
    """Tolerances and switches of the workspace study (lengths mm, angles deg).

    ``test`` names the rotation test it follows (:data:`ROTATION_TESTS`); build one with
    :meth:`for_test` so rot_deg, tol_rot_deg, rot_axes, jump_mm and sequential are the test's.
    """

    tol_mm: float = 1.0
    rot_deg: float = 10.0
    tol_rot_deg: float = 2.0
    test: str = "paper"
    rot_axes: str = "xyz"  # the axes tried, a subset of "xyz"
    jump_mm: float | None = None  # largest effector jump between successive test states (None: unchecked)
    sequential: bool = False  # each rotation from the previous one's state (else from the point's)
    max_steps: int = 60
    rotations: bool = True
    stop_after: int = 2  # consecutive failures on a ray before its outer points are left untried (0: try all)
    # consecutive rotation-tested points on a ray that pass no axis before the outer points' rotation
    # tries are left out (0: try every reached point)
    rot_stop_after: int = 0
    strain_limit: float = 0.3
    stop_beyond_strain: bool = False  # a ray ends at its first reached point beyond strain_limit
    # with stop_beyond_strain, which model carries a reduced model's reach on past its training box
    past_box: str = "reduced"
    continuity: bool = True
    substeps: int = 3
    hold_orientation: bool = False  # point goals also ask for the rest orientation (else position only)

    @property
    def point_rot_weight(self) -> float | None:
        """Rotation weight of the point reaches: the model's own, or 0 (position only)."""
        return None if self.hold_orientation else 0.0

    def __post_init__(self):
        check_range("tol_mm", self.tol_mm, 0.0, None, lo_open=True)
        check_range("rot_deg", self.rot_deg, 0.0, 90.0, lo_open=True)
        check_range("tol_rot_deg", self.tol_rot_deg, 0.0, 90.0, lo_open=True)
        check_range("max_steps", self.max_steps, 1, 100000)
        check_range("stop_after", self.stop_after, 0, 100000)
        check_range("rot_stop_after", self.rot_stop_after, 0, 100000)
        check_range("strain_limit", self.strain_limit, 0.0, None, lo_open=True)
        check_range("substeps", self.substeps, 1, 1000)
        if self.past_box not in PAST_BOX:
            raise ConfigError(f"past_box: {self.past_box!r}: allowed values are {', '.join(map(repr, PAST_BOX))}")
        if self.test not in ROTATION_TESTS:
            raise ConfigError(f"workspace.test: {self.test!r}: allowed values are "
                              f"{', '.join(repr(k) for k in ROTATION_TESTS)}")
        if not self.rot_axes or set(self.rot_axes) - set("xyz") or len(set(self.rot_axes)) != len(self.rot_axes):
            raise ConfigError(f"rot_axes: {self.rot_axes!r}: allowed: distinct letters of 'xyz'")
        if self.jump_mm is not None:
            check_range("jump_mm", self.jump_mm, 0.0, None, lo_open=True)

    @classmethod
    def for_test(cls, test: str = "paper", **overrides) -> WorkspaceSettings:
        """Settings of the rotation test ``test`` (:data:`ROTATION_TESTS`); ``overrides`` that
        are not None replace its values or set the other fields."""
        if test not in ROTATION_TESTS:
            raise ConfigError(f"workspace.test: {test!r}: allowed values are {', '.join(repr(k) for k in ROTATION_TESTS)}")
        return cls(test=test, **{**ROTATION_TESTS[test], **{k: v for k, v in overrides.items() if v is not None}})

    @property
    def axis_indices(self) -> tuple[int, ...]:
        """Indices (0, 1, 2 for x, y, z) of the axes tried, in order."""
        return tuple("xyz".index(a) for a in self.rot_axes)


@dataclass(frozen=True)
class RayTask:
    """One ray: goal positions (k, 3) [mm] (absolute), from the centre outwards."""

    spec: ModelSpec
    settings: WorkspaceSettings
    goals: np.ndarray


@dataclass(frozen=True)
class PointRecords:
    """Per-point records of a set of goals (k points); shapes in brackets.

    tried, reached (k,) bool; error_mm, error_deg (k,) of the point reach; motors_deg (k, 6);
    steps (k,) int; rot_error_mm, rot_error_deg (k, 6) for +x, -x, +y, -y, +z, -z (NaN untried);
    rot_ok (k, 3) bool per axis; strain, sigma_min (k,) (NaN when not reached);
    parent (k,) int: index in the ray of the point continuation started from (-1 = rest);
    converged (k,) bool: False where the model's equilibrium solver failed on the point reach
    (counted as not reached, with its error as recorded); rot_jump_mm (k,): the largest
    effector jump between successive test states [mm] (NaN unless the test checks it);
    left_domain (k,) bool: the reach left the model's domain (:attr:`~.model.ReachResult.left_domain`),
    its strain is the one at the domain's edge and the point counts as not reached;
    rot_beyond (k, 6) bool: with ``stop_beyond_strain``, the rotation try left the model's domain
    or met its tolerances beyond the strain limit: it fails (outside the material model);
    rot_tried (k,) bool: the point's rotations were tried (False where it was not reached, lies
    beyond the strain limit, or follows ``rot_stop_after`` points without an axis on its ray).
    """

    tried: np.ndarray
    reached: np.ndarray
    error_mm: np.ndarray
    error_deg: np.ndarray
    motors_deg: np.ndarray
    steps: np.ndarray
    rot_error_mm: np.ndarray
    rot_error_deg: np.ndarray
    rot_ok: np.ndarray
    strain: np.ndarray
    sigma_min: np.ndarray
    parent: np.ndarray
    converged: np.ndarray
    rot_jump_mm: np.ndarray
    left_domain: np.ndarray
    rot_beyond: np.ndarray
    rot_tried: np.ndarray


def rotation_goals(point: np.ndarray, rest_rot: np.ndarray, rot_deg: float) -> np.ndarray:
    """(6, 6) goal poses: ``point`` with the rest orientation turned by +-rot_deg about x, y, z."""
    out = np.zeros((6, 6))
    for a in range(3):
        for j, sgn in enumerate((1.0, -1.0)):
            w = np.zeros(3)
            w[a] = sgn * np.radians(rot_deg)
            out[2 * a + j, :3] = point
            out[2 * a + j, 3:] = _compose(w, rest_rot)
    return out


def _compose(w: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Rotation vector of exp([w]) exp([r]) (spatial increment w applied after r)."""
    from scipy.spatial.transform import Rotation

    return (Rotation.from_rotvec(w) * Rotation.from_rotvec(r)).as_rotvec()


def explore_ray(task: RayTask) -> PointRecords:
    """Work unit: continuation along one ray, then the rotation tests at every reached point."""
    model = MODELS.get(task.spec)
    s = task.settings
    rest = model.rest_pose()
    k = len(task.goals)
    nan = np.full(k, np.nan)
    rec = dict(tried=np.zeros(k, bool), reached=np.zeros(k, bool), error_mm=nan.copy(), error_deg=nan.copy(),
               motors_deg=np.full((k, len(model.rest_motors())), np.nan), steps=np.zeros(k, int),
               rot_error_mm=np.full((k, 6), np.nan), rot_error_deg=np.full((k, 6), np.nan),
               rot_ok=np.zeros((k, 3), bool), strain=nan.copy(), sigma_min=nan.copy(), parent=np.full(k, -1),
               converged=np.ones(k, bool), rot_jump_mm=nan.copy(), left_domain=np.zeros(k, bool),
               rot_beyond=np.zeros((k, 6), bool), rot_tried=np.zeros(k, bool))
    state, parent, fails, no_axis = start_state(model), -1, 0, 0
    for i, p in enumerate(task.goals):
        if s.stop_after and fails >= s.stop_after:
            break
        goal = np.concatenate([p, rest[3:]])
        res = model.reach(goal, state=state, tol_mm=s.tol_mm, tol_deg=None, max_steps=s.max_steps,
                          rot_weight=s.point_rot_weight)
        e_mm, e_deg = pose_errors(goal, res.pose)
        rec["tried"][i] = True
        rec["error_mm"][i], rec["error_deg"][i] = e_mm, e_deg
        rec["motors_deg"][i] = res.motors_deg
        rec["steps"][i] = res.steps
        rec["parent"][i] = parent
        rec["converged"][i] = res.converged
        if res.left_domain:  # beyond the strain limit on the way: outside the material model
            rec["left_domain"][i] = True
            rec["strain"][i] = model.max_principal_strain(res.state)
            if s.stop_beyond_strain:
                break
        if e_mm > s.tol_mm or not res.converged or res.left_domain:
            fails += 1
            continue
        fails = 0
        rec["reached"][i] = True
        rec["strain"][i] = model.max_principal_strain(res.state)
        rec["sigma_min"][i] = model.min_singular_value(res.state)
        beyond = s.stop_beyond_strain and not rec["strain"][i] <= s.strain_limit
        # beyond: outside the material model, not rotation-tested; after rot_stop_after points
        # without an axis the ray's outer points are reached but not rotation-tested
        if s.rotations and not beyond and not (s.rot_stop_after and no_axis >= s.rot_stop_after):
            _rotation_test(model, s, rec, i, p, rest[3:] if s.hold_orientation else res.pose[3:], res)
            rec["rot_tried"][i] = True
            no_axis = 0 if rec["rot_ok"][i].any() else no_axis + 1
        if beyond:
            break  # outside the material model's domain: the outer points are not tried
        state, parent = res.state, i
    return PointRecords(**rec)


def _rotation_test(model, s: WorkspaceSettings, rec: dict, i: int, point, base, res) -> None:
    """The +-rot_deg tries about ``s.rot_axes`` at reached point ``i`` (position ``point`` (3,),
    orientation ``base`` (3,) [rad], reach result ``res``), written into ``rec``."""
    goals = rotation_goals(point, base, s.rot_deg)
    state, pose, jump = res.state, res.pose, 0.0
    for a in s.axis_indices:
        for j in (2 * a, 2 * a + 1):
            if j % 2 and not _within(rec, i, j - 1, s):
                continue  # the axis failed one way already: the other sign cannot save it (NaN)
            r = model.reach(goals[j], state=state if s.sequential else res.state, tol_mm=s.tol_mm,
                            tol_deg=s.tol_rot_deg, max_steps=s.max_steps)
            rec["rot_error_mm"][i, j], rec["rot_error_deg"][i, j] = pose_errors(goals[j], r.pose)
            if s.stop_beyond_strain and (r.left_domain or _within(rec, i, j, s)):
                rec["rot_beyond"][i, j] = r.left_domain or not model.max_principal_strain(r.state) <= s.strain_limit
            jump = max(jump, float(np.abs(r.pose[:3] - pose[:3]).max()))  # [mm], any coordinate
            if s.sequential:
                state, pose = r.state, r.pose
    ok = (rec["rot_error_mm"][i] <= s.tol_mm) & (rec["rot_error_deg"][i] <= s.tol_rot_deg) & ~rec["rot_beyond"][i]
    if s.jump_mm is not None:
        rec["rot_jump_mm"][i] = jump
        ok &= jump <= s.jump_mm
    rec["rot_ok"][i] = ok.reshape(3, 2).all(axis=1)


def _within(rec, i, j, s) -> bool:
    return bool(rec["rot_error_mm"][i, j] <= s.tol_mm and rec["rot_error_deg"][i, j] <= s.tol_rot_deg
                and not rec["rot_beyond"][i, j])


def domain_spec(spec: ModelSpec, settings: WorkspaceSettings) -> ModelSpec:
    """``spec``, told the strain limit when the study stops beyond it and the model can use it
    (a reduced model then stops reaches past its box beyond the limit, carried on by
    ``settings.past_box``'s model)."""
    if settings.stop_beyond_strain and hasattr(spec, "with_domain_strain"):
        return spec.with_domain_strain(settings.strain_limit, settings.past_box)
    return spec


def start_state(model):
    """Where studies start: rest (None), or, when the rest angles lie outside the motor range
    (a narrowed range), the equilibrium at the rest angles clipped into it."""
    q0 = model.rest_motors()
    lo, hi = model.motor_range
    if q0.min() >= lo and q0.max() <= hi:
        return None
    return model.equilibrium(np.clip(q0, lo, hi))[1]


def classify(reached: np.ndarray, rot_ok: np.ndarray) -> np.ndarray:
    """(n,) class: number of rotation axes that work (3, 2, 1, 0) where reached, else -1."""
    return np.where(np.asarray(reached, bool), np.asarray(rot_ok, bool).sum(axis=1), -1).astype(int)


@dataclass(frozen=True)
class WorkspaceResult:
    """Everything the workspace study found; per-point arrays have n = len(grid) rows.

    goals : (n, 3) absolute goal positions [mm]; cls : (n,) class (see CLASS_NAMES);
    records : the :class:`PointRecords` of all points; valid : (n,) strain <= limit;
    component : (n,) connected component (0 = the rest pose's, -1 = unreachable);
    n_components : components among reached points; edges_tested / edges_passed : cross-ray paths.
    """

    goals: np.ndarray
    cls: np.ndarray
    records: PointRecords
    valid: np.ndarray
    component: np.ndarray
    n_components: int
    edges_tested: int
    edges_passed: int
    settings: WorkspaceSettings = field(default_factory=WorkspaceSettings)

    def counts(self) -> dict[str, int]:
        return {CLASS_NAMES[c]: int((self.cls == c).sum()) for c in (3, 2, 1, 0, -1)}


def _concat(parts: list[PointRecords]) -> PointRecords:
    return PointRecords(**{f: np.concatenate([getattr(p, f) for p in parts]) for f in PointRecords.__dataclass_fields__})


def near_rest_control(goals, cls, reached, rest_p, radius_mm: float) -> dict:
    """Full control around rest (paper Fig. 5: "at the initial position ... and in a whole area
    around it, we have a full 6 DOF control"): of the reachable goals (n, 3) [mm] within
    ``radius_mm`` of the rest position (3,) [mm], how many pass all three rotations (class 3).
    The share is the figure the report's verdict reads; a ball in which every point passes
    would hinge on the single worst grid point next to rest."""
    d = np.linalg.norm(np.asarray(goals, float) - np.asarray(rest_p, float), axis=1)
    near = np.asarray(reached, bool) & (d <= radius_mm)
    full = near & (np.asarray(cls) == 3)
    n = int(near.sum())
    return {"radius_mm": float(radius_mm), "reachable": n, "full_control": int(full.sum()),
            "share": round(int(full.sum()) / n, 4) if n else None}


def explore_workspace(
    spec: ModelSpec,
    grid: StarGrid,
    settings: WorkspaceSettings = WorkspaceSettings(),
    *,
    executor: Executor = Executor(),
    progress: Callable[[str, int, int], None] = lambda d, i, n: None,
    cache: UnitCache | None = None,
    edges_per_unit: int = 8,
) -> WorkspaceResult:
    """Run the workspace study of ``spec``'s robot on ``grid`` (see the module docstring)."""
    cache = cache or UnitCache(None)
    spec = domain_spec(spec, settings)
    rest = MODELS.get(spec).rest_pose()
    order = np.concatenate([grid.ray_points(r) for r in range(len(grid.directions))])
    tasks = [RayTask(spec, settings, rest[:3] + grid.points[grid.ray_points(r)]) for r in range(len(grid.directions))]
    parts = cache.map(executor, explore_ray, tasks, progress=lambda d, n: progress("workspace rays", d, n))
    rec_sorted = _concat(parts)
    inv = np.empty_like(order)
    inv[order] = np.arange(len(order))
    records = PointRecords(**{f: getattr(rec_sorted, f)[inv] for f in PointRecords.__dataclass_fields__})
    # parent indices are ray-local: map to global point indices
    parent = np.full(len(grid), -1)
    for r in range(len(grid.directions)):
        ids = grid.ray_points(r)
        loc = records.parent[ids]
        parent[ids] = np.where(loc >= 0, ids[np.maximum(loc, 0)], -1)
    goals = rest[:3] + grid.points
    cls = classify(records.reached, records.rot_ok)
    valid = records.reached & (records.strain <= settings.strain_limit)

    component, n_comp, tested, passed = continuity(spec, settings, grid, records, parent, goals, rest, executor=executor,
                                                   progress=progress, cache=cache, edges_per_unit=edges_per_unit)
    return WorkspaceResult(goals, cls, records, valid, component, n_comp, tested, passed, settings)
