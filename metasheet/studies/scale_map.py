"""Where the continuum holds: the printed sheets' DNS over foams and thicknesses (issue 63).

For each foam of a grid (IceSL Polyfoam settings ``infill_percentage`` x ``kgon_x_shrink`` on a
base design: its bead, gauge, seeds and material) and each sheet thickness:

- the **cell** (:func:`cell_point`, one executor unit per foam): the periodic cell built and
  homogenised in bulk (the continuum the robot's sheets use today), and cut into slabs of each
  thickness homogenised as plates with free faces (:mod:`metasheet.homogenize.plate_slabs`);
- the **prints** (one unit per print, sheet and thickness: :func:`metasheet.sheet.dns.dns_sheet`):
  the robot's two tripod sheets printed with the foam (the print map's fields as IceSL reads them:
  uniform infill and shrink, the fibre field's angle as an 8-bit texture) at seeds ``seed``,
  ``seed + 1``, ..., each a voxel DNS condensed on its four grips;
- the **comparison** (:func:`map_point`): printed over continuum on the robot's grips, for the
  bulk constants and the plate's membrane and bending moduli
  (:func:`metasheet.studies.sheet_dns.dns_study`, :func:`metasheet.studies.sheet_plate.plate_comparison`):
  the geometric mean of each sheet's 18 grip modes, the rod roll per motor degree and the
  singular values, with a 95 % Student interval over the prints.

:func:`fit_trend` fits the furthest ratio's distance from 1 against the cells through the
thickness, ``|log r| = a n^-b``, and states the thickness (in cells) from which the continuum is
within 10 % and 25 %. Lengths in mm, moduli in MPa.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, InfeasibleError
from ..homogenize.ensemble import t_quantile

#: Within these fractions of the printed sheet the continuum "holds" (the issue's two bands).
BANDS = (0.10, 0.25)
#: A print whose softest grip mode is below this fraction of the continuum's has fallen apart
#: (its grips hold separate pieces of wall): it has no stiffness ratio to fit.
APART = 1e-6


@dataclass(frozen=True)
class CellUnit:
    """One foam of the map (picklable): the base design mapping with ``infill`` [%] and
    ``shrink`` [-] set, homogenised in bulk and cut into slabs of each of ``thicknesses`` [mm]."""

    design: Mapping
    infill: float
    shrink: float
    thicknesses: tuple[float, ...]
    slabs: int
    voxel_mm: float | None = None


@dataclass(frozen=True)
class CellPoint:
    """A foam's cell: ``size`` (3,) box [mm]; ``cell_mm`` (3,) one cell's extent (the box over the
    cube root of its seed count) [mm]; ``solid_fraction`` [-]; ``C`` (6, 6) bulk stiffness
    [MPa]; ``constants``: its transverse-isotropic fit (``CONSTANT_NAMES``); ``plates``: per
    thickness the slab study's ``to_dict()`` (plate.json's form), or the reason it has none."""

    infill: float
    shrink: float
    size: tuple[float, float, float]
    cell_mm: tuple[float, float, float]
    solid_fraction: float
    C: tuple
    constants: dict
    plates: tuple


def foam_design(data: Mapping, infill: float, shrink: float, voxel_mm: float | None = None, seed: int | None = None):
    """The :class:`~metasheet.cells.polyfoam.PolyfoamDesign` of the base ``data`` at one grid point."""
    from ..cells.catalogue import parse_design

    if data.get("kind", "foam") != "polyfoam":
        raise ConfigError(f"scalemap.design: kind {data.get('kind', 'foam')!r}: the map sweeps IceSL Polyfoam "
                          "settings: give a polyfoam design (e.g. cells/paper_polyfoam.toml)")
    return parse_design(data, overrides={"infill_percentage": infill, "kgon_x_shrink": shrink, "voxel_mm": voxel_mm,
                                         "seed": seed}, source="scalemap.design")


def cell_point(u: CellUnit) -> CellPoint:
    """Build and homogenise one foam's cell, in bulk and as slabs (an executor unit)."""
    from ..cells.catalogue import design_cell
    from ..homogenize import homogenize_voxels
    from ..homogenize.plate_slabs import slab_study

    design = foam_design(u.design, u.infill, u.shrink, u.voxel_mm)
    cell = design_cell(design)
    r = homogenize_voxels(cell.phases, cell.size, cell.materials, axis=cell.axis_vector, localise=False)
    plates = []
    for t in u.thicknesses:
        try:
            plates.append(slab_study(cell.phases, cell.size, cell.materials, t, r.C, slabs=u.slabs).to_dict())
        except InfeasibleError as exc:  # a slab that falls apart in plane: a result of the map
            plates.append(f"no plate: {exc}")
    size = np.asarray(cell.size, float)
    per = size / float(design.seeds.count) ** (1.0 / 3.0)
    return CellPoint(float(u.infill), float(u.shrink), tuple(size.tolist()), tuple(per.tolist()),
                     float(r.relative_density), tuple(map(tuple, np.asarray(r.C).tolist())), r.material.to_dict(),
                     tuple(plates))


