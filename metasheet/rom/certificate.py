"""The reduced model's certificate (issue 16): reduced against full on poses not used in training.

For held-out motor angles (a Sobol set of its own over the motor box and the box's
mixed corners, the sheets' largest deformations) each model's equilibrium is solved and
compared: effector position [mm] and orientation [deg] for the same motor angles, the
Jacobian (relative Frobenius norm), and the inverse model: the reduced model's QP driven to the
full model's pose returns motor angles, compared with the ones that produced it [deg].
Worst and 95th percentile of each, against the targets.

The targets apply where the material model holds: held-out poses whose strain (beyond the
grips' band, :mod:`metasheet.robot.validity`) is within the strain limit. Poses beyond it (the box's mixed
corners of a soft foam are far beyond) lie outside the homogenised model's domain, where no
study keeps a point: their errors are reported apart, as information, not certified.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..errors import ConvergenceError
from ..robot.equilibrium import solve_equilibrium
from ..robot.inverse import InverseController
from ..robot.inverse_settings import InverseSettings
from ..robot.kinematics import kinematics
from ..mechanics.rotations import rotation_vector

#: the certificate's targets: position [mm], orientation [deg], Jacobian [relative], motors [deg]
TARGETS = {"position_mm": 0.1, "orientation_deg": 0.1, "jacobian_rel": 0.02}


@dataclass(frozen=True)
class Comparison:
    """One held-out pose: motor angles [deg] and the reduced model's errors (nan: it failed)."""

    angles_deg: tuple
    position_mm: float
    orientation_deg: float
    jacobian_rel: float
    inverse_motor_deg: float
    strain: float


def held_out_angles(lo, hi, n: int, seed: int) -> np.ndarray:
    """(n + 2, na) [rad]: a Sobol set (its own seed) and the two mixed corners (sheet A's
    motors low and B's high, and the reverse)."""
    from .training import motor_design

    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    half = len(lo) // 2
    mixed = [np.r_[lo[:half], hi[half:]], np.r_[hi[:half], lo[half:]]]
    sobol = [motor_design(lo, hi, n, seed, corners=False)] if n > 0 else []
    return np.vstack([*sobol, *mixed])


def full_strain(full_robot, full_state, strain_elements=None) -> float:
    """The full equilibrium's largest principal strain over ``strain_elements`` (m,) bool
    (:mod:`metasheet.robot.validity`; None: every element) [-]."""
    from ..robot.validity import validity_strain

    if strain_elements is None:
        strain_elements = np.ones(len(full_robot.body.tets), bool)
    return validity_strain(full_robot.body, full_state.x, strain_elements)


def compare(full_robot, full_state, reduced, reduced_lz, full_lz, strain_elements=None, *,
            full_jacobian=None, inverse: bool = True) -> Comparison:
    """Reduced vs full at the full model's equilibrium ``full_state``; its strain over
    ``strain_elements`` (:func:`full_strain`); ``full_jacobian`` (6, na): the full model's
    Jacobian there, when already computed; ``inverse`` False: the inverse model's error is
    left out (nan; :func:`with_inverse` adds it): it has no target, and its QP solve costs more
    than the rest together, so the reduce stage's rounds judge without it."""
    nan = float("nan")
    deg = tuple(np.degrees(full_state.angles).round(4).tolist())
    strain = full_strain(full_robot, full_state, strain_elements)
    try:
        r = solve_equilibrium(reduced, full_state.angles, linearizer=reduced_lz).state
    except ConvergenceError:
        return Comparison(deg, nan, nan, nan, nan, strain)
    Jf = kinematics(full_lz.linearize(full_state)).J if full_jacobian is None else full_jacobian
    Jr = kinematics(reduced_lz.linearize(r)).J
    return _comparison(deg, r, Jr, full_state, Jf, reduced if inverse else None, strain)


def compare_surface(surface_robot, full_state, full_jacobian, strain: float) -> Comparison:
    """The equilibrium surface (:mod:`.surface_robot`) vs the full model at ``full_state``
    (its Jacobian (6, na) and strain given), as :func:`compare`."""
    deg = tuple(np.degrees(full_state.angles).round(4).tolist())
    st = surface_robot.equilibrium(full_state.angles)
    J = surface_robot.surface.evaluate(full_state.angles)[2]
    return _comparison(deg, st, J, full_state, full_jacobian, surface_robot, strain)


