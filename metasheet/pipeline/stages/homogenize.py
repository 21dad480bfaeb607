"""Stage ``homogenize``: the cell's effective stiffness and its five TI constants.

Reads ``cell/voxels.npz`` (phases, size, axis) and ``cell/cell.json`` (``materials``),
or ``cell/cell.vtu`` with ``mesh_route = true``. Writes:

- ``constants.json``: ``E_t, E_l, nu_t, nu_tl, mu_l`` [MPa, -], ``C`` (6 x 6) [MPa],
  ``axis``, ``misfit``, ``relative_density``, ``symmetry_error``, ``solver``,
  ``resolution``, per-load-case diagnostics and localisation ratios (no wall-clock times:
  those go to the manifest's ``timings_s``, so the same cell gives the same bytes);
- ``fields.vtu``: the solid mesh with the local strain of every unit load case;
- ``homogenize.png``: C, the fitted constants and the strain localisation;
- with ``plate_thickness``: ``plate.json``, the sheet-scale stiffness of a sheet of that thickness
  cut from the foam (A, B, D of ``plate_slabs`` slabs, mean and 95 % interval, and their ratio
  to the bulk plate of C: :mod:`metasheet.homogenize.plate_slabs`) and ``plate.png`` (each
  diagonal stiffness over the bulk plate's, slab by slab).

With ``realisations = k > 1`` (issue 43) the design is realised again at seeds ``seed + 1 ..
seed + k - 1`` (the cell stage's voxels are realisation 0), every realisation a unit of the
executor; ``constants.json`` then holds the means over the k realisations (C the mean C), a
``ci95`` block (the 95 % half-widths, :func:`metasheet.homogenize.ensemble.ci95_block`) and
``ensemble`` (k, cells, seeds, the relative target and the realisations each constant needs
to meet it); ``realisations.json`` lists every realisation. With ``sizes`` (a Polyfoam's cell
counts) it also writes ``convergence.json`` (the cell-size study: per size the mean and
half-width, the trend in ``n**(-1/3)``) and ``convergence.png``. Wall times per realisation go
to the manifest (``realisation_s.<n>``), never to the result files.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from ...errors import ConfigError
from ...homogenize import homogenize_mesh, homogenize_voxels
from ...mechanics.material import CONSTANT_NAMES, Isotropic, TransverseIsotropic
from ..artefacts import read_cell, read_cell_tets
from ..manifest import write_json_atomic
from ..registry import Params, Stage, StageContext, register


class HomogenizeParams(Params):
    solver: Literal["auto", "direct", "amg", "voxel", "voxel-gpu"] = Field(
        "auto", description="linear solver: direct (CHOLMOD or SuperLU), amg (pyamg + CG), "
                            "voxel (matrix-free multigrid CG, voxel route only), voxel-gpu (the same on a "
                            "CUDA GPU, needs CuPy), auto by size (never the GPU)"
    )
    tolerance: float = Field(1e-5, gt=0, le=1e-4, description="relative residual of the corrector solves [-]; C* "
                             "is in energy form, its error second order in the residual (1e-5: C* within 1.3e-9 "
                             "and the constants within 3e-9 on the paper's Polyfoam at 27 cells; docs/voxel.md)")
    mesh_route: bool = Field(False, description="homogenise the periodic tet mesh cell.vtu instead of the voxels")
    fit_axis: Literal["cell", "search"] = Field(
        "cell", description="TI axis of the fit: the cell's design axis, or the best-fitting one"
    )
    realisations: int = Field(1, ge=1, le=200, description="independent seeds of the cell's design at its size "
                              "(the cell's voxels are the first); >= 2 gives means with 95 % intervals")
    sizes: list[int] = Field([], description="cell-size study: other numbers of cells (a polyfoam's seeds.count), "
                             "each realised size_realisations times -> convergence.json, convergence.png")
    size_realisations: int | None = Field(None, ge=2, le=200, description="realisations at each size of the "
                                          "study (default: realisations)")
    trend_min_cells: int = Field(1, ge=1, le=4096, description="the smallest size the size trend is fitted "
                                 "over (smaller ones stay in convergence.json and its picture)")
    size_max_voxels: int | None = Field(None, ge=1000, le=100_000_000, description="largest grid of a size-study "
                                        "realisation (voxels; default: the design's max_voxels)")
    target: float = Field(0.05, gt=0, lt=1, description="relative 95 % half-width each constant should reach "
                          "[-]; constants.json states the realisations each needs")
    fields: bool = Field(True, description="write fields.vtu (local strains)")
    plate_thickness: float | None = Field(None, gt=0, le=1000, description="a sheet of this thickness [mm] cut from "
                                          "the foam: slabs of the cell homogenised as plates (free faces) against the "
                                          "bulk continuum -> plate.json (off when unset)")
    plate_slabs: int = Field(8, ge=2, le=256, description="slabs at evenly spaced heights of the cell (the plate's "
                             "realisations: mean ABD with its 95 % interval)")

    @model_validator(mode="after")
    def _study(self):
        if any(n < 1 or n > 4096 for n in self.sizes) or len(set(self.sizes)) != len(self.sizes):
            raise ValueError(f"sizes {self.sizes}: expected distinct cell counts in [1, 4096]")
        if self.mesh_route and (self.realisations > 1 or self.sizes):
            raise ValueError("realisations / sizes: the voxel route only (mesh_route = false)")
        if self.mesh_route and self.plate_thickness is not None:
            raise ValueError("plate_thickness: the voxel route only (mesh_route = false)")
        if self.sizes and max(self.realisations, self.size_realisations or 0) < 2:
            raise ValueError("sizes: a size study needs realisations >= 2 (or size_realisations >= 2)")
        return self
    picture: bool = Field(True, description="write homogenize.png")


def materials_from_json(spec: dict) -> dict:
    """Phase -> material from ``cell.json``'s ``materials`` ({"1": {"E": .., "nu": ..}, ...})."""
    out = {}
    for key, m in spec.items():
        try:
            phase = int(key)
            if "E" in m:
                out[phase] = Isotropic(float(m["E"]), float(m["nu"]))
            else:
                out[phase] = TransverseIsotropic.from_mapping(m, where=f"cell.json materials[{key!r}]")
        except (KeyError, TypeError, ValueError) as exc:
            raise ConfigError(
                f"cell.json materials[{key!r}]: {m!r}: expected {{E, nu}} or {{E_t, E_l, nu_t, nu_tl, mu_l}}"
            ) from exc
    return out


