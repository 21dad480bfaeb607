"""Benchmark: periodic STL surface and periodic tet mesh of a 64-seed open-cell foam.

    python benchmarks/bench_cell_mesh.py [--repeats 3] [--tet-repeats 1] [--h 0.25]

Targets (issue 3, 2-core machine): surface < 20 s, periodic tet mesh of ~200k tets < 60 s.
Peers run in the same process: scikit-image's marching cubes on the same sampled grid (no
caps, not periodic: a lower bound for a surface) and our tet mesh without gmsh's optimiser.
Uses ``metasheet.cells.foam`` (10 mm cell, Poisson-disk seeds, density 0.15); falls back to
a gyroid when the foam module is missing.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np

from metasheet.cells.surface import check_surface, periodic_isosurface, sample_periodic
from metasheet.cells.tetmesh import periodic_tet_mesh, tet_volumes

from _results import add_save_option, saved_output


def make_field(seeds: int, density: float):
    """(field, size, label, voxel density) of the benchmark cell."""
    size = np.array([10.0, 10.0, 10.0])
    try:
        from metasheet.cells import Foam, foam_field, solve_thickness, voxelize
        from metasheet.cells.metrics import StretchedMetric
        from metasheet.cells.seeds import make_seeds
    except ImportError:
        L = size[0]

        def gyroid(p):
            x = 2 * np.pi * p / L
            g = np.sin(x[:, 0]) * np.cos(x[:, 1]) + np.sin(x[:, 1]) * np.cos(x[:, 2]) + np.sin(x[:, 2]) * np.cos(x[:, 0])
            return g * L / (2 * np.pi)

        return gyroid, size, "gyroid (foam module missing)", 0.5
    pts = make_seeds("poisson", seeds, size, 0)
    sol = solve_thickness(pts, size, StretchedMetric(), "open", density, 64)
    foam = Foam(pts, size, topology="open", thickness=sol.thickness)
    vox = float(voxelize(foam, 64).mean())
    return foam_field(foam), size, f"{seeds}-seed open foam, r = {sol.thickness:.3f} mm", vox


def timed(fn, repeats):
    times, out = [], None
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times), out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--tet-repeats", type=int, default=1)
    ap.add_argument("--seeds", type=int, default=64)
    ap.add_argument("--n", type=int, default=64, help="surface grid cells per axis")
    ap.add_argument("--h", type=float, default=0.25, help="tet element size [mm] (~200k tets)")
    add_save_option(ap)
    args = ap.parse_args()

    field, size, label, vox = make_field(args.seeds, 0.15)
    with saved_output(__file__, args.save, fenced=True):
        print(f"cell: {label}; box {size.tolist()} mm; voxel density (n = 64) {vox:.4f}")
        print(f"threads: OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}, gmsh 1; load {os.getloadavg()[0]:.1f}")
        rows = []

        t_surf, mesh = timed(lambda: periodic_isosurface(field, size, args.n), args.repeats)
        rep = check_surface(mesh)
        rows.append(("surface (marching tets + caps + refine)", t_surf, 1.0,
                     f"{len(mesh.faces)} tris, watertight {rep.watertight}, manifold {rep.manifold}, "
                     f"density {rep.volume / size.prod():.4f} ({rep.volume / size.prod() / vox - 1:+.1%} vs voxels)"))

        def peer_mc():
            from skimage.measure import marching_cubes

            vals = sample_periodic(field, size, args.n)
            return marching_cubes(vals, 0.0, spacing=tuple(size / args.n))

        t_mc, (v, f, _, _) = timed(peer_mc, args.repeats)
        rows.append(("  peer: skimage marching_cubes (open, no caps)", t_mc, t_mc / t_surf, f"{len(f)} tris"))

        t_tet, tm = timed(lambda: periodic_tet_mesh(field, size, args.h), args.tet_repeats)
        ok = bool(np.all(tet_volumes(tm.points, tm.tets) > 0))
        rows.append((f"periodic tet mesh (gmsh Delaunay + optimise, h = {args.h} mm)", t_tet, 1.0,
                     f"{len(tm.tets)} tets, mismatch {tm.max_mismatch:.1e} mm, positive {ok}, "
                     f"density {tm.relative_density:.4f}, min quality {tm.min_quality:.1e}, pieces {tm.n_components}"))
        t_noopt, tm2 = timed(lambda: periodic_tet_mesh(field, size, args.h, optimize=False), args.tet_repeats)
        rows.append(("  peer: same without gmsh's optimiser", t_noopt, t_noopt / t_tet,
                     f"{len(tm2.tets)} tets, min quality {tm2.min_quality:.1e}"))

        w = max(len(r[0]) for r in rows)
        print(f"\n{'case':<{w}}  {'median [s]':>10}  {'ratio':>6}  notes")
        for name, t, ratio, note in rows:
            print(f"{name:<{w}}  {t:>10.2f}  {ratio:>6.2f}  {note}")
        print(f"\ntargets: surface < 20 s ({'met' if t_surf < 20 else 'MISSED'}), "
              f"tet mesh ~200k tets < 60 s ({'met' if t_tet < 60 else 'MISSED'})")


if __name__ == "__main__":
    main()
