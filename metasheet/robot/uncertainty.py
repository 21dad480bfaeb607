"""How far the foam's uncertainty moves the robot (issue 43): the rest Jacobian at the bounds.

The homogenised constants are means over a few realisations with 95 % half-widths
(``material.json``'s ``ci95``). The robot's numbers are evaluated at the mean and at the ten
one-at-a-time extremes: each constant at ``mean - h`` and ``mean + h``, the other four at
their means. For each case the rest equilibrium is solved and the Jacobian taken there; the
spread of the rod roll per degree (all motors together) and of the singular values is what
the foam's uncertainty does to the 6th DOF. One-at-a-time bounds ignore the correlation
between constants (realisations that are soft along l are soft in shear too), so the spread
is a sensitivity, not a joint interval.

A bound that leaves a constant's allowed range is clipped and says so: a modulus to
:data:`MODULUS_FLOOR` of its mean, a Poisson ratio inside (-1, 1); a bound whose tensor is not
positive definite is skipped with the builder's reason.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np

from ..errors import ConfigError
from ..mechanics.material import CONSTANT_NAMES
from .builder import SheetPair
from .equilibrium import solve_equilibrium
from .kinematics import kinematics

#: a modulus bound below this fraction of its mean is clipped to it (a zero modulus has no tensor)
MODULUS_FLOOR = 0.05


@dataclass(frozen=True)
class Bound:
    """One one-at-a-time case: ``name`` ("E_l-", "E_l+", ...), the ``factor`` applied to that
    constant [-], ``value`` the constant there (unit of the constant), ``clipped`` whether the
    95 % bound left the allowed range."""

    name: str
    constant: str
    factor: float
    value: float
    clipped: bool


def bounds(means: Mapping[str, float], halfwidth: Mapping[str, float]) -> list[Bound]:
    """The ten extremes ``mean -+ h`` of the five constants, in CONSTANT_NAMES order."""
    out = []
    for k in CONSTANT_NAMES:
        m, h = float(means[k]), float(halfwidth.get(k) or 0.0)
        if not np.isfinite(h) or h < 0:
            raise ConfigError(f"ci95.halfwidth.{k}: {h!r}: expected a finite half-width >= 0")
        for sign, tag in ((-1.0, "-"), (1.0, "+")):
            v = m + sign * h
            lo, hi = (MODULUS_FLOOR * abs(m), np.inf) if not k.startswith("nu") else (-0.99, 0.99)
            if k == "nu_tl":  # its range depends on the others: the builder refuses what is too large
                lo, hi = -np.inf, np.inf
            w = min(max(v, lo), hi)
            out.append(Bound(f"{k}{tag}", k, w / m if m else 1.0, w, w != v))
    return out


def scaled_sheets(pair: SheetPair, constant: str, factor: float) -> SheetPair:
    """``pair`` with one per-element constant multiplied by ``factor`` on both sheets."""
    if not pair.has_constants:
        raise ConfigError("sheets: no per-element constants to scale (rerun the orient stage)")
    j = CONSTANT_NAMES.index(constant)
    cols = []
    for con in (pair.constants, pair.constants_mirrored):
        c = np.array(con, float)
        c[:, j] *= factor
        cols.append(c)
    return replace(pair, constants=cols[0], constants_mirrored=cols[1])


def rest_numbers(robot, *, length_scale: float) -> dict:
    """Singular values of the scaled rest Jacobian and the rod roll per degree of all motors."""
    lz = robot.linearizer()
    rest = solve_equilibrium(robot, robot.coupling.rest_angles, linearizer=lz)
    kin = kinematics(lz.linearize(rest.state), length_scale=length_scale)
    ax = robot.axis / np.linalg.norm(robot.axis)
    return {"singular_values": kin.singular_values.tolist(),
            "rod_rotation_deg_per_deg": float(kin.all_together[3:] @ ax)}


def summarise(mean: dict | ConfigError, at_bounds: Mapping[str, dict | ConfigError],
              bs: list[Bound]) -> dict:
    """The spread from the robot's :func:`rest_numbers` at the means (``mean``) and at each
    bound of ``bs`` (``at_bounds[b.name]``; a ConfigError where the builder refused the bound's
    tensor: skipped with its reason).

    Returns ``{"method", "cases": {name: {...}}, "skipped": {name: reason},
    "rod_rotation_range", "singular_values_min", "singular_values_max"}``; the ranges include
    the mean case.
    """
    if isinstance(mean, ConfigError):
        raise mean
    cases = {"mean": mean}
    skipped = {}
    for b in bs:
        r = at_bounds[b.name]
        if isinstance(r, ConfigError):  # e.g. nu_tl + h gives no positive-definite tensor
            skipped[b.name] = str(r)
        else:
            cases[b.name] = {**r, "value": b.value, "clipped": b.clipped}
    roll = [c["rod_rotation_deg_per_deg"] for c in cases.values()]
    sv = np.array([c["singular_values"] for c in cases.values()])
    return {"method": "one at a time: each constant at its 95 % bounds mean -+ h, the others at their means; "
                      "rest equilibrium and Jacobian of each",
            "cases": cases, "skipped": skipped,
            "rod_rotation_range": [float(min(roll)), float(max(roll))],
            "singular_values_min": sv.min(axis=0).tolist(), "singular_values_max": sv.max(axis=0).tolist()}