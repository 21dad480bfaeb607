"""metasheet: design soft robots made of 3D-printed anisotropic foam."""

from .cpu import pin_code_paths as _pin

# before numpy loads: the same kernels, so the same bytes, on every x86-64 CPU (metasheet.cpu)
_pin()

from .numba_cache import install as _guard_numba_cache  # noqa: E402

# a damaged compiled-kernel cache file is removed and compiled again, not a raw traceback
_guard_numba_cache()

__version__ = "0.1.0"
