"""The robot: corotational anisotropic tet FEM (:mod:`.body`), and on top of it the rigid
couplings, robots, static solver, Jacobian and inverse QP of the paper's Section III.

The public names below load their module on first use, so importing one submodule does
not import the whole package.
"""

from importlib import import_module

_PUBLIC = {
    "ElasticBody": "body",
    "RigidCoupling": "rigid", "Servo": "rigid",
    "Robot": "robots", "ServoGeometry": "robots", "tripod": "robots", "six_dof": "robots",
    "SheetPair": "builder", "six_dof_robot": "builder",
    "RobotState": "statics", "Equilibrium": "equilibrium", "Linearizer": "statics", "solve_equilibrium": "equilibrium",
    "Kinematics": "kinematics", "kinematics": "kinematics",
    "InverseController": "inverse", "InverseSettings": "inverse_settings", "InverseResult": "inverse",
    "QPStep": "qp", "solve_step_qp": "qp", "TangentCache": "tangent",
    "MaterialCase": "compare", "evaluate": "compare",
}
__all__ = sorted(_PUBLIC)


def __getattr__(name):
    if name in _PUBLIC:
        return getattr(import_module(f".{_PUBLIC[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
