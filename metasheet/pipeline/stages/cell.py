"""Stage ``cell``: a periodic unit cell (Voronoi foam, polyfoam, laminate or solid) from ``cells/*.toml``.

Writes into ``outputs/<pipeline>/cell/``:

- ``cell.json``: the design, achieved relative density, strut radius or wall thickness,
  connectivity/percolation report, and ``materials`` (phase -> {E, nu} [MPa, -]) for
  homogenize;
- ``voxels.npz``: ``phases`` (nx, ny, nz) uint8 (0 void; cubic but for polyfoams), ``size``
  (3,) [mm], ``axis`` (3,) unit vector of the longitudinal axis; byte-identical for
  identical inputs;
- ``cell.stl``: watertight surface of the solid clipped to the box (``surface = true``);
- ``cell.vtu``: periodic tetrahedral mesh (``tet_mesh = true``);
- ``cell.png``: the cell tiled 2 x 2 x 2.
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
from pydantic import Field

from ...cells.catalogue import CellResult, FoamDesign, LaminateDesign, design_cell, parse_design
from ...cells.polyfoam import PolyfoamDesign
from ...errors import ConfigError, MeshError
from ...runtime.npz import write_npz
from ..manifest import sha256_file, write_json_atomic
from ..registry import Params, Stage, StageContext, register


class CellParams(Params):
    design: str = Field(description="cell design file, relative to the project root (e.g. cells/paper_foam.toml)")
    resolution: int | None = Field(None, ge=16, le=128, description="voxels per side (default: the design's; "
                                   "not for polyfoams, see voxel_mm)")
    voxel_mm: float | None = Field(None, gt=0, description="polyfoam voxel edge [mm] (default: the design's)")
    seed: int | None = Field(None, ge=0, description="RNG seed of the foam's seeds (default: the design's)")
    relative_density: float | None = Field(
        None, gt=0, lt=1, description="target solid fraction [-] (default: the design's)"
    )
    surface: bool = Field(True, description="write cell.stl (watertight surface)")
    surface_resolution: int | None = Field(
        None, ge=8, le=512, description="grid cells per side of the surface (default: resolution)"
    )
    tet_mesh: bool = Field(False, description="write cell.vtu (periodic tet mesh, gmsh)")
    tet_size: float | None = Field(None, gt=0, description="tet element size [mm] (default: the voxel size)")
    picture: bool = Field(True, description="write cell.png")

    def check_files(self, table: str, params: dict, root: Path) -> None:
        """The design file is read and validated with this table's overrides (as the stage will)."""
        load_design(root, self)


def load_design(root: Path, p: CellParams):
    """Read and validate the design file named by ``p.design`` with the overrides of ``p``."""
    path = (Path(root) / p.design).resolve()
    if not path.is_file():
        raise ConfigError(f"cell.design: {p.design!r}: no such file under {root}")
    data = read_design_toml(path, f"cell.design: {p.design!r}")
    overrides = {"resolution": p.resolution, "seed": p.seed, "relative_density": p.relative_density,
                 "voxel_mm": p.voxel_mm}
    return parse_design(data, overrides=overrides, source=p.design), path


def _box_surface(size: np.ndarray):
    import trimesh

    box = trimesh.creation.box(extents=size)
    box.apply_translation(size / 2.0)
    return box


def _surface(cell: CellResult, p: CellParams):
    """(trimesh surface, report dict) of the solid clipped to the box."""
    n = p.surface_resolution or cell.resolution  # n, or (nx, ny, nz) for a non-cubic grid
    if cell.foam is None:  # laminate or solid: the solid fills the box
        mesh = _box_surface(cell.size)
        return mesh, {"kind": "box", "watertight": bool(mesh.is_watertight), "volume_mm3": float(mesh.volume)}
    from ...cells.surface import check_surface, periodic_isosurface  # colleague's module, lazily

    mesh = periodic_isosurface(cell.field, cell.size, n)
    rep = check_surface(mesh)
    box_volume = float(np.prod(cell.size))
    return mesh, {
        "kind": "isosurface",
        "grid": int(n) if np.ndim(n) == 0 else [int(v) for v in n],
        "watertight": bool(rep.watertight),
        "manifold": bool(rep.manifold),
        "components": int(rep.n_components),
        "volume_mm3": float(rep.volume),
        "volume_fraction": float(rep.volume) / box_volume,
        "volume_vs_voxels": float(rep.volume) / box_volume / cell.relative_density - 1.0,
        "triangles": int(len(mesh.faces)),
    }


def _tet_mesh(cell: CellResult, p: CellParams):
    if isinstance(cell.design, LaminateDesign):
        raise ConfigError("cell.tet_mesh: true: a laminate has two phases; use its voxels (voxels.npz)")
    from ...cells.tetmesh import periodic_tet_mesh  # colleague's module, lazily

    h = p.tet_size or float(np.min(cell.voxel_mm))
    field = cell.field
    if field is None:  # solid: negative everywhere, so the mesh fills the box
        depth = float(np.max(cell.size))
        field = lambda x: np.full(len(x), -depth)  # noqa: E731
    mesh = periodic_tet_mesh(field, cell.size, h)
    if mesh.n_components != 1:
        raise MeshError(
            f"cell.tet_size: {h:g} mm: the tet mesh falls into {mesh.n_components} periodic pieces "
            "(struts thinner than the mesh can follow); lower tet_size"
        )
    return mesh, h


