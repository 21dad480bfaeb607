"""Stage ``scalemap``: where the continuum holds, from the printed sheets' DNS (issue 63).

Over a grid of IceSL Polyfoam settings (``infill`` x ``shrink`` on the base ``design``: the
paper's bead, gauge, seeds and TPU) and sheet ``thickness``\\es, each foam's cell is homogenised
in bulk and as plates with free faces, and ``prints`` prints of the robot's two sheets (orient's
scene, outline and fibre field, re-meshed at each thickness) are solved as voxel DNS on their grips
(:mod:`metasheet.studies.scale_map`). ``scale_map.json`` holds, per foam and thickness, the
printed-over-continuum ratios (the 18 grip modes' geometric mean of each sheet, the rod roll per
motor degree, the singular values) for the bulk constants and the plate's moduli with 95 %
intervals over the prints, the cells through the thickness and across the arm, and the trend
``|log r| = a n^-b`` with the thickness (in cells) from which each continuum is within 10 % and
25 %; ``scale_map.csv`` one row per point; ``scale_map.png`` the map.

Every cell and every printed sheet is one executor unit, kept on disk as it finishes (a killed
or extended map resumes: a new foam or thickness computes only its own units).
"""

from __future__ import annotations

import itertools
from dataclasses import replace
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, model_validator
from threadpoolctl import threadpool_limits

from ...errors import ConfigError
from ..artefacts import read_orient
from ..manifest import write_bytes_atomic, write_json_atomic
from ..registry import Params, Stage, StageContext, register


class ScaleMapParams(Params):
    design: str = Field("cells/paper_polyfoam.toml", description="base Polyfoam design (bead, gauge, seeds, "
                        "material), relative to the project root; the map varies its infill and shrink")
    infill: list[float] = Field([15.0, 30.0, 50.0], min_length=1, max_length=12,
                                description="infill_percentage values of the grid [%], each in [1, 90]")
    shrink: list[float] = Field([0.2, 1.0], min_length=1, max_length=12,
                                description="kgon_x_shrink values of the grid [-], each in (0, 1]")
    thickness: list[float] = Field([2.5, 5.0], min_length=1, max_length=8,
                                   description="sheet thicknesses [mm], each in [0.5, 50]")
    prints: int = Field(3, ge=1, le=20, description="prints of each sheet (foam seeds seed, seed + 1, ...): the "
                        "error bars are their 95 % interval (>= 2 for an interval)")
    seed: int | None = Field(None, ge=0, description="first foam seed (None: the design's)")
    voxel_mm: float = Field(0.25, gt=0, le=2.0, description="voxel edge of the printed sheets [mm] (<= the bead)")
    cell_voxel_mm: float | None = Field(None, gt=0, le=2.0, description="voxel edge of the periodic cells [mm] "
                                        "(None: the design's)")
    slabs: int = Field(6, ge=2, le=64, description="slabs of each cell per thickness (the plate's realisations)")
    gauge: Literal["seed", "point"] = Field("seed", description="as sheet.gauge (docs/printed-sheet.md)")
    rtol: float = Field(1e-4, gt=0, lt=1e-3, description="CG tolerance of each grip column [-]: 1e-4 moves the "
                        "modes' geometric mean by 0.4 % from 1e-6 on the paper's print (docs/continuum-map.md)")
    max_voxels: int = Field(20_000_000, ge=1000, le=200_000_000, description="refuse larger voxel grids")
    length_scale: float = Field(50.0, gt=0, le=1e4, description="rotation -> length for singular values [mm/rad]")
    resume: bool = Field(True, description="keep finished units so an interrupted or extended map resumes")
    picture: bool = Field(True, description="write scale_map.png")

    @model_validator(mode="after")
    def _grid(self):
        for name, lo, hi, lo_open in (("infill", 1.0, 90.0, False), ("shrink", 0.0, 1.0, True),
                                      ("thickness", 0.5, 50.0, False)):
            v = getattr(self, name)
            bad = [x for x in v if not np.isfinite(x) or x > hi or (x <= lo if lo_open else x < lo)]
            if bad:
                raise ValueError(f"{name}: {bad[0]!r}: allowed range is {'(' if lo_open else '['}{lo:g}, {hi:g}]")
            if len(set(v)) != len(v):
                raise ValueError(f"{name}: {v!r}: values must differ")
        return self

    def check_files(self, table: str, params: dict, root: Path) -> None:
        """The base design is read, a Polyfoam, with a bead no thinner than ``voxel_mm``."""
        base_design(root, self)


def base_design(root: Path, p: ScaleMapParams) -> dict:
    """The base design's table; ConfigError naming scalemap.design (missing, not a Polyfoam,
    a bead thinner than a voxel)."""
    from ...studies.scale_map import foam_design
    from .cell import read_design_toml
    from .sheet import check_voxel

    path = (root / p.design).resolve()
    if not path.is_file():
        raise ConfigError(f"scalemap.design: {p.design!r}: no such file under {root}")
    data = read_design_toml(path, f"scalemap.design: {p.design!r}")
    d = foam_design(data, p.infill[0], p.shrink[0], p.cell_voxel_mm)
    check_voxel(p.voxel_mm, d.bead_width, "scalemap.voxel_mm")
    return data


