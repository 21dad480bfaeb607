"""``metasheet robot path``: a path of effector poses as a motor program for the six servos
(:mod:`metasheet.export.program`, :mod:`metasheet.export.servo`); :mod:`metasheet.cli` registers it."""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Optional

import numpy as np
import typer

from .cli_output import console, say
from .cli_robot_options import (ColumnOption, MaterialModelOption, MeshSizeOption, OrientOption, OutOption,
                                PipelineOption)
from .errors import ConfigError, UnreachableError, check_range

#: Speed of a path without times when --speed is not given [mm/s].
DEFAULT_SPEED = 10.0
#: The models a program is solved on.
PATH_MODELS = ("full", "reduced")
#: The [maze] keys that make its path (program.json's inputs)
MAZE_KEYS = ("path", "tilt_deg", "speed", "dt", "ramp_s", "tol_mm", "tol_deg")


def _stage_params(pipeline, name: str):
    """The pipeline's ``[name]`` parameters when it runs that stage, else None."""
    if pipeline is None:
        return None
    from .pipeline.config import load_pipeline

    return load_pipeline(pipeline).params.get(name)


@contextmanager
def _progress(total_hint: str):
    """``update(done, total)``: a bar on a terminal, a line every tenth in a log (stderr)."""
    if console.is_terminal:
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

        with Progress(TextColumn(total_hint), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                      console=console, transient=True) as bar:
            task = bar.add_task(total_hint)
            yield lambda done, total: bar.update(task, completed=done, total=total)
        return
    seen = {"tenth": -1}

    def update(done: int, total: int) -> None:
        tenth = 10 * done // max(total, 1)
        if tenth != seen["tenth"]:
            seen["tenth"] = tenth
            say(f"{total_hint}: {done}/{total}")

    yield update


def _check_report(check, times, angles, extra: list[str]) -> tuple[list[str], bool]:
    """Lines naming the flagged samples and a verdict; whether the program passes."""
    lines = check.lines(times, angles)
    s = check.summary()
    ok = check.ok and not extra
    verdict = (f"servo check: {s['samples']} samples, {s['beyond_stroke']} beyond the stroke, {s['too_fast']} faster "
               f"than {s['speed_limit_deg_s']:g} deg/s (largest speed {s['max_speed_deg_s']:.1f} deg/s)")
    return [*lines, *extra, verdict + ("; ready to send" if ok else "; NOT ready to send")], ok


