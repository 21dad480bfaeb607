"""The robot in time: the cost of a dynamic step against a quasi-static one (issue 64).

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_dynamics.py [--steps 40] [--save]

For the paper's robot on three meshes (P1 14 mm, P1 5 mm, P2 8 mm) with the maze plate as
its rigid body: the motors ramp at 60 deg/s (the maze program's pace) and each scheme steps
5 ms at a time; the table gives the median wall time of a step, Newton iterations and fresh
tangents per step, and the ratio to the quasi-static step (the same robot, motors and
increments, the equilibrium without inertia) measured in the same process, interleaved.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import add_save_option, saved_output  # noqa: E402

from metasheet.dynamics.maze_geometry import maze_from_path  # noqa: E402
from metasheet.dynamics.maze_run import maze_inertia  # noqa: E402
from metasheet.dynamics.robot import DynamicRobot  # noqa: E402
from metasheet.dynamics.schemes import GeneralizedAlpha, ImplicitEuler, QuasiStatic  # noqa: E402
from metasheet.pipeline.stages.maze import DEFAULT_PATH  # noqa: E402
from metasheet.studies.adapter import paper_robot_spec  # noqa: E402

MESHES = {"P1 14 mm": dict(mesh_size=14.0), "P1 5 mm": dict(mesh_size=5.0), "P2 8 mm": dict(mesh_size=8.0, element="p2")}
H = 0.005  # [s]


def run(robot, scheme, rigid, steps: int) -> tuple[list[float], float, float]:
    dyn = DynamicRobot(robot, rigid, scheme=scheme)
    qs = DynamicRobot(robot, rigid, scheme=QuasiStatic())
    ds = dyn.start(qs.step(qs.start(robot.rest_state()), robot.coupling.rest_angles, 1.0).state)
    rate = np.radians(60.0) * np.array([1, -1, 1, -1, 1, -1])
    times, newton, fresh = [], [], []
    for k in range(1, steps + 1):
        t0 = time.perf_counter()
        ds = dyn.step(ds, robot.coupling.rest_angles + rate * k * H, H)
        times.append(time.perf_counter() - t0)
        newton.append(ds.newton)
        fresh.append(ds.tangents)
    return times, float(np.mean(newton)), float(np.mean(fresh))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=40)
    add_save_option(ap)
    a = ap.parse_args()
    rows = []
    geo = maze_from_path(DEFAULT_PATH, width=12.0)
    for name, mesh in MESHES.items():
        robot = paper_robot_spec(**mesh).build().robot
        rigid = maze_inertia(geo, rod_length=80.0, origin=robot.coupling.origin)
        res = {}
        for _ in range(2):  # interleaved: the machine's load hits every scheme alike
            for label, sch in (("quasi-static", QuasiStatic()), ("implicit Euler", ImplicitEuler()),
                               ("generalised-alpha 0.8", GeneralizedAlpha(0.8))):
                t, n, f = run(robot, sch, rigid, a.steps)
                prev = res.get(label, ([], 0, 0))
                res[label] = (prev[0] + t[1:], n, f)  # the first step builds the caches
        base = statistics.median(res["quasi-static"][0])
        for label, (t, n, f) in res.items():
            rows.append((name, robot.body.n_nodes, label, statistics.median(t) * 1000, n, f, statistics.median(t) / base))
    with saved_output(__file__, a.save):
        print("| mesh | nodes | scheme | step [ms] | Newton / step | fresh tangents / step | / quasi-static |")
        print("|---|---:|---|---:|---:|---:|---:|")
        for r in rows:
            print(f"| {r[0]} | {r[1]} | {r[2]} | {r[3]:.1f} | {r[4]:.2f} | {r[5]:.2f} | {r[6]:.2f} |")
        print(f"(median over 2 x {a.steps - 1} steps of {H * 1000:g} ms, motors ramping at 60 deg/s)")


if __name__ == "__main__":
    main()
