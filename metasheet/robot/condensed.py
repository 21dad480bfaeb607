"""The 6-DOF robot's rest linearisation from its two sheets' condensed grip stiffnesses (issue 44).

Each sheet enters the robot only through its four rigid grips (:mod:`metasheet.sheet.grips`):
at the rest pose, with no gravity preload, the robot's Schur complement S (eq. 6, the stiffness
seen by q_r = (q_e (6), q_a (6))) is the sum over the two sheets of ``E^T K E``, where K is the
sheet's 24 x 24 grip stiffness and E (24, 12) maps the robot's rigid coordinates to the sheet's
grip coordinates:

* sheet A's frame goes to the world by ``x -> Q_A x + c_A``, B's by ``Q_B``, ``c_B``
  (:mod:`.robots`; both proper rotations, so a grip's (t, theta) turn by Q, axial vectors
  included); the centres ``c`` are the robot's ``info["sheet_centres_mm"]``;
* the centre grip of either sheet moves with the effector (rod centre, reference point
  ``coupling.origin``): ``t = dp + dtheta x (c - origin)``, ``theta = dtheta``;
* arm k's grip of sheet A moves with servo k, of sheet B with servo 3 + k: a rotation
  ``dphi`` about the servo's axis a through its pivot p, ``t = dphi a x (r - p)``,
  ``theta = dphi a`` at the grip's world reference point r.

The servos are the robot's own (:func:`metasheet.robot.builder.six_dof_robot`), so rod length
and servo placement are the robot stage's. Each sheet's free nodes are condensed inside its K,
and the sheets share no node, so the FEM robot's S at rest without gravity is exactly this sum
(the rigid coupling is linear there): this is how a printed sheet's voxel K (or the FEM's own,
:func:`metasheet.sheet.grips.fem_condensed`) gives the robot's Jacobian and rod roll.
"""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError
from ..mechanics.rotations import skew
from ..sheet.grips import N_GRIP_DOF, check_references, check_stiffness
from .kinematics import Kinematics, kinematics_from_schur
from .robots import Q_A, Q_B

#: rigid coordinates of the 6-DOF robot: effector (6) and six motors
N_RIGID = 12
#: [mm] default length scale of the singular values (:func:`.kinematics.kinematics`'s; the
#: design's ``objectives.LENGTH_SCALE``, not imported: the design sits above the robot)
LENGTH_SCALE = 50.0


def _check_robot(robot):
    c = getattr(robot, "coupling", None)
    if c is None or getattr(c, "n_act", None) != 6:
        raise ConfigError(f"robot: {getattr(robot, 'name', type(robot).__name__)!r}: expected the "
                          "six-DOF robot (six_dof_robot: 6 servos, 3 per sheet)")
    centres = (getattr(robot, "info", None) or {}).get("sheet_centres_mm")
    if centres is None or np.shape(centres) != (2, 3):
        raise ConfigError("robot.info['sheet_centres_mm']: missing or not (2, 3): build the robot "
                          "with metasheet.robot.builder.six_dof_robot")
    return c, np.asarray(centres, float)


def grip_map(Q, centre, references, origin, servos) -> np.ndarray:
    """(24, 12) E: one sheet's grip coordinates (in ITS frame) per unit robot coordinate.

    Q : (3, 3) the sheet's local -> world rotation; centre : (3,) its centre in the world [mm];
    references : (4, 3) grip reference points, sheet frame [mm]; origin : (3,) the effector's
    reference point [mm]; servos : three ``(j, servo)`` pairs, arm k's :class:`.rigid.Servo`
    and its index j among the robot's six motors. Columns: (dp [mm], dtheta [rad], motors
    0-5 [rad]); the other sheet's motors' columns stay zero.
    """
    r = check_references(references)
    world = r @ Q.T + centre  # the grips' reference points in the world
    Ew = np.zeros((N_GRIP_DOF, N_RIGID))
    Ew[0:3, 0:3] = np.eye(3)
    Ew[0:3, 3:6] = -skew(world[0] - origin)  # t = dp + dtheta x (c - origin)
    Ew[3:6, 3:6] = np.eye(3)
    for k, (j, sv) in enumerate(servos):
        a = np.asarray(sv.axis, float)
        Ew[6 * (k + 1):6 * (k + 1) + 3, 6 + j] = np.cross(a, world[k + 1] - np.asarray(sv.pivot, float))
        Ew[6 * (k + 1) + 3:6 * (k + 2), 6 + j] = a
    # world (t, theta) -> sheet frame: multiply each 3-block by Q^T
    return np.kron(np.eye(2 * 4), Q.T) @ Ew


