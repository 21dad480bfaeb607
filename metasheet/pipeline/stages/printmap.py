"""Stage ``printmap``: everything needed to print both sheets in IceSL, as modelled.

What is printed comes from a print source (:mod:`metasheet.pipeline.printsource`): the
modelled cell family (``infill = "auto"``: the cell stage's) and the map between its IceSL
settings and the five constants. Each element's constants (orient's, which the robot
uses) become IceSL settings through ``source.settings_for``; the fibre l becomes the
in-plane axis angle ``infill_angle`` (the k-gon's shrunk local x = the soft axis).

For each sheet (``normal/`` and ``mirrored/``): ``sheet.stl`` (the surface, world
coordinates in mm), ``solid.stl`` (the solid parts: centre ring r <= centre_radius and
the arm-end tip boxes, from sheet.json), one 64^3 field file per varying setting
(``infill_percentage.txt``, ``infill_angle.txt``, ``kgon_x_shrink.txt`` when graded;
scales in :mod:`metasheet.sheet.icesl`) and ``print.lua``, the IceSL script: brush 0 =
sheet minus solid parts, the foam (no perimeter, no shells, no cover); brush 1 = the
solid parts (100 % infill, ``solid_shells`` shells).

Plus ``printmap.json`` (boxes, scales, settings, the angle branch and its seam, the 8-bit
quantisation error of every field), ``print_consistency.json`` (the round trip of
:mod:`metasheet.sheet.consistency`: what the slicer reads back at each element against the
model) and ``printmap.png`` (mid-plane slices). The stage fails, writing nothing, when the
round trip is above ``tolerance`` / ``angle_tolerance_deg``.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field

from ...errors import ConfigError, InfeasibleError
from ...mechanics.material import CONSTANT_NAMES
from ...sheet import fibers as fb
from ...sheet import angles, icesl, icesl_lua
from ...sheet.consistency import against_uncertainty, round_trip
from ...sheet.geometry import tet_volumes
from ..artefacts import read_constants, read_orient
from ..manifest import write_json_atomic
from ..printsource import print_source
from ..registry import Params, Stage, StageContext, register

DEFAULT_SETTINGS = {"extruder_temp_degree_c_0": 230.0}
SHEETS = {"normal": False, "mirrored": True}  # output folder -> whether the sheet is the mirrored one


class PrintmapParams(Params):
    infill: Literal["auto", "polyfoam", "phasor"] = Field(
        "auto", description="IceSL infill family; auto = the cell stage's family (phasor: no modelled cell)")
    layer_thickness: float = Field(0.3, ge=0.05, le=1.0, description="z_layer_height_mm [mm]")
    settings: dict[str, float | int | bool | str] = Field(
        default_factory=lambda: dict(DEFAULT_SETTINGS),
        description="further IceSL settings, name -> value (not the foam's modelled settings)",
    )
    solid_shells: int = Field(10, ge=1, le=100, description="shells of the solid parts (brush 1)")
    tolerance: float = Field(0.02, gt=0, le=1, description="round trip: largest relative difference of a constant [-]")
    angle_tolerance_deg: float = Field(2.0, gt=0, le=90, description="round trip: largest axis angle difference [deg]")
    picture: bool = Field(True, description="write printmap.png (mid-plane slices of the fields)")
    uniform_as_value: bool = Field(True, description="write a setting equal over all the foam as an exact value "
                                   "instead of an 8-bit field (15 % as a field prints 38/255 = 14.9 %)")


def _stl_bytes(vertices: np.ndarray, faces: np.ndarray, name: str) -> bytes:
    """Binary STL with a fixed header (same mesh -> same bytes)."""
    tri = vertices[faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    rec = np.zeros(len(faces), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["n"], rec["v"] = n, tri
    header = f"metasheet {name} [mm]".encode()[:80].ljust(80, b" ")
    return header + np.uint32(len(faces)).tobytes() + rec.tobytes()


def _write_atomic(path: Path, data: bytes | str) -> None:
    """Write to a temporary name, then rename it into place."""
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    if isinstance(data, str):
        tmp.write_text(data)
    else:
        tmp.write_bytes(data)
    os.replace(tmp, path)


def _check_settings(p: PrintmapParams, modelled: set[str]) -> dict:
    settings = {"z_layer_height_mm": p.layer_thickness, **p.settings}
    clash = sorted(k for k in settings if k in modelled)
    if clash:
        raise ConfigError(f"printmap.settings: {clash}: set by the print model (the foam brush and its "
                          "modelled settings); remove them")
    return settings


def _field_settings(source, consts: dict, foam: np.ndarray, centroids: np.ndarray, label: str) -> dict:
    """The source's field settings per element; foam elements must lie in its valid range
    (an error naming the worst one), solid ones are clipped into it (they print solid)."""
    s = source.settings_for(consts)
    out = {}
    for name in source.field_names:
        v = np.asarray(s[name], dtype=float)
        lo, hi = source.valid_range.get(name, (0.0, icesl.FIELD_SCALE[name]))
        hi = min(hi, icesl.FIELD_SCALE[name])
        excess = np.where(foam, np.maximum(lo - v, v - hi), -np.inf)
        if np.any(excess > 1e-9 * max(abs(hi), 1.0)):
            e = int(np.argmax(excess))
            raise InfeasibleError(
                f"printmap: {label} sheet element {e} (centroid [{', '.join(f'{x:.2f}' for x in centroids[e])}] mm): "
                f"its constants need {name} = {v[e]:.4g} {icesl.FIELD_UNITS[name]}, outside the print model's "
                f"range [{lo:.4g}, {hi:.4g}] ({source.describe().get('model', 'model')} model); "
                "the design leaves what the modelled cell can print")
        out[name] = np.clip(v, lo, hi)
    return out


def _uniform_settings(sheets: dict) -> dict[str, float]:
    """Settings equal over every foam element of every sheet: {name: value}.

    ``sheets``: label -> (settings {name: (m,)}, foam mask (m,)). A uniform setting is written
    as a value, exactly, rather than as an 8-bit texture (15 % would print as 38/255 = 14.9 %).
    """
    out = {}
    names = set.intersection(*(set(s) for s, _ in sheets.values()))
    for name in sorted(names):
        v = np.concatenate([np.asarray(s[name], float)[foam] for s, foam in sheets.values()])
        if len(v) and np.ptp(v) <= 1e-9 * max(1.0, float(np.abs(v).max())):
            out[name] = float(np.round(np.median(v), 6))
    return out


def run(ctx: StageContext) -> dict:
    p: PrintmapParams = ctx.params
    source = print_source(ctx, p.infill)
    orient = read_orient(ctx.inputs["orient"])
    orient.sheets(need_constants=True)  # both sheets carry the five constants, else a clear error
    sp = orient.sheet_params
    per_sheet = {}
    for label, mirrored in SHEETS.items():
        sheet = orient.mirrored if mirrored else orient.normal
        centroids = sheet.mesh.centroids()
        consts = {k: np.asarray(sheet.cell_data[k], dtype=float) for k in CONSTANT_NAMES}
        solid_el = icesl.solid_mask(centroids, sp)
        per_sheet[label] = (sheet, centroids, consts, solid_el,
                            _field_settings(source, consts, ~solid_el, centroids, label))
    uniform = _uniform_settings({label: (v[4], ~v[3]) for label, v in per_sheet.items()}) if p.uniform_as_value \
        else {}
    fields = (*(k for k in source.field_names if k not in uniform), icesl.ANGLE)
    foam_values = {**icesl.FOAM_BRUSH, **source.fixed, **uniform}
    modelled = {f"infill_type_{icesl.FOAM}"} | {f"{k}_{icesl.FOAM}" for k in (*foam_values, *fields)}
    solid_values = {"infill_percentage": 100.0, "num_shells": p.solid_shells, "print_perimeter": True}
    modelled |= {f"{k}_{icesl.SOLID}" for k in solid_values}
    settings = _check_settings(p, modelled)
    files = {k: f"{k}.txt" for k in fields}
    solid_v, solid_f = icesl.solid_parts_mesh(sp)
    solid_stl = _stl_bytes(solid_v, solid_f, "solid parts (centre ring, arm-end tabs)")

    def constants_at(sampled: dict) -> dict:  # the uniform settings are printed exactly, as values
        n = np.shape(next(iter(sampled.values()))) if sampled else (1,)
        return source.constants_at({**{k: np.full(n, v) for k, v in uniform.items()}, **sampled})

    # everything is computed and checked first: a failing round trip writes nothing
    staged, summary, quant, consistency, slices = {}, {}, {}, {}, []
    failures = []
    for step, (label, (sheet, centroids, consts, solid_el, element)) in enumerate(per_sheet.items()):
        ctx.progress(f"sampling {label} sheet", step, len(SHEETS) + 1)
        mesh = sheet.mesh
        mirrored = SHEETS[label]
        pf = icesl.print_fields(
            mesh.points, mesh.tets, element_settings=element, params=sp,
            fiber_fn=lambda q, m=mirrored: orient.fibers_at(q, m),
        )
        texts = {k: icesl.field_text(pf.textures[k]) for k in fields}
        held = {k: icesl.quantise(icesl.parse_field_text(texts[k], pf.box.n)) for k in fields}
        quant[label] = {
            k: {"max_abs_error": float(np.max(np.abs(held[k] - pf.textures[k]))) * icesl.FIELD_SCALE[k],
                "units": icesl.FIELD_UNITS[k], "step": icesl.FIELD_SCALE[k] / icesl.LEVELS}
            for k in fields
        }
        rep = round_trip(
            box=pf.box, textures=held, constants_at=constants_at, centroids=centroids,
            constants=consts, fibers=sheet.fibers, printed_solid=solid_el,
            volumes=tet_volumes(mesh.points, mesh.tets),
            tolerance=p.tolerance, angle_tolerance_deg=p.angle_tolerance_deg,
        )
        consistency[label] = rep
        if not rep.ok:
            failures.append(rep.message(f"{label} sheet "))
        verts, faces = icesl.surface(mesh.points, mesh.tets)
        staged[label] = {
            "sheet.stl": _stl_bytes(verts, faces, f"{label} tripod sheet"),
            "solid.stl": solid_stl,
            **{files[k]: texts[k] for k in fields},
            "print.lua": icesl_lua.lua_script(
                sheet_stl="sheet.stl", solid_stl="solid.stl", infill_type=source.infill_type,
                foam=foam_values, fields=files, solid=solid_values, box=pf.box, settings=settings,
                title=f"metasheet print map, {label} tripod sheet ({source.family})",
            ),
        }
        angle_deg = pf.values(icesl.ANGLE)
        summary[label] = {
            "box_lo_mm": pf.box.lo.tolist(), "box_hi_mm": pf.box.hi.tolist(),
            "inside_fraction": float(pf.inside.mean()), "foam_fraction": float(pf.foam.mean()),
            "n_triangles": int(len(faces)), "elements_solid": int(solid_el.sum()),
            "field_range": {k: [float(pf.values(k)[pf.foam].min()), float(pf.values(k)[pf.foam].max())]
                            for k in source.field_names},
            "angle_branch": pf.branch.to_dict(),
            "angle_seam": angles.seam_report(angle_deg, pf.foam, pf.box),
        }
        mid = pf.box.n // 2
        ax = pf.box.axes()
        extent = (ax[0][0], ax[0][-1], ax[1][0], ax[1][-1])
        shown = {k: pf.values(k)[:, :, mid] for k in source.field_names}
        shown["axis angle"] = np.mod(angle_deg[:, :, mid], 180.0)
        slices.append((label, shown, pf.inside[:, :, mid], pf.solid[:, :, mid] & pf.inside[:, :, mid], extent))
    if failures:
        raise InfeasibleError("printmap: the print does not match the model (round trip of the quantised "
                              "fields through the print source): " + "; ".join(failures))

    ctx.progress("writing", len(SHEETS), len(SHEETS) + 1)
    for label, out_files in staged.items():
        out = ctx.path(label)
        out.mkdir(parents=True, exist_ok=True)
        for name, data in out_files.items():
            _write_atomic(out / name, data)
    write_json_atomic(ctx.path("print_consistency.json"), {
        "method": "fields sampled at each element centroid by trilinear interpolation of the quantised "
                  "(8-bit) textures, mapped through the print source's constants_at, compared with orient's "
                  "per-element constants and fibre; elements printed solid are skipped",
        **{label: rep.to_dict() for label, rep in consistency.items()},
        "ok": all(r.ok for r in consistency.values()),
        **_uncertainty(ctx, consistency),
    })
    info_out = {
        "infill": source.family, "infill_type": source.infill_type, "source": source.describe(),
        "grid": [icesl.N] * 3,
        "brushes": {
            str(icesl.FOAM): {"role": "foam: difference(sheet.stl, solid.stl)",
                              "settings": {f"{k}_{icesl.FOAM}": v for k, v in
                                           {"infill_type": source.infill_type, **foam_values}.items()},
                              "fields": {f"{k}_{icesl.FOAM}": files[k] for k in fields}},
            str(icesl.SOLID): {"role": "solid parts: intersection(sheet.stl, solid.stl)",
                               "regions": {"centre_ring_radius_mm": sp.centre_radius,
                                           "tip_box_mm": list(sp.tip_box), "reach_mm": sp.reach},
                               "settings": {f"{k}_{icesl.SOLID}": v for k, v in solid_values.items()}},
        },
        "scales": {
            "infill_percentage": "percent / 100", "kgon_x_shrink": "ratio",
            "infill_angle": "angle of the soft axis l in the print plane / 360 deg, written on the branch "
                            "'angle_branch' (offset + mod(theta + flip - offset, period)); only the angle "
                            "modulo 180 deg matters",
            "outside": "nearest inside texel",
        },
        "quantisation": {"rule": "tex3d_r8f holds round(255 v) / 255; error = |held - intended| over all "
                                 "texels, in IceSL units", **quant},
        "sheets": summary,
        "print_settings": settings,
        "consistency": {label: {"ok": r.ok, "elements_compared": r.compared, "elements_at_seam": r.seam}
                        for label, r in consistency.items()},
    }
    write_json_atomic(ctx.path("printmap.json"), info_out)
    if p.picture:
        ctx.progress("picture", len(SHEETS), len(SHEETS) + 1)
        from ...viz.sheet import printmap_picture

        _write_atomic(ctx.path("printmap.png"), printmap_picture(slices, values=uniform))
    return {
        "infill": source.family,
        **{f"{k}_{name}_range": v["field_range"][name] for k, v in summary.items() for name in source.field_names},
        **{f"{k}_max_rel_difference": max(c.max for c in r.constants.values()) for k, r in consistency.items()},
        **{f"{k}_max_axis_difference_deg": r.angle.max for k, r in consistency.items()},
    }


def _uncertainty(ctx: StageContext, consistency: dict) -> dict:
    """``against_uncertainty`` when the homogenised constants carry 95 % half-widths, else {}."""
    if "homogenize" not in ctx.inputs:
        return {}
    ci = read_constants(ctx.inputs["homogenize"]).get("ci95")
    if not ci:
        return {}
    return {"against_uncertainty": {
        "note": "each constant's largest round-trip difference against the homogenised constant's own 95 % "
                f"relative half-width ({ci['k']} realisations of {ci['n_cells']} cells): differences below it "
                "are smaller than the foam's realisations resolve",
        **against_uncertainty(consistency, ci["rel_halfwidth"])}}


register(
    Stage(
        name="printmap",
        params=PrintmapParams,
        run=run,
        requires=("orient",),
        optional=("cell", "homogenize", "chart"),
        outputs=("normal/print.lua", "normal/sheet.stl", "normal/solid.stl", "mirrored/print.lua",
                 "mirrored/sheet.stl", "mirrored/solid.stl", "printmap.json", "print_consistency.json"),
        doc="IceSL print maps (foam + solid brushes, 64^3 fields, Lua script) for both sheets, checked "
            "against the model -> normal/, mirrored/",
    )
)