def bulk_material(cell: CellPoint):
    """The cell's bulk constants as a :class:`~metasheet.mechanics.material.TransverseIsotropic`."""
    from ..mechanics.material import CONSTANT_NAMES, TransverseIsotropic

    return TransverseIsotropic(**{k: cell.constants[k] for k in CONSTANT_NAMES})


def cell_stiffness(C, fibres) -> np.ndarray:
    """(m, 6, 6) the cell's whole bulk stiffness ``C`` (6, 6) [MPa] (cell frame: x the Polyfoam's
    shrunk axis, z the build axis) in each element of a sheet whose foam's x follows ``fibres``
    (m, 3) in the plane (IceSL turns the k-gon about the build axis, the sheet's normal): not the
    transverse-isotropic fit, which ties the through-thickness modulus to an in-plane one."""
    from ..mechanics.voigt import rotate_stiffness

    f = np.asarray(fibres, float).copy()
    f[:, 2] = 0.0
    f /= np.linalg.norm(f, axis=1, keepdims=True)
    z = np.broadcast_to([0.0, 0.0, 1.0], f.shape)
    return rotate_stiffness(np.asarray(C, float), np.stack([f, np.cross(z, f), z], axis=2))


def interval(values) -> dict:
    """Mean, standard deviation and 95 % Student half-width of ``values`` (k,) (None for k < 2)."""
    v = np.asarray(values, float)
    k = len(v)
    if k < 2:
        return {"mean": float(v.mean()), "std": None, "halfwidth": None, "k": k}
    s = float(v.std(ddof=1))
    return {"mean": float(v.mean()), "std": s, "halfwidth": float(t_quantile(k, 0.95) * s / math.sqrt(k)), "k": k}


def log_interval(values) -> dict:
    """For positive ratios (k,): the geometric mean and its 95 % Student interval on the log scale
    (``lo``, ``hi``; None for k < 2) and the half-width of the log."""
    v = np.asarray(values, float)
    if np.any(v <= 0):
        raise ConfigError(f"ratios {v.tolist()}: a stiffness ratio must be positive")
    s = interval(np.log(v))
    m, hw = s["mean"], s["halfwidth"]
    return {"mean": math.exp(m), "lo": math.exp(m - hw) if hw is not None else None,
            "hi": math.exp(m + hw) if hw is not None else None, "halfwidth_log": hw, "k": s["k"]}


def _both(row: Mapping) -> float:
    """The print's geometric mean over both sheets' 36 modes."""
    return math.sqrt(float(row["geometric_mean_ratio_normal"]) * float(row["geometric_mean_ratio_mirrored"]))


def _robot_summary(study: Mapping) -> dict:
    rows = study["realisations"]
    return {"modes": log_interval([math.sqrt(r["sheets"]["normal"]["geometric_mean_ratio"]
                                             * r["sheets"]["mirrored"]["geometric_mean_ratio"]) for r in rows]),
            "rod_roll": interval([r["robot"]["rod_roll_ratio"] for r in rows]),
            "singular_values": log_interval([float(np.exp(np.mean(np.log(r["robot"]["singular_value_ratios"]))))
                                             for r in rows])}


def summary(study: Mapping, plate: Mapping | None, fit: Mapping | None = None) -> dict:
    """Per model (``bulk``: the cell's whole C; ``bulk_fit``: its transverse-isotropic fit, the
    robot's constants; ``plate_membrane``, ``plate_bending``): printed over model over the prints: ``modes`` (geometric mean of both sheets' 36 grip modes) and ``singular_values``
    (their geometric mean) as :func:`log_interval`, ``rod_roll`` (rod roll per motor degree, which
    may change sign on a sheet that barely rolls) as :func:`interval`."""
    out = {"bulk": _robot_summary(study), **({"bulk_fit": _robot_summary(fit)} if fit is not None else {})}
    for variant in ("membrane", "bending"):
        if plate and variant in plate:
            pr = plate[variant]["realisations"]
            out[f"plate_{variant}"] = {"modes": log_interval([_both(r) for r in pr]),
                                       "rod_roll": interval([r["rod_roll_ratio"] for r in pr])}
    return out


