"""Kill means stop: a signal to ``metasheet run`` during a pooled stage leaves no process of the
run and no temporary folder, and the next run's outputs equal a clean run's.

Real processes (:mod:`run_driver`): stage ``pooled`` hands two units that sleep two minutes to
the pool's two workers. Before: SIGTERM waited for the units (and the whole convergence study)
to end; after SIGKILL the workers and the resource tracker were re-parented to PID 1 and
computed on, then waited for work for ever.
"""

import signal
import time
from pathlib import Path

import pytest
from run_driver import call, make_project, outputs, start, stop_started

from metasheet.pipeline.runner import pid_alive


@pytest.fixture
def project(tmp_path):
    yield make_project(tmp_path)
    stop_started(tmp_path)


def pooled(project: Path, nap: float, *, side_by_side: bool = False) -> Path:
    """A pipeline whose stage ``pooled`` runs two units of ``nap`` seconds on 2 workers; with
    ``side_by_side`` stage ``slow`` (sleeping in this process) runs beside it."""
    p = project / "pipelines" / "k.toml"
    stages = '["pooled", "slow"]' if side_by_side else '["pooled"]'
    at_once = 2 if side_by_side else 1
    p.write_text(f'[pipeline]\nname = "k"\nstages = {stages}\nworkers = 2\nstages_at_once = {at_once}\n'
                 f'[pooled]\nnap = {nap}\n')
    return p


def children(pid: int) -> set[int]:
    """The processes whose parent is ``pid`` (Linux /proc)."""
    found = set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue
        if int(fields[1]) == pid:
            found.add(int(stat.parent.name))
    return found


def wait_for_workers(project: Path, proc, n: int = 2, timeout: float = 120.0) -> set[int]:
    """The pids of the ``n`` workers once each is inside its unit."""
    t0 = time.monotonic()
    while len(marks := list((project / "marks").glob("worker-*"))) < n:
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() - t0 < timeout, "the workers did not start their units"
        time.sleep(0.05)
    return {int(m.name.split("-")[1]) for m in marks}


def gone_within(pids: set[int], seconds: float) -> set[int]:
    """The pids of ``pids`` still alive after waiting at most ``seconds``."""
    t0 = time.monotonic()
    while (alive := {p for p in pids if pid_alive(p)}) and time.monotonic() - t0 < seconds:
        time.sleep(0.1)
    return alive


def debris(project: Path) -> list[str]:
    base = project / "outputs" / "k"
    return sorted(p.name for p in base.iterdir() if p.name.startswith(".")) if base.exists() else []


# SIGINT (with a stage beside the pooled one) and SIGHUP take the same handler as SIGTERM: slow
@pytest.mark.parametrize(("signum", "side_by_side"), [
    (signal.SIGTERM, False), pytest.param(signal.SIGINT, True, marks=pytest.mark.slow),
    pytest.param(signal.SIGHUP, False, marks=pytest.mark.slow)])
def test_a_stop_signal_during_a_pooled_stage_stops_every_process_at_once(project, signum, side_by_side):
    run = start(project, "run", str(pooled(project, 120.0, side_by_side=side_by_side)), seconds=120.0)
    workers = wait_for_workers(project, run)
    family = children(run.pid) | workers  # the workers and multiprocessing's resource tracker
    t0 = time.monotonic()
    run.send_signal(signum)
    _, err = run.communicate(timeout=60)
    took = time.monotonic() - t0
    assert run.returncode == 128 + signum, err
    assert took < 10, f"the run took {took:.1f} s to stop"
    assert f"stopped by {signal.Signals(signum).name}" in err
    assert gone_within(family, 10) == set()
    assert debris(project) == []
    assert not (project / "outputs" / ".k.lock.json").exists()


@pytest.mark.slow
def test_after_a_sigkill_the_workers_exit_and_the_next_run_equals_a_clean_one(project):
    """Default sibling: test_reliability_lock.py's
    ``test_sigkilled_run_then_a_normal_run_leaves_no_temporary_folder`` (the debris after a
    SIGKILL); the orphaned pool workers' exit is this test's own."""
    toml = pooled(project, 120.0)
    run = start(project, "run", str(toml), seconds=0.0)
    workers = wait_for_workers(project, run)
    family = children(run.pid) | workers
    run.send_signal(signal.SIGKILL)
    run.communicate(timeout=60)
    assert gone_within(family, 10) == set(), "orphaned workers still run"
    pooled(project, 0.5)
    again = call(project, "run", str(toml))
    assert again.returncode == 0, again.stderr
    assert f"removed {project / 'outputs' / 'k' / f'.pooled.tmp-{run.pid}'}" in again.stderr
    assert debris(project) == []
    clean = call(project, "run", str(toml), "--out", str(project / "clean"))
    assert clean.returncode == 0, clean.stderr
    assert outputs(project / "outputs" / "k") == outputs(project / "clean" / "k")


def test_sigterm_stops_serve_and_its_solver_thread(tmp_path):
    """The page's solver runs in a thread of ``metasheet serve``: a SIGTERM ends the process
    at once, whatever that thread is doing."""
    import os
    import socket
    import subprocess
    import sys

    from serve_outputs import write_outputs

    toml, out = write_outputs(tmp_path)
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(Path(__file__).resolve().parents[1]),
                                                       os.environ.get("PYTHONPATH", "")]))
    proc = subprocess.Popen([sys.executable, "-m", "metasheet.cli", "serve", str(toml), "--out", str(out),
                             "--port", str(port)], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        lines = []
        t0 = time.monotonic()
        while not any("serving the robot at" in ln for ln in lines):
            assert proc.poll() is None and time.monotonic() - t0 < 180, "".join(lines) + proc.stderr.read()
            lines.append(proc.stderr.readline())
        t0 = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=30)
        assert proc.returncode == 128 + signal.SIGTERM
        assert time.monotonic() - t0 < 10
        assert "stopped by SIGTERM" in proc.stderr.read()
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.communicate()


def signal_mask(field: str) -> int:
    """This process's signal mask ``field`` (``SigIgn``, ``SigCgt``: ignored, caught; Linux /proc)."""
    return int(Path("/proc/self/status").read_text().split(f"{field}:")[1].split()[0], 16)


def test_meshing_in_a_stage_thread_keeps_every_signals_action():
    """gmsh's initialize set SIGTERM, SIGHUP and SIGPIPE back to their default actions: once a
    stage had meshed, a SIGTERM or SIGHUP killed the run outright (its temporary folders and lock
    left behind), and killing the pool on Ctrl-C killed the run itself (exit 141, its feeder
    thread writing to a dead worker)."""
    import threading

    from metasheet.sheet.geometry import SheetParams, tripod_sheet

    bit = {s: 1 << (s - 1) for s in (signal.SIGPIPE, signal.SIGTERM, signal.SIGHUP)}
    previous = {s: signal.signal(s, lambda *a: None) for s in (signal.SIGTERM, signal.SIGHUP)}
    try:
        assert signal_mask("SigIgn") & bit[signal.SIGPIPE]  # Python's own start-up choice
        assert signal_mask("SigCgt") & bit[signal.SIGTERM] and signal_mask("SigCgt") & bit[signal.SIGHUP]
        t = threading.Thread(target=tripod_sheet, args=(SheetParams(mesh_size=15.0),))
        t.start()
        t.join()
        assert signal_mask("SigIgn") & bit[signal.SIGPIPE]
        assert signal_mask("SigCgt") & bit[signal.SIGTERM], "SIGTERM no longer caught after gmsh"
        assert signal_mask("SigCgt") & bit[signal.SIGHUP], "SIGHUP no longer caught after gmsh"
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
