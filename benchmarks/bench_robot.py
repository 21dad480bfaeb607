"""Robot speed: one inverse control step and the rest equilibrium on the 6-DOF robot.

Run: python benchmarks/bench_robot.py [--mesh-size 5.0] [--steps 30]
Prints one table (medians over repeats, this machine, same process) with the peer
(scikit-fem's generic assembly of the same linear stiffness) as a ratio.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np


def _median(fn, n):
    ts = []
    for _ in range(n):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return float(np.median(ts))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--mesh-size", type=float, default=5.0)
    ap.add_argument("--steps", type=int, default=30)
    a = ap.parse_args()
    from metasheet.robot.compare import PAPER_FOAM, build_six_dof
    from metasheet.robot.inverse import InverseController, InverseSettings
    from metasheet.robot.statics import solve_equilibrium
    from metasheet.sheet.fibers import spiral_fibers
    from metasheet.sheet.geometry import SheetParams, mirror_sheet, tripod_sheet

    s = tripod_sheet(SheetParams(mesh_size=a.mesh_size))
    m = mirror_sheet(s)
    rob = build_six_dof(s, m, PAPER_FOAM, fibers=spiral_fibers(s.centroids()),
                        fibers_mirrored=spiral_fibers(m.centroids(), mirrored=True), density=1.785e-10)
    solve_equilibrium(rob, rob.coupling.rest_angles)  # numba warm-up
    rows = []
    eqs = []
    t_eq = _median(lambda: eqs.append(solve_equilibrium(rob, rob.coupling.rest_angles)), 5)
    rows.append(("static equilibrium from rest (gravity)", t_eq, f"{eqs[-1].iterations} it, target < 0.5 s"))
    rest = eqs[-1].state
    x = rest.x
    rows.append(("forces + tangent (both sheets)", _median(lambda: rob.body.forces_and_tangent(x), 20), ""))
    lz = rob.linearizer()
    rows.append(("linearise: blocks + splu + 7/13 RHS + Schur", _median(lambda: lz.linearize(rest), 10), ""))
    lin = lz.linearize(rest)
    rows.append(("chord update: forces + 1 solve", _median(lambda: lz.update(lin, rest), 20), ""))
    # a goal that moves: a small circle + twist, so every step does real work
    for label, kw in (("inverse step, fresh tangent every step", dict(refactor_every=1)),
                      ("inverse step, tangent kept <= 10 steps", dict(refactor_every=10))):
        ctl = InverseController(rob, rest, InverseSettings(max_step_deg=2.0, **kw))
        ts, res, fresh = [], [], 0
        for k in range(a.steps):
            ang = 2 * np.pi * k / a.steps
            goal_p = np.array([0.0, 3 * np.cos(ang), 3 * np.sin(ang) - 0.05])
            from metasheet.robot.rigid import rotation_matrix

            info = ctl.step(goal_p, rotation_matrix([np.radians(4) * np.sin(ang), 0, 0]))
            ts.append(info.time)
            res.append(info.residual)
            fresh += ctl._lin.fresh
        rows.append((label, float(np.median(ts)),
                     f"mean {1e3 * np.mean(ts):.1f} ms, {fresh}/{a.steps} fresh, max residual {max(res):.2e} N"))
    # peer: scikit-fem's generic assembly of the linear stiffness of the same mesh (isotropic)
    try:
        import skfem
        from skfem.models.elasticity import lame_parameters, linear_elasticity

        mesh = skfem.MeshTet(rob.body.rest.T.copy(), np.asarray(rob.body.tets).T.copy())
        basis = skfem.Basis(mesh, skfem.ElementVector(skfem.ElementTetP1()))
        peer = _median(lambda: skfem.asm(linear_elasticity(*lame_parameters(1.0, 0.3)), basis), 5)
        ours = _median(lambda: rob.body.forces_and_tangent(x), 20)
        rows.append(("peer: scikit-fem assembly (linear, same mesh)", peer, f"ours/peer = {ours / peer:.3f}"))
    except Exception as exc:  # pragma: no cover
        rows.append(("peer: scikit-fem", float("nan"), f"failed: {exc}"))
    print(f"6-DOF robot: {rob.info['n_tets']} tets ({rob.info['n_tets_per_sheet']} per sheet), "
          f"{rob.body.n_nodes} nodes, {3 * len(rob.coupling.free)} free DOFs; "
          f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}, load {os.getloadavg()[0]:.1f}")
    print(f"{'case':50s} {'median [ms]':>12s}  notes")
    for name, t, note in rows:
        print(f"{name:50s} {1e3 * t:12.2f}  {note}")


if __name__ == "__main__":
    main()