def _scene(ctx: StageContext):
    from ._studies import DEFAULT_SCENE

    if "robot" in ctx.inputs:
        from ..artefacts import read_robot_scene

        return read_robot_scene(ctx.inputs["robot"])
    return DEFAULT_SCENE


def _model(ctx: StageContext) -> str:
    if "material" in ctx.inputs:
        from ..artefacts import read_material

        return read_material(ctx.inputs["material"]).model
    return "ours"


def _sheets_at(orient, sp):
    """The normal and mirrored sheet meshes at ``sp``, their fibres, and each one's angle field as
    the print map writes it (an 8-bit texture, :func:`metasheet.sheet.icesl.print_fields`)."""
    from ...sheet import icesl
    from ...sheet.geometry import mirror_sheet, tripod_sheet
    from ...sheet.printed_fields import TextureField

    normal = tripod_sheet(sp)
    mirrored = mirror_sheet(normal)
    fibres, angles = [], {}
    for label, mesh, m in (("normal", normal, False), ("mirrored", mirrored, True)):
        fibres.append(orient.fibers_at(mesh.centroids(), m))
        pf = icesl.print_fields(mesh.points, mesh.tets, element_settings={}, params=sp,
                                fiber_fn=lambda q, m=m: orient.fibers_at(q, m))
        angles[label] = TextureField(pf.box, icesl.quantise(pf.textures[icesl.ANGLE]), icesl.FIELD_SCALE[icesl.ANGLE])
    return normal, mirrored, fibres, angles


def _unit(u):
    """One unit of the map (picklable): a cell or a printed sheet."""
    from ...sheet.dns import dns_sheet
    from ...studies.scale_map import CellUnit, cell_point

    return cell_point(u) if isinstance(u, CellUnit) else dns_sheet(u)


def map_units(p: ScaleMapParams, data: dict, orient):
    """The map's work: (foams [(infill, shrink)], seeds, geometry {t: (SheetParams, normal,
    mirrored, fibres, angle textures)}, cell units, print units), the prints ordered foam,
    thickness, seed, sheet."""
    from ...sheet.dns import SheetPrint
    from ...sheet.printed_fields import FoamFields
    from ...studies.scale_map import CellUnit, foam_design

    foams = list(itertools.product(p.infill, p.shrink))
    seed0 = int(data.get("seeds", {}).get("seed", 0)) if p.seed is None else p.seed
    seeds = [seed0 + r for r in range(p.prints)]
    solid = foam_design(data, *foams[0]).material.material().stiffness()
    geometry = {}
    for t in p.thickness:
        sp = replace(orient.sheet_params, thickness=float(t))
        geometry[t] = (sp, *_sheets_at(orient, sp))
    cells = [CellUnit(data, i, s, tuple(p.thickness), p.slabs, p.cell_voxel_mm) for i, s in foams]
    prints = [SheetPrint(label, seed, p.gauge, p.voxel_mm, foam_design(data, i, s, seed=seed), geometry[t][0],
                         FoamFields(i, s, geometry[t][4][label]), solid, p.rtol, p.max_voxels)
              for i, s in foams for t in p.thickness for seed in seeds for label in ("normal", "mirrored")]
    return foams, seeds, geometry, cells, prints


def run(ctx: StageContext) -> dict:
    from ...published import paper
    from ...robot.builder import SheetPair, six_dof_robot
    from ...studies.resume import keep_only_used
    from ...studies.scale_map import bulk_material, map_point
    from ._studies import _cache_dir, unit_cache, write_csv

    p: ScaleMapParams = ctx.params
    data = base_design(ctx.root, p)
    orient = read_orient(ctx.inputs["orient"])
    scene, model = _scene(ctx), _model(ctx)
    ctx.progress("scalemap: sheets at each thickness", 0, 1)
    foams, seeds, geometry, cells, prints = map_units(p, data, orient)
    results = unit_cache(ctx).map(ctx.executor, _unit, cells + prints,
                                  progress=lambda d, n: ctx.progress("scalemap: cells and printed sheets", d, n))
    cell_of = dict(zip(foams, results[:len(cells)]))
    dns = results[len(cells):]
    for s, u in zip(dns, prints):  # manifest only: wall times differ run to run
        ctx.timings[f"dns_s.{u.design.infill_percentage:g}.{u.design.kgon_x_shrink:g}.{u.params.thickness:g}."
                    f"{u.label}.{u.seed}"] = round(s.build_s + s.solve_s, 3)
    points = []
    with threadpool_limits(limits=1, user_api="blas"):  # fixed-order sums: the same bytes on any thread count
        for ti, t in enumerate(p.thickness):
            sp, normal, mirrored, (fib, fib_m), _ = geometry[t]
            # the robot places the grips (servos, rod): its sheets' stiffness is not used here
            robot = six_dof_robot(SheetPair(normal, mirrored, fib, fib_m, element="p1"),
                                  bulk_material(cell_of[foams[0]]), rod_length=scene.rod_length,
                                  geometry=scene.servo_geometry(), density=paper.FOAM_DENSITY, model=model)
            pair = SheetPair(normal, mirrored, fib, fib_m, element=orient.element)
            for foam in foams:
                mine = [s for s, u in zip(dns, prints)
                        if (u.design.infill_percentage, u.design.kgon_x_shrink, u.params.thickness) == (*foam, t)]
                points.append(map_point(cell_of[foam], ti, mine, pair, robot, sp, model=model,
                                        length_scale=p.length_scale))
                ctx.progress("scalemap: comparisons", len(points), len(foams) * len(p.thickness))
    doc = document(p, data, seeds, model, scene, orient.element, points)
    write_json_atomic(ctx.path("scale_map.json"), doc)
    write_csv(ctx.path("scale_map.csv"), CSV_COLUMNS, [csv_row(q) for q in points])
    if p.picture:
        from ...viz.scale_map import scale_map_picture

        write_bytes_atomic(ctx.path("scale_map.png"), scale_map_picture(doc))
    if p.resume:  # an extended grid reuses these units: keep the ones this map used
        keep_only_used(_cache_dir(ctx))
    bulk = doc["trend"]["bulk"]
    return {"points": len(points), "prints": len(prints), "unknowns_max": max(s.n_dof for s in dns),
            "bulk_within_cells": bulk.get("n_within"), "verdict": doc["verdict"]}


