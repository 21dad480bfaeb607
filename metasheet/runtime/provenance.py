"""Which code made a result: a digest of metasheet's own Python sources.

Stage cache keys (:func:`metasheet.pipeline.manifest.cache_key`) and work-unit keys
(:func:`metasheet.studies.resume.unit_key`) both hash it, so an edited stage reruns without
``--force`` and a kept unit is reused by the same code only. The digest is coarse on purpose:
any edit anywhere in the package invalidates every cached result, because a stage's result
depends on code far below it (kernels, solvers) that no per-stage list would keep complete.
"""

from __future__ import annotations

import functools
import hashlib
from pathlib import Path


#: the metasheet package's folder (this module lives in ``metasheet/runtime/``)
PACKAGE = Path(__file__).resolve().parents[1]


def source_files() -> list[Path]:
    """Every ``.py`` file of the metasheet package, sorted."""
    return sorted(PACKAGE.rglob("*.py"))


@functools.cache
def code_digest() -> str:
    """sha256 (hex) of every ``.py`` file of the package (:func:`source_files`), by path and
    bytes, once per process."""
    h = hashlib.sha256()
    for f in source_files():
        h.update(f.relative_to(PACKAGE).as_posix().encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()
