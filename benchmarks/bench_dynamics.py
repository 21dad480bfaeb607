"""The robot in time: the cost of a dynamic step against a quasi-static one, and a maze played
on the full robot and on the modal model (issue 64).

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_dynamics.py [--steps 40] [--save]

For the paper's robot on three meshes (P1 14 mm, P1 5 mm, P2 8 mm) with the maze plate as
its rigid body: the motors ramp at 60 deg/s (the maze program's pace) and each scheme steps
5 ms at a time; the table gives the median wall time of a step, Newton iterations and fresh
tangents per step, and the ratio to the quasi-static step (the same robot, motors and
increments, the equilibrium without inertia) measured in the same process, interleaved.

The second table plays a maze program (the default maze path's tilt commands at 3 deg through
the rest Jacobian's inverse, samples every 0.2 s) on the P1 5 mm robot: the quasi-static path
at the samples, the full robot in time (generalised-alpha, 5 ms), the modal model (its ten
modes, the path's modal coordinates and its response on the same grid) and the marble on the
modal model's plate, against the program's own duration.
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


def maze_program(robot, rest, tilt_deg=3.0, dt=0.2, ramp=0.6, speed=20.0):
    """Tilt commands along :data:`DEFAULT_PATH` (a ramp, then a hold of length / speed), motors by
    the rest Jacobian's inverse; times (T,) [s] and angles (T, na) [rad]."""
    from metasheet.robot.kinematics import kinematics_at

    J = kinematics_at(robot, rest.state).J
    a0 = rest.state.angles
    times, angles = [0.0], [a0]
    P = np.asarray(DEFAULT_PATH, float)
    prev = a0
    for d in np.diff(P, axis=0):
        n = np.linalg.norm(d)
        rot = np.radians(tilt_deg) * np.cross([0, 0, 1.0], [*d / n, 0.0])
        a = a0 + np.linalg.solve(J, np.concatenate([np.zeros(3), rot]))
        for k in range(1, int(round(ramp / dt)) + 1):
            times.append(times[-1] + dt)
            angles.append(prev + (a - prev) * k * dt / ramp)
        for _ in range(int(round(n / speed / dt))):
            times.append(times[-1] + dt)
            angles.append(a)
        prev = a
    return np.array(times), np.array(angles)


def maze_table(steps_h: float = H) -> list[tuple[str, float]]:
    from metasheet.dynamics.marble import MarbleSettings, plate_motion, roll
    from metasheet.dynamics.modal import modal_model, path_coordinates, respond
    from metasheet.dynamics.response import play, quasi_static_path
    from metasheet.dynamics.robot_modes import robot_modes

    robot = paper_robot_spec(mesh_size=5.0).build().robot
    geo = maze_from_path(DEFAULT_PATH, width=12.0)
    rigid = maze_inertia(geo, rod_length=80.0, origin=robot.coupling.origin)
    qs = DynamicRobot(robot, rigid, scheme=QuasiStatic())
    dyn = DynamicRobot(robot, rigid, scheme=GeneralizedAlpha(0.8))
    rest = qs.step(qs.start(robot.rest_state()), robot.coupling.rest_angles, 1.0)
    times, angles = maze_program(robot, rest)
    out = [("the program's duration", float(times[-1]))]
    t0 = time.perf_counter()
    xs = []
    quasi = quasi_static_path(qs, rest, times, angles, keep_x=xs)
    out.append(("quasi-static path at the samples (full model)", time.perf_counter() - t0))
    t0 = time.perf_counter()
    play(dyn, dyn.start(rest.state), times, angles, steps_h)
    out.append(("full robot in time, generalised-alpha", time.perf_counter() - t0))
    t0 = time.perf_counter()
    modes = robot_modes(qs, rest.state, n=10)
    out.append(("its ten modes at rest (once per robot)", time.perf_counter() - t0))
    t0 = time.perf_counter()
    model = modal_model(modes, 0.0, 0.01)
    pts = np.array([qs.points(p, R) for p, R in zip(quasi.p, quasi.R)])
    m = path_coordinates(modes.shapes, modes.effector, qs.M, np.array(xs), pts, qs.m_pts, rest.state.p)
    t, eta = respond(model, times, m, steps_h)
    modal_s = time.perf_counter() - t0
    out.append(("modal model in time (path coordinates and response)", modal_s))
    out.append(("modal model, per step [ms]", 1000 * modal_s / len(t)))
    qp = quasi.pose
    pose = np.stack([np.interp(t, times, qp[:, k]) for k in range(6)], axis=1) + eta @ model.effector
    t0 = time.perf_counter()
    roll(plate_motion(t, pose, top=6.0), geo, geo.path[0], MarbleSettings(radius=4.0, mass=2.1e-6))
    out.append(("the marble on the modal model's plate (1 ms steps)", time.perf_counter() - t0))
    return out


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
    maze = maze_table()
    with saved_output(__file__, a.save):
        print("| mesh | nodes | scheme | step [ms] | Newton / step | fresh tangents / step | / quasi-static |")
        print("|---|---:|---|---:|---:|---:|---:|")
        for r in rows:
            print(f"| {r[0]} | {r[1]} | {r[2]} | {r[3]:.1f} | {r[4]:.2f} | {r[5]:.2f} | {r[6]:.2f} |")
        print(f"(median over 2 x {a.steps - 1} steps of {H * 1000:g} ms, motors ramping at 60 deg/s)")
        print()
        print("| the maze played, P1 5 mm | wall [s] |")
        print("|---|---:|")
        for name, v in maze:
            print(f"| {name} | {v:.3g} |")


if __name__ == "__main__":
    main()
