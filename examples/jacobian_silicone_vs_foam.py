"""The robot's rest Jacobian with silicone sheets against foam sheets: the sixth DOF.

Builds the 6-DOF robot (two tripod sheets face to face, the rod between their centres, six
servos) twice on the same sheets: isotropic silicone, and the paper's anisotropic foam with
its soft axis along the spiral fibres. At the rest equilibrium under gravity (paper eq. 1)
it condenses the tangent onto the effector and the motors, the compliance W (eq. 6) and the
direct Jacobian J = W_ea W_aa^-1 (eq. 7), and compares J's singular values (rotations
counted at 50 mm, so they read in mm per rad) and the roll of the rod about its own axis
when all six motors turn together. Silicone's tripods have mirror planes through the rod, so
that roll vanishes by symmetry and J loses a rank (5 DOF); the spiral fibres break the
symmetry (6 DOF). Small case: linear tetrahedra, 14 mm (about a second); full case:
quadratic tetrahedra, 10 mm graded to 3 mm at the grips (under a minute).

Run: python examples/jacobian_silicone_vs_foam.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import metasheet  # first: pins numpy's code path, so the numbers repeat on any x86-64 CPU)
import matplotlib

matplotlib.use("Agg")  # off screen: no display needed
import matplotlib.pyplot as plt
import numpy as np

from metasheet.published import paper
from metasheet.robot import SheetPair, evaluate, six_dof_robot
from metasheet.sheet import SheetParams
from metasheet.viz import figure_png

ROOT = Path(__file__).resolve().parents[1]


def main(small: bool = False, out: Path | None = None) -> dict:
    params, element = (SheetParams(mesh_size=14.0), "p1") if small else (SheetParams(mesh_size=10.0, grip_size=3.0), "p2")
    sheets = SheetPair.spiral(params, element)  # one mesh for both materials: only the material differs
    materials = {"silicone": (paper.SILICONE, paper.SILICONE_DENSITY),
                 "foam": (paper.PAPER_FOAM, paper.FOAM_DENSITY)}
    cases = {}
    for name, (material, density) in materials.items():
        robot = six_dof_robot(sheets, material, density=density)
        # rest equilibrium, J there, and a finite move of every motor by -10 deg as a check on J
        cases[name] = evaluate(robot, name, delta_deg=-10.0)

    print(f"{len(sheets.sheet.tets)} {element} tetrahedra a sheet")
    print(f"  {'':26s} {'silicone':>10s} {'foam':>10s}")
    for i in range(6):
        print(f"  singular value {i + 1} [mm/rad]  " + " ".join(f"{c.kin.singular_values[i]:10.4f}"
                                                         for c in cases.values()))
    print("  rod roll [deg/deg], J     " + " ".join(f"{c.rod_rotation_per_degree:10.4f}" for c in cases.values()))
    print("  rod roll [deg/deg], -10   " + " ".join(f"{c.rod_rotation_finite:10.4f}" for c in cases.values()))
    numbers = {f"{name}_{key}": value for name, c in cases.items() for key, value in (
        ("singular_values", c.kin.singular_values.tolist()), ("roll_per_degree", c.rod_rotation_per_degree),
        ("roll_finite", c.rod_rotation_finite), ("lateral_mm_per_degree", c.lateral_finite))}

    out = Path(out) if out is not None else ROOT / "outputs" / "examples" / "jacobian_silicone_vs_foam.png"
    picture(cases, f"{len(sheets.sheet.tets)} {element} tets a sheet", out)
    return numbers


def picture(cases: dict, mesh: str, out: Path) -> None:
    """Singular values side by side (log scale: silicone's sixth is orders smaller), and the roll."""
    colours = {"silicone": "#7f7f7f", "foam": "#d62728"}
    fig, (a0, a1) = plt.subplots(1, 2, figsize=(12, 4.5), gridspec_kw={"width_ratios": [2.2, 1]})
    k = np.arange(1, 7)
    for j, (name, c) in enumerate(cases.items()):
        a0.bar(k + (j - 0.5) * 0.38, c.kin.singular_values, width=0.38, color=colours[name], label=name)
    a0.set(yscale="log", xticks=k, xlabel="singular value number",
           ylabel="singular value of diag(1, 1, 1, 50 mm) J [mm/rad]",
           title=f"rest Jacobian (eq. 7), {mesh}: silicone loses the 6th")
    a0.set_ylim(top=100.0)  # room for the legend above the bars
    a0.legend(loc="upper right", ncol=2)
    roll = [abs(c.rod_rotation_per_degree) for c in cases.values()]
    a1.bar(list(cases), roll, color=[colours[n] for n in cases])
    for i, v in enumerate(roll):
        a1.annotate(f"{v:.2g}", (i, v), ha="center", va="bottom")
    a1.set(yscale="log", ylim=(1e-4, 3.0), ylabel="|rod roll| per degree of all motors [deg/deg]", title="roll about the rod (from J)")
    metasheet.write_file(out, figure_png(fig))  # never half a file


if __name__ == "__main__":  # python examples/NAME.py [PICTURE] (default: outputs/examples/NAME.png)
    main(out=Path(sys.argv[1]) if len(sys.argv) > 1 else None)
