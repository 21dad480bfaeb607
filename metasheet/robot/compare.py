"""Isotropic silicone vs the anisotropic foam (the paper's main claim, Fig. 4, 7, 8).

Evaluates one robot per material (built by :func:`.builder.six_dof_robot`) and reports the Jacobian's
singular values at the rest equilibrium and the rod-axis rotation per degree when all six
motors move together (from J, and from a finite actuation solved to equilibrium). With an
isotropic material each tripod has mirror planes that contain the rod, so that rotation
vanishes by symmetry (up to the mesh's asymmetry): 5 controllable DOF. The spiral fibres
break the mirror symmetry: a sixth DOF.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mechanics.rotations import rotation_vector
from .kinematics import Kinematics, kinematics
from .robots import Robot
from .statics import RobotState
from .equilibrium import solve_equilibrium


@dataclass(frozen=True)
class MaterialCase:
    """One material's numbers.

    Attributes
    ----------
    rest : equilibrium under gravity at the rest angles.
    moved : equilibrium with every motor moved by ``delta_deg``.
    kin : :class:`Kinematics` at ``rest``.
    rod_rotation_per_degree : rotation about the rod axis per degree of all motors, from J [deg/deg].
    rod_rotation_finite : the same from the finite move ``moved - rest`` [deg/deg].
    lateral_finite : effector translation across the rod per degree of all motors [mm/deg].
    """

    name: str
    rest: RobotState
    moved: RobotState
    delta_deg: float
    kin: Kinematics
    rod_rotation_per_degree: float
    rod_rotation_finite: float
    lateral_finite: float
    newton_iterations: int

    def to_dict(self) -> dict:
        return {"singular_values": self.kin.singular_values.tolist(),
                "rod_rotation_deg_per_deg": self.rod_rotation_per_degree,
                "rod_rotation_finite_deg_per_deg": self.rod_rotation_finite,
                "lateral_translation_finite_mm_per_deg": self.lateral_finite,
                "all_motors_delta_deg": self.delta_deg,
                "rest_pose_mm_deg": _pose_deg(self.rest).tolist(),
                "moved_pose_mm_deg": _pose_deg(self.moved).tolist(),
                **self.kin.to_dict()}


def _pose_deg(st: RobotState) -> np.ndarray:
    return np.concatenate([st.p, np.degrees(rotation_vector(st.R))])


def evaluate(robot: Robot, name: str, *, delta_deg: float = -10.0, length_scale: float = 50.0) -> MaterialCase:
    """Rest equilibrium, Jacobian there, and the all-motors move by ``delta_deg`` [deg]."""
    lz = robot.linearizer()
    rest = solve_equilibrium(robot, robot.coupling.rest_angles, linearizer=lz)
    kin = kinematics(lz.linearize(rest.state), length_scale=length_scale)
    angles = np.clip(rest.state.angles + np.radians(delta_deg), robot.angle_min, robot.angle_max)
    moved = solve_equilibrium(robot, angles, state=rest.state, linearizer=lz)
    ax = robot.axis / np.linalg.norm(robot.axis)
    d = float(np.mean(np.degrees(angles - rest.state.angles)))
    rot = np.degrees(rotation_vector(moved.state.R @ rest.state.R.T))
    dp = moved.state.p - rest.state.p
    lateral = np.linalg.norm(dp - np.dot(dp, ax) * ax)
    return MaterialCase(name, rest.state, moved.state, d, kin, float(kin.all_together[3:] @ ax),
                        float(rot @ ax) / d, float(lateral) / abs(d), rest.iterations + moved.iterations)


def compare(robots: dict, *, delta_deg: float = -10.0) -> dict:
    """``{name: MaterialCase}`` for each ``{name: Robot}``."""
    return {name: evaluate(rob, name, delta_deg=delta_deg) for name, rob in robots.items()}
