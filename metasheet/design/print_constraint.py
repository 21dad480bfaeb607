"""The fibre angle's print round trip as a linear constraint of the free-form design (issue 45).

IceSL reads the fibre angle from a 64^3 texture of 8-bit values (:mod:`metasheet.sheet.icesl`):
the field is sampled at the texel centres, rounded to 360/255 deg and read back trilinearly
(:func:`.printability.angle_round_trip` checks the result against the print map's 2 deg). For a
design ``theta(x) = theta_spiral(x) + B(x) c`` the texture is linear in ``c`` on a fixed angle
branch, and so is the read-back angle wherever a stencil's 8 texels lie on one side of the branch's
seam. There the signed error at each foam element centroid is affine in the coefficients:

    e(c) = e0 + G c    [deg],    e = wrap_90(read-back angle - design angle)

before the 8-bit rounding, which moves the read-back angle by at most half a step,
:data:`QUANTUM_DEG`. SLSQP keeps ``|e0 + G c| <= tolerance - QUANTUM_DEG`` at every element off
the seam, so the printed design passes the round trip up to the linearisation (a seam that moves
with ``c``). The stage then checks it exactly. The branch writes ``theta + const`` off its wrap,
so column j of ``G`` is the basis function B_j [deg] sampled at the texel centres and read back,
less B_j at the centroid (tested against central differences of the whole round trip).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..sheet import angles, icesl
from .printability import ANGLE_TOLERANCE_DEG

#: [deg] the largest change of a read-back angle by the 8-bit rounding of its texels
QUANTUM_DEG = 0.5 * icesl.FIELD_SCALE[icesl.ANGLE] / 255


@dataclass(frozen=True)
class PrintConstraint:
    """``|e0 + G c| <= budget_deg`` at the ``compared`` foam elements off the seam.

    Attributes
    ----------
    e0 : (k,) [deg] signed read-back error of the spiral (c = 0), before the 8-bit rounding.
    G : (k, n) [deg/rad] its derivative in the coefficients.
    budget_deg : [deg] the tolerance less :data:`QUANTUM_DEG`.
    seam : elements on the seam at c = 0, left out (as the round trip check leaves them out).
    """

    e0: np.ndarray
    G: np.ndarray
    budget_deg: float
    seam: int

    @property
    def compared(self) -> int:
        return len(self.e0)

    def errors(self, c: np.ndarray) -> np.ndarray:
        """(k,) [deg] the linear model's signed errors at coefficients c (n,) [rad]."""
        return self.e0 + self.G @ np.asarray(c, float)

    def slack(self, c: np.ndarray) -> np.ndarray:
        """(2k,) >= 0 where satisfied, in units of the budget (SLSQP's ``ineq``)."""
        e = self.errors(c)
        return np.concatenate([self.budget_deg - e, self.budget_deg + e]) / self.budget_deg

    def slack_jacobian(self, c: np.ndarray) -> np.ndarray:
        """(2k, n) derivative of :meth:`slack`."""
        return np.concatenate([-self.G, self.G]) / self.budget_deg


def print_constraint(points: np.ndarray, tets: np.ndarray, params, spiral: Callable[[np.ndarray], np.ndarray],
                     basis: Callable[[np.ndarray], np.ndarray], *,
                     tolerance_deg: float = ANGLE_TOLERANCE_DEG) -> PrintConstraint:
    """The linear round trip model of the designs ``spiral(q) + basis(q) @ c`` [rad] (``spiral``:
    points (q, 3) [mm] -> (q,) [rad]; ``basis``: points -> (q, n) [rad per rad]) printed on sheet A
    (``points`` (k, 3) [mm], ``tets`` (m, 4), geometry ``params``).

    Raises ConfigError when ``tolerance_deg`` leaves no budget above the 8-bit rounding, or when
    every foam element is on the seam.
    """
    if not tolerance_deg > QUANTUM_DEG:
        raise ConfigError(f"angle_tolerance_deg: {tolerance_deg!r}: must exceed the 8-bit rounding's "
                          f"{QUANTUM_DEG:.3f} deg")
    pts, tets = np.asarray(points, float), np.asarray(tets)
    cent = foam_centroids(pts, tets, params)
    e0, seam, box = read_back_errors(pts, tets, params, spiral, cent)
    keep = ~seam
    if not keep.any():
        raise ConfigError("fibre field: every foam element is on the angle field's seam: nothing to constrain")
    texels = box.centers().reshape(-1, 3)
    B_tex = np.degrees(basis(texels)).reshape(box.n, box.n, box.n, -1)
    B_cent = np.degrees(basis(cent[keep]))
    G = np.stack([icesl.sample(B_tex[..., j], box, cent[keep]) for j in range(B_tex.shape[-1])], axis=1) - B_cent
    return PrintConstraint(e0[keep], G, float(tolerance_deg - QUANTUM_DEG), int(seam.sum()))


def foam_centroids(points: np.ndarray, tets: np.ndarray, params) -> np.ndarray:
    """(e, 3) [mm] centroids of the foam elements (not in the solid parts): the round trip's points."""
    cent = np.asarray(points, float)[np.asarray(tets)[:, :4]].mean(axis=1)
    return cent[~icesl.solid_mask(cent, params)]


def read_back_errors(points, tets, params, angles_of: Callable[[np.ndarray], np.ndarray], cent: np.ndarray,
                     branch=None):
    """The unrounded round trip of the field ``angles_of`` (points -> (q,) [rad]) at ``cent`` (e, 3):
    (signed errors (e,) [deg] in [-90, 90), on the seam (e,) bool, the texture's box)."""
    from ..sheet.fibre_field import fibres_at

    pf = icesl.print_fields(points, tets, element_settings={}, params=params, branch=branch,
                            fiber_fn=lambda q: fibres_at(angles_of(q)))
    scale = icesl.FIELD_SCALE[icesl.ANGLE]
    tex = pf.textures[icesl.ANGLE]
    read = scale * icesl.sample(tex, pf.box, cent)
    e = (read - np.degrees(angles_of(cent)) + 90.0) % 180.0 - 90.0
    seam = scale * icesl.stencil_span(tex, pf.box, cent) > angles.SEAM_JUMP
    return e, seam, pf.box
