"""Stage ``sheet``: the printed sheet simulated voxel by voxel, against the homogenised sheet (issue 44).

For each realisation (foam seed) both print maps (``printmap``'s normal and mirrored sheets,
their fields as IceSL reads them) are built as printed Polyfoam (:mod:`metasheet.sheet.printed_foam`,
the cell stage's design) and solved as a voxel DNS with the robot's four grips rigid
(:mod:`metasheet.sheet.dns`): each sheet's 24 x 24 grip stiffness. The robot's homogenised
sheets (orient's mesh, element, fibres and constants under the material's model) are condensed
the same way. ``sheet_dns.json`` holds, per realisation, both sheets' eigen-ratios and
compliances, the printed robot's rest Jacobian singular values and rod roll per motor degree
beside the homogenised robot's (linear rest model, :mod:`metasheet.robot.condensed`), the
apparent constants (``fit``) and the spread over realisations, with a verdict line; also the
voxel file of realisation 0's normal sheet (``sheet_normal.npz``) and the pictures.

Each sheet of each realisation is one executor unit. The resolution, the unknowns, the CG
iterations, the kept share of the solid and the times are recorded per sheet.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Literal

from pydantic import Field
from threadpoolctl import threadpool_limits

from ...errors import ConfigError
from ..artefacts import read_cell_design, read_material, read_orient, read_robot_scene
from ..manifest import write_json_atomic
from ..registry import Params, Stage, StageContext, register

LABELS = ("normal", "mirrored")


class SheetDnsParams(Params):
    voxel_mm: float = Field(0.25, gt=0, le=2.0, description="voxel edge of the printed foam [mm] (<= the bead width); "
                            "0.25 puts 1.6 voxels on the paper's 0.4 mm bead: within 1 % of 0.2 mm in the modes' "
                            "geometric mean, the rod roll and five of the six singular values, 10 % in the softest "
                            "mode; 0.3 mm (1.33 voxels: thin joints) is 12 to 24 % softer (docs/printed-sheet.md)")
    gauge: Literal["seed", "point"] = Field("seed", description="how the varying angle and shrink enter the "
                                            "polyhedral distance (docs/printed-sheet.md, assumption 4)")
    realisations: int = Field(1, ge=1, le=20, description="foam seeds per sheet (seed, seed + 1, ...): their "
                              "spread is what two prints of one design differ by")
    seed: int | None = Field(None, ge=0, description="first foam seed (None: the cell design's)")
    rtol: float = Field(1e-6, gt=0, lt=1e-3, description="CG tolerance of each grip column [-]")
    fit: bool = Field(True, description="fit the apparent constants of each realisation (both sheets at once)")
    max_voxels: int = Field(20_000_000, ge=1000, le=200_000_000, description="refuse larger voxel grids")
    length_scale: float = Field(50.0, gt=0, le=1e4, description="rotation -> length for singular values [mm/rad]")
    picture: bool = Field(True, description="write sheet_dns.png and printed_sheet.png")
    walls: bool = Field(False, description="keep each print's displacement fields on its walls (walls/, about 80 MB "
                        "a sheet at 0.25 mm) for the printed stage's walls' limits, which then skip their own DNS")

    def check_files(self, table: str, params: dict, root: Path) -> None:
        """What the stage checks against the cell's design and the sheet, when the pipeline is
        loaded: a Polyfoam design, voxel_mm at most its bead, a grid within max_voxels."""
        from ...cells.polyfoam import PolyfoamDesign
        from ...sheet.printed_foam import tripod_region, voxel_grid
        from .cell import load_design
        from .orient import sheet_params

        if "cell" not in params or "orient" not in params:
            return  # the stage itself names the missing stage
        design = load_design(root, params["cell"])[0]
        if not isinstance(design, PolyfoamDesign):
            raise ConfigError(f"cell.design: {params['cell'].design!r}: the printed sheet is modelled for Polyfoam "
                              "cells only (the print map's foam): use a polyfoam design in the cell stage")
        check_voxel(self.voxel_mm, design.bead_width)
        try:
            voxel_grid(tripod_region(sheet_params(params["orient"])), self.voxel_mm, self.max_voxels)
        except ConfigError as err:
            raise ConfigError(f"{table}.{err}") from None


def check_voxel(voxel_mm: float, bead_width: float, field: str = "sheet.voxel_mm") -> None:
    if voxel_mm > bead_width:
        raise ConfigError(f"{field}: {voxel_mm:g}: allowed range (0, bead_width = {bead_width:g}] mm "
                          "(a wall must be at least one voxel)")


def cell_design(ctx: StageContext):
    from ...cells.catalogue import parse_design
    from ...cells.polyfoam import PolyfoamDesign

    d = parse_design(read_cell_design(ctx.inputs["cell"]), source="cell.json design")
    if not isinstance(d, PolyfoamDesign):
        raise ConfigError(f"cell.design: {type(d).__name__}: the printed sheet is modelled for Polyfoam cells only "
                          "(the print map's foam): use a polyfoam design in the cell stage")
    return d


def _fields(ctx: StageContext, label: str):
    from ...sheet.printed_foam import printmap_fields

    folder = ctx.inputs["printmap"]
    info = json.loads((folder / "printmap.json").read_text())
    texts = {p.name: p.read_text() for p in sorted((folder / label).glob("*.txt"))}
    return printmap_fields(info, label, texts)


def scene_robot(ctx: StageContext, pair, material):
    """The six-DOF robot of the robot stage's scene on ``pair`` (orient's sheets): it places the
    grips (its servos, rod and centres)."""
    from ...robot.builder import six_dof_robot

    sc = read_robot_scene(ctx.inputs["robot"])
    mass = {"sheet_mass_g": sc.sheet_mass_g} if sc.sheet_mass_g else {"density": material.density}
    return six_dof_robot(pair, model=material.model, rod_length=sc.rod_length, geometry=sc.servo_geometry(),
                         gravity=sc.gravity, **mass)


def sheet_prints(ctx: StageContext, seeds, gauge: str, voxel_mm: float, rtol: float, max_voxels: int) -> list:
    """The :class:`~metasheet.sheet.dns.SheetPrint` of each seed's normal and mirrored sheet (in that
    order), from the cell stage's design and the print maps (``ctx.inputs``: cell, orient, printmap)."""
    from ...sheet.dns import SheetPrint

    design = cell_design(ctx)
    params = read_orient(ctx.inputs["orient"]).sheet_params
    solid = design.material.material().stiffness()
    fields = {label: _fields(ctx, label) for label in LABELS}
    return [SheetPrint(label, seed, gauge, voxel_mm, design, params, fields[label], solid, rtol, max_voxels)
            for seed in seeds for label in LABELS]


