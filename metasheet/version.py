"""The package's version, in a module of its own: the manifests and the command line read it
without importing the package's top level (which exports the Python API)."""

__version__ = "0.1.0"
