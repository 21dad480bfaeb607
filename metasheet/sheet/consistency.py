"""Round trip of a print map: what the slicer reads back at each element, against the model.

For each sheet element (not printed solid) the printed fields are sampled at its centroid
as the slicer would (trilinear interpolation of the **quantised** 8-bit textures, texel
centres as in :mod:`metasheet.sheet.icesl`), mapped back through the print source's
``constants_at`` to the five constants, and compared with the constants the robot uses for
that element; the printed soft axis (in-plane angle ``infill_angle``) is compared with the
element's fibre l as an axis (the angle between the two lines, in [0, 90] deg).

Relative differences: |printed - model| / |model| for the moduli; for the Poisson ratios
|printed - model| / max(|model|, :data:`NU_FLOOR`) so that a ratio near 0 does not blow up.

Elements whose interpolation stencil straddles a seam of the angle field (8 texels spanning
more than ``SEAM_JUMP`` deg, see :class:`~metasheet.sheet.angles.AngleBranch`) get a wrong
axis there whatever the branch: they are counted and reported (``seam``), and their angle
is not held to the tolerance; their constants are.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..mechanics.material import CONSTANT_NAMES
from . import angles, grid, icesl

NU_FLOOR = 0.1


@dataclass(frozen=True)
class Worst:
    """The worst element of one comparison: index, centroid (3,) [mm], model and printed values."""

    element: int
    centroid: tuple[float, float, float]
    model: float
    printed: float
    difference: float

    def to_dict(self) -> dict:
        return {"element": self.element, "centroid_mm": list(self.centroid), "model": self.model,
                "printed": self.printed, "difference": self.difference}


@dataclass(frozen=True)
class Comparison:
    """max and p99 of a difference over the compared elements, and where the max is."""

    max: float
    p99: float
    worst: Worst | None

    def to_dict(self) -> dict:
        return {"max": self.max, "p99": self.p99, "worst": None if self.worst is None else self.worst.to_dict()}


@dataclass(frozen=True)
class ConsistencyReport:
    """The round trip of one sheet (module doc).

    constants : name -> :class:`Comparison` of the relative differences [-];
    angle : :class:`Comparison` of the axis angle differences [deg] (seam elements excluded);
    compared, solid, seam : element counts; seam_angle_max : largest axis difference at the
    seam [deg]; seam_volume_fraction : the seam elements' share of the compared volume.
    """

    constants: dict[str, Comparison]
    angle: Comparison
    compared: int
    solid: int
    seam: int
    seam_angle_max: float
    seam_volume_fraction: float
    tolerance: float
    angle_tolerance_deg: float

    def failures(self) -> list[tuple[str, Comparison]]:
        """(quantity, comparison) above tolerance, worst first (by its ratio to the tolerance)."""
        bad = [(k, c, c.max / self.tolerance) for k, c in self.constants.items() if c.max > self.tolerance]
        if self.angle.max > self.angle_tolerance_deg:
            bad.append(("axis angle", self.angle, self.angle.max / self.angle_tolerance_deg))
        return [(k, c) for k, c, _ in sorted(bad, key=lambda t: -t[2])]

    @property
    def ok(self) -> bool:
        return not self.failures()

    def message(self, label: str = "") -> str:
        """One line per failure, naming the worst element and its values."""
        out = []
        for k, c in self.failures():
            w = c.worst
            at = f"element {w.element} (centroid [{', '.join(f'{x:.2f}' for x in w.centroid)}] mm)"
            if k == "axis angle":
                out.append(f"{label}{at}: printed soft axis {w.printed:.2f} deg vs fibre {w.model:.2f} deg: "
                           f"{w.difference:.2f} deg apart > angle_tolerance_deg {self.angle_tolerance_deg:g}")
            else:
                out.append(f"{label}{at}: {k} printed {w.printed:.6g} vs modelled {w.model:.6g}: relative "
                           f"difference {w.difference:.4g} > tolerance {self.tolerance:g}")
        return "; ".join(out)

    def to_dict(self) -> dict:
        return {
            "ok": self.ok,
            "elements_compared": self.compared, "elements_solid": self.solid, "elements_at_seam": self.seam,
            "constants_relative_difference": {k: c.to_dict() for k, c in self.constants.items()},
            "axis_angle_difference_deg": self.angle.to_dict(),
            "seam": {"elements": self.seam, "max_axis_difference_deg": self.seam_angle_max,
                     "volume_fraction": self.seam_volume_fraction,
                     "note": "elements whose interpolation stencil straddles the angle field's seam; "
                             "their angle is reported here, not held to the tolerance"},
            "tolerance": self.tolerance, "angle_tolerance_deg": self.angle_tolerance_deg,
        }


def _compare(diff: np.ndarray, model: np.ndarray, printed: np.ndarray, ids: np.ndarray,
             centroids: np.ndarray) -> Comparison:
    if len(diff) == 0:
        return Comparison(0.0, 0.0, None)
    i = int(np.argmax(diff))
    e = int(ids[i])
    worst = Worst(e, tuple(float(x) for x in centroids[e]), float(model[i]), float(printed[i]), float(diff[i]))
    return Comparison(float(diff.max()), float(np.percentile(diff, 99)), worst)


def axis_difference_deg(angle_deg: np.ndarray, fibers: np.ndarray) -> np.ndarray:
    """Angle [deg] in [0, 90] between the in-plane axes at ``angle_deg`` (m,) and fibres (m, 3)."""
    a = np.radians(np.asarray(angle_deg, dtype=float))
    f = np.asarray(fibers, dtype=float)
    f = f / np.linalg.norm(f, axis=1, keepdims=True)
    c = np.abs(np.cos(a) * f[:, 0] + np.sin(a) * f[:, 1])
    return np.degrees(np.arccos(np.clip(c, 0.0, 1.0)))


def round_trip(
    *,
    box: grid.GridBox,
    textures: Mapping[str, np.ndarray],
    constants_at: Callable[[dict], dict],
    centroids: np.ndarray,
    constants: Mapping[str, np.ndarray],
    fibers: np.ndarray,
    printed_solid: np.ndarray,
    volumes: np.ndarray | None = None,
    tolerance: float = 0.02,
    angle_tolerance_deg: float = 2.0,
) -> ConsistencyReport:
    """Compare the print with the model at every element centroid (module doc).

    Parameters
    ----------
    box : the texture box; textures : setting -> (n, n, n) texture values **as the slicer
        holds them** (quantised), including ``infill_angle``; every other texture is a field
        setting passed to ``constants_at`` in IceSL units.
    constants_at : the print source's settings -> constants map.
    centroids : (m, 3) [mm]; constants : name -> (m,) the model's constants [MPa, -];
    fibers : (m, 3) the model's soft axes l; printed_solid : (m,) bool, elements printed
        solid (skipped); volumes : (m,) [mm^3] (for the seam's volume share; default 1).
    """
    c = np.asarray(centroids, dtype=float)
    m = len(c)
    solid = np.asarray(printed_solid, dtype=bool)
    if solid.shape != (m,) or np.shape(fibers) != (m, 3):
        raise ConfigError(f"printed_solid, fibers: shapes {solid.shape}, {np.shape(fibers)} should be ({m},), ({m}, 3)")
    if icesl.ANGLE not in textures:
        raise ConfigError(f"textures: no {icesl.ANGLE!r} field")
    ids = np.flatnonzero(~solid)
    if len(ids) == 0:
        raise ConfigError("printed_solid: every element is printed solid: nothing to compare")
    p = c[ids]
    settings = {k: icesl.FIELD_SCALE[k] * icesl.sample(t, box, p) for k, t in textures.items() if k != icesl.ANGLE}
    printed = constants_at(settings)
    out = {}
    for k in CONSTANT_NAMES:
        model = np.asarray(constants[k], dtype=float)[ids]
        got = np.asarray(printed[k], dtype=float)
        floor = NU_FLOOR if k.startswith("nu") else 1e-300
        out[k] = _compare(np.abs(got - model) / np.maximum(np.abs(model), floor), model, got, ids, c)
    ang_tex = textures[icesl.ANGLE]
    angle = icesl.FIELD_SCALE[icesl.ANGLE] * icesl.sample(ang_tex, box, p)
    fib = np.asarray(fibers, dtype=float)[ids]
    diff = axis_difference_deg(angle, fib)
    seam = icesl.FIELD_SCALE[icesl.ANGLE] * icesl.stencil_span(ang_tex, box, p) > angles.SEAM_JUMP
    fib_angle = np.mod(np.degrees(np.arctan2(fib[:, 1], fib[:, 0])), 180.0)
    ok = ~seam
    ang = _compare(diff[ok], fib_angle[ok], np.mod(angle[ok], 180.0), ids[ok], c)
    vol = np.ones(m) if volumes is None else np.abs(np.asarray(volumes, dtype=float))
    return ConsistencyReport(
        constants=out, angle=ang, compared=int(len(ids)), solid=int(solid.sum()), seam=int(seam.sum()),
        seam_angle_max=float(diff[seam].max()) if seam.any() else 0.0,
        seam_volume_fraction=float(vol[ids][seam].sum() / vol[ids].sum()),
        tolerance=float(tolerance), angle_tolerance_deg=float(angle_tolerance_deg),
    )


def against_uncertainty(reports: dict, rel_halfwidth: dict) -> dict:
    """Per constant: the round trip's largest relative difference over the sheets next to the
    homogenised constant's own 95 % relative half-width (``constants.json``'s ``ci95``).

    ``reports``: label -> :class:`ConsistencyReport`; ``rel_halfwidth``: name -> [-]. A
    difference below the half-width is smaller than what the foam's realisations can resolve.
    """
    out = {}
    for k, r in rel_halfwidth.items():
        diffs = [rep.constants[k].max for rep in reports.values() if k in rep.constants]
        if not diffs or r is None:
            continue
        d = float(max(diffs))
        out[k] = {"max_relative_difference": d, "rel_halfwidth_95": float(r), "below_uncertainty": bool(d <= r)}
    return out