def run(ctx: StageContext) -> dict:
    p: HomogenizeParams = ctx.params
    cell = read_cell(ctx.inputs["cell"])
    info, phases, size = cell.info, cell.phases, cell.size
    materials = materials_from_json(info["materials"])
    axis = cell.axis if p.fit_axis == "cell" else None
    ctx.progress("homogenize: solve", 0, 3)
    if p.mesh_route:
        points, tets, phase = read_cell_tets(ctx.inputs["cell"])
        r = homogenize_mesh(points, tets, materials, phase, size=size, origin=np.zeros(3),
                            solver=p.solver, rtol=p.tolerance, axis=axis)
        resolution = [int(len(tets))]
        others = []
    else:
        own = {"phases": phases, "size": size, "materials": materials, "solver": p.solver, "rtol": p.tolerance,
               "axis": axis}
        items = _realisation_items(p, info)
        r, *others = (ctx.executor.map(_unit, [own, *items],
                                       progress=lambda done, total: ctx.progress("homogenize: realisations",
                                                                                 done, total))
                      if items else [_unit(own)])
        resolution = list(phases.shape)
    ctx.progress("homogenize: write", 1, 3)
    constants = r.constants()
    constants.update(
        route="tet mesh" if p.mesh_route else "voxels",
        resolution=resolution,
        size_mm=size.tolist(),
        nu_lt=r.fit.material.nu_lt,
        alpha_percent=r.fit.material.alpha,
        units={"E_t": "MPa", "E_l": "MPa", "nu_t": "-", "nu_tl": "-", "mu_l": "MPa", "C": "MPa"},
        voigt_order=["11", "22", "33", "23", "13", "12"],
        cell=info.get("name"),
    )
    ctx.timings.update({k: round(float(v), 3) for k, v in r.timings.items()})  # manifest only
    if p.realisations > 1 or p.sizes:
        constants.update(_ensemble(ctx, p, info["design"], r, others, seconds=sum(r.timings.values())))
    write_json_atomic(ctx.path("constants.json"), constants)
    plate = _plate(ctx, p, phases, size, materials, constants) if p.plate_thickness else None
    if p.fields:
        from ...viz.homogenize import tet_field_mesh, voxel_field_mesh

        fm = tet_field_mesh(r, points, tets) if p.mesh_route else voxel_field_mesh(r, phases.shape, size)
        fm.write(ctx.path("fields.vtu"))
    ctx.progress("homogenize: picture", 2, 3)
    if p.picture:
        from ...viz.homogenize import summary_picture

        title = f"{info.get('name', 'cell')}: {'x'.join(map(str, resolution))} {'tets' if p.mesh_route else 'voxels'}"
        ctx.path("homogenize.png").write_bytes(summary_picture(r, title))
    ctx.progress("homogenize: done", 3, 3)
    out = {k: round(constants[k], 6) for k in CONSTANT_NAMES}
    if "ci95" in constants:
        out["rel_halfwidth_95"] = {k: round(v, 4) for k, v in constants["ci95"]["rel_halfwidth"].items()}
        out["realisations"] = constants["ci95"]["k"]
    if plate is not None:
        out["plate_ratio_to_bulk"] = round(plate["ratio_to_bulk"]["geometric_mean"]["mean"], 4)
        out["plate_thickness_mm"] = round(plate["thickness_mm"], 4)
        if "shear" in plate:
            out["plate_shear_ratio_to_bulk"] = [round(v["mean"], 4) for v in plate["shear"]["ratio_to_bulk"].values()]
    return {**out, "misfit": round(r.fit.misfit, 6), "relative_density": round(r.relative_density, 6),
            "solver": r.solver, "n_dof": r.n_dof}


