"""A damaged numba cache file is removed and its kernel compiled again, with a warning.

metasheet's kernels are compiled by numba with ``cache=True``: the machine code lands in
``__pycache__/*.nbi`` (index) and ``*.nbc`` (data) beside the module, or under
``NUMBA_CACHE_DIR``. numba unpickles them without a guard: one truncated file (a full disk, a
killed write, a bad copy) made every later call fail with a raw ``UnpicklingError`` and never
repaired itself. :func:`install` wraps numba's two loaders so that a file that does not load
is logged, removed and treated as absent: the next call compiles the kernel and writes it anew.

The wrap is put in place when ``numba.core.caching`` is imported (a finder on
``sys.meta_path``), so a command that never compiles a kernel does not pay numba's import.
"""

from __future__ import annotations

import importlib.abc
import logging
import sys
from pathlib import Path

log = logging.getLogger(__name__)

_MODULE = "numba.core.caching"


def install() -> None:
    """Guard numba's cache loaders now if numba's caching is imported, else when it is."""
    if _MODULE in sys.modules:
        guard(sys.modules[_MODULE])
    elif not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.insert(0, _Finder())


def guard(caching) -> None:
    """Wrap ``caching.IndexDataCacheFile``'s ``_load_index`` and ``_load_data`` (idempotent)."""
    cls = getattr(caching, "IndexDataCacheFile", None)
    if cls is None or getattr(cls, "_metasheet_guarded", False):
        return
    load_index, load_data = cls._load_index, cls._load_data

    def _load_index(self):
        try:
            return load_index(self)
        except Exception as exc:  # noqa: BLE001 - any unpickling failure: the file is unusable
            _drop(Path(self._index_path), exc)
            return {}

    def _load_data(self, name):
        try:
            return load_data(self, name)
        except OSError:
            raise  # numba's own case: a data file removed under its index
        except Exception as exc:  # noqa: BLE001
            _drop(Path(self._data_path(name)), exc)
            return None  # numba's load() returns it: no cached kernel, compile

    cls._load_index, cls._load_data = _load_index, _load_data
    cls._metasheet_guarded = True


def _drop(path: Path, exc: Exception) -> None:
    log.warning("numba's cache file %s is damaged (%s: %s): removed; the kernel is compiled again",
                path, type(exc).__name__, exc)
    try:
        path.unlink(missing_ok=True)
    except OSError as err:  # a read-only cache: numba compiles in memory every time
        log.warning("could not remove %s (%s): the kernel is compiled on every run", path, err)


class _Finder(importlib.abc.MetaPathFinder):
    """Guards ``numba.core.caching`` right after Python executes it."""

    def find_spec(self, name, path, target=None):
        if name != _MODULE:
            return None
        sys.meta_path.remove(self)  # find the real spec, and never be asked again
        from importlib.util import find_spec

        spec = find_spec(name)
        if spec is None or spec.loader is None:
            return spec
        execute = spec.loader.exec_module

        def exec_module(module):
            execute(module)
            guard(module)

        spec.loader.exec_module = exec_module
        return spec