def robot_grip_maps(robot, references, references_b=None) -> tuple[np.ndarray, np.ndarray]:
    """(E_A, E_B), each (24, 12): :func:`grip_map` of sheet A (servos 0-2) and B (3-5) of the
    six-DOF ``robot``; ``references_b`` defaults to ``references`` (the mirror keeps arm k's
    direction, :mod:`metasheet.sheet.grips`)."""
    c, centres = _check_robot(robot)
    rb = references if references_b is None else references_b
    sv = list(enumerate(c.servos))
    Ea = grip_map(Q_A, centres[0], references, c.origin, sv[:3])
    Eb = grip_map(Q_B, centres[1], check_references(rb, "references_b"), c.origin, sv[3:])
    return Ea, Eb


def condensed_robot_S(K_a, K_b, robot, references, references_b=None) -> np.ndarray:
    """(12, 12) rest Schur complement S of the six-DOF ``robot`` [N/mm, N, N mm per mm or rad]
    from the sheets' grip stiffnesses ``K_a``, ``K_b`` (24, 24, each in its own sheet frame,
    :mod:`metasheet.sheet.grips` conventions) with grip ``references`` (4, 3) [mm]. Rows and
    columns as the robot's: (q_e (6): dp, dtheta about the origin; q_a (6): motors)."""
    Ka, Kb = check_stiffness(K_a, "K_a"), check_stiffness(K_b, "K_b")
    Ea, Eb = robot_grip_maps(robot, references, references_b)
    S = Ea.T @ Ka @ Ea + Eb.T @ Kb @ Eb
    return 0.5 * (S + S.T)


def grip_motions_per_motor(K_a, K_b, robot, references, references_b=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(G_A (24, 6), G_B (24, 6), J (6, 6)): per unit motor change [rad] at rest, each sheet's grip
    motions (its frame, :mod:`metasheet.sheet.grips`' coordinates) and the effector's (dp [mm],
    dtheta [rad]), the rod in equilibrium: ``J = -S_ee^-1 S_ea``, ``G = E (J; I)``."""
    S = condensed_robot_S(K_a, K_b, robot, references, references_b)
    J = -np.linalg.solve(S[:6, :6], S[:6, 6:])
    Ea, Eb = robot_grip_maps(robot, references, references_b)
    q = np.vstack([J, np.eye(6)])
    return Ea @ q, Eb @ q, J


def condensed_kinematics(K_a, K_b, robot, references, *, length_scale: float = LENGTH_SCALE,
                         references_b=None) -> Kinematics:
    """:class:`.kinematics.Kinematics` of the robot at rest from the condensed sheets."""
    S = condensed_robot_S(K_a, K_b, robot, references, references_b)
    return kinematics_from_schur(S, length_scale=length_scale)


def rest_numbers_condensed(K_a, K_b, robot, references, *, length_scale: float = LENGTH_SCALE,
                           references_b=None) -> dict:
    """As :func:`metasheet.robot.uncertainty.rest_numbers`, from the condensed sheets: the
    scaled singular values [mm/rad] of the rest Jacobian and the rod roll per degree of all
    motors together [deg/deg] (about ``robot.axis``). Linear rest model: no gravity sag (it
    moves the roll by ~1e-5 relative on the foam robot, :mod:`metasheet.design.adjoint`)."""
    kin = condensed_kinematics(K_a, K_b, robot, references, length_scale=length_scale,
                               references_b=references_b)
    ax = np.asarray(robot.axis, float) / np.linalg.norm(robot.axis)
    return {"singular_values": kin.singular_values.tolist(),
            "rod_rotation_deg_per_deg": float(kin.all_together[3:] @ ax)}
