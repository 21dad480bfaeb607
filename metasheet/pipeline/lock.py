"""One run per output folder at a time, first come first served.

A run holds a lock (:func:`output_lock`, the ``filelock`` library: an OS lock the kernel drops
when its process dies) on ``<out>/.<pipeline>.lock`` for its whole duration, and writes who
holds it (pid, host, start, command) to ``<out>/.<pipeline>.lock.json``. A second run (or a
``clean``) waits, saying who it waits for, or with ``wait=False`` raises
:class:`~metasheet.errors.LockedError`. Waiters take their turn in the order they came: each
leaves a ticket ``<out>/.<pipeline>.queue/<time ns>-<pid>`` and tries the lock only when its
ticket is the oldest of a live process (before: whichever polled first after a release won,
so a later ``clean --all`` could overtake a waiting run). A lock or ticket left by a dead
process is free and taken over, with a note naming the dead pid.
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import sys
import time
from collections.abc import Callable, Iterator
from datetime import datetime, timezone
from pathlib import Path

from ..errors import LockedError, output_error
from . import manifest as mf

Reporter = Callable[[str, str], None]  # (stage, message)


def _quiet(stage: str, message: str) -> None:
    pass




def pid_alive(pid: int) -> bool:
    """True when process ``pid`` exists on this host and is not a zombie."""
    if pid <= 0:
        return False
    if os.name == "nt":  # pragma: no cover  (os.kill would terminate it)
        import ctypes

        handle = ctypes.windll.kernel32.OpenProcess(0x1000, False, pid)  # QUERY_LIMITED_INFORMATION
        if not handle:
            return False
        code = ctypes.c_ulong()
        ctypes.windll.kernel32.GetExitCodeProcess(handle, ctypes.byref(code))
        ctypes.windll.kernel32.CloseHandle(handle)
        return code.value == 259  # STILL_ACTIVE
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    except OSError:
        return False
    try:  # a killed child its parent has not reaped yet is gone for our purposes
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] not in ("Z", "X")
    except (OSError, IndexError):
        return True


# ---------------------------------------------------------------------------------- lock


def lock_paths(out_root: Path, name: str) -> tuple[Path, Path]:
    """The lock file of output folder ``out_root/name`` and the side file naming its holder."""
    return out_root / f".{name}.lock", out_root / f".{name}.lock.json"


def read_holder(info_file: Path) -> dict | None:
    """The holder recorded in a lock's side file (pid, host, started, command), or None."""
    try:
        data = json.loads(info_file.read_text())
        return data if isinstance(data, dict) and isinstance(data.get("pid"), int) else None
    except (OSError, ValueError):
        return None


def describe_holder(holder: dict | None) -> str:
    """``run pid 123 on host since 2026-01-01T10:00:00+00:00 (metasheet run ...)``."""
    if not holder:
        return "another run (no holder recorded)"
    text = f"run pid {holder['pid']}"
    if holder.get("host") and holder["host"] != socket.gethostname():
        text += f" on {holder['host']}"
    if holder.get("started"):
        text += f" since {holder['started']}"
    if holder.get("command"):
        text += f" ({holder['command']})"
    return text


@contextlib.contextmanager
def output_lock(out_root: Path, name: str, *, wait: bool = True, report: Reporter | None = None,
                poll: float = 0.2) -> Iterator[Path]:
    """Hold the lock of output folder ``out_root/name`` for the ``with`` block.

    ``wait``: when another run holds it, report who (pid, since when) and wait; else raise
    :class:`~metasheet.errors.LockedError` at once. A lock whose holder died is free (the
    kernel drops it) and is taken over with a note naming the dead pid. Yields the lock file.
    """
    from filelock import FileLock, Timeout

    report = report or _quiet
    out_root = Path(out_root)
    base = out_root / name
    lock_file, info_file = lock_paths(out_root, name)
    queue = out_root / f".{name}.queue"
    try:
        out_root.mkdir(parents=True, exist_ok=True)
        lock = FileLock(str(lock_file))
        if _first_waiter(queue) is not None or not _try(lock, Timeout):  # busy, or others wait first
            holder = read_holder(info_file)
            if not wait:
                raise LockedError(
                    f"{base}: in use by {describe_holder(holder)}; wait for it to finish "
                    "(run without --no-wait to wait) or stop it"
                ) from None
            report("lock", f"{base}: in use by {describe_holder(holder)}; waiting for it to finish")
            _acquire_in_turn(lock, Timeout, queue, poll)
            report("lock", f"{base}: free, going on")
        else:
            holder = read_holder(info_file)
            if holder and holder["pid"] != os.getpid() and not pid_alive(holder["pid"]):
                report("lock", f"{base}: taking over the lock left by {describe_holder(holder)}: "
                       "that process is gone")
    except OSError as exc:
        raise output_error(exc, str(base)) from exc
    try:
        try:
            mf.write_json_atomic(info_file, {
                "pid": os.getpid(), "host": socket.gethostname(),
                "started": datetime.now(timezone.utc).isoformat(timespec="seconds"),
                "command": " ".join([Path(sys.argv[0]).name, *sys.argv[1:]]) if sys.argv and sys.argv[0] else "",
            })
        except OSError as exc:
            raise output_error(exc, str(base)) from exc
        yield lock_file
    finally:
        with contextlib.suppress(OSError):
            if (read_holder(info_file) or {}).get("pid") == os.getpid():
                info_file.unlink()
        lock.release()



def _try(lock, timeout_error) -> bool:
    try:
        lock.acquire(timeout=0)
    except timeout_error:
        return False
    return True


def _first_waiter(queue: Path) -> str | None:
    """The oldest ticket in ``queue`` of a live process (those of dead ones are removed)."""
    try:
        tickets = sorted(p.name for p in queue.iterdir())
    except OSError:  # no queue: nobody waits
        return None
    for ticket in tickets:
        pid = ticket.rpartition("-")[2]
        if pid.isdigit() and (int(pid) == os.getpid() or pid_alive(int(pid))):
            return ticket
        with contextlib.suppress(OSError):
            (queue / ticket).unlink()  # a waiter that died (or a stray file)
    return None


def _acquire_in_turn(lock, timeout_error, queue: Path, poll: float) -> None:
    """Take ``lock`` once this process's ticket is the oldest live one in ``queue``."""
    ticket = f"{time.time_ns():020d}-{os.getpid()}"
    while True:  # another waiter may remove the empty queue between our mkdir and our ticket
        queue.mkdir(exist_ok=True)
        with contextlib.suppress(FileNotFoundError):
            (queue / ticket).touch()
            break
    try:
        while not (_first_waiter(queue) == ticket and _try(lock, timeout_error)):
            time.sleep(poll)
    finally:
        with contextlib.suppress(OSError):
            (queue / ticket).unlink()
        with contextlib.suppress(OSError):
            queue.rmdir()  # only when nobody else waits