def _title(cell: CellResult) -> str:
    d = cell.design
    lines = [f"{d.name}: {d.kind}, relative density {cell.relative_density:.3f}"]
    if isinstance(d, FoamDesign) and cell.solution is not None:
        what = "strut radius" if d.topology == "open" else "wall thickness"
        lines.append(f"{d.topology}-cell, {len(cell.foam.seeds)} seeds, {what} {cell.solution.thickness:.3f} mm")
        m = cell.foam.metric.describe()
        lines.append(", ".join(f"{k} {v}" for k, v in m.items() if k not in ("extent", "axis", "kind")))
    if isinstance(d, PolyfoamDesign) and cell.polyfoam is not None:
        pf = cell.polyfoam
        lines.append(f"polyfoam: infill {d.infill_percentage:g} %, kgon_x_shrink {d.kgon_x_shrink:g}, "
                     f"min angle {d.kgon_min_angle:g} deg, k {d.kgon_sides}")
        lines.append(f"{len(cell.foam.seeds)} seeds, walls {pf.wall_thickness:g} mm (one bead), "
                     f"scale L {pf.cell_scale:.3g} mm, grid {'x'.join(map(str, cell.shape))}")
    lines.append(f"box {' x '.join(f'{v:g}' for v in cell.size)} mm, shown 2x2x2, axis l = {'xyz'[cell.axis]}")
    return "\n".join(lines)


def run(ctx: StageContext) -> dict:
    p: CellParams = ctx.params
    design, path = load_design(ctx.root, p)
    ctx.progress("cell: voxels", 0, 3)
    cell = design_cell(design)
    write_npz(ctx.path("voxels.npz"), phases=cell.phases.astype(np.uint8), size=cell.size.astype(float),
              axis=cell.axis_vector.astype(float))
    info = {
        "design_file": p.design,
        "design_sha256": sha256_file(path),
        "design": json.loads(design.model_dump_json()),
        **cell.summary(),
    }
    ctx.progress("cell: surface", 1, 3)
    mesh = None
    if p.surface:
        mesh, info["surface"] = _surface(cell, p)
        mesh.export(ctx.path("cell.stl"), file_type="stl")
    if p.tet_mesh:
        tm, h = _tet_mesh(cell, p)
        tm.to_meshio().write(ctx.path("cell.vtu"))
        info["tet_mesh"] = {
            "h_mm": h, "points": int(len(tm.points)), "tets": int(len(tm.tets)),
            "max_mismatch_mm": float(tm.max_mismatch), "relative_density": tm.relative_density,
            "min_quality": float(tm.min_quality), "components": int(tm.n_components),
        }
    write_json_atomic(ctx.path("cell.json"), info)
    ctx.progress("cell: picture", 2, 3)
    if p.picture:
        from ...viz.cell import surface_picture, voxel_picture

        if mesh is not None and cell.foam is not None:
            png = surface_picture(mesh.vertices, mesh.faces, cell.size, title=_title(cell))
        else:
            names = {}
            if isinstance(cell.design, LaminateDesign):
                names = {i + 1: layer.material.name for i, layer in enumerate(cell.design.layers)}
            labels = {p: f"phase {p}: {names.get(p, 'material')}, E {m.E:g} MPa, nu {m.nu:g}"
                      for p, m in cell.materials.items()}
            png = voxel_picture(cell.phases, cell.size, title=_title(cell), labels=labels)
        ctx.path("cell.png").write_bytes(png)
    ctx.progress("cell: done", 3, 3)
    summary = {k: info[k] for k in ("name", "kind", "resolution", "relative_density") if k in info}
    for key in ("strut_radius_mm", "wall_thickness_mm"):
        if key in info:
            summary[key] = info[key]
    summary["percolates"] = info["connectivity"]["ok"]
    return summary


register(
    Stage(
        name="cell",
        params=CellParams,
        run=run,
        outputs=("cell.json", "voxels.npz"),
        doc="periodic unit cell (foam, laminate, solid) -> cell.json, voxels.npz, cell.stl, cell.png",
    )
)


def read_design_toml(path: Path, field: str) -> dict:
    """The parsed TOML of design file ``path``; ConfigError ``field: why`` for a file that is not
    UTF-8 TOML (random bytes, a binary, a directory)."""
    try:
        return tomllib.loads(path.read_text(encoding="utf-8").removeprefix("\ufeff"))  # an editor's BOM
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(f"{field}: not valid TOML: {err}") from None
    except UnicodeDecodeError:
        raise ConfigError(f"{field}: not a text file (not UTF-8): a TOML design file is expected") from None
    except OSError as err:
        raise ConfigError(f"{field}: cannot read: {err.strerror or err}") from None
