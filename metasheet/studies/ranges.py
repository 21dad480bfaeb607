"""Motor-range study (paper Fig. 6): the reach test repeated for several motor ranges.

Each (range, ray) pair is one work unit: the same continuation as the workspace study
(:func:`.workspace.explore_ray`) without the rotation tests, on the robot with the motors
limited to that range. A narrower range is a subset of the control set of a wider one, so
its reachable set should nest inside the wider one's; the check counts the exceptions
(a continuation path can in principle stall in one range and not another). A range that
excludes the rest angles starts from the equilibrium at the rest angles clipped into it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from ..errors import ConfigError
from ..executor import Executor
from .grid import StarGrid
from .model import MODELS, ModelSpec, check_motor_range
from .resume import UnitCache
from .workspace import RayTask, WorkspaceSettings, domain_spec, explore_ray


@dataclass(frozen=True)
class RangesResult:
    """ranges : (r, 2) [deg]; goals : (n, 3) [mm]; reached : (r, n) bool; error_mm : (r, n);
    violations : list of (wide range index, narrow range index, points reached by the narrow
    range only); nested : no violation; motors_deg : (r, n, n_motors) the final motor angles
    of each point's reach [deg] (NaN where untried); rest_pose : (6,) the model's rest pose
    [mm, rad] (the goals' orientation)."""

    ranges: np.ndarray
    goals: np.ndarray
    reached: np.ndarray
    error_mm: np.ndarray
    violations: list
    nested: bool
    motors_deg: np.ndarray
    rest_pose: np.ndarray

    def counts(self) -> list[int]:
        return [int(r.sum()) for r in self.reached]


def contains(a: Sequence[float], b: Sequence[float]) -> bool:
    """True when motor range ``a`` contains range ``b``."""
    return a[0] <= b[0] and b[1] <= a[1]


def motor_range_study(
    spec: ModelSpec,
    grid: StarGrid,
    ranges: Sequence[tuple[float, float]],
    settings: WorkspaceSettings = WorkspaceSettings(),
    *,
    executor: Executor = Executor(),
    progress: Callable[[str, int, int], None] = lambda d, i, n: None,
    cache: UnitCache | None = None,
) -> RangesResult:
    """Reachable sets of ``grid`` for each motor range (lo, hi) [deg] in ``ranges``."""
    if len(ranges) == 0:
        raise ConfigError("ranges: []: expected at least one (lo, hi) motor range")
    ranges = [check_motor_range(f"ranges[{i}]", *r) for i, r in enumerate(ranges)]
    s = replace(settings, rotations=False, continuity=False)
    cache = cache or UnitCache(None)
    spec = domain_spec(spec, s)
    rest = MODELS.get(spec).rest_pose()
    rays = [grid.ray_points(r) for r in range(len(grid.directions))]
    tasks = [RayTask(spec.with_motor_range(lo, hi), s, rest[:3] + grid.points[ids]) for lo, hi in ranges for ids in rays]
    parts = cache.map(executor, explore_ray, tasks, progress=lambda d, n: progress("motor ranges", d, n))
    n = len(grid)
    reached = np.zeros((len(ranges), n), bool)
    err = np.full((len(ranges), n), np.nan)
    motors = np.full((len(ranges), n, parts[0].motors_deg.shape[1] if parts else 0), np.nan)
    for t, rec in enumerate(parts):
        r, ray = divmod(t, len(rays))
        reached[r, rays[ray]] = rec.reached
        err[r, rays[ray]] = rec.error_mm
        motors[r, rays[ray]] = rec.motors_deg
    violations = []
    for a, ra in enumerate(ranges):
        for b, rb in enumerate(ranges):
            if a != b and contains(ra, rb):
                extra = np.flatnonzero(reached[b] & ~reached[a])
                if len(extra):
                    violations.append((a, b, extra.tolist()))
    return RangesResult(np.array(ranges), rest[:3] + grid.points, reached, err, violations, not violations, motors,
                        rest.copy())
