"""Benchmark of the robot FEM core (issue 6): our corotational kernel vs plain scikit-fem.

Run: ``python benchmarks/bench_fem.py [--repeats N]``. Prints one table of medians over
repeats (wall clock, and process CPU time, which is steadier on a shared machine) and ratios
against peers run in the same process: scikit-fem's linear-elasticity assembly of the same
(isotropic, rest) stiffness with ``intorder=1`` (exact for P1) and with its default quadrature,
and our own batched-numpy reference kernel. Mesh: two 60 x 60 x 5 mm plates of 15 x 15 x 2
cells, 6 tets each: 2 x 2,700 = 5,400 tets, like the 6-DOF robot's two sheets.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np
import scipy.sparse.linalg as spla

from metasheet.mechanics.material import Isotropic, TransverseIsotropic
from metasheet.fem.meshes import box_mesh
from metasheet.robot.body import ElasticBody
from metasheet.robot.dirichlet import solve_static

from _results import add_save_option, saved_output

FOAM = TransverseIsotropic(E_t=1.39, E_l=0.0942, nu_t=0.3, nu_tl=0.05, mu_l=0.08)


def two_sheets():
    P, T = box_mesh((60.0, 60.0, 5.0), (15, 15, 2))
    return np.vstack([P, P + [0.0, 0.0, 100.0]]), np.vstack([T, T + len(P)])


def timed(fn, repeats):
    fn()  # warm-up (and numba compilation / cache load)
    wall, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return float(np.median(wall)), float(np.median(cpu))


def skfem_assembler(points, tets, material: Isotropic, intorder):
    from skfem import Basis, ElementTetP1, ElementVector, MeshTet, asm
    from skfem.models.elasticity import linear_elasticity

    mesh = MeshTet(points.T.copy(), tets.T.copy())
    form = linear_elasticity(material.lam, material.mu)

    def run():
        # Basis construction is part of a from-scratch assembly, as in a generic FE code.
        basis = Basis(mesh, ElementVector(ElementTetP1()), intorder=intorder)
        return asm(form, basis)

    return run


def environment() -> str:
    try:
        from threadpoolctl import threadpool_info

        pools = ", ".join(f"{p['internal_api']} {p.get('version')} x{p['num_threads']}" for p in threadpool_info())
    except ImportError:  # pragma: no cover
        pools = "threadpoolctl not installed"
    import numba

    env = {k: os.environ.get(k, "-") for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
    return (
        f"python {platform.python_version()}, numpy {np.__version__}, cpus {os.cpu_count()}, "
        f"load average {os.getloadavg()[0]:.1f}\nBLAS pools: {pools}\nenv: {env}; "
        f"numba {numba.__version__} (our kernel is serial, NUMBA_NUM_THREADS={numba.config.NUMBA_NUM_THREADS} unused)"
    )


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=21)
    add_save_option(ap)
    args = ap.parse_args(argv)
    rng = np.random.default_rng(0)
    P, T = two_sheets()
    fibers = rng.normal(size=(len(T), 3))
    foam = ElasticBody.from_material(P, T, FOAM, fibers)
    foam_np = ElasticBody.from_material(P, T, FOAM, fibers, backend="numpy")
    iso_mat = Isotropic(0.25, 0.45)
    iso = ElasticBody.from_material(P, T, iso_mat)
    x = P + 0.2 * rng.normal(size=P.shape)  # a deformed state: rotations are not identity

    # Correctness of the comparison: at rest our tangent is the linear stiffness skfem assembles.
    K_ours = iso.forces_and_tangent(P)[1]
    K_sk = skfem_assembler(P, T, iso_mat, 1)()
    rel = abs(K_ours - K_sk).max() / abs(K_sk).max()

    rows = []
    t_ft = timed(lambda: foam.forces_and_tangent(x), args.repeats)
    rows.append(("ours numba: forces (foam, 5,400 tets)", timed(lambda: foam.forces(x), args.repeats)))
    rows.append(("ours numba: forces_and_tangent (foam)", t_ft))
    rows.append(("ours numba: forces_and_tangent symmetric=True", timed(
        lambda: foam.forces_and_tangent(x, symmetric=True), args.repeats)))
    rows.append(("ours numba: forces_and_tangent (isotropic)", timed(lambda: iso.forces_and_tangent(x), args.repeats)))
    rows.append(("ours numpy reference: forces_and_tangent", timed(
        lambda: foam_np.forces_and_tangent(x), max(3, args.repeats // 4))))
    rows.append(("scikit-fem linear_elasticity intorder=1", timed(
        skfem_assembler(P, T, iso_mat, 1), max(3, args.repeats // 4))))
    rows.append(("scikit-fem linear_elasticity default", timed(
        skfem_assembler(P, T, iso_mat, None), max(3, args.repeats // 4))))

    # One linear solve of the tangent with the bottom face of each sheet fixed (SuperLU).
    z = P[:, 2] % 100.0
    fixed = np.flatnonzero(z < 1e-9)
    free = np.setdiff1d(np.arange(3 * len(P)), (3 * fixed[:, None] + np.arange(3)).ravel())
    f, K = foam.forces_and_tangent(x)
    K_ff = K[free][:, free].tocsc()
    rows.append(("splu factor + solve of K_ff (SuperLU, MMD_AT_PLUS_A)", timed(
        lambda: spla.splu(K_ff, permc_spec="MMD_AT_PLUS_A").solve(f[free]), max(3, args.repeats // 4))))
    loads = foam.gravity() * 1e3  # heavy enough for a few Newton iterations
    res = solve_static(foam, fixed, loads=loads)
    rows.append((f"solve_static under 1000 g ({res.iterations} Newton it.)", timed(
        lambda: solve_static(foam, fixed, loads=loads), 3)))

    with saved_output(__file__, args.save, fenced=True):
        print(environment())
        print(f"mesh: {foam.n_elements} tets, {foam.n_nodes} nodes, tangent nnz {foam.pattern.nnz}")
        print(f"check: |K_ours(rest) - K_skfem| / |K_skfem| = {rel:.2e} (isotropic, same matrix)\n")
        ref_wall, ref_cpu = t_ft
        print(f"{'case':<56} {'wall ms':>9} {'cpu ms':>9} {'x ours f+K (cpu)':>17}")
        for name, (w, c) in rows:
            print(f"{name:<56} {w * 1e3:9.2f} {c * 1e3:9.2f} {c / ref_cpu:17.2f}")


if __name__ == "__main__":
    main()
