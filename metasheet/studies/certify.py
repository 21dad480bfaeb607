"""Re-certification of a study's reduced-model results by the full model (issue 16).

A study run on the reduced robot (:mod:`.reduced_adapter`) reports goals as reachable on the
reduced model's word. Here every such point (or a seeded random sample of ``size`` of them)
is re-solved by the full model, in work units on the executor: the full equilibrium at the
reduced result's motor angles, started from the reduced equilibrium's reconstruction
(:meth:`~.reduced_adapter.ReducedFem.certify`), then the full pose's error against the goal
with the study's own tolerances. A point *disagrees* when the full pose misses the goal (or
the full equilibrium fails).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import check_range
from ..runtime.executor import Executor
from .model import MODELS, ModelSpec
from .resume import UnitCache


@dataclass(frozen=True)
class CertifyTask:
    """Points to re-solve: goals (c, 6) [mm, rad], the reduced results' motors (c, na) [deg],
    the study's tolerances [mm], [deg] (None: orientation not tested)."""

    spec: ModelSpec
    goals: np.ndarray
    motors_deg: np.ndarray
    tol_mm: float
    tol_deg: float | None


def certify_points(task: CertifyTask) -> list:
    """Work unit: one :class:`~.reduced_adapter.PointCertificate` per point."""
    model = MODELS.get(task.spec)
    return [model.certify(g, q, tol_mm=task.tol_mm, tol_deg=task.tol_deg)
            for g, q in zip(task.goals, task.motors_deg)]


@dataclass(frozen=True)
class Certification:
    """What the full model says of the reduced model's reachable points.

    reachable : points the reduced model reported reachable; requested : the sample size
    asked for (0: all); seed : the sample's seed; certified : points re-solved; disagree :
    those the full model does not reach within the tolerances; points : one dict per
    disagreeing point (index, goal, motors, reduced and full errors, full_converged, in_box);
    solves : full solves run, one per distinct (goal, motors) among the certified points.
    """

    reachable: int
    requested: int
    seed: int
    certified: int
    disagree: int
    points: tuple
    solves: int = -1

    @property
    def rate(self) -> float:
        """Disagreement rate, disagree / certified (0 when nothing was certified) [-]."""
        return self.disagree / self.certified if self.certified else 0.0

    def to_dict(self) -> dict:
        return {"reachable": self.reachable, "requested": self.requested, "seed": self.seed,
                "certified": self.certified, "solves": self.solves, "disagree": self.disagree,
                "rate": round(self.rate, 6), "points": list(self.points)}


def sample(n: int, size: int, seed: int) -> np.ndarray:
    """Sorted indices of a seeded random sample of ``size`` of ``range(n)`` (0 or >= n: all)."""
    check_range("certify", size, 0, None)
    if size == 0 or size >= n:
        return np.arange(n)
    return np.sort(np.random.default_rng(seed).choice(n, int(size), replace=False))


def _r(v) -> float | None:
    return None if not np.isfinite(v) else round(float(v), 6)


def certify_study(
    spec: ModelSpec,
    goals: np.ndarray,
    motors_deg: np.ndarray,
    *,
    tol_mm: float,
    tol_deg: float | None = None,
    size: int = 0,
    seed: int = 0,
    executor: Executor = Executor(),
    progress: Callable[[str, int, int], None] = lambda d, i, n: None,
    cache: UnitCache | None = None,
    points_per_unit: int = 8,
    labels: list | None = None,
) -> Certification:
    """Certify reachable points ``goals`` (n, 6) [mm, rad] with motors ``motors_deg`` (n, na) [deg].

    ``size`` points (0: all) of a seeded random sample go to the full model, ``points_per_unit``
    per work unit; ``labels`` (n,) name each point in the list of disagreements (default: its index).
    """
    goals = np.asarray(goals, float).reshape(-1, 6)
    motors = np.asarray(motors_deg, float).reshape(len(goals), -1)
    idx = sample(len(goals), int(size), int(seed))
    distinct, which = _distinct(goals[idx], motors[idx])
    solve = idx[distinct]
    chunks = [solve[i:i + points_per_unit] for i in range(0, len(solve), points_per_unit)]
    tasks = [CertifyTask(spec, goals[c], motors[c], float(tol_mm), None if tol_deg is None else float(tol_deg))
             for c in chunks]
    cache = cache or UnitCache(None)
    parts = cache.map(executor, certify_points, tasks, progress=lambda d, n: progress("certify (full model)", d, n))
    solved = [c for part in parts for c in part]
    certs = [solved[j] for j in which]
    bad = []
    for i, c in zip(idx, certs):
        if c.agree:
            continue
        bad.append({"point": labels[i] if labels is not None else int(i),
                    "goal": [round(float(v), 6) for v in goals[i]],
                    "motors_deg": [round(float(v), 4) for v in motors[i]],
                    "reduced_error_mm": _r(c.reduced_error_mm), "reduced_error_deg": _r(c.reduced_error_deg),
                    "full_error_mm": _r(c.full_error_mm), "full_error_deg": _r(c.full_error_deg),
                    "full_converged": c.full_converged, "in_box": c.in_box})
    return Certification(len(goals), int(size), int(seed), len(certs), len(bad), tuple(bad), len(solve))


def _distinct(goals: np.ndarray, motors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rows, which): the indices of the points (goal (c, 6), motors (c, na)) that differ bit
    for bit from every point before them, in order, and for each point the position among
    ``rows`` of its own. A point a study reached twice with the same motors (two motor ranges
    that both contain its path) gets one full solve: the same inputs give the same answer."""
    first: dict[bytes, int] = {}
    rows, which = [], np.empty(len(goals), int)
    for i, (g, m) in enumerate(zip(goals, motors)):
        key = g.tobytes() + m.tobytes()
        if key not in first:
            first[key] = len(rows)
            rows.append(i)
        which[i] = first[key]
    return np.array(rows, int), which
