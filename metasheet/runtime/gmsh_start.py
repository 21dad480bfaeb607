"""Start gmsh without changing how this process handles signals.

``gmsh.initialize`` (its C library) sets SIGTERM, SIGHUP and SIGPIPE back to their default
actions (measured: ``/proc/PID/status`` SigCgt 0x4003 -> 0x0002 and SIGPIPE out of SigIgn).
After any meshing, a SIGTERM or SIGHUP then killed a run outright, leaving its temporary
folders and its lock (the handlers of :mod:`metasheet.runtime.stop_signals` never ran), and a write to
a pipe whose reader had died killed it with SIGPIPE (exit 141). So every signal's action
(``sigaction``) is read before gmsh starts and put back after. ``signal.signal`` cannot do it:
it works in the main thread only, and stages running side by side mesh in theirs.
"""

from __future__ import annotations

import contextlib
import ctypes
import signal
from collections.abc import Iterator

#: Bytes of a ``struct sigaction`` on the platforms we run on (152 on x86-64 and aarch64 Linux,
#: smaller elsewhere): a buffer this large holds it whole, read and written back opaquely.
_SIGACTION_BYTES = 512


def initialize(**options) -> bool:
    """``gmsh.initialize(**options)`` unless gmsh runs already; True when this call started it.
    Every signal's handler, mask and flags stay what they were."""
    import gmsh

    if gmsh.isInitialized():
        return False
    with signal_actions_kept():
        gmsh.initialize(**options)
    return True


@contextlib.contextmanager
def signal_actions_kept() -> Iterator[None]:
    """The action of every catchable signal, read before the block and restored after it,
    from any thread (POSIX ``sigaction``; on a platform without it, nothing is done)."""
    libc = _libc()
    if libc is None:
        yield
        return
    saved = {}
    for s in _catchable():
        buf = ctypes.create_string_buffer(_SIGACTION_BYTES)
        if libc.sigaction(int(s), None, buf) == 0:
            saved[s] = buf
    try:
        yield
    finally:
        for s, buf in saved.items():
            libc.sigaction(int(s), buf, None)


def _catchable() -> list[int]:
    return [s for s in signal.valid_signals() if 0 < s < 32 and s not in (signal.SIGKILL, signal.SIGSTOP)]


def _libc():
    if not hasattr(signal, "SIGKILL"):  # Windows: no POSIX signals
        return None
    libc = ctypes.CDLL(None, use_errno=True)
    if not hasattr(libc, "sigaction"):
        return None
    libc.sigaction.argtypes = [ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p]
    libc.sigaction.restype = ctypes.c_int
    return libc
