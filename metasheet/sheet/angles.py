"""The axis angle of the foam's soft axis in a print map: its branch and its seams.

IceSL's ``infill_angle`` texture (:mod:`metasheet.sheet.icesl`) holds an angle in [0, 360)
deg, while the foam's soft axis l is an axis (period 180 deg). :class:`AngleBranch` says
how the fibre's vector angle theta [deg] is written into [0, 360); :func:`choose_branch`
picks, among :func:`branch_candidates`, the branch whose seams (face-neighbouring texels
more than :data:`SEAM_JUMP` deg apart, where trilinear interpolation gives a wrong axis)
touch the fewest foam texels; :func:`seam_report` says where the seams of a written field
cross the foam. Fields are (n, n, n) texel arrays indexed [i, j, k] along x, y, z; angles
in degrees, lengths in mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from .grid import GridBox


@dataclass(frozen=True)
class AngleBranch:
    """How an axis angle (period 180 deg) is written into a [0, 360) deg texture.

    The written angle is ``offset + mod(theta + flip - offset, period)`` [deg] with theta the
    fibre's vector angle: always congruent to the fibre's axis angle modulo 180 deg.

    - ``period`` 180: values in [offset, offset + 180), offset in [0, 180]: the axis itself.
    - ``period`` 360 (offset 0): the vector angle of the fibre, flipped by ``flip`` (0 or
      180 deg): values in [0, 360).

    A fibre field that turns once around the sheet centre (the spiral: its axis angle grows
    by 360 deg per turn) cannot be written without a seam, where neighbouring texels differ
    by one period and the interpolation between them gives a wrong axis: period 180 gives two
    seams (opposite rays from the centre), period 360 one. :func:`choose_branch` picks the
    branch whose seams touch the fewest foam texels.
    """

    period: float
    offset: float = 0.0
    flip: float = 0.0

    def __post_init__(self):
        if self.period not in (180.0, 360.0):
            raise ConfigError(f"period: {self.period!r}: allowed values are 180, 360 [deg]")
        if not 0.0 <= self.offset <= 360.0 - self.period:
            raise ConfigError(f"offset: {self.offset!r}: allowed range is [0, {360.0 - self.period:g}] [deg]")

    def write(self, theta_deg: np.ndarray) -> np.ndarray:
        """Written angle [deg], in [offset, offset + period), of vector angles theta [deg]."""
        t = np.asarray(theta_deg, dtype=float) + self.flip
        return self.offset + np.mod(t - self.offset, self.period)

    def to_dict(self) -> dict:
        return {"period_deg": self.period, "offset_deg": self.offset, "flip_deg": self.flip}


def branch_candidates(step: float = 1.0) -> list[AngleBranch]:
    """The branches :func:`choose_branch` tries: the two vector lifts, then period 180 offsets."""
    out = [AngleBranch(360.0, 0.0, 0.0), AngleBranch(360.0, 0.0, 180.0)]
    out += [AngleBranch(180.0, float(c)) for c in np.arange(0.0, 180.0, step)]
    return out


SEAM_JUMP = 90.0  # [deg] neighbouring texels further apart than this straddle a seam


def _neighbour_pairs(weight: np.ndarray):
    """Pairs of face-neighbouring texels (flat indices a, b) with weight[a] | weight[b]."""
    n = weight.shape
    flat = np.arange(weight.size).reshape(n)
    a_all, b_all = [], []
    for ax in range(3):
        lo = [slice(None)] * 3
        hi = [slice(None)] * 3
        lo[ax], hi[ax] = slice(0, -1), slice(1, None)
        a, b = flat[tuple(lo)].ravel(), flat[tuple(hi)].ravel()
        keep = weight.ravel()[a] | weight.ravel()[b]
        a_all.append(a[keep])
        b_all.append(b[keep])
    return np.concatenate(a_all), np.concatenate(b_all)


def seam_pairs(written_deg: np.ndarray, foam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Face-neighbour texel pairs (flat indices a, b) that straddle a seam and touch the foam."""
    a, b = _neighbour_pairs(foam)
    w = written_deg.ravel()
    jump = np.abs(w[a] - w[b]) > SEAM_JUMP
    return a[jump], b[jump]


def choose_branch(theta_deg: np.ndarray, foam: np.ndarray, *, step: float = 1.0) -> tuple[AngleBranch, int]:
    """The branch (:func:`branch_candidates`) whose seams touch the fewest foam texel pairs.

    theta_deg : (n, n, n) the fibre's vector angle at every texel [deg] (continuous where
        the fibre field is); foam : (n, n, n) bool, texels printed as foam. Returns the
        branch and its count of seam pairs touching the foam; ties go to the earlier
        candidate (a single seam first).
    """
    a, b = _neighbour_pairs(foam)
    t = np.asarray(theta_deg, dtype=float).ravel()
    ta, tb = t[a], t[b]
    best, best_n = None, None
    for br in branch_candidates(step):
        k = int(np.count_nonzero(np.abs(br.write(ta) - br.write(tb)) > SEAM_JUMP))
        if best_n is None or k < best_n:
            best, best_n = br, k
    return best, int(best_n)


def seam_report(written_deg: np.ndarray, foam: np.ndarray, box: GridBox) -> dict:
    """Where the seams of a written angle field cross the foam: pair count, polar angles and
    radii [deg, mm] of their midpoints (sheet centre at the origin)."""
    a, b = seam_pairs(written_deg, foam)
    out = {"foam_texel_pairs": int(len(a)), "foam_texels": int(len(np.unique(np.concatenate([a, b]))))}
    if len(a):
        c = box.centers().reshape(-1, 3)
        mid = 0.5 * (c[a] + c[b])
        t = np.degrees(np.arctan2(mid[:, 1], mid[:, 0]))
        r = np.hypot(mid[:, 0], mid[:, 1])
        # seams run outwards from the centre: their polar angles, rounded to 5 deg
        out["polar_angle_deg"] = sorted({float(x) for x in np.mod(5.0 * np.round(t / 5.0), 360.0)})
        out["radius_mm"] = [float(r.min()), float(r.max())]
    return out