def walls_file(label: str, seed: int) -> str:
    """The stage's file of a print's walls' fields (``walls``), relative to its folder."""
    return f"walls/{label}-seed{int(seed)}.npz"


def run(ctx: StageContext) -> dict:
    from ...sheet.dns import dns_sheet, dns_sheet_fields
    from ...studies.sheet_dns import dns_study, homogenised_grips

    p: SheetDnsParams = ctx.params
    design = cell_design(ctx)
    check_voxel(p.voxel_mm, design.bead_width)
    orient = read_orient(ctx.inputs["orient"])
    pair = orient.sheets()
    material = read_material(ctx.inputs["material"])
    sc = read_robot_scene(ctx.inputs["robot"])
    robot = scene_robot(ctx, pair, material)
    seed0 = design.seeds.seed if p.seed is None else p.seed
    specs = sheet_prints(ctx, [seed0 + r for r in range(p.realisations)], p.gauge, p.voxel_mm, p.rtol, p.max_voxels)
    ctx.progress("homogenised sheets", 0, 3)
    with threadpool_limits(limits=1, user_api="blas"):  # fixed-order sums: the same bytes on any thread count
        hom = homogenised_grips(pair, material.model)
    unit = dns_sheet_fields if p.walls else dns_sheet
    sheets = ctx.executor.map(unit, specs, progress=lambda d, n: ctx.progress("printed sheets (DNS)", d, n))
    if p.walls:
        for s, fields in sheets:
            fields.save(ctx.path(walls_file(s.label, s.seed)))
        sheets = [s for s, _ in sheets]
    for s in sheets:  # manifest only: wall times differ run to run
        ctx.timings[f"dns_s.{s.label}.{s.seed}"] = round(s.build_s + s.solve_s, 3)
    fits = None
    if p.fit:
        ctx.progress("apparent constants", 1, 3)
        with threadpool_limits(limits=1, user_api="blas"):
            fits = _fits(pair, sheets, material, orient.sheet_params)
    study = dns_study(sheets, hom, robot, orient.sheet_params, length_scale=p.length_scale, fits=fits)
    plate = _plate(ctx, pair, material, sheets, study, robot, orient.sheet_params, p)
    out = {"method": "printed Polyfoam from the print maps (metasheet.sheet.printed_foam), voxel DNS with the four "
                     "grips rigid, condensed on their 24 rigid DOF (metasheet.sheet.dns); the homogenised sheets "
                     "condensed the same way (metasheet.sheet.grips.fem_condensed); both robots' linear rest "
                     "models without gravity (metasheet.robot.condensed)",
           "units": {"K": "N/mm, N, N mm (grip order centre, arm 0, arm 1, arm 2; t then theta)",
                     "rod_rotation_deg_per_deg": "rod roll per degree of all six motors together",
                     "singular_values": "of diag(1,1,1,L,L,L) J, L = length_scale [mm/rad]"},
           "voxel_mm": p.voxel_mm, "gauge": p.gauge, "seeds": [seed0 + r for r in range(p.realisations)],
           "material": {"model": material.model, "constants": material.material.to_dict(),
                        "solid": design.material.model_dump()},
           "element": pair.element, "scene": sc.scene,
           "homogenised_K": {"normal": hom[0].tolist(), "mirrored": hom[1].tolist()},
           **study, **({"plate": plate} if plate else {})}
    write_json_atomic(ctx.path("sheet_dns.json"), out)
    ctx.progress("voxel file and pictures", 2, 3)
    _pictures(ctx, p, specs[0], study)
    ctx.progress("done", 3, 3)
    spr = study["spread"]
    return {"verdict": study["verdict"],
            "homogenised_rod_rotation_deg_per_deg": round(study["homogenised_robot"]["rod_rotation_deg_per_deg"], 5),
            "printed_rod_rotation_deg_per_deg": [round(spr["rod_rotation_deg_per_deg"][k], 5) for k in ("min", "max")],
            "printed_over_homogenised_modes": round(spr["geometric_mean_ratio_normal"]["mean"], 4),
            "unknowns": [s.n_dof for s in sheets[:2]],
            "kept_share": [round(s.kept_share, 4) for s in sheets[:2]]}


