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
    candidates = branch_candidates(step)
    counts = [int(np.count_nonzero(np.abs(br.write(ta) - br.write(tb)) > SEAM_JUMP)) for br in candidates[:2]]
    if step == 1.0:
        counts += _seam_counts_by_offset(ta, tb).tolist()
    else:
        counts += [int(np.count_nonzero(np.abs(br.write(ta) - br.write(tb)) > SEAM_JUMP)) for br in candidates[2:]]
    best = int(np.argmin(counts))  # the first of equal counts
    return candidates[best], int(counts[best])


#: an angle within this of a whole degree, or a difference within this of 0 or 90 deg, is
#: counted by writing it (:meth:`AngleBranch.write`), as the other pairs' arcs assume no tie
_TIE = 1e-6


def _seam_counts_by_offset(ta: np.ndarray, tb: np.ndarray) -> np.ndarray:
    """(180,) for the period-180 branches of offsets 0, 1, ..., 179 deg, the count of pairs
    (ta, tb) [deg] whose written angles differ by more than :data:`SEAM_JUMP`: the counts of
    writing every pair at every offset, in one pass.

    With a = ta mod 180, b = tb mod 180 and a < b, the written pair is (a, b) shifted for an
    offset c outside (a, b], and (a + 180, b) for c inside (a, b]: its difference is a - b
    or a - b + 180, one or the other more than 90 deg apart (and symmetrically for a > b), so
    each pair adds its verdict outside the arc to every offset and the change inside the arc
    to the offsets in it (a difference array). Equal angles are never a seam; pairs within
    :data:`_TIE` of a whole degree or of a difference of 0 or 90 deg are written at every
    offset instead: rounding decides them.
    """
    same = ta == tb  # written alike at every offset: never a seam
    ta, tb = ta[~same], tb[~same]
    a, b = np.mod(ta, 180.0), np.mod(tb, 180.0)
    d = a - b
    near = ((np.abs(a - np.round(a)) < _TIE) | (np.abs(b - np.round(b)) < _TIE)
            | (np.abs(np.abs(d) - 90.0) < _TIE) | (np.abs(d) < _TIE) | (np.abs(np.abs(d) - 180.0) < _TIE))
    counts = np.zeros(180, dtype=np.int64)
    if np.any(near):
        na, nb = ta[near], tb[near]
        counts += np.array([np.count_nonzero(np.abs(AngleBranch(180.0, float(c)).write(na)
                                                    - AngleBranch(180.0, float(c)).write(nb)) > SEAM_JUMP)
                            for c in range(180)])
    a, b, d = a[~near], b[~near], d[~near]
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    inside = np.where(a < b, d + 180.0, d - 180.0)  # the difference for offsets in (lo, hi]
    out_seam, in_seam = np.abs(d) > SEAM_JUMP, np.abs(inside) > SEAM_JUMP
    counts += int(np.count_nonzero(out_seam))
    change = in_seam.astype(np.int64) - out_seam.astype(np.int64)
    first, last = np.floor(lo).astype(np.int64) + 1, np.floor(hi).astype(np.int64)  # whole c in (lo, hi]
    step = np.zeros(181, dtype=np.int64)
    np.add.at(step, first, change)
    np.add.at(step, last + 1, -change)
    counts += np.cumsum(step)[:180]
    return counts


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
