"""``metasheet export``: a pipeline's robot for the users' own tools (:mod:`metasheet.export`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from .cli_output import docs, say

export_app = typer.Typer(help="Take a pipeline's robot into other tools (SOFA).", epilog=docs("export"),
                         no_args_is_help=True, rich_markup_mode=None, pretty_exceptions_enable=False,
                         add_completion=False, context_settings={"help_option_names": ["-h", "--help"]})


@export_app.command("sofa", epilog=docs("export sofa"),
                    short_help="A SOFA scene (SoftRobots, the authors' anisotropic force field) of a pipeline's robot.")
def export_sofa(
    outputs: Annotated[Path, typer.Argument(help="a pipeline's output folder holding its orient, material and robot "
                                                 "stages, e.g. outputs/quick")],
    to: Annotated[Path, typer.Option("--to", help="folder to write the scene into (replaced whole)")],
    column: Annotated[str, typer.Option("--column", help="'prediction' (the material stage's constants) or "
                                                         "'reproduction' (the published foam)")] = "prediction",
    mesh_size: Annotated[Optional[float], typer.Option("--mesh-size", min=2.0, max=30.0, help="re-mesh the sheets at "
                                                       "this size [mm] (default: the orient stage's tetrahedra, "
                                                       "linear)")] = None,
    direct: Annotated[bool, typer.Option("--direct", help="servos commanded (no QP): they hold rest, or follow "
                                                          "--program")] = False,
    program: Annotated[Optional[Path], typer.Option("--program", help="a `metasheet robot path` program.csv the "
                                                    "direct scene plays (implies --direct)")] = None,
    isotropic: Annotated[bool, typer.Option("--isotropic", help="SOFA's TetrahedronFEMForceField instead of the "
                                                                "authors' plugin: the anisotropy is lost")] = False,
    rod_mass_g: Annotated[float, typer.Option("--rod-mass-g", min=0.001, max=1e4, help="mass of the rod and maze "
                                              "[g] (metasheet's statics carry none)")] = 10.0,
    no_picture: Annotated[bool, typer.Option("--no-picture", help="leave out scene.png (the sheets, fibres, servo "
                                             "axes and horns as exported)")] = False,
) -> None:
    """Write a SOFA scene folder (scene.py, sheets.vtk, elements.txt, robot.json, maze.obj) of
    the pipeline's 6-DOF robot: runSofa scene.py in it."""
    import json

    from .export.sofa import export_sofa as write

    out = write(outputs, to, column=column, mesh_size=mesh_size, rod_mass_g=rod_mass_g, anisotropic=not isotropic,
                inverse=not (direct or program is not None), program=program,
                picture=not no_picture)
    data = json.loads((out / "robot.json").read_text())
    say(f"wrote {out}: {sum(data['n_tets_per_sheet'])} linear tetrahedra, 6 servos, material model "
        f"{data['material_model']!r}; run: runSofa {out / 'scene.py'}", err=False)
    if data["material_model"] != "authors":
        gap = data["model_gap"]["largest_relative_difference"]
        say(f"note: {data['material_model_note']}: at rest its Jacobian's singular values differ by up to "
            f"{100 * gap:.1f} % (robot.json model_gap)", err=False)
