"""Where MKL's runtime is, found once per process for pypardiso.

pypardiso looks for ``mkl_rt`` at every ``PyPardisoSolver()`` (one at its own import, one per
direct homogenisation). A pip-installed MKL is not on the loader's path, so each look globs
``sys.prefix`` recursively: 1.2 s at import and 0.7 s of CPU a solve in a full environment,
more than a test cell's solve. pypardiso reads ``PYPARDISO_MKL_RT`` first; :func:`tell_pypardiso`
sets it to the library pypardiso's own search would load.
"""

from __future__ import annotations

import ctypes
import glob
import os
import site
import sys
from ctypes.util import find_library

#: pypardiso's own override (pypardiso/pardiso_wrapper.py, ``PyPardisoSolver.__init__``).
ENV = "PYPARDISO_MKL_RT"


def _loads(path: str) -> bool:
    try:
        ctypes.CDLL(path)
        return True
    except OSError:
        return False


def mkl_rt_path() -> str | None:
    """The ``mkl_rt`` library pypardiso would load, or None when it needs no search (the
    environment names one, or the loader finds it) or there is none.

    pypardiso globs ``{prefix}/[Ll]ib*/**/*mkl_rt*`` and loads the shortest path that loads. The
    shortest paths are the ones directly under ``lib*/`` (where pip's ``mkl`` wheel puts it),
    so those are tried first; the recursive search runs only when there is none there."""
    if os.environ.get(ENV) or find_library("mkl_rt") or find_library("mkl_rt.1"):
        return None
    for base in (sys.prefix, site.USER_BASE or ""):
        if not base:
            continue
        for pattern, recursive in ((f"{base}/[Ll]ib*/*mkl_rt*", False),
                                   (f"{base}/[Ll]ib*/**/*mkl_rt*", True)):
            found = sorted(glob.glob(pattern, recursive=recursive), key=len)
            for path in found:
                if _loads(path):
                    return path
            if found:
                break  # pypardiso too stops at the first base with a match
    return None


def tell_pypardiso() -> None:
    """Set ``PYPARDISO_MKL_RT`` for this process (and its children) unless it is set."""
    path = mkl_rt_path()
    if path:
        os.environ[ENV] = path