def robot_path(
    path_csv: Annotated[Optional[Path], typer.Argument(
        metavar="PATH.csv", help="poses to follow: a CSV with the header x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg "
        "(rotation vector [deg], as robot goto takes it), optionally t_s (times [s]: no --speed then)")] = None,
    maze: Annotated[bool, typer.Option("--maze", help="the maze study's path instead: its tilt commands over "
                                       "time (the pipeline's [maze] table, else the stage's defaults)")] = False,
    ray: Annotated[Optional[int], typer.Option("--ray", help="ray K of the workspace study's star grid instead "
                                               "(the pipeline's [workspace] table, else the defaults: rays 0-61): "
                                               "its goals outwards from rest, at the rest orientation")] = None,
    tilt_deg: Annotated[Optional[float], typer.Option("--tilt-deg", help="with --maze: the maze's tilt [deg], (0, "
                                                      "45] (default the [maze] table's, else 8)")] = None,
    speed: Annotated[Optional[float], typer.Option("--speed", help="speed along the path [mm/s]; default 10 "
                                                   "(--maze: the marble's, default the [maze] table's)")] = None,
    rot_speed: Annotated[float, typer.Option("--rot-speed", help="rotation speed [deg/s]: a segment takes the longer "
                                             "of its length / --speed and its turn / --rot-speed")] = 10.0,
    rate: Annotated[float, typer.Option("--rate", help="samples per second [Hz], at most 1000")] = 10.0,
    to: Annotated[Optional[Path], typer.Option("--to", help="folder to write program.csv, program.json and "
                                               "program.png into (needed unless --dry-run)")] = None,
    pipeline: PipelineOption = None,
    out: OutOption = None,
    model: Annotated[str, typer.Option("--model", help="with --pipeline: 'full' (FEM) or 'reduced' (the reduce "
                                       "stage's; outside its training box the full model solves)")] = "full",
    orient: OrientOption = None,
    mesh_size: MeshSizeOption = 8.0,
    material_model: MaterialModelOption = None,
    column: ColumnOption = "prediction",
    tol_mm: Annotated[Optional[float], typer.Option("--tol-mm", min=1e-6, max=100.0, help="position tolerance of "
                                                    "each sample [mm]; default robot goto's (--maze: the [maze] "
                                                    "table's, 1)")] = None,
    tol_deg: Annotated[Optional[float], typer.Option("--tol-deg", min=1e-6, max=90.0, help="rotation tolerance of "
                                                     "each sample [deg]; default robot goto's (--maze: the [maze] "
                                                     "table's, 1)")] = None,
    pulse_min: Annotated[float, typer.Option("--pulse-min-us", help="pulse width at 0 deg [us]")] = 500.0,
    pulse_max: Annotated[float, typer.Option("--pulse-max-us", help="pulse width at --servo-range-deg [us]")] = 2500.0,
    servo_range: Annotated[float, typer.Option("--servo-range-deg", help="the angle the pulse range spans [deg] "
                                               "(a 180-degree hobby servo: 180)")] = 180.0,
    reversed_: Annotated[Optional[list[int]], typer.Option("--reversed", metavar="MOTOR", help="a servo (0-5) "
                                                           "mounted mirrored: its pulse is mirrored; repeat for "
                                                           "more")] = None,
    max_speed: Annotated[float, typer.Option("--max-speed", help="the servos' speed limit [deg/s]; default the "
                                             "SG90 / MG90S datasheets' typical 0.1 s / 60 deg at 4.8 V")] = 600.0,
    dry_run: Annotated[bool, typer.Option("--dry-run", help="check every sample against the stroke and the speed "
                                          "limit; write nothing")] = False,
    program_file: Annotated[Optional[Path], typer.Option("--program", help="with --dry-run: check this "
                                                         "program.csv instead of solving")] = None,
    pvd: Annotated[bool, typer.Option("--pvd", help="also write the deformed robot at every sample as a "
                                      "ParaView series (path.pvd)")] = False,
) -> None:
    """Solve a path of effector poses into the six motor angles over time (a motor program).

    Exits with status 4 when a sample is not reached, beyond the stroke or faster than the
    servos (the files are written all the same, the samples flagged), 2 on bad input.
    """
    from .export import path as pth, program as prog
    from .goto import command_robot
    from .export.servo import ServoPulse, check_program, motors, stroke_deg

    pulse = ServoPulse.with_reversed(reversed_ or (), pulse_min_us=pulse_min, pulse_max_us=pulse_max,
                                     angle_at_min_deg=0.0, angle_at_max_deg=servo_range)
    if program_file is not None:
        if not dry_run:
            raise ConfigError("--program: checks an existing program.csv: give --dry-run too")
        return _check_file(program_file, max_speed)
    sources = [n for n, on in (("PATH.csv", path_csv is not None), ("--maze", maze), ("--ray", ray is not None)) if on]
    if len(sources) != 1:
        raise ConfigError("path: give one of PATH.csv, --maze or --ray K" + (f" (given: {', '.join(sources)})"
                                                                             if sources else ""))
    if to is None and not dry_run:
        raise ConfigError("--to: the folder to write the program into is needed (or --dry-run)")
    check_range("--rate", rate, 0.0, 1000.0, lo_open=True)
    check_range("--rot-speed", rot_speed, 0.0, 1e5, lo_open=True)
    if speed is not None:
        check_range("--speed", speed, 0.0, 1e4, lo_open=True)
    if tilt_deg is not None:
        if not maze:
            raise ConfigError("--tilt-deg: only with --maze (the maze's tilt)")
        check_range("--tilt-deg", tilt_deg, 0.0, 45.0, lo_open=True)
    check_range("--max-speed", max_speed, 0.0, None, lo_open=True)
    csv_path = pth.read_path_csv(path_csv) if path_csv is not None else None
    maze_p = None
    if maze:
        from .pipeline.stages.maze import MazeParams

        maze_p = _stage_params(pipeline, "maze") or MazeParams()
        maze_p = maze_p.model_copy(update={k: v for k, v in (("speed", speed), ("tilt_deg", tilt_deg)) if v is not None})
        tol_mm, tol_deg = (maze_p.tol_mm if tol_mm is None else tol_mm), (maze_p.tol_deg if tol_deg is None else tol_deg)

    from .goto import goto_tolerances
    from .robot.inverse_settings import InverseSettings
    from .serve.models import RobotModels

    tol_mm, tol_deg = goto_tolerances(column, tol_mm, tol_deg)
    settings = InverseSettings(pos_tol=tol_mm, rot_tol_deg=tol_deg)
    robot = command_robot(pipeline, out, model, orient, mesh_size, material_model, column, PATH_MODELS)[0]
    models = RobotModels(robot, None, settings)  # the rest equilibrium
    speed = speed if speed is not None else DEFAULT_SPEED
    times, poses, timing = _path(prog.rest_pose(models.rest), csv_path, maze_p, ray, pipeline, speed, rot_speed)
    t, goals = pth.sample_path(times, poses, rate)
    say(f"robot path: {len(t)} samples over {t[-1] - t[0]:.2f} s at {rate:g} Hz ({model} model, tolerance "
        f"{tol_mm:g} mm, {tol_deg:g} deg)")
    with _progress("solving the samples") as update:
        program = prog.solve_program(robot, t, goals, settings, models=models, progress=update)
    lo, hi = stroke_deg(robot)
    check = check_program(program.angles_deg, program.times, lo, hi, max_speed)
    s = program.summary()
    say(f"{s['reached']} of {s['samples']} samples reached; largest error {s['max_error_mm']:.3f} mm, "
        f"{s['max_error_deg']:.3f} deg; model(s): {', '.join(s['models'])}", err=False)
    missed = []
    if s["not_reached"]:
        i = s["first_not_reached"]
        missed = [f"{s['not_reached']} of {s['samples']} samples not reached (first: sample {i} at "
                  f"{program.times[i]:.3f} s, {program.reason[i] or program.status[i]})"]
    lines, ok = _check_report(check, program.times, program.angles_deg, missed)
    if dry_run:
        lines.append("dry run: nothing written")
    else:
        record = {"inputs": {"path": path_csv, "maze": None if maze_p is None else
                             {k: getattr(maze_p, k) for k in MAZE_KEYS}, "ray": ray, "pipeline": pipeline,
                             "out": out, "column": column, "orient": orient, "material_model": material_model,
                             "mesh_size_mm": mesh_size if pipeline is None and orient is None else None},
                  "timing": timing, "rate_hz": rate, "speed_mm_s": speed if timing == "speed" else None,
                  "rot_speed_deg_s": rot_speed if timing == "speed" else None, "model": model,
                  "tolerances": {"position_mm": tol_mm, "rotation_deg": tol_deg},
                  "motors": motors(robot), "stroke_deg": {"lo": lo.tolist(), "hi": hi.tolist()},
                  "pulse": pulse.to_dict(), "check": check.summary()}
        record["inputs"] = {k: str(v) if isinstance(v, Path) else v for k, v in record["inputs"].items()}
        files = {"program.csv": prog.program_csv(program, pulse.pulse_us(program.angles_deg)),
                 "program.json": prog.program_json(program, record),
                 "program.png": prog.program_picture(program, (lo, hi), tolerances=(tol_mm, tol_deg),
                                                     title=f"motor program ({timing}, {model} model)")}
        written = _write(to, files)
        if pvd:
            written.append(_write_series(robot, program, to, None if maze_p is None else maze_p.path))
        lines = [*lines[-1 - len(missed):], "wrote " + ", ".join(str(p) for p in written)]  # counts, not each sample
    for line in lines:
        say(line, err=False)
    if not ok:
        flagged = [] if check.ok else [f"{int(check.flagged.sum())} sample(s) beyond the stroke or too fast"]
        raise UnreachableError("the program is not ready to send: " + "; ".join([*missed, *flagged]))


