"""A printed foam robot: how far its walls let it move, and how its rod rolls.

Prints both sheets of a small tripod robot as Polyfoam, voxel by voxel (the soft axis turning
in a spiral, mirrored on the second sheet), condenses each on its four grips with a linear
voxel DNS, and builds the printed robot from two corotational superelements. The walls' own
limit comes from the same DNS's displacement fields: the motor travel at which two walls first
touch, with all six motors pulled or pushed and each sheet's three. Then the rod is rolled both
ways (the paper's Fig. 7 travels: 15 deg pulled, 35 deg pushed), with the walls' limit marked.
This is the ``printed`` stage (``pipelines/printed-robot.toml``) in miniature. Small case:
0.5 mm voxels (seconds); full case: 0.4 mm.

Run: python examples/printed_robot.py
"""

from __future__ import annotations

import sys
import tomllib
from pathlib import Path

import metasheet  # first: pins numpy's code path, so the numbers repeat on any x86-64 CPU
import numpy as np

from metasheet.cells.catalogue import parse_design
from metasheet.published import paper
from metasheet.robot.builder import SheetPair, six_dof_robot
from metasheet.robot.condensed import grip_motions_per_motor
from metasheet.sheet.dns import SheetPrint, dns_sheet
from metasheet.sheet.grips import grip_references
from metasheet.sheet.outline import SheetParams
from metasheet.sheet.printed_fields import FoamFields
from metasheet.studies.printed_adapter import printed_spec
from metasheet.studies.printed_claims import roll_claim
from metasheet.studies.printed_limits import WallUnit, combine, directions, wall_unit

ROOT = Path(__file__).resolve().parents[1]
PARAMS = SheetParams(arm_width=10.0, reach=20.0, thickness=2.0, hole_radius=1.0, fillet_radius=1.0,
                     tip_box=(5.0, 15.0, 10.0), centre_radius=3.0, mesh_size=4.0)
DESIGN = """kind = "polyfoam"
name = "small_polyfoam"
infill_percentage = 30.0
kgon_x_shrink = 0.5
bead_width = 0.8
[seeds]
sampler = "poisson"
count = 4
seed = 1
[material]
name = "TPU"
E = 12.0
nu = 0.3
"""


def spiral(sign: float):
    """The soft axis' angle [deg] at points (n, 3) [mm]: 45 deg off the radius, turning with it."""
    return lambda p: sign * (np.degrees(np.arctan2(p[:, 1], p[:, 0])) + 45.0)


def main(small: bool = False, out: Path | None = None) -> dict:
    design = parse_design(tomllib.loads(DESIGN), source="examples/printed_robot.py")
    solid = design.material.material().stiffness()
    voxel = 0.5 if small else 0.4
    prints = [SheetPrint(label, 1, "seed", voxel, design, PARAMS, FoamFields(30.0, 0.5, spiral(sign)), solid, 1e-6)
              for label, sign in (("normal", 1.0), ("mirrored", -1.0))]
    Ka, Kb = (dns_sheet(p).K for p in prints)  # each sheet on its grips (24 x 24)
    # the robot's servos, rod and sheet centres (its FEM sheets are not used)
    robot = six_dof_robot(SheetPair.spiral(PARAMS), paper.PAPER_FOAM, density=paper.FOAM_DENSITY,
                          gravity=(0.0, 0.0, 0.0))
    refs = grip_references(PARAMS)
    Ga, Gb, _ = grip_motions_per_motor(Ka, Kb, robot, refs)
    dirs = tuple(directions().items())
    limits = combine(*(wall_unit(WallUnit(p, tuple(map(tuple, G)), dirs, 10.0, 0.3)) for p, G in zip(prints, (Ga, Gb))))
    spec = printed_spec(robot, Ka, Kb, refs, valid_deg=limits["valid_deg"], motor_range=(-90.0, 180.0))
    roll = roll_claim(spec, 15.0, 35.0, limits)
    numbers = {"valid_deg": limits["valid_deg"], "binding": limits["binding"], "status": roll["status"],
               **{f"rod_{k}_deg": roll[k]["rod_rotation_deg"] for k in ("pull", "push")},
               **{f"rod_{k}_within_deg": v for k, v in roll["rod_rotation_within_limits_deg"].items()}}
    print(f"walls first touch {numbers['valid_deg']:.2f} deg from rest ({numbers['binding']}); rod rolled "
          f"{numbers['rod_pull_within_deg']:+.2f} deg pulled and {numbers['rod_push_within_deg']:+.2f} deg pushed "
          f"within it ({numbers['rod_pull_deg']:+.1f} / {numbers['rod_push_deg']:+.1f} deg at 15 / 35 deg, walls "
          f"ignored): {roll['status']}")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.0, 4.2))
    for name, sign in (("pull", 1.0), ("push", -1.0)):
        path = np.asarray(roll[name]["path"])
        ax.plot(sign * path[:, 0], path[:, 1], "C0:" if name == "push" else "C0-", label=f"all motors {name}ed")
    for name, d in limits["directions"].items():
        if d["contact_deg"] is not None and name.startswith("roll"):
            ax.axvline((1 if name == "roll up" else -1) * d["contact_deg"], color="C3", lw=1)
    ax.set_xlabel("all six motors from rest [deg]")
    ax.set_ylabel("rod rotation [deg]")
    ax.set_title("A small printed robot's roll; red: its walls first touch", fontsize=10)
    ax.legend(fontsize=8)
    out = Path(out) if out is not None else ROOT / "outputs" / "examples" / "printed_robot.png"
    from metasheet.viz import figure_png

    metasheet.write_file(out, figure_png(fig, dpi=110))  # never half a file
    return numbers


if __name__ == "__main__":
    main(out=Path(sys.argv[1]) if len(sys.argv) > 1 else None)
