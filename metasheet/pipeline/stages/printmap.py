"""Stage ``printmap``: everything needed to print both sheets in IceSL.

For each sheet (``normal/`` and ``mirrored/``): ``sheet.stl`` (the surface, world
coordinates in mm), the 64^3 field files (``density.txt``, ``theta.txt``, ``phi.txt``,
``iso.txt`` for Phasor; ``density.txt``, ``angle.txt`` for Polyfoam; scales in
``metasheet.sheet.icesl``) and ``print.lua``, the IceSL script that loads the STL, picks
the infill, reads the fields next to it and binds them over the sheet's bounding box.
Plus ``printmap.json`` (boxes, scales, density mapping) and ``printmap.png`` (mid-plane
slices of the fields).

Density: each element's relative density rho (from orient's grading; when the ``cell``
stage runs, scaled so that the design density equals the cell's measured relative
density) maps to the infill percentage clip(100 * density_gain * rho, min_percent,
max_percent), written as percentage / 100.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from ...errors import ConfigError
from ...sheet import fibers as fb
from ...sheet import icesl
from ..artefacts import read_cell_density, read_orient
from ..manifest import write_json_atomic
from ..registry import Params, Stage, StageContext, register

DEFAULT_SETTINGS = {
    "num_shells_0": 0,
    "print_perimeter_0": True,
    "cover_thickness_mm_0": 0.0,
    "extruder_temp_degree_c_0": 230.0,
}
SHEETS = {"normal": False, "mirrored": True}  # output folder -> whether the sheet is the mirrored one
FILES = {"density": "density.txt", "theta": "theta.txt", "phi": "phi.txt", "iso": "iso.txt"}


class PrintmapParams(Params):
    infill: Literal["phasor", "polyfoam"] = Field("phasor", description="IceSL infill type")
    layer_thickness: float = Field(0.3, ge=0.05, le=1.0, description="z_layer_height_mm [mm]")
    settings: dict[str, float | int | bool | str] = Field(
        default_factory=lambda: dict(DEFAULT_SETTINGS),
        description="further IceSL settings, name -> value (set before the fields)",
    )
    density_gain: float = Field(1.0, gt=0, le=10, description="infill % = 100 * gain * rho [-]")
    min_percent: float = Field(0.0, ge=0, le=100, description="lowest infill percentage [%]")
    max_percent: float = Field(100.0, ge=0, le=100, description="highest infill percentage [%]")


def _write_stl(path, vertices: np.ndarray, faces: np.ndarray, name: str) -> None:
    """Binary STL with a fixed header (same mesh -> same bytes)."""
    tri = vertices[faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    rec = np.zeros(len(faces), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["n"], rec["v"] = n, tri
    header = f"metasheet {name} [mm]".encode()[:80].ljust(80, b" ")
    with open(path, "wb") as fh:
        fh.write(header)
        fh.write(np.uint32(len(faces)).tobytes())
        fh.write(rec.tobytes())


def run(ctx: StageContext) -> dict:
    p: PrintmapParams = ctx.params
    if p.min_percent > p.max_percent:
        raise ConfigError(f"min_percent: {p.min_percent!r}: allowed range is [0, max_percent = {p.max_percent:g}]")
    orient = read_orient(ctx.inputs["orient"])
    info, fs = orient.info, orient.fiber_settings
    alpha_design = float(info["material"]["alpha_percent"])
    rho_cell = read_cell_density(ctx.inputs["cell"]) if "cell" in ctx.inputs else None
    scale = 1.0 if rho_cell is None else rho_cell / float(info["relative_density"])
    settings = {"z_layer_height_mm": p.layer_thickness, **p.settings}
    names = list(icesl.SETTINGS[p.infill])
    files = {k: ("angle.txt" if (k == "theta" and p.infill == "polyfoam") else FILES[k]) for k in names}
    summary, slices = {"infill": p.infill, "sheets": {}}, []
    for step, (label, mirrored) in enumerate(SHEETS.items()):
        ctx.progress(f"sampling {label} sheet", step, len(SHEETS) + 1)
        sheet = orient.mirrored if mirrored else orient.normal
        mesh, tets = sheet.mesh, sheet.mesh.tets
        rho = np.asarray(sheet.cell_data["density"], dtype=float) * scale
        alpha = np.asarray(sheet.cell_data["alpha"], dtype=float)
        iso = np.ones_like(alpha) if alpha_design <= 0 else np.clip(1.0 - alpha / alpha_design, 0.0, 1.0)
        pf = icesl.print_fields(
            mesh.points, tets,
            fiber_fn=lambda q, m=mirrored: fb.spiral_fibers(q, mirrored=m, **fs),
            density=rho, iso=iso, gain=p.density_gain,
            min_percent=p.min_percent, max_percent=p.max_percent,
        )
        out = ctx.path(label)
        out.mkdir(parents=True, exist_ok=True)
        verts, faces = icesl.surface(mesh.points, tets)
        _write_stl(out / "sheet.stl", verts, faces, f"{label} tripod sheet")
        for k in names:
            (out / files[k]).write_text(icesl.field_text(pf.fields[k]))
        (out / "print.lua").write_text(icesl.lua_script(
            stl="sheet.stl", infill=p.infill, files=files, box=pf.box, settings=settings,
            title=f"metasheet print map, {label} tripod sheet ({p.infill})",
        ))
        summary["sheets"][label] = {
            "box_lo_mm": pf.box.lo.tolist(), "box_hi_mm": pf.box.hi.tolist(),
            "percent_range": list(pf.percent_range), "inside_fraction": float((pf.cell >= 0).mean()),
            "n_triangles": int(len(faces)),
        }
        mid = pf.box.n // 2
        ax = pf.box.axes()
        extent = (ax[0][0], ax[0][-1], ax[1][0], ax[1][-1])
        slices.append((label, {k: pf.fields[k][:, :, mid] for k in names}, pf.cell[:, :, mid] >= 0, extent))
    info_out = {
        **summary,
        "grid": [icesl.N] * 3,
        "settings": {icesl.SETTINGS[p.infill][k]: files[k] for k in names},
        "scales": {
            "density": "infill percentage / 100; percentage = clip(100 * gain * rho, min, max)",
            "theta": "atan2(l_y, l_x) / 360 deg", "phi": "asin(l_z) mod 360 deg / 360 deg",
            "iso": "1 - alpha / alpha_design (1 = isotropic)",
            "outside": "nearest inside texel",
        },
        "density_gain": p.density_gain, "density_scale_from_cell": scale, "cell_relative_density": rho_cell,
        "print_settings": settings,
    }
    write_json_atomic(ctx.path("printmap.json"), info_out)
    ctx.progress("picture", len(SHEETS), len(SHEETS) + 1)
    from ...viz.sheet import printmap_picture

    ctx.path("printmap.png").write_bytes(printmap_picture(slices))
    return {"infill": p.infill, "density_scale_from_cell": scale,
            **{f"{k}_percent_range": v["percent_range"] for k, v in summary["sheets"].items()}}


register(
    Stage(
        name="printmap",
        params=PrintmapParams,
        run=run,
        requires=("orient",),
        optional=("cell",),
        outputs=("normal/print.lua", "normal/sheet.stl", "mirrored/print.lua", "mirrored/sheet.stl",
                 "printmap.json", "printmap.png"),
        doc="IceSL print maps (STL, 64^3 fields, Lua script) for both sheets -> normal/, mirrored/",
    )
)
