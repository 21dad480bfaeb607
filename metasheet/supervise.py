"""``metasheet run`` watched from a parent process: a native crash still ends in a sentence.

Python unwinds a stop signal, an exception or ``MemoryError`` (:mod:`.stop_signals`,
:mod:`.pipeline.runner`), but a native library can end the process under it: a segmentation
fault in VTK's rendering under ``ulimit -v``, a library's fatal-error ``exit``, the kernel's
out-of-memory killer (SIGKILL). Then nothing prints an ``error:`` line and the run's temporary
folders and lock side file stay behind.

So the ``metasheet run`` command (console script or ``python -m metasheet``, POSIX) runs in a
child process that this one waits for. The parent imports nothing heavy, forwards the stop
signals (SIGINT, SIGTERM, SIGHUP: the child unwinds as it always did) and exits with the child's
code. The child dies with it (``PR_SET_PDEATHSIG``: a SIGKILLed parent gives the child a
SIGTERM, which it unwinds). When the child ends without having said why (killed by a signal it
did not handle, or an exit the interpreter did not make: a native library's ``exit``, whatever its
code, e.g. MKL's fatal error), the parent says so in a sentence naming
the signal or code and the stages under way, and removes what the child left: its temporary
folders (putting back previous outputs cut mid-swap, :func:`~.pipeline.debris.remove_debris_of`)
and the lock's side file when it names the child. The child tells the parent where its output
folder is (:func:`tell`) through the file named in :data:`ENV`, and that it ended saying why
(:func:`said`: Python's ``atexit``, which a native ``exit`` skips, and the stop-signal exit).
"""

from __future__ import annotations

import atexit
import contextlib
import json
import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

from .runtime.stop_signals import STOP_SIGNALS

#: ``"<parent pid>:<note file>"`` in a supervised child's environment.
ENV = "METASHEET_SUPERVISOR"


#: What a signal that Python does not handle usually means here.
CAUSES = {
    "SIGKILL": "killed from outside; the kernel's out-of-memory killer does this when memory runs out "
               "(see `dmesg`)",
    "SIGSEGV": "a native library crashed; under a memory limit (`ulimit -v`) this is usually memory "
               "running out",
    "SIGBUS": "a native library crashed (a memory-mapped file or the disk failing)",
    "SIGABRT": "a native library aborted (often memory running out)",
}


def wanted(args: list[str]) -> bool:
    """Whether the command line ``args`` (without the program) is supervised: a ``run`` on
    POSIX, in a process that is not already a supervised child."""
    if os.name != "posix" or _parent_note() is not None:
        return False
    words = [a for a in args if not a.startswith("-")]
    return bool(words) and words[0] == "run"


def _parent_note() -> Path | None:
    """The note file when this process is the supervised child of a live parent, else None."""
    value = os.environ.get(ENV, "")
    pid, _, note = value.partition(":")
    if not note or not pid.isdigit() or int(pid) != os.getppid():
        return None
    return Path(note)


def become_child() -> None:
    """In a supervised child: die with the parent (SIGTERM, which :mod:`.stop_signals` unwinds),
    and mark the note :func:`said` when the interpreter ends the process. Nothing in any other
    process (a variable inherited from elsewhere names another parent)."""
    if _parent_note() is None:
        return
    atexit.register(said)
    if not sys.platform.startswith("linux"):
        return
    with contextlib.suppress(OSError, AttributeError):
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGTERM))  # PR_SET_PDEATHSIG
    if _parent_note() is None:  # the parent died before the prctl took effect
        os.kill(os.getpid(), signal.SIGTERM)


def tell(out_root: Path, name: str) -> None:
    """Tell a supervising parent (if any) the run's output root and pipeline name."""
    _write_note(out_root=str(Path(out_root).resolve()), name=name)


def said() -> None:
    """Tell a supervising parent (if any) that this process ends having said why (its exit is
    Python's: a result, an ``error:`` line, a traceback, "stopped by")."""
    _write_note(said=True)


