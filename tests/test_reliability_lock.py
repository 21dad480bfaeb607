"""Issue 15, items 2 and 3: one run per output folder at a time, no debris after a kill.

Real processes: a small driver script registers two test stages (``slow`` sleeps while its
temporary folder holds a partial file, ``after`` reads it) and calls ``metasheet.cli.main``.
"""

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

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


def run_after(ctx):
    v = float((ctx.inputs["slow"] / "out.txt").read_text())
    ctx.path("after.txt").write_text(f"{2 * v}\\n")
    return {}


register(Stage("slow", SlowParams, run_slow, outputs=("out.txt",)))
register(Stage("after", SlowParams, run_after, requires=("slow",), outputs=("after.txt",)))

if __name__ == "__main__":
    from metasheet.cli import main

    main(sys.argv[1:])
'''


STARTED: list[subprocess.Popen] = []


@pytest.fixture
def project(tmp_path):
    (tmp_path / "cells").mkdir()
    (tmp_path / "pipelines").mkdir()
    (tmp_path / "driver.py").write_text(DRIVER)
    yield tmp_path
    (tmp_path / "gate-open").write_text("")  # a failed test leaves no run behind
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


def env(seconds: float | str = 0.0):
    e = dict(os.environ, SLOW_STAGE_SECONDS=str(seconds))
    e["PYTHONPATH"] = os.pathsep.join([str(ROOT), e.get("PYTHONPATH", "")])
    return e


def start(project: Path, *args: str, seconds: float | str) -> subprocess.Popen:
    """A run whose stage ``slow`` sleeps ``seconds`` (or until ``gate-open`` exists: "gate"), in the background."""
    proc = subprocess.Popen([sys.executable, str(project / "driver.py"), *args], cwd=project, env=env(seconds),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    STARTED.append(proc)
    return proc


def call(project: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(project / "driver.py"), *args], cwd=project, env=env(),
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


def test_second_run_waits_for_the_first_and_outputs_equal_a_single_run(project):
    """Before: both ran every stage at once into the same folder, nothing said so."""
    toml = pipeline(project)
    single = call(project, "run", str(toml), "--out", str(project / "single"))
    assert single.returncode == 0, single.stderr
    first = start(project, "run", str(toml), "--out", str(project / "out"), seconds="gate")
    wait_started(project, first)
    second = start(project, "run", str(toml), "--out", str(project / "out"), seconds="gate")
    lines = stderr_lines(second)
    t0 = time.monotonic()
    while not any("waiting for it to finish" in ln for ln in lines):
        assert not (project / "started" / str(second.pid)).exists(), "the second run did not wait"
        assert second.poll() is None and time.monotonic() - t0 < 120, lines
        time.sleep(0.05)
    (project / "gate-open").write_text("")
    _, err1 = first.communicate(timeout=300)
    out2, _ = second.communicate(timeout=300)
    assert first.returncode == 0, err1
    assert second.returncode == 0, "".join(lines)
    assert any(f"in use by run pid {first.pid} since " in ln for ln in lines), lines
    assert out2.count("cached") == 2  # it found the first run's outputs fresh
    assert len(list((project / "started").iterdir())) == 2  # only the single run and the first ran ``slow``
    assert outputs(project / "out" / "p") == outputs(project / "single" / "p")


def test_no_wait_refuses_with_status_3_naming_the_holder(project):
    """Before: no --no-wait (a usage error), and no lock to refuse on."""
    toml = pipeline(project)
    first = start(project, "run", str(toml), seconds="gate")
    wait_started(project, first)
    second = call(project, "run", str(toml), "--no-wait")
    (project / "gate-open").write_text("")
    first.communicate(timeout=300)
    assert second.returncode == 3, second.stderr
    lines = [ln for ln in second.stderr.splitlines() if ln.startswith("error: ")]
    assert len(lines) == 1 and f"in use by run pid {first.pid} since " in lines[0], second.stderr
    assert "--no-wait" in lines[0] and "Traceback" not in second.stderr
    assert first.returncode == 0


def test_sigkilled_run_then_a_normal_run_leaves_no_temporary_folder(project):
    """Before: ``.slow.tmp-<pid>/`` (with its partial file) stayed for ever."""
    toml = pipeline(project)
    first = start(project, "run", str(toml), seconds=60.0)
    wait_started(project, first)
    base = project / "outputs" / "p"
    assert (base / f".slow.tmp-{first.pid}" / "partial.txt").is_file()
    first.send_signal(signal.SIGKILL)
    first.communicate(timeout=60)
    again = call(project, "run", str(toml))
    assert again.returncode == 0, again.stderr
    assert f"taking over the lock left by run pid {first.pid}" in again.stderr
    assert f"removed {base / f'.slow.tmp-{first.pid}'}" in again.stderr
    assert sorted(p.name for p in base.iterdir()) == ["after", "slow"]
    assert (base / "after" / "after.txt").read_text() == "2.0\n"
    assert not (project / "outputs" / ".p.lock.json").exists()  # the holder file goes with its run


def test_sigterm_unwinds_like_ctrl_c(project):
    """A polite kill removes the temporary folder itself and keeps no lock."""
    toml = pipeline(project)
    first = start(project, "run", str(toml), seconds=60.0)
    wait_started(project, first)
    first.send_signal(signal.SIGTERM)
    first.communicate(timeout=60)
    assert first.returncode == 128 + signal.SIGTERM
    base = project / "outputs" / "p"
    assert not any(".tmp-" in p.name for p in base.iterdir())
    assert not (project / "outputs" / ".p.lock.json").exists()


def test_clean_removes_debris_of_dead_processes_and_all_outputs(project):
    """Before: there was no ``metasheet clean``."""
    toml = pipeline(project)
    assert call(project, "run", str(toml)).returncode == 0
    base = project / "outputs" / "p"
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    dead_pid = int(dead.stdout)
    (base / f".slow.tmp-{dead_pid}").mkdir()
    (base / f".slow.tmp-{dead_pid}" / "partial.txt").write_text("x")
    (base / f".after.old-{dead_pid}").mkdir()
    live = base / f".after.tmp-{os.getpid()}"  # this test process is alive: kept
    live.mkdir()
    r = call(project, "clean", str(toml))
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in base.iterdir()) == sorted(["after", "slow", live.name])
    assert "removed 2 item(s)" in r.stdout
    r = call(project, "clean", str(toml), "--all")
    assert r.returncode == 0, r.stderr
    assert not base.exists()
    r = call(project, "clean", str(toml))
    assert r.returncode == 0 and "nothing to remove" in r.stdout


@pytest.mark.parametrize("where", ["process pool", "dask cluster"])
def test_workers_never_take_the_lock(project, where):
    """The run holds the lock; the workers its stages hand work units to find it taken.
    Before: there was no lock at all (a worker found it free)."""
    if where == "dask cluster":
        distributed = pytest.importorskip("distributed")
        cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1",
                                           dashboard_address=None)
        args = ("--scheduler", cluster.scheduler_address)
    else:
        cluster, args = None, ("--workers", "2")
    try:
        first = start(project, "run", str(pipeline(project, probe=True)), *args, seconds=0.0)
        out, err = first.communicate(timeout=300)
    finally:
        if cluster is not None:
            cluster.close()
    assert first.returncode == 0, err
    probes = eval((project / "outputs/p/slow/probe.json").read_text())
    assert [p[0] for p in probes] == ["held by another process"] * 2
    assert all(p[1] != first.pid for p in probes)  # they ran in workers
