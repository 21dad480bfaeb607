"""Issue 15, items 2 and 3: one run per output folder at a time, no debris after a kill.

Real processes: a small driver script registers two test stages (``slow`` sleeps while its
temporary folder holds a partial file, ``after`` reads it) and calls ``metasheet.cli.main``.
"""

import os
import signal
import subprocess
import sys
import time
from types import SimpleNamespace

import pytest
from run_driver import call, make_project, outputs, pipeline, start, stderr_lines, stop_started, wait_started


@pytest.fixture
def project(tmp_path):
    yield make_project(tmp_path)
    stop_started(tmp_path)


@pytest.fixture(scope="module")
def contended(tmp_path_factory):
    """One scene for the two tests below (each driver process spends about four CPU seconds
    importing the stages; the scene needs four, not six): a single run for reference; then a
    first run holds the lock (its stage waits at a gate), a ``--no-wait`` run is refused, and a
    second run waits for the first; the gate opens and both finish."""
    project = make_project(tmp_path_factory.mktemp("contended"))
    try:
        toml = pipeline(project)
        single = call(project, "run", str(toml), "--out", str(project / "single"))
        assert single.returncode == 0, single.stderr
        first = start(project, "run", str(toml), "--out", str(project / "out"), seconds="gate")
        wait_started(project, first)
        refused = call(project, "run", str(toml), "--out", str(project / "out"), "--no-wait")
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
        yield SimpleNamespace(project=project, first=first, err1=err1, refused=refused, second=second,
                              lines=lines, out2=out2)
    finally:
        stop_started(project)


def test_second_run_waits_for_the_first_and_outputs_equal_a_single_run(contended):
    """Before: both ran every stage at once into the same folder, nothing said so."""
    c, project = contended, contended.project
    assert c.first.returncode == 0, c.err1
    assert c.second.returncode == 0, "".join(c.lines)
    assert any(f"in use by run pid {c.first.pid} since " in ln for ln in c.lines), c.lines
    assert c.out2.count("cached") == 2  # it found the first run's outputs fresh
    assert len(list((project / "started").iterdir())) == 2  # only the single run and the first ran ``slow``
    assert outputs(project / "out" / "p") == outputs(project / "single" / "p")


def test_no_wait_refuses_with_status_3_naming_the_holder(contended):
    """Before: no --no-wait (a usage error), and no lock to refuse on."""
    refused, first = contended.refused, contended.first
    assert refused.returncode == 3, refused.stderr
    lines = [ln for ln in refused.stderr.splitlines() if ln.startswith("error: ")]
    assert len(lines) == 1 and f"in use by run pid {first.pid} since " in lines[0], refused.stderr
    assert "--no-wait" in lines[0] and "Traceback" not in refused.stderr
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


@pytest.mark.slow
def test_clean_removes_debris_of_dead_processes_and_all_outputs(project):
    """Before: there was no ``metasheet clean``. Default siblings: test_reliability_confine.py's
    clean tests (the same ``clean`` code, in process) and test_cli.py's clean command."""
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


# the dask cluster's workers check the lock with the same code as the pool's: slow
@pytest.mark.parametrize("where", ["process pool", pytest.param("dask cluster", marks=pytest.mark.slow)])
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


@pytest.mark.slow
def test_waiters_take_their_turn_in_the_order_they_came(project):
    """Default sibling: :func:`test_second_run_waits_for_the_first_and_outputs_equal_a_single_run`.
    A run waiting for the lock goes before a ``clean --all`` that came after it. Before:
    whichever polled first after the release won, so the clean could remove the outputs the
    first run wrote and the waiting run then rebuilt them."""
    toml = pipeline(project)
    first = start(project, "run", str(toml), seconds="gate")
    wait_started(project, first)
    waiting = []
    for args in (("run", str(toml)), ("clean", str(toml), "--all")):
        proc = start(project, *args, seconds="gate")
        lines = stderr_lines(proc)
        t0 = time.monotonic()
        while not any("waiting for it to finish" in ln for ln in lines):
            assert proc.poll() is None and time.monotonic() - t0 < 120, lines
            time.sleep(0.05)
        waiting.append(proc)
    (project / "gate-open").write_text("")
    assert first.wait(timeout=300) == 0
    second, cleaner = waiting
    assert second.wait(timeout=300) == 0 and cleaner.wait(timeout=300) == 0
    assert "cached" in second.stdout.read()  # it ran after the first, before the clean
    assert not (project / "outputs" / "p").exists()  # the clean came last
    assert not (project / "outputs" / ".p.queue").exists()
