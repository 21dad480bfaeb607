"""Stage ``homogenize``: the cell's effective stiffness and its five TI constants.

Reads ``cell/voxels.npz`` (phases, size, axis) and ``cell/cell.json`` (``materials``),
or ``cell/cell.vtu`` with ``mesh_route = true``. Writes:

- ``constants.json``: ``E_t, E_l, nu_t, nu_tl, mu_l`` [MPa, -], ``C`` (6 x 6) [MPa],
  ``axis``, ``misfit``, ``relative_density``, ``symmetry_error``, ``solver``,
  ``resolution``, per-load-case diagnostics and localisation ratios (no wall-clock times:
  those go to the manifest's ``timings_s``, so the same cell gives the same bytes);
- ``fields.vtu``: the solid mesh with the local strain of every unit load case;
- ``homogenize.png``: C, the fitted constants and the strain localisation.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from ...errors import ConfigError
from ...homogenize import homogenize_mesh, homogenize_voxels
from ...material import Isotropic, TransverseIsotropic
from ..artefacts import read_cell, read_cell_tets
from ..manifest import write_json_atomic
from ..registry import Params, Stage, StageContext, register


class HomogenizeParams(Params):
    solver: Literal["auto", "direct", "amg", "voxel"] = Field(
        "auto", description="linear solver: direct (CHOLMOD or SuperLU), amg (pyamg + CG), "
                            "voxel (matrix-free multigrid CG, voxel route only), auto by size"
    )
    tolerance: float = Field(1e-8, gt=0, le=1e-4, description="relative residual of the corrector solves [-]")
    mesh_route: bool = Field(False, description="homogenise the periodic tet mesh cell.vtu instead of the voxels")
    fit_axis: Literal["cell", "search"] = Field(
        "cell", description="TI axis of the fit: the cell's design axis, or the best-fitting one"
    )
    fields: bool = Field(True, description="write fields.vtu (local strains)")
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
    else:
        r = homogenize_voxels(phases, size, materials, solver=p.solver, rtol=p.tolerance, axis=axis)
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
    write_json_atomic(ctx.path("constants.json"), constants)
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
    m = r.fit.material
    return {**{k: round(v, 6) for k, v in m.to_dict().items()}, "misfit": round(r.fit.misfit, 6),
            "relative_density": round(r.relative_density, 6), "solver": r.solver, "n_dof": r.n_dof}


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