def _plate(ctx: StageContext, p: HomogenizeParams, phases, size, materials: dict, constants: dict) -> dict:
    """``plate.json``: slabs of the cell's own voxels as sheets of ``plate_thickness``
    (:func:`metasheet.homogenize.plate_slabs.slab_study`) against the bulk plate of the stage's C."""
    from ...homogenize.plate_slabs import slab_study

    study = slab_study(phases, size, materials, p.plate_thickness, np.asarray(constants["C"]), slabs=p.plate_slabs,
                       shear=True, progress=lambda done, total: ctx.progress("homogenize: plate slabs", done, total))
    doc = {"bulk_C": "constants.json C (the mean over the realisations when there are several)",
           "realisations": "slabs of the cell stage's voxels at evenly spaced heights", **study.to_dict()}
    write_json_atomic(ctx.path("plate.json"), doc)
    if p.picture:
        from ...viz.plate import plate_picture

        ctx.path("plate.png").write_bytes(plate_picture(doc))
    return doc


def _unit(item: dict):
    """One unit of the stage's map (picklable): the cell stage's own voxels, homogenised whole
    (the result the stage writes: fit, load cases, fields), or a further realisation's row.
    Both kinds go to the executor together, so the cell's own solve no longer waits alone
    while the workers idle (the paper's four realisations: 199 s of wall before)."""
    from ...homogenize.realisations import evaluate_realisation

    if "phases" not in item:
        return evaluate_realisation(item)
    return homogenize_voxels(item["phases"], item["size"], item["materials"], solver=item["solver"],
                             rtol=item["rtol"], axis=item["axis"])


def _realisation_items(p: HomogenizeParams, info: dict) -> list[dict]:
    """The further realisations (seeds, sizes) of the cell stage's design: work items of
    :func:`metasheet.homogenize.realisations.evaluate_realisation`; none without an ensemble."""
    if p.realisations == 1 and not p.sizes:
        return []
    from ...homogenize.realisations import check_design, realisation_items

    design = info["design"]
    check_design(design, realisations=p.realisations, sizes=p.sizes)
    n0, s0 = int(design["seeds"]["count"]), int(design["seeds"]["seed"])
    k_size = p.size_realisations or p.realisations
    items = realisation_items(design, n0, range(s0 + 1, s0 + p.realisations), solver=p.solver, rtol=p.tolerance)
    study = design if p.size_max_voxels is None else {**design, "max_voxels": int(p.size_max_voxels)}
    for n in p.sizes:
        if n != n0:
            items += realisation_items(study, n, range(s0, s0 + k_size), solver=p.solver, rtol=p.tolerance)
    return items


