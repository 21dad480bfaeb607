"""The reduced-order robot (issue 16): a few coordinates for the sheets, a few elements for
their forces, and on top of it the equilibrium surface. It uses :mod:`metasheet.robot` (the
full model it is trained on and certified against); :mod:`metasheet.robot` never uses it.

- :mod:`.coordinates`: the reduced state, the trained :class:`ReducedBasis` (``basis.npz``),
  the full robot's key, the projection of a full state and ``dx/dq``.
- :mod:`.model`: :class:`ReducedRobot`, the Galerkin-projected, hyper-reduced robot.
- :mod:`.linearizer`: its :class:`ReducedLinearizer` (the full linearizer's interface, dense).
- :mod:`.tangents`: the library of exact reduced tangents the control loop reuses.
- :mod:`.basis`: the basis: static modes plus POD of snapshots and of their static responses.
- :mod:`.ecsw`: energy-conserving sampling and weighting of the elements.
- :mod:`.training`: snapshots, basis and element sample, each by its error target (:func:`train`).
- :mod:`.certificate`: reduced against full on held-out poses, against :data:`TARGETS`.
- :mod:`.surface`: the equilibrium surface, equilibria as polynomials in the motor angles.
- :mod:`.surface_robot`: that surface as a robot (:class:`SurfaceRobot`), the real-time model.

The public names below load their module on first use, so importing one submodule does
not import the whole package.
"""

from importlib import import_module

_PUBLIC = {
    "ReducedBasis": "coordinates", "ReducedState": "coordinates", "robot_key": "coordinates",
    "ReducedRobot": "model", "ReducedLinearizer": "linearizer", "TangentLibrary": "tangents",
    "motor_design": "training", "train": "training",
    "TARGETS": "certificate", "summarize": "certificate",
    "Surface": "surface", "SurfaceRobot": "surface_robot", "load_surface": "surface_robot",
}
__all__ = sorted(_PUBLIC)


def __getattr__(name):
    if name in _PUBLIC:
        return getattr(import_module(f".{_PUBLIC[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
