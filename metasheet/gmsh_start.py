"""Start gmsh without changing how this process treats a broken pipe.

``gmsh.initialize`` sets SIGPIPE back to its default action (measured: the bit leaves the
process's ignored-signal mask), which Python ignores so that a write to a closed pipe is an
``EPIPE`` error. After any meshing, a write to a pipe whose reader had died then killed the
whole process with SIGPIPE (exit 141): a pool's feeder thread writing to the workers a run
had just killed on Ctrl-C did so, before the run could remove its temporary folders.
"""

from __future__ import annotations

import ctypes
import signal


def initialize(**options) -> bool:
    """``gmsh.initialize(**options)`` unless gmsh runs already; True when this call started it.
    SIGPIPE stays ignored."""
    import gmsh

    if gmsh.isInitialized():
        return False
    gmsh.initialize(**options)
    ignore_sigpipe()
    return True


def ignore_sigpipe() -> None:
    """Ignore SIGPIPE process-wide, from any thread (``signal.signal`` works in the main thread
    only: stages running side by side mesh in theirs)."""
    if not hasattr(signal, "SIGPIPE"):  # Windows has none
        return
    libc = ctypes.CDLL(None, use_errno=True)
    libc.signal.argtypes = [ctypes.c_int, ctypes.c_void_p]
    libc.signal.restype = ctypes.c_void_p
    libc.signal(int(signal.SIGPIPE), ctypes.c_void_p(1))  # SIG_IGN