def _ensemble(ctx: StageContext, p: HomogenizeParams, design: dict, r, rows: list[dict], *,
              seconds: float) -> dict:
    """Write realisations.json and the size study from the cell's own result ``r`` and the
    further realisations' ``rows`` (:func:`_realisation_items`, in order).

    Returns the keys that replace or join ``constants.json``'s: the means over the cell's own
    size (when it has k >= 2), ``ci95`` and ``ensemble``.
    """
    from ...homogenize import ensemble as ens
    from ...homogenize.realisations import by_size, ensemble_input, public_rows, result_row

    n0, s0 = int(design["seeds"]["count"]), int(design["seeds"]["seed"])
    rows = [{**result_row(r, n0, s0), "seconds": seconds}, *rows]
    groups = by_size(rows)
    for n, g in groups.items():  # manifest only: wall times differ run to run
        ctx.timings[f"realisation_s.{n}"] = round(float(np.median([row["seconds"] for row in g])), 3)
    write_json_atomic(ctx.path("realisations.json"), {"design": design.get("name"), "rows": public_rows(rows)})
    stats = {n: ens.ensemble_stats(ensemble_input(g)) for n, g in groups.items() if len(g) >= 2}
    out = {}
    if n0 in stats:
        own = stats[n0]
        means = {k: float(own[k].mean) for k in CONSTANT_NAMES}
        plan = ens.plan_realisations(own, p.target, names=CONSTANT_NAMES)
        ti = TransverseIsotropic(**means)
        out = {**means, "C": np.asarray(own["C"].mean).tolist(), "nu_lt": ti.nu_lt, "alpha_percent": ti.alpha,
               "ci95": ens.ci95_block(own, n0),
               "ensemble": {"value": f"mean over {own['E_t'].k} realisations (seeds {s0}..{s0 + own['E_t'].k - 1}) "
                                     f"of {n0} cells; misfit, load cases and fields are realisation 0's",
                            "k": own["E_t"].k, "n_cells": n0, "seeds": [row["seed"] for row in groups[n0]],
                            "target_rel_halfwidth": p.target,
                            "meets_target": {k: bool(own[k].rel_halfwidth <= p.target) for k in CONSTANT_NAMES},
                            "k_required": plan.k_required, "governing": plan.governing,
                            "realisation_0": {k: float(getattr(r.fit.material, k)) for k in CONSTANT_NAMES}}}
    if p.sizes and len(stats) >= 2:
        sizes = sorted(stats)
        summary = ens.convergence_summary(sizes, [stats[n] for n in sizes],
                                          plan=ens.plan_realisations(stats[n0], p.target, names=CONSTANT_NAMES)
                                          if n0 in stats else None, trend_min_cells=p.trend_min_cells)
        summary["k_required_per_size"] = {str(n): ens.plan_realisations(stats[n], p.target,
                                                                          names=CONSTANT_NAMES).k_required
                                          for n in sizes}
        write_json_atomic(ctx.path("convergence.json"), summary)
        if p.picture:
            from ...viz.convergence import convergence_picture

            ks = sorted({s["k"] for s in summary["sizes"]})
            title = (f"{design.get('name', 'cell')}: constants against the number of cells "
                     f"(mean +- 95 % interval of k = {' or '.join(map(str, ks))} realisations per size)")
            ctx.path("convergence.png").write_bytes(convergence_picture(summary, title))
    return out


register(
    Stage(
        name="homogenize",
        params=HomogenizeParams,
        run=run,
        requires=("cell",),
        outputs=("constants.json",),
        doc="periodic FEM homogenisation of the cell -> constants.json (5 TI constants, C), fields.vtu, homogenize.png",
    )
)
