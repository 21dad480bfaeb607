"""metasheet: design soft robots made of 3D-printed anisotropic foam."""

__version__ = "0.1.0"
