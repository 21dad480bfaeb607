"""The ``metasheet`` command: run pipelines, list stages, drive the robot.

Every message prints verbatim: user and library text is never read as rich markup, so
square brackets, units ("X Y Z [mm]") and values ("nan") reach the terminal unchanged.
Errors metasheet raises on purpose (a :class:`~metasheet.errors.MetasheetError`: bad
config, missing file, failed stage, outputs not writable, disk full, folder in use,
unreachable goal) print as one message without a traceback (``metasheet --debug ...``
shows it) and exit with the status their class carries:

| status | meaning |
|---|---|
| 0 | success (``robot goto``: the goal was reached) |
| 1 | ``metasheet diff``: the trees differ |
| 2 | an error: bad config or command line, missing file, failed stage, outputs not writable, disk full |
| 3 | another run holds the output folder (``run --no-wait``, ``clean --no-wait``) |
| 4 | ``robot goto``: the goal was not reached (the closest pose and the remaining error are printed) |
| 129, 130, 143 | interrupted by SIGHUP, Ctrl-C (SIGINT) or SIGTERM (128 + the signal): the run's workers are stopped and its temporary folders removed first |

Anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

import sys
import traceback
from pathlib import Path
from typing import Annotated, Optional

import typer
from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
)
from rich.text import Text

from .errors import ConfigError, MetasheetError
from .goto import command_robot, format_result, goto_tolerances, parse_pose, pose_text, stall_text
from .pipeline.config import MAX_WORKERS
from .cli_export import export_app
from .cli_files import FILE_COMMANDS
from .cli_output import console, docs, say, stdout, table
from .cli_robot_options import (ColumnOption, MaterialModelOption, MeshSizeOption, OrientOption, OutOption,
                                PipelineOption)
from .cli_path import robot_path
from .runtime.stop_signals import Stopped, exit_now, stop_on_signals
from . import supervise

# rich_markup_mode=None: help and click's usage errors print as plain text (no markup, no
# panels that wrap long messages); pretty_exceptions off: a bug prints a plain traceback.
_TYPER = dict(rich_markup_mode=None, pretty_exceptions_enable=False, add_completion=False,
              context_settings={"help_option_names": ["-h", "--help"]})
#: --set's help (run, validate).
SET_HELP = ("override a value of the file, as TOML (orient.mesh_size=8; a bare word is a string: "
            "orient.element=p1); repeat for more")


app = typer.Typer(
    help="metasheet: soft robots from 3D-printed anisotropic foam, cell to controller.",
    epilog=docs("metasheet"),
    no_args_is_help=True,
    **_TYPER,
)
robot_app = typer.Typer(help="Drive the robot model.", epilog=docs("robot"), no_args_is_help=True, **_TYPER)
app.add_typer(robot_app, name="robot")
app.add_typer(export_app, name="export")
_STATE = {"debug": False}


@app.callback()
def _options(
    debug: Annotated[bool, typer.Option("--debug", help="show the traceback of an error")] = False,
    version: Annotated[bool, typer.Option("--version", is_eager=True, callback=lambda v: _print_version(v),
                                          help="print the version and exit")] = False,
) -> None:
    """metasheet: soft robots from 3D-printed anisotropic foam, cell to controller."""
    _STATE["debug"] = _STATE["debug"] or debug


def _print_version(asked: bool) -> None:
    if asked:
        from .version import __version__

        say(f"metasheet {__version__}", err=False)
        raise typer.Exit()


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


def _log_progress_factory(target: Console, every_s: float = 30.0, clock=None):
    """Progress as plain lines for a log (no terminal): a line when a task starts, ends, passes
    another tenth of its total, or ``every_s`` seconds after the last line, with the elapsed
    time and a linear estimate of the time left."""
    import time

    clock = clock or time.monotonic

    def factory(stage: str):
        seen: dict[str, tuple] = {}  # label -> (start, last line time, last tenth)

        def update(desc: str, done: int, total: int) -> None:
            desc = desc.removeprefix(f"{stage}: ")  # a stage that names itself: "cell: voxels", once
            label, now = f"{stage}: {desc}", clock()
            start, last, tenth = seen.get(label, (now, None, -1))
            t = int(10 * done / total) if total else 10
            if last is not None and done < total and t == tenth and now - last < every_s:
                return
            seen[label] = (start, now, t)
            took = now - start
            left = took * (total - done) / done if 0 < done < total and took >= 5.0 else None
            eta = "" if left is None or left < 1.0 else f", ~{left:.0f} s left"  # estimates from 5 s on
            times = f" ({took:.0f} s{eta})" if took >= 1.0 else ""
            target.print(f"{label} {done}/{total}{times}", soft_wrap=True, markup=False)

        return update

    return factory


def _reporter(target: Console):
    def report(stage: str, message: str) -> None:
        target.print(Text.assemble((stage, "bold"), ": ", str(message)), soft_wrap=True)

    return report


@app.command(epilog=docs("run"), short_help="Run a pipeline's stages, skipping those whose inputs did not change.")
def run(
    pipeline: Annotated[Path, typer.Argument(help="pipeline TOML file, e.g. pipelines/quick.toml")],
    stage: Annotated[Optional[list[str]], typer.Option("--stage", help="run only this stage (and what it "
                                                       "needs)")] = None,
    force: Annotated[bool, typer.Option("--force", help="rerun even when outputs are up to date")] = False,
    workers: Annotated[Optional[int], typer.Option("--workers", min=1, max=MAX_WORKERS,
                                                   help="local worker processes")] = None,
    scheduler: Annotated[Optional[str], typer.Option("--scheduler", help="dask scheduler, tcp://HOST:PORT")] = None,
    out: Annotated[Optional[Path], typer.Option("--out", help="output root (default: outputs/ of the project)")] = None,
    no_wait: Annotated[bool, typer.Option("--no-wait", help="exit (status 3) instead of waiting when another "
                                          "run holds the output folder")] = False,
    overwrite: Annotated[bool, typer.Option("--overwrite", help="replace stage folders even when they hold files "
                                            "metasheet did not write")] = False,
    assignments: Annotated[Optional[list[str]], typer.Option("--set", metavar="TABLE.KEY=VALUE",
                                                             help=SET_HELP)] = None,
) -> None:
    """Run the stages of PIPELINE in dependency order; up-to-date stages are skipped.

    One run per output folder at a time: a second run waits for the first (or exits with
    status 3 with --no-wait). Temporary folders left by killed runs are removed first. A stage
    folder holding files metasheet did not write is not replaced (exit 2) without --overwrite.
    """
    from .runtime.executor import Executor
    from .pipeline.config import load_pipeline
    from .pipeline.runner import run_pipeline

    if stage and len(stage) > 1:
        raise ConfigError(f"--stage: given {len(stage)} times ({', '.join(stage)}): run one stage (and what it "
                          "needs) at a time, or the whole pipeline without --stage")
    p = load_pipeline(pipeline, assignments or ())
    ex = Executor(workers or p.section.workers, scheduler or p.section.scheduler)
    options = dict(out_root=out, only=stage[0] if stage else None, force=force, executor=ex, wait=not no_wait,
                   overwrite=overwrite)
    if console.is_terminal:  # progress bars on a terminal; plain lines in a log
        columns = (TextColumn("{task.description}", markup=False), BarColumn(), MofNCompleteColumn(),
                   TimeElapsedColumn())
        with Progress(*columns, console=console, transient=True) as progress:
            outcomes = run_pipeline(p, report=_reporter(progress.console),
                                    progress_factory=_progress_factory(progress), **options)
    else:
        outcomes = run_pipeline(p, report=_reporter(console), progress_factory=_log_progress_factory(console),
                                **options)
    stdout.print(table(f"pipeline {p.name}", ("stage", "status", "time [s]", "CPU [s]", "outputs"),
                        [(o.name, o.status, f"{o.wall_time:.1f}", "" if o.cpu_time is None else f"{o.cpu_time:.0f}",
                          o.directory) for o in outcomes]))


@app.command(epilog=docs("clean"), short_help="Remove what killed runs left (--all: the outputs metasheet wrote).")
def clean(
    pipeline: Annotated[Path, typer.Argument(help="pipeline TOML file, e.g. pipelines/quick.toml")],
    everything: Annotated[bool, typer.Option("--all", help="also remove the stage folders metasheet wrote (files "
                                             "it did not write are kept)")] = False,
    out: Annotated[Optional[Path], typer.Option("--out", help="output root (default: outputs/ of the project)")] = None,
    no_wait: Annotated[bool, typer.Option("--no-wait", help="exit (status 3) instead of waiting for a "
                                          "running run")] = False,
) -> None:
    """Remove the temporary folders killed runs left in PIPELINE's outputs (--all: the outputs too).

    Only what metasheet wrote is removed: a stage folder whose manifest lists every file in it.
    Anything else in the output folder is kept, and named.
    """
    from .pipeline.config import load_pipeline
    from .pipeline.runner import clean as clean_outputs

    p = load_pipeline(pipeline)
    removed = clean_outputs(p, out_root=out, everything=everything, wait=not no_wait, report=_reporter(console))
    say(f"{p.name}: removed {len(removed)} item(s)" if removed else f"{p.name}: nothing to remove", err=False)


for _name, _command, _short in FILE_COMMANDS:  # init, status, schema: the pipeline file's commands
    app.command(_name, epilog=docs(_name), short_help=_short)(_command)


@app.command("stages", epilog=docs("stages"), short_help="List the stages, what each reads and writes.")
def list_stages() -> None:
    """List the stages, what they read and what they write."""
    from .pipeline.registry import stages

    rows = [(s.name, ", ".join([*s.requires, *(f"({o})" for o in s.optional)]) or "-", ", ".join(s.outputs), s.doc)
            for s in stages().values()]
    stdout.print(table("metasheet stages", ("stage", "reads", "writes", "what"), rows))


@app.command(epilog=docs("validate"), short_help="Check a pipeline file and the files it names, without running it.")
def validate(
    pipeline: Annotated[Path, typer.Argument(help="pipeline TOML file")],
    assignments: Annotated[Optional[list[str]], typer.Option("--set", metavar="TABLE.KEY=VALUE",
                                                             help=SET_HELP)] = None,
) -> None:
    """Check a pipeline file without running it (fields, stages, files it names)."""
    from .pipeline.config import load_pipeline

    p = load_pipeline(pipeline, assignments or ())
    say(f"{pipeline}: ok; stages in order: {' -> '.join(p.order)}", err=False)
    for stage in ("cell", "printcheck"):  # will the foam printed in this sheet behave like a continuum?
        if stage in p.params and "orient" in p.params:
            from .cells.polyfoam import PolyfoamDesign
            from .pipeline.stages.orient import sheet_params
            from .studies.continuum_check import check_design

            if stage == "cell":
                from .pipeline.stages.cell import load_design

                design = load_design(p.root, p.params["cell"])[0]
            else:
                from .pipeline.stages.printcheck import print_design

                design = print_design(p.root, p.params["printcheck"])
            if isinstance(design, PolyfoamDesign):
                chk = check_design(design, sheet_params(p.params["orient"]).thickness)
                say(f"{'warning' if chk.holds != 'bulk' else 'note'}: {stage}: {chk.message()} "
                    "(docs/continuum-map.md)")


@app.command(epilog=docs("diff"), short_help="Compare two output trees, file by file, number by number.")
def diff(
    a: Annotated[Path, typer.Argument(help="an output directory (e.g. outputs/quick)")],
    b: Annotated[Path, typer.Argument(help="the output directory to compare it with")],
    rtol: Annotated[float, typer.Option("--rtol", min=0.0, help="largest relative difference accepted")] = 1e-12,
    atol: Annotated[float, typer.Option("--atol", min=0.0, help="absolute difference always accepted, in each "
                                        "quantity's unit (mm, MPa, N, t/mm^3...): the floor for values zero up to "
                                        "round-off, e.g. 1e-12; default 0")] = 0.0,
) -> None:
    """Compare two output trees: identical bytes, numbers within tolerance, or different (exit 1).

    A quantity (a JSON key, a mesh array, a CSV column) agrees when
    max|a - b| <= ATOL + RTOL * max(max|a|, max|b|). ATOL defaults to 0: values here come in
    units as far apart as mm and t/mm^3 (the foam's density is ~1.8e-10), so no one floor
    fits them all; pass one for quantities that are zero by symmetry.
    """
    from .errors import ConfigError
    from .pipeline.outputs_diff import compare_trees

    for d in (a, b):
        if not d.is_dir():
            raise ConfigError(f"{d}: not a directory")
    rows = compare_trees(a, b, rtol=rtol, atol=atol)
    out = []
    for r in rows:
        numbers = r.status == "numbers"
        out.append((r.path, Text(r.status, style="" if r.within else "red"), f"{r.max_rel:.2e}" if numbers else "",
                    f"{r.max_abs:.2e}" if numbers else "", r.note))
    stdout.print(table("", ("file", "result", "max relative difference", "max absolute difference", "note"), out))
    bad = sum(not r.within for r in rows)
    say(f"{len(rows) - bad} of {len(rows)} files identical or within rtol {rtol:g}, atol {atol:g}", err=False)
    if bad:
        raise typer.Exit(1)


@robot_app.command("goto", epilog=docs("robot goto"),
                   short_help="Motor angles that bring the rod to a pose (the inverse model, paper eq. 8).")
def robot_goto(
    pose: Annotated[list[str], typer.Argument(
        metavar="POSE", help="X Y Z [mm] RX RY RZ [deg] of the rod centre (use -- before negatives)")],
    pipeline: PipelineOption = None,
    out: OutOption = None,
    model: Annotated[str, typer.Option("--model", help="robot model with --pipeline: 'full' (FEM), 'reduced' (the "
                                       "reduce stage's) or 'surface' (its equilibrium surface, the real-time "
                                       "model); outside their training box the full model solves")] = "full",
    orient: OrientOption = None,
    mesh_size: MeshSizeOption = 8.0,
    material_model: MaterialModelOption = None,
    column: ColumnOption = "prediction",
    tol_mm: Annotated[Optional[float], typer.Option("--tol-mm", min=1e-6, max=100.0, help="position tolerance "
                                                    "[mm]; default 0.1, the reproduction column's the paper's "
                                                    "test: 1")] = None,
    tol_deg: Annotated[Optional[float], typer.Option("--tol-deg", min=1e-6, max=90.0, help="rotation tolerance "
                                                     "[deg]; default 0.2, the reproduction column's the paper's "
                                                     "test: 2")] = None,
) -> None:
    """Solve the inverse model (paper eq. 8) from rest to a pose and print the motor angles.

    Exits with status 4 when the goal is not reached, after printing the closest pose
    and the remaining error.
    """
    from .errors import UnreachableError
    from .robot.inverse_settings import InverseSettings
    from .serve.loading import GOTO_MODELS
    from .serve.models import goto

    goal = parse_pose(pose)
    robot, info = command_robot(pipeline, out, model, orient, mesh_size, material_model, column, GOTO_MODELS)
    tol_mm, tol_deg = goto_tolerances(column, tol_mm, tol_deg)
    res, note = goto(robot, goal, InverseSettings(pos_tol=tol_mm, rot_tol_deg=tol_deg))
    used = "full" if info is None or note else info.model
    say(f"model: {used}" + (f" ({note})" if note else "") + f"; {column}, tolerance {tol_mm:g} mm, {tol_deg:g} deg",
        err=False)
    say(format_result(res), err=False)
    if not res.reached:
        why = stall_text(robot, res)
        say(why, err=False)
        raise UnreachableError(
            f"goal not reached ({res.status}): remaining error {res.pos_error:.3f} mm, {res.rot_error:.3f} deg; "
            f"closest pose {pose_text(res.pose)}; " + why.splitlines()[0]
        )


robot_app.command("path", epilog=docs("robot path"),
                  short_help="A path of poses as motor angles over time for the servos (a motor program).")(robot_path)


@app.command(epilog=docs("serve"), short_help="Drive the pipeline's robot from a browser.")
def serve(
    pipeline: Annotated[Path, typer.Argument(help="pipeline TOML file whose robot to drive, e.g. pipelines/quick.toml")],
    host: Annotated[str, typer.Option("--host", help="address to serve on (127.0.0.1: this machine only)")] = "127.0.0.1",
    port: Annotated[int, typer.Option("--port", min=1, max=65535, help="port to serve on")] = 8080,
    model: Annotated[str, typer.Option("--model", help="robot model: 'full' (FEM) or 'reduced' (the reduce "
                                       "stage's reduced-order robot)")] = "full",
    out: Annotated[Optional[Path], typer.Option("--out", help="output root the pipeline ran with (default: "
                                                "outputs/ of the project)")] = None,
) -> None:
    """Drive the pipeline's robot from a browser: drag the goal, the inverse model follows live.

    Serves a page at http://HOST:PORT showing the robot the robot stage built (run the
    pipeline first); Ctrl-C stops it.
    """
    from .serve.app import serve as serve_page
    from .serve.loading import MODELS, find_outputs

    if model not in MODELS:
        from .errors import ConfigError

        raise ConfigError(f"--model: {model!r}: allowed values are {', '.join(MODELS)}")
    outputs = find_outputs(pipeline, out)
    if host not in ("127.0.0.1", "localhost", "::1"):
        say(f"note: --host {host}: the page is served beyond this machine; anyone who reaches it drives the robot")
    say(f"loading the robot of {outputs.directory} ...")
    try:
        serve_page(outputs, host=host, port=port, model=model,
                   ready=lambda url: say(f"serving the robot at {url} (Ctrl-C stops)"))
    except KeyboardInterrupt:
        say("stopped")
        raise typer.Exit(130) from None


def _pop_debug(args: list[str]) -> bool:
    """Remove ``--debug`` from ``args`` wherever it stands before ``--``; True if it was there."""
    end = args.index("--") if "--" in args else len(args)
    found = "--debug" in args[:end]
    if found:
        args[:] = [a for a in args[:end] if a != "--debug"] + args[end:]
    return found


def main(argv: list[str] | None = None) -> None:
    """Console-script entry point."""
    args = list(sys.argv[1:] if argv is None else argv)
    _STATE["debug"] = _pop_debug(args)
    try:
        with stop_on_signals():
            app(args=args, prog_name="metasheet")
    except Stopped as stop:
        supervise.said()  # exit_now skips atexit: tell a supervising parent the stop was said
        exit_now(stop.code, lambda text: say(text, prefix="interrupted: "))
    except MetasheetError as err:
        if _STATE["debug"]:
            traceback.print_exc()
        say(str(err), prefix="error: ", style="bold red")
        sys.exit(err.exit_code)
    except OSError as err:  # the environment, not a bug: a file that cannot be read or written
        if _STATE["debug"]:
            traceback.print_exc()
        where = f"{err.filename}: " if err.filename else ""
        say(f"{where}{err.strerror or err}", prefix="error: ", style="bold red")
        sys.exit(2)


if __name__ == "__main__":
    main()
