"""Reduced vs full robot (issue 16): training cost, equilibrium from rest, inverse control step.

Trains a reduced model in process (the ``reduce`` stage's functions) on the paper robot built
in memory, then times, on the same held-out motor angles and goals, in the same process:

* equilibrium from rest (:func:`metasheet.robot.equilibrium.solve_equilibrium`), median;
  the reduced model twice: exact tangents, and its tangent library (``exact_tangent=False``,
  :mod:`metasheet.rom.tangents`) after one warm-up pass over the same angles;
* the inverse control step (:meth:`~metasheet.robot.inverse.InverseController.step`),
  median, mean and p99 over a goal sequence, with the fresh tangents taken; the reduced
  model with its library computing missing tangents in the background;
* the same on the equilibrium surface (:mod:`metasheet.rom.surface`): the reduce
  stage's ``surface.npz``, or (without ``--pipeline``) one fitted here on reduced equilibria.

    python benchmarks/bench_reduced.py --mesh-size 14 --element p1 --box 12 --snapshots 24

or, without training, on a pipeline's robot and its reduce stage's basis (the robot and
reduce stages must have run; the held-out angles are drawn inside the basis's and the
surface's boxes):

    python benchmarks/bench_reduced.py --pipeline pipelines/paper.toml [--out outputs]

``--column reproduction`` times the reproduction column's robot and basis (the published
constants under the authors' force field, P1 5 mm: ``reduce/reproduction/``, trained when
``[reduce] columns`` names it).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from metasheet.robot.equilibrium import solve_equilibrium
from metasheet.robot.inverse import InverseController
from metasheet.rom.model import ReducedRobot
from metasheet.rom.training import motor_design, sensitivity, train
from metasheet.mechanics.rotations import rotation_matrix
from metasheet.studies.adapter import paper_robot_spec

from _results import add_save_option, saved_output


def _control(robot, goals, steps: int):
    ctrl = InverseController(robot)
    times, fresh = [], 0
    for g in goals:
        R = rotation_matrix(np.radians(g[3:]))
        for _ in range(steps):
            info = ctrl.step(g[:3], R)
            times.append(info.time)
            fresh += info.fresh
    t = np.array(times) * 1e3
    lib = getattr(ctrl.linearizer, "library", None)
    if lib is not None:
        lib.close()
        print(f"  {robot.name}: tangent library {lib.stats}, exact tangents in a step: "
              f"{ctrl.linearizer.stats['tangents']}")
    return float(np.median(t)), float(t.mean()), float(np.percentile(t, 99)), fresh, len(t)


def _from_pipeline(pipeline: str, out: str | None, column: str):
    """(full robot, reduced robot, full linearizer, full rest equilibrium, description) of a
    pipeline's outputs for ``column``, as ``metasheet robot goto --column`` loads them."""
    import json

    from metasheet.rom.surface_robot import load_surface
    from metasheet.serve.loading import find_outputs, load_robot
    from metasheet.pipeline.column import column_folder

    outputs = find_outputs(pipeline, out)
    folder = column_folder(outputs.directory / "reduce", column, "reduce")
    rob, _ = load_robot(outputs, "full", "foam", column)
    red, _ = load_robot(outputs, "reduced", "foam", column)
    surf = load_surface(folder / "surface.npz", red)
    lz = rob.linearizer()
    rest = solve_equilibrium(rob, rob.coupling.rest_angles, linearizer=lz).state
    box = np.degrees(red.basis.box_hi - red.basis.box_lo).max() / 2
    timings = json.loads((outputs.directory / "reduce" / "manifest.json").read_text()).get("timings_s", {})
    return rob, red, surf, lz, rest, (f"{pipeline}'s reduce stage, {column} column, box rest +- {box:.3g} deg; "
                                f"training (manifest timings_s): {timings}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh-size", type=float, default=14.0)
    ap.add_argument("--element", default="p1", choices=("p1", "p2"))
    ap.add_argument("--box", type=float, default=12.0, help="training box: rest +- this [deg]")
    ap.add_argument("--snapshots", type=int, default=24)
    ap.add_argument("--repeats", type=int, default=8)
    ap.add_argument("--surface", type=int, default=64, help="reduced equilibria the surface is fitted on")
    ap.add_argument("--pipeline", default=None, help="a pipeline whose robot and reduce stages have run")
    ap.add_argument("--out", default=None, help="its outputs folder (default: the pipeline's)")
    ap.add_argument("--column", default="prediction", choices=("prediction", "reproduction"),
                    help="with --pipeline: which column's robot and basis")
    add_save_option(ap)
    a = ap.parse_args()
    if a.pipeline:
        rob, red, surf, lz, rest, what = _from_pipeline(a.pipeline, a.out, a.column)
        basis, c = red.basis, rob.coupling
        # every model on the same angles: inside the surface's box, which may be the smaller
        slo, shi = surf.surface.box
        lo, hi = np.maximum(basis.box_lo, slo), np.minimum(basis.box_hi, shi)
    else:
        fem = paper_robot_spec(mesh_size=a.mesh_size, element=a.element).build()
        rob, lz, rest = fem.robot, fem.lz, fem.rest
        c = rob.coupling
        lo, hi = c.rest_angles - np.radians(a.box), c.rest_angles + np.radians(a.box)
        t0 = time.perf_counter()
        snaps = [solve_equilibrium(rob, q, state=rest, linearizer=lz).state
                 for q in motor_design(lo, hi, a.snapshots, 0)]
        t_snap = time.perf_counter() - t0
        t0 = time.perf_counter()
        basis = train(rob, snaps, rest, sensitivities=np.hstack([sensitivity(lz, s) for s in snaps]), box=(lo, hi))
        t_train = time.perf_counter() - t0
        red = ReducedRobot(rob, basis)
        t0 = time.perf_counter()
        surf = _fit_surface(red, lo, hi, a.surface)
        t_surf = time.perf_counter() - t0
        what = (f"{a.element} {a.mesh_size:g} mm; box rest +- {a.box:g} deg\n"
                f"training: {len(snaps)} full equilibria {t_snap:.1f} s, basis + sample + fit {t_train:.1f} s, "
                f"surface ({a.surface} reduced equilibria, degree {surf.surface.info['degree']}) {t_surf:.1f} s")
    angles = motor_design(lo, hi, a.repeats, 5, corners=False) * 0.8 + 0.2 * c.rest_angles
    rows = []
    for name, robot, exact in (("full", rob, True), ("reduced", red, True), ("reduced+lib", red, False),
                               ("surface", surf, True)):
        lzr = robot.linearizer()
        for _ in range(1 if exact else 2):  # the library's warm-up pass, then the timed one
            ts = []
            for q in angles:
                t = time.perf_counter()
                solve_equilibrium(robot, q, linearizer=lzr, exact_tangent=exact)
                ts.append(time.perf_counter() - t)
        rows.append((name, 1e3 * float(np.median(ts))))
    poses = [solve_equilibrium(rob, q, state=rest, linearizer=lz).state.pose for q in angles[:4]]
    goals = [np.concatenate([p[:3], np.degrees(p[3:])]) for p in poses]
    live = red.with_limits(red.angle_min, red.angle_max)
    live.background_tangents = True
    ctl = {name: _control(robot, goals, 10)
           for name, robot in (("full", rob), ("reduced", red), ("reduced+lib", live), ("surface", surf))}
    with saved_output(__file__, a.save, fenced=True):
        print(f"robot: {3 * len(c.free)} free dofs, {rob.body.n_elements} elements; "
              f"reduced: k = {basis.k}, {len(basis.elements)} elements; {what}")
        print(f"{'model':12s} {'equilibrium from rest [ms]':>26s} {'step median':>12s} {'mean':>8s} {'p99':>8s} "
              f"{'fresh':>6s} {'steps':>6s}")
        for name, eq in rows:
            m, mean, p99, fresh, n = ctl[name]
            print(f"{name:12s} {eq:26.2f} {m:12.2f} {mean:8.2f} {p99:8.2f} {fresh:6d} {n:6d}")
        print(f"ratio full / reduced+lib: equilibrium {rows[0][1] / rows[2][1]:.2f}, "
              f"step median {ctl['full'][0] / ctl['reduced+lib'][0]:.2f}, p99 {ctl['full'][2] / ctl['reduced+lib'][2]:.2f}")
        print(f"ratio full / surface: equilibrium {rows[0][1] / rows[3][1]:.0f}, "
              f"step median {ctl['full'][0] / ctl['surface'][0]:.0f}, p99 {ctl['full'][2] / ctl['surface'][2]:.0f}")


def _fit_surface(red, lo, hi, n: int):
    """The equilibrium surface of ``red`` on the box [lo, hi], fitted on ``n`` reduced equilibria
    (its degree chosen on n / 2 more), as the reduce stage does (without its strain limit)."""
    from metasheet.rom.certificate import TARGETS
    from metasheet.rom.surface_robot import equilibrium_data, fit_surface_robot

    lz = red.linearizer()
    rest = solve_equilibrium(red, red.coupling.rest_angles, linearizer=lz).state
    train, check = (equilibrium_data(red, q, linearizer=lz, start=rest)
                    for q in (motor_design(lo, hi, n, 2), motor_design(lo, hi, n // 2, 3, corners=False)))
    return fit_surface_robot(red, train, check, lo, hi, TARGETS)


if __name__ == "__main__":
    main()
