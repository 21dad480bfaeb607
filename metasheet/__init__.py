"""metasheet: design soft robots made of 3D-printed anisotropic foam."""

from .cpu import pin_code_paths as _pin

# before numpy loads: the same kernels, so the same bytes, on every x86-64 CPU (metasheet.cpu)
_pin()

__version__ = "0.1.0"