def _path(rest, csv_path, maze_p, ray, pipeline, speed: float, rot_speed: float):
    """(times (n,) [s], poses (n, 6) [mm, deg], how it is timed) of the path asked for, from
    the rest pose ``rest`` (6,) [mm, deg]."""
    from .export import path as pth

    if csv_path is not None:
        poses, times = csv_path
        pth.check_reach(poses, rest)
        if times is not None:
            return times, poses, "t_s column"
    elif maze_p is not None:
        return (*pth.maze_path(rest, maze_p), "maze commands")
    else:
        from .pipeline.stages._studies import grid_from
        from .studies.grid import star_grid

        grid_p = _stage_params(pipeline, "workspace")
        poses = pth.ray_path(rest, grid_from(grid_p) if grid_p is not None else star_grid(), ray)
        pth.check_reach(poses, rest)
    return pth.path_times(poses, speed, rot_speed), poses, "speed"


def _write(folder: Path, files: dict) -> list[Path]:
    from .errors import output_error
    from .export.program import write_files

    try:
        return write_files(folder, files)
    except OSError as exc:
        raise output_error(exc, str(folder)) from exc


def _write_series(robot, program, folder: Path, maze_path=None) -> Path:
    """``<folder>/path.pvd`` and ``<folder>/path/``: the robot at every sample, the maze's path
    drawn on its plate when the program follows it."""
    from .export.series import MazePlate, write_robot_series

    plate = None if maze_path is None else MazePlate(path=tuple(tuple(map(float, p)) for p in maze_path))
    return write_robot_series(robot, program.states, program.times, folder, name="path", maze=plate)


def _check_file(file: Path, max_speed: float) -> None:
    """``--dry-run --program FILE``: the servo check of an existing program.csv, against the
    stroke its program.json states (else the paper's, 0-90 deg)."""
    import json

    from .export.program import read_program_csv
    from .export.servo import check_program
    from .published import paper

    times, angles = read_program_csv(file)
    meta = Path(file).with_name("program.json")
    lo, hi, where = paper.ANGLE_MIN, paper.ANGLE_MAX, "the paper's stroke"
    if meta.is_file():
        stroke = json.loads(meta.read_text()).get("stroke_deg") or {}
        if "lo" in stroke and "hi" in stroke:
            lo, hi, where = np.asarray(stroke["lo"], float), np.asarray(stroke["hi"], float), f"the stroke of {meta}"
    say(f"checking {file}: {len(times)} samples against {where} and {max_speed:g} deg/s")
    check = check_program(angles, times, lo, hi, max_speed)
    lines, ok = _check_report(check, times, angles, [])
    for line in lines:
        say(line, err=False)
    if not ok:
        raise UnreachableError(f"{file}: {int(check.flagged.sum())} of {len(times)} samples beyond the stroke or "
                               "too fast: the program is not ready to send")
