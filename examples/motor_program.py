"""A motor program for the real robot: the rod centre driven round a circle, checked against the servos.

Samples a path of poses (a circle of the rod centre, 3 mm across, in the plane across the rod,
walked at 6 mm/s and sampled at 5 Hz), solves each sample by the inverse model from the
previous one (paper eq. 8, continuation as the robot moves), turns the motor angles into
hobby-servo pulse widths (500-2500 us over 0-180 deg: calibrate yours) and checks every
sample against the stroke and a micro-servo's speed (600 deg/s). This is ``metasheet robot
path circle.csv --speed 6 --rate 5`` without the command line; the same program plays in a
SOFA scene (``metasheet export sofa --program``) and as a ParaView series (``--pvd``). Small
case: linear tetrahedra, 14 mm (seconds); full case: linear tetrahedra, 8 mm.

Run: python examples/motor_program.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import metasheet  # first: pins numpy's code path, so the numbers repeat on any x86-64 CPU)
import numpy as np

from metasheet.export import path as pth, program as prog
from metasheet.export.servo import ServoPulse, check_program, stroke_deg
from metasheet.published import paper
from metasheet.robot import InverseSettings, SheetPair, six_dof_robot, solve_equilibrium
from metasheet.sheet import SheetParams

ROOT = Path(__file__).resolve().parents[1]
RADIUS_MM, SPEED_MM_S, RATE_HZ = 1.5, 6.0, 5.0


def main(small: bool = False, out: Path | None = None) -> dict:
    sheets = SheetPair.spiral(SheetParams(mesh_size=14.0 if small else 8.0), "p1")
    robot = six_dof_robot(sheets, paper.PAPER_FOAM, density=paper.FOAM_DENSITY)
    rest = solve_equilibrium(robot, robot.coupling.rest_angles).state  # motors at 60 deg, gravity on
    r0 = prog.rest_pose(rest)  # (6,) x, y, z [mm], rotation vector [deg]
    phi = np.linspace(0.0, 2.0 * np.pi, 9)
    corners = np.tile(r0, (len(phi), 1))
    corners[:, 1] += RADIUS_MM * np.sin(phi)  # y across the rod, z up: a circle seen along the rod
    corners[:, 2] += RADIUS_MM * (np.cos(phi) - 1.0)
    times, goals = pth.sample_path(pth.path_times(corners, SPEED_MM_S), corners, RATE_HZ)
    program = prog.solve_program(robot, times, goals, InverseSettings())  # 0.1 mm, 0.2 deg
    pulses = ServoPulse().pulse_us(program.angles_deg)
    lo, hi = stroke_deg(robot)
    check = check_program(program.angles_deg, program.times, lo, hi)

    print(f"{len(times)} samples over {times[-1]:.2f} s; {int(program.reached.sum())} reached; "
          f"servo check: {'ready to send' if check.ok else 'NOT ready'} "
          f"(largest speed {check.speed.max():.1f} deg/s)")
    print(f"  {'t [s]':>6s} {'motor angles [deg]':>44s}   {'pulses [us]':>41s}")
    for i in range(0, len(times), 4):
        angles = " ".join(f"{a:6.2f}" for a in program.angles_deg[i])
        print(f"  {times[i]:6.2f} {angles}   {' '.join(f'{p:6.0f}' for p in pulses[i])}")

    out = Path(out) if out is not None else ROOT / "outputs" / "examples" / "motor_program.png"
    metasheet.write_file(out, prog.program_picture(program, (lo, hi), title="a 3 mm circle of the rod centre"))
    return {"samples": len(times), "reached": int(program.reached.sum()), "ok": bool(check.ok),
            "max_error_mm": float(program.error_mm.max()), "max_speed_deg_s": float(check.speed.max()),
            "angles_deg": program.angles_deg.tolist(), "pulses_us": pulses.tolist(), "duration_s": float(times[-1])}


if __name__ == "__main__":  # python examples/NAME.py [PICTURE] (default: outputs/examples/NAME.png)
    main(out=Path(sys.argv[1]) if len(sys.argv) > 1 else None)