#: scale_map.csv's columns: one row per foam and thickness; ratios printed over model (modes: geometric mean
#: and 95 % interval over the prints; rod roll: mean and 95 % half-width).
CSV_COLUMNS = ["infill", "shrink", "thickness_mm", "cell_x_mm", "cell_y_mm", "cell_z_mm", "cells_through",
               "cells_across", "bulk_modes", "bulk_modes_lo", "bulk_modes_hi", "bulk_rod_roll", "bulk_rod_roll_hw",
               "bulk_singular_values", "plate_membrane_modes", "plate_membrane_modes_lo", "plate_membrane_modes_hi",
               "plate_bending_modes", "plate_ratio_to_bulk"]


def csv_row(q: dict) -> list:
    s = q["summary"]

    def get(model, key, what="mean"):
        return s[model][key][what] if model in s else None

    pr = q["plate_ratio_to_bulk"]
    return [q["infill"], q["shrink"], q["thickness_mm"], *q["cell_mm"], q["cells_through"], q["cells_across"],
            get("bulk", "modes"), get("bulk", "modes", "lo"), get("bulk", "modes", "hi"), get("bulk", "rod_roll"),
            get("bulk", "rod_roll", "halfwidth"), get("bulk", "singular_values"), get("plate_membrane", "modes"),
            get("plate_membrane", "modes", "lo"), get("plate_membrane", "modes", "hi"),
            get("plate_bending", "modes"), pr["mean"] if isinstance(pr, dict) else None]


def document(p: ScaleMapParams, data: dict, seeds: list[int], model: str, scene, element: str,
             points: list[dict]) -> dict:
    """``scale_map.json``: the settings, the points, the trends and the verdict line."""
    from ...studies.scale_map import BANDS, trends, verdict

    tr = trends(points)
    return {"method": "per foam: the periodic cell homogenised in bulk and as plates with free faces (slabs of each "
                      "thickness); per print: the robot's two sheets printed with the foam (the print map's fields), "
                      "voxel DNS on the four grips; printed over continuum on the grips (metasheet.studies.scale_map)",
            "units": {"lengths": "mm", "ratios": "printed over model (1: the model is the print)",
                      "modes": "geometric mean of both sheets' 36 grip-mode stiffness ratios, mean and 95 % interval "
                               "over the prints", "cells_through": "thickness over one cell's height",
                      "cells_across": "arm width over one cell's larger in-plane extent"},
            "design": {"file": p.design, "name": data.get("name"), "bead_width": data.get("bead_width"),
                       "material": data.get("material")},
            "grid": {"infill": p.infill, "shrink": p.shrink, "thickness_mm": p.thickness},
            "prints": {"seeds": seeds, "voxel_mm": p.voxel_mm, "gauge": p.gauge, "rtol": p.rtol},
            "cell_voxel_mm": p.cell_voxel_mm, "slabs": p.slabs, "model": model, "element": element,
            "scene": {"rod_length_mm": scene.rod_length}, "bands": list(BANDS),
            "points": points, "trend": tr, "verdict": verdict(points, tr)}


register(
    Stage(
        name="scalemap",
        params=ScaleMapParams,
        run=run,
        requires=("orient",), optional=("robot", "material"),
        outputs=("scale_map.json", "scale_map.csv"),
        doc="where the continuum holds: printed sheets' DNS over foams and thicknesses against the bulk and plate "
            "continua, the trend against cells through the thickness -> scale_map.json, .csv, .png",
    )
)