def _plate(ctx: StageContext, pair, material, sheets, study: dict, robot, params, p: SheetDnsParams) -> dict | None:
    """The plate continuum against the prints (:func:`metasheet.studies.sheet_plate.plate_comparison`)
    when the homogenize stage wrote ``plate.json``, else None."""
    from ...studies.sheet_dns import _pairs
    from ...studies.sheet_plate import plate_comparison

    path = ctx.inputs.get("homogenize")
    if path is None or not (path / "plate.json").exists():
        return None
    bulk = material.material
    bulk = bulk if hasattr(bulk, "nu_tl") else bulk.as_transverse()
    plate = json.loads((path / "plate.json").read_text())
    with threadpool_limits(limits=1, user_api="blas"):
        return plate_comparison(pair, material.model, bulk, plate, _pairs(sheets),
                                [r["robot"]["rod_rotation_deg_per_deg"] for r in study["realisations"]], robot, params,
                                length_scale=p.length_scale)


def _fits(pair, sheets, material, params) -> list:
    """Per realisation the apparent constants fitted to both printed sheets at once."""
    from ...sheet.apparent import fit_apparent, sheet_basis
    from ...studies.sheet_dns import _pairs

    bases = (sheet_basis(pair.sheet, pair.fibers, pair.element),
             sheet_basis(pair.mirrored, pair.fibers_mirrored, pair.element))
    return [fit_apparent(bases, (a.K, b.K), material.material, model=material.model)
            for a, b in _pairs(sheets)]


def _pictures(ctx: StageContext, p: SheetDnsParams, spec, study: dict) -> None:
    """Realisation 0's normal print (voxel file, picture) and the comparison chart."""
    from ...sheet.printed_foam import printed_foam, tripod_region
    from ...viz.printed_foam import printed_foam_npz, printed_foam_picture

    foam = printed_foam(tripod_region(spec.params), spec.fields, spec.design, voxel_mm=spec.voxel_mm,
                        gauge=spec.gauge, seed=spec.seed, max_voxels=spec.max_voxels)
    _write_bytes(ctx.path("sheet_normal.npz"), printed_foam_npz(foam))
    if not p.picture:
        return
    from ...viz.sheet_dns import sheet_dns_picture

    _write_bytes(ctx.path("printed_sheet.png"), printed_foam_picture(
        foam.phases, foam.region, foam.origin, foam.voxel_mm,
        title=f"printed normal sheet, seed {spec.seed}, {spec.voxel_mm:g} mm voxels ({spec.gauge} gauge)"))
    _write_bytes(ctx.path("sheet_dns.png"), sheet_dns_picture(study))


def _write_bytes(path, data: bytes) -> None:
    import os

    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    tmp.write_bytes(data)
    os.replace(tmp, path)


register(
    Stage(
        name="sheet",
        params=SheetDnsParams,
        run=run,
        requires=("cell", "orient", "material", "printmap", "robot"), optional=("homogenize",),
        outputs=("sheet_dns.json", "sheet_normal.npz"),
        doc="the printed sheets as voxel DNS on the robot's grips against the homogenised sheets: eigen-ratios, "
            "the printed robot's rod roll and singular values, apparent constants, print-to-print spread",
    )
)
