"""Stage ``printcheck``: the design stage's chosen fibre field printed and solved, against its model (issue 63).

The design stage optimises the fibre field on a continuum; whether the printed foam follows
depends on its cells against the sheet's thickness (docs/continuum-map.md). This stage prints
the chosen design (and the spiral, with ``spiral``) in the foam of ``print_design`` (a Polyfoam:
its infill and shrink, uniform; the field's angle as the print map writes it), ``prints`` times
(seeds ``seed``, ``seed + 1``, ...), solves both sheets as voxel DNS on the robot's grips, and
compares the printed robot's rod roll per motor degree with the design model's on the same grips
(:mod:`metasheet.studies.print_check`): within 15 % "meets", else the report says by how much it
misses. Writes ``print_check.json``; each printed sheet is one executor unit.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import Literal

from pydantic import Field
from threadpoolctl import threadpool_limits

from ...errors import ConfigError
from ..artefacts import read_material, read_orient
from ..manifest import write_json_atomic
from ..registry import Params, Stage, StageContext, register


class PrintCheckParams(Params):
    print_design: str = Field("cells/paper_polyfoam.toml", description="the Polyfoam the sheets are printed with "
                              "(its infill, shrink, bead, gauge, TPU), relative to the project root")
    prints: int = Field(1, ge=1, le=20, description="prints of each sheet (seeds seed, seed + 1, ...)")
    seed: int | None = Field(None, ge=0, description="first foam seed (None: print_design's)")
    voxel_mm: float = Field(0.25, gt=0, le=2.0, description="voxel edge of the printed sheets [mm] (<= the bead)")
    rtol: float = Field(1e-4, gt=0, lt=1e-3, description="CG tolerance of each grip column [-] (as scalemap.rtol)")
    gauge: Literal["seed", "point"] = Field("seed", description="as sheet.gauge (docs/printed-sheet.md)")
    spiral: bool = Field(True, description="print the spiral too: the design's gain over it, modelled and printed")
    max_voxels: int = Field(20_000_000, ge=1000, le=200_000_000, description="refuse larger voxel grids")
    length_scale: float = Field(50.0, gt=0, le=1e4, description="rotation -> length for singular values [mm/rad]")

    def check_files(self, table: str, params: dict, root: Path) -> None:
        print_design(root, self)


def print_design(root: Path, p: PrintCheckParams):
    """The Polyfoam ``print_design`` names; ConfigError naming printcheck.print_design or .voxel_mm."""
    from ...studies.scale_map import foam_design
    from .cell import read_design_toml
    from .sheet import check_voxel

    path = (Path(root) / p.print_design).resolve()
    if not path.is_file():
        raise ConfigError(f"printcheck.print_design: {p.print_design!r}: no such file under {root}")
    data = read_design_toml(path, f"printcheck.print_design: {p.print_design!r}")
    try:
        d = foam_design(data, data.get("infill_percentage"), data.get("kgon_x_shrink"), seed=p.seed)
    except ConfigError as err:
        raise ConfigError(str(err).replace("scalemap.design", "printcheck.print_design")) from None
    check_voxel(p.voxel_mm, d.bead_width, "printcheck.voxel_mm")
    return d


def run(ctx: StageContext) -> dict:
    from ...studies.print_check import compare_roll, design_fibres, design_prints, model_grips, verdict
    from ...published import paper
    from ...robot.builder import six_dof_robot
    from ...sheet.dns import dns_sheet
    from ...studies.continuum_check import check_design

    p: PrintCheckParams = ctx.params
    foam = print_design(ctx.root, p)
    orient, mat = read_orient(ctx.inputs["orient"]), read_material(ctx.inputs["material"])
    d = json.loads((ctx.inputs["design"] / "design.json").read_text())
    spiral_kw = {"law": d["spiral"]["law"], "r_ref": d["spiral"]["r_ref"]}
    designs = {"chosen": d["chosen"]["design"]}
    if p.spiral:
        designs["spiral"] = {"pitch_deg": d["spiral"]["pitch_deg"], "basis": None, "coefficients_rad": []}
    pair = replace(orient.sheets(need_constants=False), element="p1")  # the design's rest problem: P1
    sp, sc = orient.sheet_params, orient.scene
    seeds = [foam.seeds.seed + r for r in range(p.prints)]
    # the chosen design may be the spiral itself (nothing feasible beat it): printed once
    same = {k: next(j for j in designs if designs[j] == v) for k, v in designs.items()}
    fibres = {k: design_fibres(v, spiral_kw) for k, v in designs.items()}
    specs = {k: design_prints(fibres[k], pair, sp, foam, seeds=seeds, voxel_mm=p.voxel_mm, gauge=p.gauge,
                              rtol=p.rtol, max_voxels=p.max_voxels) for k in designs if same[k] == k}
    flat = [(k, s) for k in specs for s in specs[k]]
    done = ctx.executor.map(dns_sheet, [s for _, s in flat],
                            progress=lambda i, n: ctx.progress("printcheck: printed sheets", i, n))
    printed = {k: [r for (j, _), r in zip(flat, done) if j == k] for k in specs}
    for (k, u), s in zip(flat, done):  # manifest only: wall times differ run to run
        ctx.timings[f"dns_s.{k}.{u.label}.{u.seed}"] = round(s.build_s + s.solve_s, 3)
    out = {}
    with threadpool_limits(limits=1, user_api="blas"):  # fixed-order sums: the same bytes on any thread count
        robot = six_dof_robot(replace(pair, fibers=fibres["chosen"](pair.sheet.centroids(), False),
                                      fibers_mirrored=fibres["chosen"](pair.mirrored.centroids(), True)),
                              mat.material, rod_length=sc.rod_length, geometry=sc.servo_geometry(),
                              density=paper.FOAM_DENSITY, model=mat.model)
        for k in designs:
            out[k] = compare_roll(model_grips(pair, fibres[k], mat.material, mat.model), printed[same[k]], robot, sp,
                                  length_scale=p.length_scale)
    doc = {"method": "the design's fibre field printed in print_design's foam (the print map's fields), voxel DNS "
                     "on the four grips, against the design's continuum sheets (its material, P1 on orient's mesh) "
                     "condensed on the same grips; linear rest models without gravity (metasheet.studies.print_check)",
           "print_design": {"file": p.print_design, "name": foam.name, "infill_percentage": foam.infill_percentage,
                            "kgon_x_shrink": foam.kgon_x_shrink, "bead_width": foam.bead_width},
           "seeds": seeds, "voxel_mm": p.voxel_mm, "gauge": p.gauge, "rtol": p.rtol,
           "material": {**mat.material.to_dict(), "model": mat.model, "source": mat.source},
           "design_roll_deg_per_deg": d["chosen"].get("roll_deg_per_deg"),
           # the search moves the fibres, not the foam: whether a continuum holds is the foam's and the sheet's
           "continuum": check_design(foam, sp.thickness).to_dict(),
           **out, "verdict": verdict(out["chosen"], out.get("spiral"))}
    write_json_atomic(ctx.path("print_check.json"), doc)
    return {"verdict": doc["verdict"], "meets": out["chosen"]["meets"],
            "roll_ratio": round(out["chosen"]["roll_ratio"]["mean"], 4)}


register(
    Stage(
        name="printcheck",
        params=PrintCheckParams,
        run=run,
        requires=("design", "orient", "material"),
        outputs=("print_check.json",),
        doc="the design's chosen fibre field printed (voxel DNS of both sheets) against its model: rod roll per "
            "degree within 15 % or by how much it misses -> print_check.json",
    )
)