def map_point(cell: CellPoint, thickness_index: int, sheets: Sequence, pair, robot, params, *, model: str,
              length_scale: float) -> dict:
    """One (foam, thickness) of the map: the prints ``sheets`` (normal and mirrored
    :class:`~metasheet.sheet.dns.DnsSheet` of each seed) against the robot's sheets ``pair``
    (meshed at this thickness) made of the cell's whole bulk C (:func:`cell_stiffness`), of its
    transverse-isotropic fit (the robot's constants) and of the plate's moduli. A print whose
    grips hold separate pieces (:data:`APART`) is named and has no ratios."""
    from ..robot.builder import SheetPair
    from ..sheet.grips import fem_condensed
    from .sheet_dns import _pairs, dns_study, homogenised_grips
    from .sheet_plate import plate_comparison

    bulk = bulk_material(cell)
    row = np.array(bulk.as_tuple(), float)
    built = SheetPair(pair.sheet, pair.mirrored, pair.fibers, pair.fibers_mirrored,
                      np.tile(row, (len(pair.sheet.tets), 1)), np.tile(row, (len(pair.mirrored.tets), 1)),
                      pair.element)
    full = tuple(fem_condensed(mesh, cell_stiffness(cell.C, fib), pair.element).K
                 for mesh, fib in ((pair.sheet, pair.fibers), (pair.mirrored, pair.fibers_mirrored)))
    study = dns_study(sheets, full, robot, params, length_scale=length_scale)
    fit = dns_study(sheets, homogenised_grips(built, model), robot, params, length_scale=length_scale)
    t = float(params.thickness)
    head = {"infill": cell.infill, "shrink": cell.shrink, "thickness_mm": t, "cell_mm": list(cell.cell_mm),
            "solid_fraction": cell.solid_fraction, "cells_through": t / cell.cell_mm[2],
            "cells_across": float(params.arm_width) / max(cell.cell_mm[:2]), "bulk_constants": dict(cell.constants)}
    apart = [r["seed"] for r in study["realisations"]
             if min(min(s["eigen_ratios"]) for s in r["sheets"].values()) < APART]
    if apart:
        return {**head, "falls_apart": apart, "summary": {}, "plate_ratio_to_bulk": None}
    plate_doc = cell.plates[thickness_index]
    plate = None
    if isinstance(plate_doc, Mapping):
        plate = plate_comparison(built, model, bulk, plate_doc, _pairs(sheets),
                                 [r["robot"]["rod_rotation_deg_per_deg"] for r in study["realisations"]], robot,
                                 params, length_scale=length_scale)
    return {**head, "summary": summary(study, plate, fit),
            "homogenised_robot_fit": fit["homogenised_robot"],
            "plate_ratio_to_bulk": (plate_doc["ratio_to_bulk"]["geometric_mean"] if plate is not None else plate_doc),
            "homogenised_robot": study["homogenised_robot"], "spread": study["spread"], "verdict": study["verdict"],
            "prints": [{"seed": r["seed"], "sheets": {lab: {k: s[k] for k in ("geometric_mean_ratio", "log_ratio_rms",
                                                                              "n_dof", "kept_share", "iterations")}
                                                      for lab, s in r["sheets"].items()},
                        "rod_roll_ratio": r["robot"]["rod_roll_ratio"],
                        "singular_value_ratios": r["robot"]["singular_value_ratios"]} for r in study["realisations"]],
            **({"plate": {v: {"constants": plate[v]["constants"], "spread": plate[v]["spread"]}
                          for v in ("membrane", "bending")}} if plate is not None else {})}


@dataclass(frozen=True)
class Trend:
    """``|log r| = a n^-b`` fitted over the map's points (n cells through the thickness, r the
    printed-over-model ratio); ``n_within``: band -> the n from which the fit is within it
    (None when b <= 0: no approach to 1); ``scatter``: rms of the fit's log residual; ``points``."""

    a: float
    b: float
    scatter: float
    points: int
    n_within: dict

    def to_dict(self) -> dict:
        return {"law": "|log r| = a n^-b", "a": self.a, "b": self.b, "scatter_log": self.scatter,
                "points": self.points, "n_within": {f"{band:.0%}": n for band, n in self.n_within.items()}}


