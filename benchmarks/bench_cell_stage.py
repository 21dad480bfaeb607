"""The paper's Polyfoam cell stage, piece by piece (issue 59: the cell stage runs alone at the
start of the paper pipeline, on one core but for numba's kernels).

Run:  python benchmarks/bench_cell_stage.py [--repeats 3] [--design cells/paper_polyfoam.toml]

Times, median over the repeats in one process: the cell's voxels (``design_cell``) with numba's
kernels on one thread and on two; the surface check with the edges as one int64 key each
(:func:`metasheet.cells.surface_check.check_surface`) against the same check on rows of
vertex pairs (``np.unique(axis=0)``, the former way), with their ratio; the periodic
isosurface. The two checks must agree.
"""

from __future__ import annotations

import argparse
import statistics
import time
import tomllib

import metasheet  # noqa: F401  (pins numpy's code paths before numpy is imported)

# isort: split
import numba
import numpy as np

from _results import add_save_option, saved_output


def rows_check(faces: np.ndarray) -> tuple[bool, bool]:
    """(watertight, consistently wound) the former way: unique rows of vertex pairs."""
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    _, dcount = np.unique(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=0, return_counts=True)
    return bool(np.all(counts == 2)), bool(np.all(dcount == 1))


def timed(fn, repeats: int) -> tuple[float, object]:
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--design", default="cells/paper_polyfoam.toml")
    add_save_option(ap)
    a = ap.parse_args()

    from metasheet.cells.catalogue import design_cell, parse_design
    from metasheet.cells.surface import periodic_isosurface
    from metasheet.cells.surface_check import check_surface

    with open(a.design, "rb") as f:
        design = parse_design(tomllib.load(f), source=a.design)
    design_cell(design)  # warm-up: loads numba's cached kernels
    rows = []
    threads = numba.get_num_threads()
    for n in sorted({1, min(2, threads)}):
        numba.set_num_threads(n)
        t, cell = timed(lambda: design_cell(design), a.repeats)
        rows.append((f"voxels (design_cell), numba on {n} thread{'s' if n > 1 else ''}", t, ""))
    numba.set_num_threads(threads)
    t_iso, mesh = timed(lambda: periodic_isosurface(cell.field, cell.size, cell.resolution), a.repeats)
    rows.append((f"periodic isosurface ({len(mesh.faces):,} triangles)", t_iso, ""))
    faces = np.asarray(mesh.faces, dtype=np.int64)
    t_new, rep = timed(lambda: check_surface(mesh), a.repeats)
    t_old, (tight, wound) = timed(lambda: rows_check(faces), a.repeats)
    assert rep.watertight == tight and (not tight or rep.manifold <= wound)
    rows.append(("surface check, int64 edge keys", t_new, f"{t_old / t_new:.1f}x faster than the rows' unique"))
    rows.append(("the rows' unique alone (the former way, peer)", t_old, ""))
    with saved_output(__file__, a.save):
        print(f"{a.design}: {'x'.join(map(str, cell.phases.shape))} voxels, median of {a.repeats}")
        print("| piece | median [s] | note |")
        print("|---|---|---|")
        for name, t, note in rows:
            print(f"| {name} | {t:.2f} | {note} |")


if __name__ == "__main__":
    main()
