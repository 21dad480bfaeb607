"""The ``metasheet`` command: run pipelines, list stages, drive the robot.

Errors metasheet raises on purpose (bad config, infeasible target, failed stage)
print as one red message and exit with status 2; anything else is a bug and keeps
its traceback.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated, Optional

import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from .errors import MetasheetError

app = typer.Typer(
    help="metasheet: soft robots from 3D-printed anisotropic foam, cell to controller.",
    no_args_is_help=True,
    add_completion=False,
)
robot_app = typer.Typer(help="Drive the robot model.", no_args_is_help=True)
app.add_typer(robot_app, name="robot")
console = Console(stderr=True)


def _progress_factory(progress: Progress):
    def factory(stage: str):
        tasks: dict[str, int] = {}

        def update(desc: str, done: int, total: int) -> None:
            label = f"{stage}: {desc}"
            if label not in tasks:
                tasks[label] = progress.add_task(label, total=total)
            progress.update(tasks[label], completed=done, total=total)

        return update

    return factory


@app.command()
def run(
    pipeline: Annotated[Path, typer.Argument(help="pipeline TOML file, e.g. pipelines/quick.toml")],
    stage: Annotated[Optional[str], typer.Option("--stage", help="run only this stage (and what it needs)")] = None,
    force: Annotated[bool, typer.Option("--force", help="rerun even when outputs are up to date")] = False,
    workers: Annotated[Optional[int], typer.Option("--workers", min=1, help="local worker processes")] = None,
    scheduler: Annotated[Optional[str], typer.Option("--scheduler", help="dask scheduler, tcp://HOST:PORT")] = None,
    out: Annotated[Optional[Path], typer.Option("--out", help="output root (default: outputs/ of the project)")] = None,
) -> None:
    """Run the stages of PIPELINE in dependency order; up-to-date stages are skipped."""
    from .executor import Executor
    from .pipeline.config import load_pipeline
    from .pipeline.runner import run_pipeline

    p = load_pipeline(pipeline)
    ex = Executor(workers or p.section.workers, scheduler or p.section.scheduler)
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn())
    with Progress(*columns, console=console, transient=True) as progress:
        outcomes = run_pipeline(
            p,
            out_root=out,
            only=stage,
            force=force,
            executor=ex,
            report=lambda s, msg: progress.console.print(f"[bold]{s}[/bold]: {msg}"),
            progress_factory=_progress_factory(progress),
        )
    table = Table(title=f"pipeline {p.name}")
    for col in ("stage", "status", "time [s]", "outputs"):
        table.add_column(col)
    for o in outcomes:
        table.add_row(o.name, o.status, f"{o.wall_time:.1f}", str(o.directory))
    Console().print(table)


@app.command("stages")
def list_stages() -> None:
    """List the stages, what they read and what they write."""
    from .pipeline.registry import stages

    table = Table(title="metasheet stages")
    for col in ("stage", "reads", "writes", "what"):
        table.add_column(col)
    for s in stages().values():
        reads = ", ".join([*s.requires, *(f"({o})" for o in s.optional)]) or "-"
        table.add_row(s.name, reads, ", ".join(s.outputs), s.doc)
    Console().print(table)


@app.command()
def validate(pipeline: Annotated[Path, typer.Argument(help="pipeline TOML file")]) -> None:
    """Check a pipeline file without running it."""
    from .pipeline.config import load_pipeline

    p = load_pipeline(pipeline)
    Console().print(f"{pipeline}: ok; stages in order: {' -> '.join(p.order)}")


@app.command()
def diff(
    a: Annotated[Path, typer.Argument(help="an output directory (e.g. outputs/quick)")],
    b: Annotated[Path, typer.Argument(help="the output directory to compare it with")],
    rtol: Annotated[float, typer.Option("--rtol", min=0.0, help="largest relative difference accepted")] = 1e-12,
) -> None:
    """Compare two output trees: identical bytes, numbers equal to RTOL, or different (exit 1)."""
    from .errors import ConfigError
    from .pipeline.outputs_diff import compare_trees

    for d in (a, b):
        if not d.is_dir():
            raise ConfigError(f"{d}: not a directory")
    rows = compare_trees(a, b)
    table = Table("file", "result", "max relative difference", "note")
    bad = 0
    for r in rows:
        ok = r.status == "identical" or (r.status == "numbers" and r.max_rel <= rtol)
        bad += not ok
        shown = "" if r.status in ("identical", "different") or r.status.startswith("missing") else f"{r.max_rel:.2e}"
        table.add_row(r.path, r.status if ok else f"[red]{r.status}[/red]", shown, r.note)
    Console().print(table)
    Console().print(f"{len(rows) - bad} of {len(rows)} files identical or within rtol {rtol:g}")
    if bad:
        raise typer.Exit(1)


def goto_robot(orient: Path | None = None, mesh_size: float = 8.0):
    """The 6-DOF robot ``robot goto`` drives: from an orient stage's sheets (their own
    per-element constants), else freshly meshed sheets (``mesh_size`` [mm]) with the paper's
    foam along the default spiral; the paper's scene and foam density either way."""
    from . import paper
    from .robot.builder import SheetPair, six_dof_robot

    if orient is not None:
        from .pipeline.artefacts import read_orient

        return six_dof_robot(read_orient(Path(orient)).sheets(), density=paper.FOAM_DENSITY)
    from .sheet.geometry import SheetParams

    return six_dof_robot(SheetPair.spiral(SheetParams(mesh_size=mesh_size)), paper.PAPER_FOAM,
                         density=paper.FOAM_DENSITY)


def format_result(res) -> str:
    """Human-readable lines of an :class:`~metasheet.robot.inverse.InverseResult`."""
    lines = [f"status: {res.status} after {res.steps} control steps",
             "motor angles [deg]: " + " ".join(f"{a:.2f}" for a in res.angles_deg),
             "pose reached: X Y Z [mm] " + " ".join(f"{v:.3f}" for v in res.pose[:3])
             + " | RX RY RZ [deg] " + " ".join(f"{v:.3f}" for v in res.pose[3:]),
             f"remaining error: {res.pos_error:.3f} mm, {res.rot_error:.3f} deg",
             f"equilibrium: residual {res.residual:.2e} N = {res.residual / max(res.reference, 1e-300):.1e} x "
             f"force scale (certified by {res.certified or '-'})"]
    return "\n".join(lines)


@robot_app.command("goto")
def robot_goto(
    pose: Annotated[list[float], typer.Argument(help="X Y Z [mm] RX RY RZ [deg] of the rod centre (use -- before negatives)")],
    orient: Annotated[Optional[Path], typer.Option("--orient", help="an orient stage's output directory")] = None,
    mesh_size: Annotated[float, typer.Option("--mesh-size", min=2.0, max=20.0, help="sheet mesh size [mm] when no --orient")] = 8.0,
) -> None:
    """Solve the inverse model (paper eq. 8) from rest to a pose and print the motor angles."""
    from .errors import ConfigError
    from .robot.inverse import InverseController

    if len(pose) != 6:
        raise ConfigError(f"pose: {len(pose)} numbers given: expected 6 (X Y Z RX RY RZ)")
    robot = goto_robot(orient, mesh_size)
    typer.echo(format_result(InverseController(robot).goto(pose)))


def main() -> None:
    """Console-script entry point."""
    try:
        app()
    except MetasheetError as err:
        console.print(f"[red]error:[/red] {err}", markup=True, highlight=False)
        sys.exit(2)


if __name__ == "__main__":
    main()
