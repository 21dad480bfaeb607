"""The driver of the real-process reliability tests: a script that registers small test
stages (``slow`` sleeps while its temporary folder holds a partial file, ``after`` reads it,
``pooled`` hands two sleeping units to the pool's workers, each marking its pid) and calls
``metasheet.cli.main``; and helpers to start, call and watch it."""

import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

DRIVER = '''
import os, sys, time
from metasheet.pipeline.registry import Params, Stage, register, stages

stages()


class SlowParams(Params):
    value: float = 1.0
    workers_probe: bool = False


def probe(lock_file):
    """Runs in a pool worker: the lock is held by the run, never by a worker."""
    from filelock import FileLock, Timeout
    try:
        FileLock(lock_file).acquire(timeout=0)
    except Timeout:
        return ("held by another process", os.getpid())
    return ("free", os.getpid())


def run_slow(ctx):
    ctx.path("partial.txt").write_text("half-written")
    (ctx.root / "started").mkdir(exist_ok=True)
    (ctx.root / "started" / str(os.getpid())).write_text("")
    wait = os.environ.get("SLOW_STAGE_SECONDS", "0")
    if wait == "gate":  # until the test opens the gate (at most two minutes)
        t0 = time.monotonic()
        while not (ctx.root / "gate-open").exists() and time.monotonic() - t0 < 120:
            time.sleep(0.05)
    else:
        time.sleep(float(wait))
    ctx.path("out.txt").write_text(f"{ctx.params.value}\\n")
    if ctx.params.workers_probe:
        lock = str(ctx.workdir.parents[1] / f".{ctx.workdir.parent.name}.lock")
        ctx.path("probe.json").write_text(repr(ctx.executor.map(probe, [lock, lock])))
    return {"value": ctx.params.value}


def nap(seconds):
    """A unit in a pool worker: marks its pid, then sleeps (a long unit under way)."""
    from pathlib import Path
    Path(os.environ["RUN_MARKS"], f"worker-{os.getpid()}").write_text("")
    time.sleep(seconds)
    return seconds


class PooledParams(Params):
    nap: float = 0.0


def run_pooled(ctx):
    ctx.path("partial.txt").write_text("half-written")
    ctx.path("naps.txt").write_text(repr(ctx.executor.map(nap, [ctx.params.nap] * 2,
                                                          progress=lambda d, n: ctx.progress("naps", d, n))))
    return {}


def run_after(ctx):
    v = float((ctx.inputs["slow"] / "out.txt").read_text())
    ctx.path("after.txt").write_text(f"{2 * v}\\n")
    return {}


register(Stage("slow", SlowParams, run_slow, outputs=("out.txt",)))
register(Stage("after", SlowParams, run_after, requires=("slow",), outputs=("after.txt",)))
register(Stage("pooled", PooledParams, run_pooled, outputs=("naps.txt",)))

if __name__ == "__main__":
    from metasheet.cli import main

    main(sys.argv[1:])
'''


STARTED: list[subprocess.Popen] = []


def make_project(tmp_path: Path) -> Path:
    (tmp_path / "cells").mkdir()
    (tmp_path / "pipelines").mkdir()
    (tmp_path / "driver.py").write_text(DRIVER)
    return tmp_path


def stop_started(tmp_path: Path) -> None:
    """A failed test leaves no run behind."""
    (tmp_path / "gate-open").write_text("")
    while STARTED:
        proc = STARTED.pop()
        if proc.poll() is None:
            proc.kill()
        proc.communicate()


def pipeline(project: Path, *, name: str = "p", probe: bool = False) -> Path:
    p = project / "pipelines" / f"{name}.toml"
    p.write_text(f'[pipeline]\nname = "{name}"\nstages = ["slow", "after"]\n'
                 f'[slow]\nworkers_probe = {str(probe).lower()}\n')
    return p


def env(seconds: float | str = 0.0, marks: Path | None = None):
    e = dict(os.environ, SLOW_STAGE_SECONDS=str(seconds))
    if marks is not None:
        e["RUN_MARKS"] = str(marks)
    e["PYTHONPATH"] = os.pathsep.join([str(ROOT), e.get("PYTHONPATH", "")])
    return e


def start(project: Path, *args: str, seconds: float | str) -> subprocess.Popen:
    """A run whose stage ``slow`` sleeps ``seconds`` (or until ``gate-open`` exists: "gate"), in the background."""
    (project / "marks").mkdir(exist_ok=True)
    proc = subprocess.Popen([sys.executable, str(project / "driver.py"), *args], cwd=project,
                            env=env(seconds, project / "marks"),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    STARTED.append(proc)
    return proc


def call(project: Path, *args: str) -> subprocess.CompletedProcess:
    (project / "marks").mkdir(exist_ok=True)
    return subprocess.run([sys.executable, str(project / "driver.py"), *args], cwd=project,
                          env=env(marks=project / "marks"),
                          capture_output=True, text=True, timeout=300)


def wait_started(project: Path, proc: subprocess.Popen, timeout: float = 120.0) -> None:
    """Until ``proc`` is inside stage ``slow`` (its temporary folder holds a partial file)."""
    t0 = time.monotonic()
    while not (project / "started" / str(proc.pid)).exists():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() - t0 < timeout, "the first run did not start its stage"
        time.sleep(0.05)


def outputs(root: Path) -> dict[str, object]:
    """Every file under ``root``: bytes, or for manifests every field but the wall-clock ones."""
    out = {}
    for p in sorted(root.rglob("*")):
        if p.is_file():
            rel = p.relative_to(root).as_posix()
            if p.name == "manifest.json":
                m = json.loads(p.read_text())
                out[rel] = {k: v for k, v in m.items() if k not in ("started", "wall_time_s", "cpu_s", "timings_s")}
            else:
                out[rel] = p.read_bytes()
    return out


def stderr_lines(proc: subprocess.Popen) -> list[str]:
    """Collect ``proc``'s stderr lines as they come (a reader thread)."""
    lines: list[str] = []
    threading.Thread(target=lambda: lines.extend(iter(proc.stderr.readline, "")), daemon=True).start()
    return lines


