"""A run whose process dies under Python (a native crash, the out-of-memory killer) still ends
in an ``error:`` sentence, and leaves no temporary folder and no lock side file
(:mod:`metasheet.supervise`; issue 60, item 7: a segmentation fault in VTK under ``ulimit -v``
printed nothing and left the lock's json).

The child in these tests is a small script standing in for ``python -m metasheet run``: it
tells its supervisor the output folder, writes what a run writes (a stage's temporary folder,
a swap cut between its renames, the lock's side file), then dies the way a native crash does.
"""

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from metasheet import supervise
from metasheet.pipeline.lock import pid_alive

ROOT = Path(__file__).resolve().parents[1]

CHILD = textwrap.dedent('''
    import json, os, signal, sys, time
    from pathlib import Path
    from metasheet import supervise
    out, how = Path(sys.argv[1]), sys.argv[2]
    supervise.become_child()
    supervise.tell(out, "q")
    base, pid = out / "q", os.getpid()
    (base / f".robot.tmp-{pid}").mkdir(parents=True)
    (base / f".robot.tmp-{pid}" / "half.vtu").write_text("half-written")
    (base / f".orient.old-{pid}").mkdir()          # a swap cut between its renames
    (base / f".orient.old-{pid}" / "sheets.msh").write_text("the previous outputs")
    (out / ".q.lock.json").write_text(json.dumps({"pid": pid, "host": "h"}))
    (out / "ready").write_text(str(pid))
    if how == "segv":
        os.kill(pid, signal.SIGSEGV)
    elif how.startswith("exit"):
        os._exit(int(how[4:]))                       # a native exit: Python's atexit does not run
    elif how == "said":
        sys.exit(2)
    else:                                            # wait to be stopped
        time.sleep(60)
''')


def run_supervised(tmp_path: Path, how: str) -> subprocess.CompletedProcess:
    """``supervise`` in its own process (it handles signals) over the stand-in child."""
    (tmp_path / "child.py").write_text(CHILD)
    code = (f"import sys; from metasheet import supervise; "
            f"sys.exit(supervise.supervise([{str(tmp_path / 'out')!r}, {how!r}], "
            f"[sys.executable, {str(tmp_path / 'child.py')!r}]))")
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          env=dict(os.environ, PYTHONPATH=str(ROOT)))


def left(out: Path) -> list[str]:
    return sorted(str(p.relative_to(out)) for p in out.rglob("*"))


def test_a_child_killed_by_a_native_crash_ends_in_a_sentence_and_leaves_nothing(tmp_path):
    r = run_supervised(tmp_path, "segv")
    pid = (tmp_path / "out" / "ready").read_text()
    assert r.returncode == 128 + signal.SIGSEGV
    err = r.stderr.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: "), r.stderr
    assert f"pid {pid}" in err[0] and "SIGSEGV" in err[0] and "memory" in err[0]
    assert "stage(s) under way: robot" in err[0] and "run the same command again" in err[0]
    # the temporary folder and the lock's side file are gone; the cut swap's outputs are back
    assert left(tmp_path / "out") == ["q", "q/orient", "q/orient/sheets.msh", "ready"]
    assert (tmp_path / "out" / "q" / "orient" / "sheets.msh").read_text() == "the previous outputs"


@pytest.mark.parametrize(("code", "words"), [(34, "exit code 34 without a message"),
                                              (1, "exit code 1 without a message"),
                                              (2, "exit code 2 without a message: a native library's fatal")])
def test_an_exit_the_interpreter_did_not_make_is_named(tmp_path, code, words):
    """A native ``exit`` (here ``os._exit``, which skips Python's ``atexit`` as C's ``exit`` does)
    is named whatever its code: MKL's fatal error exits with 2, a code metasheet uses too."""
    r = run_supervised(tmp_path, f"exit{code}")
    assert r.returncode == code
    assert r.stderr.startswith("error: ") and words in r.stderr
    assert left(tmp_path / "out") == ["q", "q/orient", "q/orient/sheets.msh", "ready"]


def test_a_child_that_said_why_is_not_talked_over(tmp_path):
    r = run_supervised(tmp_path, "said")  # sys.exit(2) after its own message: Python's exit
    assert r.returncode == 2 and r.stderr == ""
    assert left(tmp_path / "out") == ["q", "q/orient", "q/orient/sheets.msh", "ready"]


