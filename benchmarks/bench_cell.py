"""Benchmark of the cell stage's pieces on a 64-seed open-cell foam (issue 3's performance targets).

Run:  python benchmarks/bench_cell.py [--repeats 5] [--n 64]

Prints one row per measurement: median and min wall seconds over the repeats (after one
warm-up call that also compiles the numba kernels), the target when the issue sets one,
and a note. To add a row, append ``Row(name, make, target_s, note)`` to ``ROWS``: ``make``
receives the shared :class:`Case` and returns the zero-argument callable to time.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from metasheet.cells import Foam, foam_field, solve_thickness, voxelize
from metasheet.cells.connectivity import check_percolation
from metasheet.cells.metrics import PolyhedralMetric, StretchedMetric
from metasheet.cells.seeds import poisson_disk_seeds

from _results import add_save_option, saved_output


@dataclass
class Case:
    """The benchmark foam: 64 Poisson-disk seeds in a 10 mm box, open cells, rho 0.15."""

    n: int = 64
    size: np.ndarray = field(default_factory=lambda: np.array([10.0, 10.0, 10.0]))
    count: int = 64
    rho: float = 0.15
    metric: StretchedMetric = field(default_factory=StretchedMetric)

    def __post_init__(self):
        self.seeds = poisson_disk_seeds(self.count, self.size, 1, scale=self.metric.scale)
        sol = solve_thickness(self.seeds, self.size, self.metric, "open", self.rho, self.n)
        self.foam = Foam(self.seeds, self.size, self.metric, "open", sol.thickness)
        self.phases = voxelize(self.foam, self.n)

    def foam_with(self, metric) -> Foam:
        seeds = poisson_disk_seeds(self.count, self.size, 1, scale=metric.scale)
        sol = solve_thickness(seeds, self.size, metric, "open", self.rho, self.n)
        return Foam(seeds, self.size, metric, "open", sol.thickness)


@dataclass(frozen=True)
class Row:
    name: str
    make: Callable[[Case], Callable[[], object]]
    target_s: float | None = None
    note: str = ""


def _design(case: Case):
    from metasheet.cells.catalogue import design_cell, parse_design

    d = parse_design({
        "name": "bench", "size": case.size.tolist(), "resolution": case.n, "relative_density": case.rho,
        "seeds": {"count": case.count, "seed": 1}, "metric": {"kind": "stretched", "stretch": 1.0},
    })
    return lambda: design_cell(d)


ROWS: list[Row] = [
    Row("seeds: 64 Poisson-disk", lambda c: lambda: poisson_disk_seeds(c.count, c.size, 1)),
    Row("voxels n^3 (voxelize, Euclidean)", lambda c: lambda: voxelize(c.foam, c.n), 5.0,
        "the issue's target: 64-seed open foam, n = 64"),
    Row("density solve n^3 (solve_thickness)",
        lambda c: lambda: solve_thickness(c.seeds, c.size, c.metric, "open", c.rho, c.n)),
    Row("design_cell n^3 (seeds + solve + checks)", _design, 5.0, "what the stage does before writing"),
    Row("voxels n^3, stretched 3 transverse",
        lambda c: (lambda f: lambda: voxelize(f, c.n))(c.foam_with(StretchedMetric(3.0, 2, "transverse")))),
    Row("voxels n^3, polyhedral k = 6",
        lambda c: (lambda f: lambda: voxelize(f, c.n))(c.foam_with(PolyhedralMetric(6, 1.5, 0.8))),
        None, "k-nearest search (no Delaunay shortcut)"),
    Row("field at 10^5 random points", lambda c: (
        lambda f, p: lambda: f(p))(foam_field(c.foam), np.random.default_rng(0).random((100_000, 3)) * c.size)),
    Row("percolation check n^3", lambda c: lambda: check_percolation(c.phases)),
]


def time_row(fn: Callable[[], object], repeats: int) -> tuple[float, list[float]]:
    t0 = time.perf_counter()
    fn()  # warm-up (numba compilation, caches)
    warm = time.perf_counter() - t0
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return warm, times


def main(argv=None, rows: list[Row] | None = None) -> list[dict]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--n", type=int, default=64, help="voxels per side")
    add_save_option(ap)
    args = ap.parse_args(argv)
    case = Case(n=args.n)
    with saved_output(__file__, args.save, fenced=True):
        print(f"64-seed open-cell foam, 10 mm box, rho {case.rho}, n = {case.n}; "
              f"{os.cpu_count()} cpus, OMP/NUMBA threads {os.environ.get('NUMBA_NUM_THREADS', 'default')}; "
              f"median of {args.repeats} after one warm-up")
        header = f"{'measurement':44s} {'median s':>9s} {'min s':>8s} {'warm-up s':>9s} {'target s':>8s}  note"
        print(header)
        print("-" * len(header))
        out = []
        for row in rows or ROWS:
            warm, times = time_row(row.make(case), args.repeats)
            med = statistics.median(times)
            flag = "" if row.target_s is None else ("ok" if med < row.target_s else "SLOW")
            target = "" if row.target_s is None else f"{row.target_s:g} {flag}"
            print(f"{row.name.replace('n^3', f'{case.n}^3'):44s} {med:9.3f} {min(times):8.3f} {warm:9.3f} {target:>8s}  {row.note}")
            out.append({"name": row.name, "median_s": med, "min_s": min(times), "warmup_s": warm,
                        "target_s": row.target_s})
    return out


if __name__ == "__main__":
    main()
