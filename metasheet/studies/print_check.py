"""Does the printed design do what its model says? The chosen fibre field printed and solved (issue 63).

The design stage chooses a fibre field on a continuum (its material stage's constants); the
printed sheet is foam whose cells may be as large as the sheet is thick, where no continuum
holds (docs/continuum-map.md). This module prints a design's field (the print map's angle
texture over the foam of a Polyfoam design, :func:`design_prints`), solves both sheets as voxel
DNS on the robot's grips (:func:`metasheet.sheet.dns.dns_sheet`, through an executor) and
compares the printed robot's rod roll per motor degree with the design model's on the same grips
(:func:`compare_roll`): "meets" within :data:`ROLL_TOLERANCE`, else by how much it misses.
Lengths in mm, angles in deg.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import numpy as np

#: The chosen design's rod roll per degree, printed, within this fraction of its model's: "meets".
ROLL_TOLERANCE = 0.15


def design_fibres(design: Mapping, spiral_kw: Mapping) -> Callable[[np.ndarray, bool], np.ndarray]:
    """``(points (q, 3) [mm], mirrored) -> (q, 3)`` unit fibres of a design stage's design
    (``{"pitch_deg", "basis", "coefficients_rad"}``): the spiral of that pitch (``spiral_kw``: law,
    r_ref) and, with a basis, its free-form correction (:func:`metasheet.sheet.fibre_field.field_at`)."""
    from ..sheet.fibers import spiral_fibers
    from ..sheet.fibre_field import PolarBSpline, field_at

    kw = {**spiral_kw, "pitch_deg": float(design["pitch_deg"])}
    if not design.get("basis"):
        return lambda q, mirrored=False: spiral_fibers(q, mirrored=mirrored, **kw)
    basis, c = PolarBSpline(**design["basis"]), np.asarray(design["coefficients_rad"], float)
    return lambda q, mirrored=False: field_at(q, lambda x: spiral_fibers(x, mirrored=False, **kw), basis, c, mirrored)


def design_prints(fibres, pair, params, foam_design, *, seeds: Sequence[int], voxel_mm: float, gauge: str,
                  rtol: float, max_voxels: int) -> list:
    """The :class:`~metasheet.sheet.dns.SheetPrint` of both sheets of ``pair`` (meshes) printed
    with ``fibres`` (:func:`design_fibres`) in the foam of ``foam_design`` (a
    :class:`~metasheet.cells.polyfoam.PolyfoamDesign`: its infill and shrink, uniform), one
    pair per seed: the print map's fields as IceSL reads them (the angle an 8-bit texture)."""
    from ..sheet import icesl
    from ..sheet.dns import SheetPrint
    from ..sheet.printed_fields import FoamFields, TextureField

    fields = {}
    for label, mesh, m in (("normal", pair.sheet, False), ("mirrored", pair.mirrored, True)):
        pf = icesl.print_fields(mesh.points, mesh.tets, element_settings={}, params=params,
                                fiber_fn=lambda q, m=m: fibres(q, m))
        angle = TextureField(pf.box, icesl.quantise(pf.textures[icesl.ANGLE]), icesl.FIELD_SCALE[icesl.ANGLE])
        fields[label] = FoamFields(foam_design.infill_percentage, foam_design.kgon_x_shrink, angle)
    solid = foam_design.material.material().stiffness()
    return [SheetPrint(label, int(s), gauge, voxel_mm, foam_design, params, fields[label], solid, rtol, max_voxels)
            for s in seeds for label in ("normal", "mirrored")]


def model_grips(pair, fibres, material, model: str):
    """(K_A, K_B) (24, 24): the design's continuum sheets (``pair``'s meshes and element, the fibres
    of ``fibres`` at their centroids, ``material`` everywhere) condensed on their grips."""
    from ..robot.builder import SheetPair
    from .sheet_dns import homogenised_grips

    fa, fb = fibres(pair.sheet.centroids(), False), fibres(pair.mirrored.centroids(), True)
    row = np.array(material.as_tuple(), float)
    built = SheetPair(pair.sheet, pair.mirrored, fa, fb, np.tile(row, (len(pair.sheet.tets), 1)),
                      np.tile(row, (len(pair.mirrored.tets), 1)), pair.element)
    return homogenised_grips(built, model)


def compare_roll(model_K, printed: Sequence, robot, params, *, length_scale: float) -> dict:
    """The design's model (``model_K``: (K_A, K_B)) against its prints (``printed``: the
    :class:`~metasheet.sheet.dns.DnsSheet` of both sheets, per seed): each one's rod roll per
    motor degree and singular values (linear rest model, :mod:`metasheet.robot.condensed`), the
    printed-over-model roll per print and the verdict."""
    from ..robot.condensed import rest_numbers_condensed
    from ..sheet.grips import grip_references
    from .sheet_dns import _pairs

    refs = grip_references(params)
    m = rest_numbers_condensed(*model_K, robot, refs, length_scale=length_scale)
    rows = []
    for a, b in _pairs(printed):
        d = rest_numbers_condensed(a.K, b.K, robot, refs, length_scale=length_scale)
        rows.append({"seed": a.seed, "rod_rotation_deg_per_deg": d["rod_rotation_deg_per_deg"],
                     "singular_values": d["singular_values"],
                     "roll_ratio": d["rod_rotation_deg_per_deg"] / m["rod_rotation_deg_per_deg"]})
    ratios = np.array([r["roll_ratio"] for r in rows])
    worst = float(ratios[np.argmax(np.abs(ratios - 1.0))])
    meets = bool(np.all(np.abs(ratios - 1.0) <= ROLL_TOLERANCE))
    return {"model": m, "prints": rows, "roll_ratio": {"mean": float(ratios.mean()), "min": float(ratios.min()),
                                                       "max": float(ratios.max())},
            "meets": meets, "misses_by": 0.0 if meets else abs(worst - 1.0)}


def verdict(chosen: Mapping, spiral: Mapping | None = None) -> str:
    """One line on the chosen design's print against its model (and the spiral's, when checked)."""
    r = chosen["roll_ratio"]
    n = len(chosen["prints"])
    span = f"{r['min']:.2f}" if n == 1 else f"{r['min']:.2f} to {r['max']:.2f}"
    head = (f"the chosen design printed rolls the rod by {span} x its model's {chosen['model']['rod_rotation_deg_per_deg']:+.3f}"
            f" deg/deg over {n} print{'s' if n > 1 else ''}: ")
    head += (f"meets the model within {ROLL_TOLERANCE:.0%}" if chosen["meets"] else
             f"misses the model by {chosen['misses_by']:.0%} (beyond {ROLL_TOLERANCE:.0%})")
    if spiral is not None:
        gain_model = abs(chosen["model"]["rod_rotation_deg_per_deg"] / spiral["model"]["rod_rotation_deg_per_deg"])
        gain_print = abs(np.mean([p["rod_rotation_deg_per_deg"] for p in chosen["prints"]])
                         / np.mean([p["rod_rotation_deg_per_deg"] for p in spiral["prints"]]))
        head += f"; its gain over the spiral: {gain_model:.2f} x in the model, {gain_print:.2f} x printed"
    return head
