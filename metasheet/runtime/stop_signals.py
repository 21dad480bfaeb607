"""Stop signals: SIGINT (Ctrl-C), SIGTERM and SIGHUP stop a command as Ctrl-C does.

While :func:`stop_on_signals` holds, the first of them raises :class:`Stopped` in the main
thread: the command unwinds (a run kills its workers, removes its temporary folders and
releases its lock, :mod:`metasheet.pipeline.runner`); later ones are ignored so the
unwinding finishes. :func:`exit_now` then ends the process with 128 + the signal, without
waiting for threads still computing (a stage beside the interrupted one, a server's solver).
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator

#: The signals that stop a command (those this platform has).
STOP_SIGNALS = tuple(getattr(signal, n) for n in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, n))


class Stopped(SystemExit):
    """Raised in the main thread by a stop signal; its code is 128 + the signal."""


@contextlib.contextmanager
def stop_on_signals() -> Iterator[None]:
    """Stop signals raise :class:`Stopped` for the block (in the main thread; elsewhere
    nothing changes: only it may set handlers); the previous handlers come back after."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    first: list[int] = []

    def stop(signum, frame):
        if first:  # the first one is unwinding: let it finish
            return
        first.append(signum)
        raise Stopped(128 + signum)

    previous = {s: signal.signal(s, stop) for s in STOP_SIGNALS}
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


def exit_now(code: int, say: Callable[[str], None]) -> None:
    """``say`` which signal stopped the command, flush, and end the process with ``code``."""
    say(f"stopped by {signal.Signals(code - 128).name}")
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    os._exit(code)
