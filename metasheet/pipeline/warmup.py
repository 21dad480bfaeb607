"""Compile the workers' numba kernels while the cell stage leaves them idle.

On a fresh clone numba's cache is empty, and every process compiles a kernel on its first call.
The homogenize stage's realisations start on both workers at once, so both compiled the voxel
solver's kernels side by side: 20.8 s of the stage's own realisation's 24 s of set-up and 42
of its 197 CPU s on the paper pipeline (3.6 s of set-up once compiled); the robot stage's
units did the same with the corotational kernels (13 CPU s). The cell stage runs alone in the
run's own process before them, with the workers idle. :func:`warm_up` hands each worker one
small problem per kernel family the run's stages need, at a priority before every stage: the
kernels are compiled once, while the cell is built, and written to numba's cache, from which
the stages' units load them. Once cached, a warm-up costs a second or so of a worker.

A warm-up computes nothing that is kept, and its failure is not the run's: a kernel it did not
compile is compiled where it is first called, as before. Its problems use the types the stages
use (contiguous float64 fields, int64 connectivity), so that the signature it compiles is the
one they load: :mod:`tests.test_warmup` checks that a stage's path finds every kernel
signature already compiled.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Iterable, Mapping

import numpy as np

log = logging.getLogger(__name__)

#: Which kernel families a stage's work units call on the workers.
STAGE_KERNELS = {
    "homogenize": ("voxel",),
    "chart": ("voxel",),
    "robot": ("corotational",),
    "design": ("corotational",),
    "dynamics": ("corotational",),
    "reduce": ("corotational",),  # and its ECSW kernel
    "workspace": ("corotational",),
    "ranges": ("corotational",),
    "anisotropy": ("corotational",),
    "maze": ("corotational",),
}

#: Priority of the warm-up units in the run's pool: before every stage (stages are 0, 1, ...).
PRIORITY = -1


def families(stage_names: Iterable[str]) -> tuple[str, ...]:
    """The kernel families (sorted, unique) that ``stage_names``' work units call."""
    return tuple(sorted({f for s in stage_names for f in STAGE_KERNELS.get(s, ())}))


class Warmer:
    """Submits the warm-ups of a run once, when its first stage that computes starts.

    pool : the run's :class:`~metasheet.runtime.priority_pool.PriorityPool` (None: a serial or
    dask run, nothing to warm); downstream : stage -> the stages that run after it when it
    does (itself included). A run whose stages are all up to date starts no worker for it.
    """

    def __init__(self, pool, downstream: Mapping[str, Iterable[str]]):
        self.pool, self.downstream = pool, {k: tuple(v) for k, v in downstream.items()}
        self.submitted: set[str] = set()
        self._lock = threading.Lock()

    def starting(self, stage: str) -> None:
        """Stage ``stage`` computes now: submit the warm-ups its and its downstream stages' units
        need that this run has not submitted, at :data:`PRIORITY`."""
        if self.pool is None:
            return
        with self._lock:
            todo = [f for f in families(self.downstream.get(stage, (stage,))) if f not in self.submitted]
            self.submitted.update(todo)
        for family in todo:
            self.pool.submit(PRIORITY, warm, family).add_done_callback(_log_failure)


def downstream_closure(names: Iterable[str], upstream: Callable[[str], Iterable[str]]) -> dict[str, tuple[str, ...]]:
    """stage -> itself and every stage of ``names`` that needs it, directly or not."""
    names = tuple(names)
    needs = {n: set(upstream(n)) & set(names) for n in names}
    out = {}
    for n in names:
        found, frontier = {n}, [n]
        while frontier:
            cur = frontier.pop()
            for m in names:
                if cur in needs[m] and m not in found:
                    found.add(m)
                    frontier.append(m)
        out[n] = tuple(m for m in names if m in found)
    return out


def _log_failure(fut) -> None:
    if not fut.cancelled() and fut.exception() is not None:
        log.warning("kernel warm-up failed (the kernels compile where first called): %s", fut.exception())


def warm(family: str) -> str:
    """Compile (or load from numba's cache) the kernels of ``family``: "voxel" or "corotational"."""
    if family == "voxel":
        _voxel()
    elif family == "corotational":
        _corotational()
    else:
        raise ValueError(f"family: {family!r}: allowed 'voxel' or 'corotational'")
    return family


def lattice_phases(n: int = 12, bar: int = 3) -> np.ndarray:
    """(n, n, n) uint8 periodic cubic frame (1 = solid): bars ``bar`` voxels wide along the
    three axes, one piece that percolates in every direction."""
    i = np.arange(n) < bar
    a, b, c = np.meshgrid(i, i, i, indexing="ij")
    return ((a & b) | (b & c) | (a & c)).astype(np.uint8)


def _voxel() -> None:
    """A periodic frame homogenised as a realisation is, with a hierarchy deep enough to run the
    split levels' kernels (their first factorised level has at most 300 unknowns here)."""
    from ..homogenize.voxel_periodic import periodic_stiffness
    from ..mechanics.material import Isotropic

    C = Isotropic(12.0, 0.3).stiffness()
    periodic_stiffness(lattice_phases(), np.ones(3), {1: C}, rtol=1e-6, direct_dofs=300)


def _corotational() -> None:
    """A force and a tangent of a P1 and a P2 body (six tetrahedra of a cube, their midpoints),
    and the reduce stage's ECSW deletion (a block of a C-ordered factor, as it is called)."""
    from ..rom.ecsw import _givens_sweep

    L = np.eye(4)
    _givens_sweep(L[1:3, 1:3], np.array([0.5, 0.25]))  # a strided block ("A" layout)
    _givens_sweep(L[3:4, 3:4], np.array([0.5]))  # a 1 x 1 block is C-contiguous: numba's other type
    from ..fem.tet10 import elevate_to_p2
    from ..robot.body import ElasticBody
    from ..mechanics.material import Isotropic

    pts, tets = cube_tets()
    C = np.ascontiguousarray(np.broadcast_to(Isotropic(12.0, 0.3).stiffness(), (len(tets), 6, 6)))
    for p, t in ((pts, tets), elevate_to_p2(pts, tets)):
        body = ElasticBody(p, t, C)
        x = body.rest + 0.01 * np.sin(np.arange(body.rest.size)).reshape(body.rest.shape)
        body.evaluate(np.ascontiguousarray(x), True)
        body.evaluate(np.ascontiguousarray(x), False)


def cube_tets() -> tuple[np.ndarray, np.ndarray]:
    """The unit cube's 8 corners (8, 3) and its split into 6 tetrahedra (6, 4) int64 (Kuhn)."""
    pts = np.array([[i & 1, (i >> 1) & 1, (i >> 2) & 1] for i in range(8)], float)
    paths = ((1, 2, 4), (1, 4, 2), (2, 1, 4), (2, 4, 1), (4, 1, 2), (4, 2, 1))
    tets = []
    for path in paths:
        v, t = 0, [0]
        for step in path:
            v += step
            t.append(v)
        tets.append(t)
    return pts, np.array(tets, dtype=np.int64)