def test_the_parent_forwards_sigterm_and_a_sigkilled_parent_takes_its_child_along(tmp_path):
    (tmp_path / "child.py").write_text(CHILD)
    code = (f"import sys; from metasheet import supervise; "
            f"sys.exit(supervise.supervise([{str(tmp_path / 'out')!r}, 'wait'], "
            f"[sys.executable, {str(tmp_path / 'child.py')!r}]))")
    for signum in (signal.SIGTERM, signal.SIGKILL):
        (tmp_path / "out" / "ready").unlink(missing_ok=True)
        parent = subprocess.Popen([sys.executable, "-c", code], stderr=subprocess.PIPE, text=True,
                                  env=dict(os.environ, PYTHONPATH=str(ROOT)))
        t0 = time.monotonic()
        while not (tmp_path / "out" / "ready").exists():
            assert parent.poll() is None and time.monotonic() - t0 < 60, parent.communicate()
            time.sleep(0.05)
        child = int((tmp_path / "out" / "ready").read_text())
        parent.send_signal(signum)
        parent.communicate(timeout=60)
        t0 = time.monotonic()
        while pid_alive(child) and time.monotonic() - t0 < 10:
            time.sleep(0.05)
        assert not pid_alive(child), f"the child outlived its parent's {signum.name}"
        if signum == signal.SIGTERM:  # the stand-in does not unwind: it dies of the forwarded signal
            assert parent.returncode == 128 + signal.SIGTERM


@pytest.mark.parametrize(("args", "expected"), [
    (["run", "p.toml"], True), (["--debug", "run", "p.toml"], True), (["validate", "p.toml"], False),
    (["serve", "p.toml"], False), ([], False)])
def test_only_run_is_supervised(args, expected, monkeypatch):
    monkeypatch.delenv(supervise.ENV, raising=False)
    assert supervise.wanted(args) is (expected and os.name == "posix")
    # a supervised child is not supervised again; a stale variable (another parent) is ignored
    monkeypatch.setenv(supervise.ENV, f"{os.getppid()}:/tmp/note.json")
    assert supervise.wanted(args) is False
    monkeypatch.setenv(supervise.ENV, f"{os.getpid()}:/tmp/note.json")
    assert supervise.wanted(args) is (expected and os.name == "posix")


def test_tell_writes_the_note_only_for_a_live_parent(tmp_path, monkeypatch):
    note = tmp_path / "note.json"
    monkeypatch.setenv(supervise.ENV, f"{os.getppid()}:{note}")
    supervise.tell(tmp_path / "out", "q")
    assert json.loads(note.read_text()) == {"out_root": str((tmp_path / "out").resolve()), "name": "q"}
    note.unlink()
    monkeypatch.setenv(supervise.ENV, f"{os.getpid()}:{note}")
    supervise.tell(tmp_path / "out", "q")
    assert not note.exists()


def test_the_next_run_puts_back_a_swap_a_dead_process_cut(tmp_path):
    from metasheet.pipeline.debris import remove_debris

    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True).stdout.strip()
    base = tmp_path / "q"
    (base / f".orient.old-{dead}").mkdir(parents=True)
    (base / f".orient.old-{dead}" / "sheets.msh").write_text("the previous outputs")
    (base / f".robot.tmp-{dead}").mkdir()
    (base / "material").mkdir()
    (base / f".material.old-{dead}").mkdir()  # the swap finished: the previous outputs are dropped
    notes = []
    removed = remove_debris(base, lambda stage, text: notes.append(text))
    assert sorted(p.name for p in removed) == [f".material.old-{dead}", f".robot.tmp-{dead}"]
    assert sorted(p.name for p in base.iterdir()) == ["material", "orient"]
    assert (base / "orient" / "sheets.msh").read_text() == "the previous outputs"
    assert any(n.startswith(f"put back {base / 'orient'}") for n in notes)


def test_a_variable_naming_another_parent_changes_nothing(tmp_path):
    """A stale ``METASHEET_SUPERVISOR`` (inherited from elsewhere) neither stops the process nor
    marks a note: ``become_child`` acts only under the parent the variable names."""
    note = tmp_path / "note.json"
    code = "from metasheet import supervise; supervise.become_child(); print('alive')"
    env = dict(os.environ, PYTHONPATH=str(ROOT), **{supervise.ENV: f"1:{note}"})  # pid 1 is not the parent
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=60)
    assert r.returncode == 0 and r.stdout.strip() == "alive", r.stderr
    assert not note.exists()
