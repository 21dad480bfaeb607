"""metasheet: design soft robots made of 3D-printed anisotropic foam.

The Python API is at the top level (:mod:`metasheet.api`): ``metasheet.run(path)``,
``metasheet.load_pipeline``, ``metasheet.read_constants``, ``read_jacobian``, ``read_study``.
"""

from .runtime.cpu import pin_code_paths as _pin

# before numpy loads: the same kernels, so the same bytes, on every x86-64 CPU (metasheet.runtime.cpu)
_pin()

from .runtime.numba_cache import install as _guard_numba_cache  # noqa: E402

# a damaged compiled-kernel cache file is removed and compiled again, not a raw traceback
_guard_numba_cache()

from .version import __version__  # noqa: E402

#: The Python API (:mod:`metasheet.api`), imported when first used: ``import metasheet`` stays
#: light for the command line's supervising process.
_API = ("Constants", "Jacobian", "Run", "load_pipeline", "read_constants", "read_jacobian", "read_study",
        "run", "write_file")
__all__ = [*_API, "__version__"]


def __getattr__(name: str):
    if name in _API:
        from . import api

        return getattr(api, name)
    raise AttributeError(f"module 'metasheet' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *_API})