def fit_trend(n, ratio, bands: Sequence[float] = BANDS) -> Trend:
    """Least squares of ``log |log r|`` on ``log n`` over the points with ``r != 1`` (>= 2 of
    them, at two different n at least); raises ConfigError otherwise."""
    n, r = np.asarray(n, float), np.asarray(ratio, float)
    if n.shape != r.shape or n.ndim != 1:
        raise ConfigError(f"fit_trend: n {n.shape} and ratio {r.shape}: expected two (k,) arrays")
    if np.any(n <= 0) or np.any(r <= 0) or not np.all(np.isfinite(n) & np.isfinite(r)):
        raise ConfigError("fit_trend: n and ratio must be finite and positive")
    keep = np.abs(np.log(r)) > 1e-12
    x, y = np.log(n[keep]), np.log(np.abs(np.log(r[keep])))
    if len(x) < 2 or np.ptp(x) == 0:
        raise ConfigError(f"fit_trend: {len(x)} point(s) at {len(set(x.tolist()))} thickness(es) in cells: "
                          "need two at different cells through the thickness")
    slope, icpt = np.polyfit(x, y, 1)
    a, b = float(np.exp(icpt)), float(-slope)
    res = y - (icpt + slope * x)
    within = {band: (float((a / math.log1p(band)) ** (1.0 / b)) if b > 0 else None) for band in bands}
    return Trend(a, b, float(np.sqrt(np.mean(res ** 2))), int(len(x)), within)


def trends(points: Sequence[Mapping]) -> dict:
    """Per model, the :func:`fit_trend` of its mode ratio (mean over prints) against the cells
    through the thickness, or the reason there is none."""
    out = {}
    for model in ("bulk", "bulk_fit", "plate_membrane", "plate_bending"):
        pts = [p for p in points if model in p["summary"]]
        try:
            out[model] = fit_trend([p["cells_through"] for p in pts],
                                   [p["summary"][model]["modes"]["mean"] for p in pts]).to_dict()
        except ConfigError as exc:
            out[model] = {"none": str(exc)}
    return out


def _within(r: float, band: float) -> bool:
    return abs(math.log(r)) <= math.log1p(band)


def verdict(points: Sequence[Mapping], trend: Mapping) -> str:
    """One line: from how many cells through the sheet the bulk continuum is within each band
    (the fit), and on the grid how many points each continuum brings within 10 % / 25 %."""
    k = len(points)
    parts = []
    b = trend.get("bulk", {})
    if "n_within" in b and all(v is not None for v in b["n_within"].values()):
        w = b["n_within"]
        parts.append(f"the bulk continuum is within 10 % of the prints from {w['10%']:.2g} cells through the sheet "
                     f"and within 25 % from {w['25%']:.2g} (|log r| = {b['a']:.2g} n^-{b['b']:.2f}, {b['points']} "
                     "points)")
    for model, name in (("bulk", "bulk"), ("bulk_fit", "the robot's constants (bulk, transverse-isotropic fit)"),
                        ("plate_membrane", "plate (membrane)")):
        rs = [p["summary"][model]["modes"]["mean"] for p in points if model in p["summary"]]
        if rs:
            parts.append(f"{name}: {sum(_within(r, BANDS[0]) for r in rs)} / {sum(_within(r, BANDS[1]) for r in rs)}"
                         f" of {len(rs)} within 10 / 25 %")
    apart = [p for p in points if p.get("falls_apart")]
    if apart:
        parts.append(f"{len(apart)} print(s) fall apart (" + ", ".join(
            f"infill {p['infill']:g} %, shrink {p['shrink']:g}, {p['thickness_mm']:g} mm" for p in apart) + ")")
    whole = [p for p in points if "bulk" in p["summary"]]
    worst = min(whole, key=lambda p: p["summary"]["bulk"]["modes"]["mean"]) if whole else None
    if worst is not None:
        parts.append(f"softest print against the bulk: {worst['summary']['bulk']['modes']['mean']:.2f} x (infill "
                     f"{worst['infill']:g} %, shrink {worst['shrink']:g}, {worst['thickness_mm']:g} mm, "
                     f"{worst['cells_through']:.2f} cells through)")
    return f"{k} points: " + "; ".join(parts)