def _comparison(deg, st, J, full_state, Jf, robot, strain) -> Comparison:
    pos = float(np.linalg.norm(st.p - full_state.p))
    rot = float(np.degrees(np.linalg.norm(rotation_vector(st.R @ full_state.R.T))))
    jrel = float(np.linalg.norm(J - Jf) / np.linalg.norm(Jf))
    motors = float("nan") if robot is None else inverse_error(robot, full_state)
    return Comparison(deg, pos, rot, jrel, motors, strain)


def inverse_error(robot, full_state) -> float:
    """The inverse model's error [deg]: ``robot``'s QP driven to the full equilibrium
    ``full_state``'s pose returns motor angles, compared (largest difference) with the ones
    that produced it; nan when it does not reach the pose."""
    goal = np.concatenate([full_state.p, np.degrees(full_state.pose[3:])])
    settings = InverseSettings(pos_tol=0.01, rot_tol_deg=0.01, max_steps=400, stall_steps=30)
    inv = InverseController(robot, settings=settings).goto(goal)
    return float(np.abs(inv.angles_deg - np.degrees(full_state.angles)).max()) if inv.reached else float("nan")


def with_inverse(row: Comparison, robot, full_state) -> Comparison:
    """``row`` (from :func:`compare` with ``inverse=False``) with the inverse model's error of
    ``robot`` at ``full_state`` (:func:`inverse_error`); a pose the reduced model failed stays nan."""
    if not np.isfinite(row.position_mm):
        return row
    return replace(row, inverse_motor_deg=inverse_error(robot, full_state))


def summarize(rows: list[Comparison], strain_limit: float | None = None) -> dict:
    """Worst and 95th percentile per measure, failures counted, and the verdict per target, over
    the poses within ``strain_limit`` [-] (None: all); the others summarised under "beyond_strain"."""
    if strain_limit is None:
        return _summary(rows)
    inside = [r for r in rows if r.strain <= strain_limit]
    beyond = [r for r in rows if not r.strain <= strain_limit]
    out = {**_summary(inside), "strain_limit": float(strain_limit), "poses_beyond_strain": len(beyond)}
    if beyond:
        out["beyond_strain"] = {k: v for k, v in _summary(beyond).items() if k != "met"}
    return out


def surface_check(errs: dict, strain, strain_limit: float | None, reduced: dict) -> dict:
    """The equilibrium surface against the reduced model on equilibria it was not fitted on,
    and from it a bound on its error against the full model.

    ``errs`` : :func:`.surface.errors` on them (each (s,)); ``strain`` (s,) [-] (None: all
    count) and ``strain_limit``: only those within count; ``reduced`` : the reduced model's
    certificate (:func:`summarize`). Per measure: worst and p95 against the reduced model and
    ``bound_with_reduced`` = that worst + the reduced model's worst against the full one
    (the triangle inequality; for the Jacobian to the first order, both being relative to
    Jacobians ~1 % apart), judged against :data:`TARGETS`. The held-out full poses are
    few; these equilibria see the surface's whole box."""
    n = len(next(iter(errs.values())))
    keep = np.ones(n, bool) if strain is None or strain_limit is None else np.asarray(strain) <= strain_limit
    out = {"equilibria": int(n), "within_strain": int(keep.sum())}
    met = bool(keep.any())
    for name, target in TARGETS.items():
        v = np.asarray(errs[name], float)[keep]
        red = (reduced.get(name) or {}).get("worst")
        if not len(v) or red is None:
            out[name], met = None, False
            continue
        bound = float(v.max()) + float(red)
        out[name] = {"worst": float(v.max()), "p95": float(np.percentile(v, 95)), "bound_with_reduced": bound,
                     "target": target, "met": bool(bound <= target)}
        met = met and bound <= target
    out["met"] = bool(met)
    return out


def _summary(rows: list[Comparison]) -> dict:
    out = {"poses": len(rows)}
    for name in ("position_mm", "orientation_deg", "jacobian_rel", "inverse_motor_deg"):
        v = np.array([getattr(r, name) for r in rows], float)
        ok = v[np.isfinite(v)]
        out[name] = {"worst": float(ok.max()) if len(ok) else None,
                     "p95": float(np.percentile(ok, 95)) if len(ok) else None, "failed": int((~np.isfinite(v)).sum())}
        if name in TARGETS:
            out[name]["target"] = TARGETS[name]
            out[name]["met"] = bool(len(ok) == len(v) and len(ok) and ok.max() <= TARGETS[name])
    out["max_strain"] = float(max(r.strain for r in rows)) if rows else None
    out["met"] = all(out[n]["met"] for n in TARGETS)
    return out
