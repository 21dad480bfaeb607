"""Freed memory kept for reuse in a pipeline run's processes (glibc's malloc), not handed back.

glibc serves an allocation above its mmap threshold (at most 32 MiB) with fresh pages from the
kernel and unmaps them on free, so the next one of that size faults every page in again,
zero-filled. The robot's sparse factorisations do that at each fresh linearisation (SuperLU
grows its L and U storage by reallocation): on the paper pipeline's reduce stage 83 % of its
5.6 million page faults were in SuperLU's column copies, 25 of its 317 CPU s in the kernel.
:func:`keep_freed_memory` turns mmap off for the heap and raises the trim threshold, so freed
blocks are reused: the same stage then took 1.1 million faults and 12 s of system time, the
same bytes (docs/performance.md, "Session 27"). The cost is resident memory: a process keeps
up to :data:`TRIM_BYTES` of freed heap (the stage's largest process: 1.96 GB instead of 1.54).

Set for the run's process (``mallopt`` through ctypes) and, through the environment, for the
processes it starts (glibc reads ``MALLOC_*`` when a process starts). Elsewhere (macOS, musl)
nothing changes. Allocation changes no number: the kernels' results do not depend on where
their arrays lie.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os

#: Freed heap a process keeps at its top before giving it back [bytes].
TRIM_BYTES = 1 << 30
#: Extra heap asked for at each growth [bytes] (fewer brk calls).
TOP_PAD_BYTES = 64 << 20

# mallopt's parameters (malloc.h)
_M_TRIM_THRESHOLD, _M_TOP_PAD, _M_MMAP_MAX = -1, -2, -4


def environment() -> dict[str, str]:
    """The variables that give a process started with them the same settings."""
    return {"MALLOC_MMAP_MAX_": "0", "MALLOC_TRIM_THRESHOLD_": str(TRIM_BYTES),
            "MALLOC_TOP_PAD_": str(TOP_PAD_BYTES)}


def _glibc():
    if not hasattr(os, "confstr"):
        return None
    try:
        if not os.confstr("CS_GNU_LIBC_VERSION"):
            return None
    except (ValueError, OSError):
        return None
    name = ctypes.util.find_library("c")
    try:
        return ctypes.CDLL(name or "libc.so.6")
    except OSError:
        return None


def keep_freed_memory(environ=None) -> bool:
    """Apply the settings to this process and record them in ``environ`` (default
    ``os.environ``) for the processes it starts; values already there are kept (a user's own
    ``MALLOC_*``). Returns whether this process's malloc took them (glibc only)."""
    environ = os.environ if environ is None else environ
    if any(var in environ for var in environment()):
        return False  # the user's or a parent's choice: left as it is
    libc = _glibc()
    if libc is None:
        return False
    ok = all(libc.mallopt(param, value) == 1 for param, value in
             ((_M_MMAP_MAX, 0), (_M_TRIM_THRESHOLD, TRIM_BYTES), (_M_TOP_PAD, TOP_PAD_BYTES)))
    if ok:
        environ.update(environment())
    return ok
