"""Robot speed: one inverse control step and the rest equilibrium on the 6-DOF robot.

Run: OPENBLAS_NUM_THREADS=1 python benchmarks/bench_robot.py [--mesh-size 5.0] [--steps 40]
         [--element p1|p2] [--grip-size 0] (the converged paper mesh: --element p2 --mesh-size 10
         --grip-size 1; P1 at about its accuracy needs far finer meshes, see bench_convergence.py)

Prints one table (medians, same process, this machine, with the load average) comparing
peers: SuperLU vs CHOLMOD (when scikit-sparse is installed) for the factorisation and the
linearisation, the control step with a fresh tangent every step vs the default kept tangent,
and our forces + tangent vs scikit-fem's generic assembly of the same mesh. Every control
variant is checked for accuracy too: after the loop, the pose of its one-Newton-step state is
compared with the converged equilibrium at the same motor angles ("drift").
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from _results import add_save_option, saved_output


def _median(fn, n):
    ts = []
    for _ in range(n):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return float(np.median(ts))


def _blas() -> str:
    try:
        from threadpoolctl import threadpool_info

        return ", ".join(f"{i['internal_api']} {i.get('num_threads')} thr" for i in threadpool_info())
    except Exception:  # pragma: no cover - threadpoolctl is optional
        return f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}"


def _control_run(rob, rest, steps, **kw):
    """A moving goal (small circle + twist): every step does real work. Returns times, drift, ctl."""
    from metasheet.robot.inverse import InverseController, InverseSettings
    from metasheet.mechanics.rotations import rotation_matrix
    from metasheet.robot.equilibrium import solve_equilibrium

    ctl = InverseController(rob, rest, InverseSettings(max_step_deg=2.0, **kw))
    ts, drift = [], []
    for k in range(steps):
        ang = 2 * np.pi * k / steps
        goal_p = np.array([0.0, 3 * np.cos(ang), 3 * np.sin(ang) - 0.05])
        info = ctl.step(goal_p, rotation_matrix([np.radians(4) * np.sin(ang), 0, 0]))
        ts.append(info.time)
        if k % 10 == 9:  # accuracy probe (own linearizer, not timed): loop state vs equilibrium
            eq = solve_equilibrium(rob, ctl.state.angles, state=ctl.state).state
            drift.append(np.linalg.norm(eq.p - ctl.state.p))
    return np.asarray(ts), max(drift), ctl


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--mesh-size", type=float, default=5.0)
    ap.add_argument("--steps", type=int, default=40)
    ap.add_argument("--element", choices=("p1", "p2"), default="p1")
    ap.add_argument("--grip-size", type=float, default=0.0)
    add_save_option(ap)
    a = ap.parse_args()
    from metasheet.published.paper import FOAM_DENSITY, PAPER_FOAM
    from metasheet.robot.builder import SheetPair, six_dof_robot
    from metasheet.fem.solvers import available
    from metasheet.robot.statics import Linearizer
    from metasheet.robot.equilibrium import solve_equilibrium
    from metasheet.sheet.geometry import SheetParams

    rob = six_dof_robot(SheetPair.spiral(SheetParams(mesh_size=a.mesh_size, grip_size=a.grip_size), a.element),
                        PAPER_FOAM, density=FOAM_DENSITY)
    solve_equilibrium(rob, rob.coupling.rest_angles)  # numba warm-up
    solvers = ["superlu"] + (["cholmod"] if available("cholmod") else [])
    rows = []
    eqs = []
    t_eq = _median(lambda: eqs.append(solve_equilibrium(rob, rob.coupling.rest_angles)), 5)
    rows.append(("static equilibrium from rest (gravity)", t_eq, f"{eqs[-1].iterations} it, target < 0.5 s"))
    rest = eqs[-1].state
    # a deformed state too: the anisotropic tangent's asymmetry grows with deformation
    moved = solve_equilibrium(rob, rest.angles + np.radians([8, -4, 6, 2, -8, 4]), state=rest).state
    x = rest.x
    t_f = _median(lambda: rob.body.forces(x), 20)
    t_ft = _median(lambda: rob.body.forces_and_tangent(x), 20)
    rows.append(("forces only (both sheets)", t_f, ""))
    rows.append(("forces + tangent (both sheets)", t_ft, f"= {t_ft / t_f:.1f} x forces only"))
    for st_name, st in (("rest", rest), ("deformed", moved)):
        lzs = {n: Linearizer(rob, n) for n in solvers}
        _, K = rob.body.forces_and_tangent(st.x)
        Kff = lzs["superlu"]._blocks(K)["ff"]
        t_fac = {n: _median(lambda n=n: lzs[n].solver.factorize(Kff), 7) for n in solvers}
        t_lin = {n: _median(lambda n=n: lzs[n].linearize(st), 7) for n in solvers}
        for n in solvers:
            ratio = f", {t_fac[n] / t_fac['superlu']:.2f} x superlu" if n != "superlu" else ""
            rows.append((f"factorise K_ff ({st_name}), {n}", t_fac[n], f"{Kff.shape[0]} DOFs{ratio}"))
        for n in solvers:
            ratio = f", {t_lin[n] / t_lin['superlu']:.2f} x superlu" if n != "superlu" else ""
            rows.append((f"exact linearisation ({st_name}), {n}", t_lin[n], f"{lzs[n].solver.stats}{ratio}"))
    lz = Linearizer(rob)
    lin = lz.linearize(rest)
    rows.append(("chord update: forces + 1 solve", _median(lambda: lz.update(lin, rest), 20), ""))
    variants = [("fresh tangent every step, superlu", dict(refactor_every=1)),
                ("kept tangent (defaults), superlu", dict())]
    if available("cholmod"):
        variants.append(("kept tangent, cholmod (symmetric part)", dict(linear_solver="cholmod")))
    base = None
    for label, kw in variants:
        ts, drift, ctl = _control_run(rob, rest, a.steps, **kw)
        med = float(np.median(ts))
        base = base or med
        rows.append((f"inverse step: {label}", med,
                     f"{med / base:.2f} x fresh; mean {1e3 * ts.mean():.1f}, p90 {1e3 * np.quantile(ts, 0.9):.1f} ms; "
                     f"{ctl.refreshes}/{a.steps} fresh {ctl.refresh_reasons}; drift <= {1e3 * drift:.1f} um"))
    # peer: scikit-fem's generic assembly of the linear stiffness of the same mesh (isotropic)
    try:
        if a.element != "p1":
            raise ValueError("the peer assembles linear tetrahedra only")
        import skfem
        from skfem.models.elasticity import lame_parameters, linear_elasticity

        mesh = skfem.MeshTet(rob.body.rest.T.copy(), np.asarray(rob.body.tets).T.copy())
        basis = skfem.Basis(mesh, skfem.ElementVector(skfem.ElementTetP1()))
        peer = _median(lambda: skfem.asm(linear_elasticity(*lame_parameters(1.0, 0.3)), basis), 5)
        rows.append(("peer: scikit-fem assembly (linear, same mesh)", peer, f"ours/peer = {t_ft / peer:.3f}"))
    except Exception as exc:  # pragma: no cover
        rows.append(("peer: scikit-fem", float("nan"), f"failed: {exc}"))
    with saved_output(__file__, a.save, fenced=True):
        print(f"6-DOF robot ({a.element}, mesh {a.mesh_size:g} mm, grip {a.grip_size:g} mm): {rob.info['n_tets']} tets ({rob.info['n_tets_per_sheet']} per sheet), "
              f"{rob.body.n_nodes} nodes, {3 * len(rob.coupling.free)} free DOFs; BLAS: {_blas()}; "
              f"load {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; solvers: {', '.join(solvers)}")
        print(f"{'case':52s} {'median [ms]':>12s}  notes")
        for name, t, note in rows:
            print(f"{name:52s} {1e3 * t:12.2f}  {note}")


if __name__ == "__main__":
    main()