def _write_note(**fields) -> None:
    note = _parent_note()
    if note is None:
        return
    with contextlib.suppress(OSError, ValueError):
        known = json.loads(note.read_text() or "{}") if note.is_file() else {}
        tmp = note.with_suffix(".tmp")
        tmp.write_text(json.dumps({**known, **fields}))
        os.replace(tmp, note)


def supervise(args: list[str], command: list[str] | None = None) -> int:
    """Run ``python -m metasheet ARGS`` (or ``command``) as a child, forward stop signals to
    it, and return the exit code to end with (module docstring)."""
    fd, note = tempfile.mkstemp(prefix="metasheet-run-", suffix=".json")
    os.close(fd)
    note_path = Path(note)
    try:
        env = dict(os.environ, **{ENV: f"{os.getpid()}:{note}"})
        child = subprocess.Popen([*(command or [sys.executable, "-m", "metasheet"]), *args], env=env)

        def forward(signum, frame):
            with contextlib.suppress(ProcessLookupError):
                child.send_signal(signum)

        for s in STOP_SIGNALS:
            signal.signal(s, forward)
        code = child.wait()
        for s in STOP_SIGNALS:
            signal.signal(s, signal.SIG_IGN)  # the clean-up below is short: let it finish
        return _after(code, child.pid, note_path)
    finally:
        note_path.unlink(missing_ok=True)
        note_path.with_suffix(".tmp").unlink(missing_ok=True)


def _after(code: int, pid: int, note: Path) -> int:
    """Clean what child ``pid`` left and say why it ended when it did not; the code to exit with."""
    told = _read_note(note)
    left = _clean(told, pid)
    if told.get("said") or code == 0:
        return code
    if code < 0:
        name = signal.Signals(-code).name
        cause = ("stopped before it could unwind" if -code in STOP_SIGNALS
                 else CAUSES.get(name, "a native library ended it"))
        why = f"the run's process (pid {pid}) died of {name}: {cause}"
        code = 128 - code
    else:
        why = (f"the run's process (pid {pid}) ended with exit code {code} without a message: a native "
               "library's fatal error (MKL's, for one, exits with 1 to 3)")
    if left["stages"]:
        why += f"; stage(s) under way: {', '.join(left['stages'])}"
    if left["removed"]:
        why += f"; removed what it left: {', '.join(left['removed'])}"
    why += ". The finished stages are kept: run the same command again to resume."
    print(f"error: {why}", file=sys.stderr, flush=True)
    return code


def _read_note(note: Path) -> dict:
    try:
        told = json.loads(note.read_text() or "{}")
    except (OSError, ValueError):
        return {}
    return told if isinstance(told, dict) else {}


def _clean(told: dict, pid: int) -> dict:
    """Remove child ``pid``'s temporary folders and lock side file under the output folder it
    told (:func:`tell`); the stages it had under way and the names removed."""
    try:
        out_root, name = Path(told["out_root"]), str(told["name"])
    except (KeyError, TypeError):
        return {"stages": [], "removed": []}
    from .pipeline.debris import DEBRIS, remove_debris_of
    from .pipeline.lock import lock_paths, read_holder

    base = out_root / name
    stages = sorted({m["stage"] for p in (base.iterdir() if base.is_dir() else ())
                     if (m := DEBRIS.match(p.name)) and m["kind"] == "tmp" and int(m["pid"]) == pid})
    removed = [p.name for p in remove_debris_of(base, pid)]
    info = lock_paths(out_root, name)[1]
    holder = read_holder(info)
    if holder is not None and holder["pid"] == pid:
        with contextlib.suppress(OSError):
            info.unlink()
            removed.append(info.name)
    for ticket in (out_root / f".{name}.queue").glob(f"*-{pid}"):
        with contextlib.suppress(OSError):
            ticket.unlink()
    return {"stages": stages, "removed": removed}
