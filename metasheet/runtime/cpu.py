"""The same bytes on every x86-64 CPU: numpy, OpenBLAS and MKL pinned to one code path.

Each library picks its kernels by the CPU it finds, and kernels of other vector widths round
differently. Measured on the quick pipeline (one BLAS thread, an AMD EPYC with AVX-512):
OpenBLAS's SkylakeX kernels against its Haswell ones changed 10 of 26 files (the Jacobian,
the constants, the print map); with those pinned, numpy's AVX-512 loops against its AVX2
ones still changed the sheet's fibre field (``orient/sheet.vtu``) and the Jacobian.

So :func:`pin_code_paths`, run when metasheet is imported before numpy (``metasheet run``
and every pool worker are), asks each library for the code path that every x86-64 CPU
since 2013 has (AVX2 with FMA): ``OPENBLAS_CORETYPE=Haswell``, numpy's AVX-512 targets off
(``NPY_DISABLE_CPU_FEATURES``), ``MKL_CBWR=AVX2`` (Intel's reproducibility switch; it
changed nothing on the AMD machine measured). A value already set, by the user or the
platform, is kept. On a CPU without AVX2 and FMA nothing is pinned (the Haswell kernels do
not run there). A process that loaded numpy before metasheet keeps its own code path: the
decision is recorded in ``METASHEET_CODE_PATHS`` so that the workers it starts follow it,
and a pool's results stay those of the serial run.

:func:`code_paths` says what this process uses; every stage's manifest records it.
"""

from __future__ import annotations

import os
import sys
from importlib import metadata

#: Recorded decision, inherited by child processes: "pinned" or "native".
DECISION = "METASHEET_CODE_PATHS"

#: numpy's dispatch targets wider than AVX2 (numpy >= 2.4 names them by x86-64 levels).
_NUMPY_AVX512 = {"new": "X86_V4 AVX512_ICL AVX512_SPR",
                 "old": "AVX512F AVX512CD AVX512_KNL AVX512_KNM AVX512_SKX AVX512_CLX AVX512_CNL AVX512_ICL AVX512_SPR"}


def _numpy_avx512_targets() -> str:
    try:
        major, minor = (int(p) for p in metadata.version("numpy").split(".")[:2])
    except (metadata.PackageNotFoundError, ValueError):
        return _NUMPY_AVX512["new"]
    return _NUMPY_AVX512["new" if (major, minor) >= (2, 4) else "old"]


def pins() -> dict[str, str]:
    """The environment variables that select the AVX2 code path of each library."""
    return {"OPENBLAS_CORETYPE": "Haswell", "NPY_DISABLE_CPU_FEATURES": _numpy_avx512_targets(),
            "MKL_CBWR": "AVX2"}


def has_avx2_fma(cpuinfo: str | None = None) -> bool:
    """True when this CPU (Linux ``/proc/cpuinfo`` flags, or ``cpuinfo`` given) has AVX2 and FMA."""
    if cpuinfo is None:
        try:
            with open("/proc/cpuinfo") as fh:
                cpuinfo = fh.read(1 << 16)
        except OSError:
            return False
    for line in cpuinfo.splitlines():
        if line.startswith("flags"):
            flags = set(line.split(":", 1)[1].split())
            return {"avx2", "fma"} <= flags
    return False


def pin_code_paths(environ=None, *, numpy_loaded: bool | None = None, cpuinfo: str | None = None) -> str:
    """Set :func:`pins` in ``environ`` (default ``os.environ``) unless numpy is loaded already,
    the CPU lacks AVX2 / FMA or a parent process decided otherwise; returns the decision,
    "pinned" or "native", also recorded in ``environ[DECISION]``. Values already set are kept."""
    environ = os.environ if environ is None else environ
    decided = environ.get(DECISION)
    if decided not in ("pinned", "native"):
        loaded = "numpy" in sys.modules if numpy_loaded is None else numpy_loaded
        decided = "pinned" if not loaded and has_avx2_fma(cpuinfo) else "native"
        environ[DECISION] = decided
    if decided == "pinned":
        for var, value in pins().items():
            environ.setdefault(var, value)
    return decided


def code_paths() -> dict:
    """What this process computes with: the decision, the pins in force, numpy's enabled
    dispatch targets and each BLAS library's kernel family (threadpoolctl)."""
    from threadpoolctl import threadpool_info

    try:
        from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__
    except ImportError:  # numpy < 2
        from numpy.core._multiarray_umath import __cpu_dispatch__, __cpu_features__
    return {
        "decision": os.environ.get(DECISION, "native"),
        "environment": {var: os.environ[var] for var in pins() if var in os.environ},
        "numpy_dispatch": [t for t in __cpu_dispatch__ if __cpu_features__.get(t)],
        "blas": sorted({f"{i.get('internal_api')} {i.get('version')} {i.get('architecture', '')}".strip()
                        for i in threadpool_info() if i.get("user_api") == "blas"}),
    }
