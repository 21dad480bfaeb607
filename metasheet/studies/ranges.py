"""Motor-range study (paper Fig. 6): the reach test repeated for several motor ranges.

Each (range, ray) pair is one work unit: the same continuation as the workspace study
(:func:`.workspace.explore_ray`) without the rotation tests, on the robot with the motors
limited to that range. A range that excludes the rest angles starts from the equilibrium at
the rest angles clipped into it.

A point is reachable in a range when some motor path inside the range leads from rest to it.
A narrower range's path is such a path in every wider range that holds the rest angles: it
starts at rest (or moves from rest straight to the rest angles clipped into the narrower
range, inside the wider one, which is a box) and stays inside the narrower range. The
continuation of one range can stall where another's path goes on (the paths differ once a
motor meets a bound), so each range's own search (``found``) misses some points a narrower
range reached; they are counted reachable in the wider range, with the narrower range's
motors as their witness (``via``). Nesting is then checked on the reachable sets: it can
still fail for a wider range that excludes the rest angles, where no witness applies.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from ..errors import ConfigError
from ..runtime.executor import Executor
from .grid import StarGrid
from .model import MODELS, ModelSpec, check_motor_range
from .resume import UnitCache
from .workspace import RayTask, WorkspaceSettings, domain_spec, explore_ray


@dataclass(frozen=True)
class RangesResult:
    """ranges : (r, 2) [deg]; goals : (n, 3) [mm]; reached : (r, n) bool, reachable in each
    range (its own search or a narrower range's path, :func:`adopt_narrower`); found : (r, n)
    bool, reached by the range's own search; via : (r, n) int, the range whose path reached the
    point (-1: unreached); error_mm : (r, n) and motors_deg : (r, n, n_motors) [deg] of that
    path's reach (NaN where untried); violations : list of (wide range index, narrow range
    index, points reachable in the narrow range only); nested : no violation; rest_pose : (6,)
    the model's rest pose [mm, rad] (the goals' orientation)."""

    ranges: np.ndarray
    goals: np.ndarray
    reached: np.ndarray
    found: np.ndarray
    via: np.ndarray
    error_mm: np.ndarray
    violations: list
    nested: bool
    motors_deg: np.ndarray
    rest_pose: np.ndarray

    def counts(self) -> list[int]:
        return [int(r.sum()) for r in self.reached]

    def found_counts(self) -> list[int]:
        return [int(r.sum()) for r in self.found]


def contains(a: Sequence[float], b: Sequence[float]) -> bool:
    """True when motor range ``a`` contains range ``b``."""
    return a[0] <= b[0] and b[1] <= a[1]


def adopt_narrower(found: np.ndarray, ranges: Sequence[Sequence[float]], rest_deg: np.ndarray) -> np.ndarray:
    """via (r, n) int: for each range and point, the range whose path reached the point: the
    range itself where its own search did (``found`` (r, n) bool), else the first narrower range
    (in ``ranges`` order) that did, when the range holds the rest angles ``rest_deg`` (na,)
    [deg] (the narrower path is then admissible in it); -1: unreached."""
    r = len(ranges)
    via = np.where(found, np.arange(r)[:, None], -1)
    for a, ra in enumerate(ranges):
        if not (ra[0] <= rest_deg.min() and rest_deg.max() <= ra[1]):
            continue
        for b, rb in enumerate(ranges):
            if b != a and contains(ra, rb):
                via[a, found[b] & (via[a] < 0)] = b
    return via


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
    model = MODELS.get(spec)
    rest = model.rest_pose()
    rays = [grid.ray_points(r) for r in range(len(grid.directions))]
    tasks = [RayTask(spec.with_motor_range(lo, hi), s, rest[:3] + grid.points[ids]) for lo, hi in ranges for ids in rays]
    parts = cache.map(executor, explore_ray, tasks, progress=lambda d, n: progress("motor ranges", d, n))
    n = len(grid)
    found = np.zeros((len(ranges), n), bool)
    err = np.full((len(ranges), n), np.nan)
    motors = np.full((len(ranges), n, parts[0].motors_deg.shape[1] if parts else 0), np.nan)
    for t, rec in enumerate(parts):
        r, ray = divmod(t, len(rays))
        found[r, rays[ray]] = rec.reached
        err[r, rays[ray]] = rec.error_mm
        motors[r, rays[ray]] = rec.motors_deg
    via = adopt_narrower(found, ranges, np.asarray(model.rest_motors(), float))
    reached = via >= 0
    own = np.arange(len(ranges))[:, None]
    src, pts = np.where(reached, via, own), np.arange(n)[None, :]
    err, motors = err[src, pts], motors[src, pts]
    violations = []
    for a, ra in enumerate(ranges):
        for b, rb in enumerate(ranges):
            if a != b and contains(ra, rb):
                extra = np.flatnonzero(reached[b] & ~reached[a])
                if len(extra):
                    violations.append((a, b, extra.tolist()))
    return RangesResult(np.array(ranges), rest[:3] + grid.points, reached, found, via, err, violations,
                        not violations, motors, rest.copy())
