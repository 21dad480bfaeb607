"""Cell designs (the ``cells/*.toml`` catalogue) and :func:`design_cell`, which builds one.

A design is a plain mapping (a parsed TOML file) validated into one of four frozen models,
told apart by ``kind``:

- ``foam``: a periodic Voronoi foam (:mod:`metasheet.cells.foam`) whose strut radius or
  wall thickness is solved for a relative density (:mod:`metasheet.cells.thickness`);
- ``polyfoam``: IceSL's Polyfoam as modelled here: Voronoi walls one bead thick under the
  k-gon gauge (:mod:`metasheet.cells.kgon`), the cell size solved for the infill density
  on a non-cubic grid of edge ``voxel_mm``; the longitudinal (soft) axis is x. Its model
  (:class:`~metasheet.cells.polyfoam.PolyfoamDesign`) and builder live in
  :mod:`metasheet.cells.polyfoam`;
- ``laminate``: layers of isotropic materials stacked along ``axis`` (exact Backus
  averages downstream);
- ``solid``: the bulk base material.

The shared sub-tables (``[material]``, ``[seeds]``, ``[metric]``) are in
:mod:`metasheet.cells.specs`. :class:`CellResult` is the built cell, ``phases`` (nx, ny, nz)
uint8. Units: lengths in mm, moduli in MPa, angles in degrees. ``axis`` is the longitudinal
axis ``l`` numbered 1, 2, 3 (x, y, z) as in the paper; code works with 0-based indices.
Reading the file is the stage's job (no file I/O here).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import Field, ValidationError

from ..errors import TYPE_WORDS, ConfigError
from ..mechanics.material import Isotropic
from .connectivity import ConnectivityReport, check_percolation, settle_phases
from .foam import Foam, foam_field, voxel_centres
from .measure import mean_chord_lengths
from .polyfoam import PolyfoamDesign, PolyfoamField, PolyfoamSolution, build_polyfoam
from .seeds import make_seeds
from .skeleton import SkeletonIndex
from .specs import MaterialSpec, PolyhedralSpec, SeedSpec, StretchedSpec, _Model
from .thickness import ThicknessSolution, solve_thickness

Length = Annotated[float, Field(gt=0)]


class _CellBase(_Model):
    name: str
    description: str = ""
    size: tuple[Length, Length, Length] = (10.0, 10.0, 10.0)  # [mm]
    axis: int = Field(3, ge=1, le=3)
    resolution: int = Field(64, ge=16, le=128)


class FoamDesign(_CellBase):
    """A periodic Voronoi foam; see ``cells/paper_foam.toml`` for every field documented."""

    kind: Literal["foam"] = "foam"
    topology: Literal["open", "closed"] = "open"
    relative_density: float = Field(0.15, gt=0.0, lt=1.0)
    tolerance: float = Field(0.005, gt=0.0, lt=1.0)
    min_voxels: float = Field(2.0, ge=1.0, le=16.0)
    max_island_fraction: float = Field(0.01, ge=0.0, le=1.0)
    seeds: SeedSpec = SeedSpec()
    metric: Annotated[StretchedSpec | PolyhedralSpec, Field(discriminator="kind")] = StretchedSpec()
    material: MaterialSpec = MaterialSpec()


class Layer(_Model):
    """One laminate layer: its volume ``fraction`` [-] and its material."""

    fraction: float = Field(gt=0.0, lt=1.0)
    material: MaterialSpec


class LaminateDesign(_CellBase):
    """Layers stacked along ``axis`` (layer normal = axis), phases 1, 2, ... in order."""

    kind: Literal["laminate"]
    layers: list[Layer] = Field(min_length=2, max_length=8)


class SolidDesign(_CellBase):
    """The bulk base material filling the box (phase 1)."""

    kind: Literal["solid"]
    material: MaterialSpec = MaterialSpec()


CellDesign = FoamDesign | LaminateDesign | SolidDesign | PolyfoamDesign
_METRIC_KINDS = ("stretched", "polyhedral")
_KINDS = {"foam": FoamDesign, "laminate": LaminateDesign, "solid": SolidDesign, "polyfoam": PolyfoamDesign}
_POLYFOAM_ONLY = ("infill_percentage", "kgon_x_shrink", "voxel_mm")


def _config_error(err: ValidationError, prefix: str) -> ConfigError:
    lines = []
    for e in err.errors():
        parts = [str(p) for p in e["loc"]]
        # a discriminated union puts its tag in the path (metric.stretched.stretch): drop it
        parts = [p for i, p in enumerate(parts) if not (i and parts[i - 1] == "metric" and p in _METRIC_KINDS)]
        loc = ".".join(parts)
        field = f"{prefix}.{loc}" if loc else prefix
        value = e.get("input")
        shown = "" if isinstance(value, dict) else f" {value!r}:"
        msg = "required key is missing" if e["type"] == "missing" else TYPE_WORDS.get(e["type"], e["msg"])
        lines.append(f"{field}:{shown} {msg}")
    return ConfigError("; ".join(lines))


def parse_design(data: Mapping[str, Any], *, overrides: Mapping[str, Any] | None = None,
                 source: str = "design") -> CellDesign:
    """Validate a design mapping (a parsed ``cells/*.toml``), with optional overrides.

    ``overrides`` may set ``seed`` (the seeds' RNG seed) and ``relative_density`` (foams and
    polyfoams), ``resolution`` (all but polyfoams, whose grid follows ``voxel_mm``),
    ``infill_percentage``, ``kgon_x_shrink`` and ``voxel_mm`` (polyfoams). For a polyfoam
    ``relative_density`` rho means ``infill_percentage = 100 rho`` (the volume-fraction
    density model). ``None`` values are ignored. Errors are :class:`ConfigError` naming the
    field as ``{source}.field.subfield`` and the allowed range.
    """
    data = dict(data)
    kind = data.get("kind", "foam")
    if kind not in _KINDS:
        raise ConfigError(f"{source}.kind: {kind!r}: expected one of {', '.join(_KINDS)}")
    given = {k: v for k, v in (overrides or {}).items() if v is not None}
    if kind == "polyfoam" and "relative_density" in given:
        rho = given.pop("relative_density")
        try:
            infill = 100.0 * float(rho)
        except (TypeError, ValueError):
            raise ConfigError(f"relative_density: {rho!r}: expected a number in [0.01, 0.9]") from None
        if "infill_percentage" in given and abs(float(given["infill_percentage"]) - infill) > 1e-9:
            raise ConfigError(
                f"relative_density: {rho!r}: disagrees with infill_percentage {given['infill_percentage']!r} "
                "(under the volume_fraction model infill_percentage = 100 relative_density); give one"
            )
        given["infill_percentage"] = infill
    for key, value in given.items():
        if key == "seed":
            if kind not in ("foam", "polyfoam"):
                raise ConfigError(f"seed: {value!r}: only foam and polyfoam designs have seeds (this is a {kind})")
            data["seeds"] = {**dict(data.get("seeds", {})), "seed": value}
        elif key == "relative_density":
            if kind != "foam":
                raise ConfigError(f"relative_density: {value!r}: only foam designs have one (this is a {kind})")
            data[key] = value
        elif key == "resolution":
            if kind == "polyfoam":
                raise ConfigError(
                    f"resolution: {value!r}: a polyfoam's grid follows voxel_mm (its voxel edge [mm]); "
                    "override voxel_mm instead"
                )
            data[key] = value
        elif key in _POLYFOAM_ONLY:
            if kind != "polyfoam":
                raise ConfigError(f"{key}: {value!r}: only polyfoam designs have one (this is a {kind})")
            data[key] = value
        else:
            raise ConfigError(
                f"overrides: {key!r}: expected resolution, seed, relative_density, infill_percentage, "
                "kgon_x_shrink or voxel_mm"
            )
    if isinstance(data.get("metric"), Mapping) and "kind" not in data["metric"]:
        data["metric"] = {"kind": "stretched", **data["metric"]}
    try:
        # strict, as pipeline files: no string or bool read as a number
        return _KINDS[kind].model_validate_json(json.dumps(data), strict=True)
    except ValidationError as err:
        raise _config_error(err, source) from None


@dataclass(frozen=True, eq=False)
class CellResult:
    """A built unit cell.

    Attributes
    ----------
    design : the validated design.
    phases : (nx, ny, nz) uint8, 0 void, 1.. material phases; ``[i, j, k]`` along x, y, z
        (cubic, n = nx = ny = nz, for all but polyfoams).
    size : (3,) [mm] the periodic box.
    axis : longitudinal axis index (0, 1, 2).
    materials : phase -> :class:`~metasheet.mechanics.material.Isotropic`.
    relative_density : solid voxels / all voxels [-].
    foam : the :class:`Foam` (foam and polyfoam designs), else None.
    solution : the thickness solve (foam designs), else None.
    connectivity : report of the final phases.
    removed_voxels : solid voxels of small islands dropped after voxelisation.
    chords : (3,) mean void chord lengths along x, y, z [mm] (NaN without void).
    layer_fractions : achieved volume fraction of each phase (laminates), else ().
    polyfoam : the scale solve (polyfoam designs), else None.
    """

    design: CellDesign
    phases: np.ndarray
    size: np.ndarray
    axis: int
    materials: dict[int, Isotropic]
    relative_density: float
    foam: Foam | None
    solution: ThicknessSolution | None
    connectivity: ConnectivityReport
    removed_voxels: int = 0
    chords: np.ndarray | None = None
    layer_fractions: tuple[float, ...] = ()
    polyfoam: PolyfoamSolution | None = None

    @property
    def shape(self) -> tuple[int, int, int]:
        """(nx, ny, nz) voxels along x, y, z."""
        return tuple(int(v) for v in self.phases.shape)

    @property
    def resolution(self) -> int | tuple[int, int, int]:
        """Voxels per side of a cubic grid, else the grid's :attr:`shape`."""
        sh = self.shape
        return sh[0] if sh[0] == sh[1] == sh[2] else sh

    @property
    def voxel_mm(self) -> np.ndarray:
        """(3,) voxel edges [mm]."""
        return self.size / np.array(self.shape)

    @property
    def axis_vector(self) -> np.ndarray:
        """(3,) unit vector of the longitudinal axis."""
        return np.eye(3)[self.axis]

    @property
    def field(self) -> Callable[[np.ndarray], np.ndarray] | None:
        """The foam's level set (:func:`foam_field`; polyfoams: :class:`PolyfoamField`), None for
        laminates and solids."""
        if self.polyfoam is not None:
            return PolyfoamField(self.foam, self.polyfoam)
        return None if self.foam is None else foam_field(self.foam)

    def summary(self) -> dict:
        """JSON-able description (no arrays): what ``cell.json`` holds besides the design."""
        out: dict[str, Any] = {
            "name": self.design.name,
            "kind": self.design.kind,
            "size_mm": [float(v) for v in self.size],
            "axis": int(self.axis) + 1,
            "axis_vector": self.axis_vector.tolist(),
            "resolution": self.resolution if isinstance(self.resolution, int) else list(self.resolution),
            "grid_shape": list(self.shape),
            "voxel_mm": [float(v) for v in self.voxel_mm],
            "relative_density": float(self.relative_density),
            "materials": {str(k): {"E": m.E, "nu": m.nu} for k, m in sorted(self.materials.items())},
            "connectivity": self.connectivity.to_dict(),
        }
        if self.foam is not None and self.solution is not None:
            s = self.solution
            key = "strut_radius_mm" if self.foam.topology == "open" else "wall_thickness_mm"
            out.update({
                "topology": self.foam.topology,
                key: s.thickness,
                "target_relative_density": s.target,
                "volume_estimate": s.volume_estimate,
                "reachable_relative_density": list(s.reachable),
                "removed_island_voxels": int(self.removed_voxels),
                "seed_count": int(len(self.foam.seeds)),
                "metric": self.foam.metric.describe(),
                "mean_void_chord_mm": [float(v) for v in self.chords],
            })
        if self.polyfoam is not None:
            d, p = self.design, self.polyfoam
            out.update({
                "icesl": {k: getattr(d, k) for k in (
                    "infill_percentage", "kgon_x_shrink", "kgon_min_angle", "kgon_norm_alpha",
                    "infill_angle", "bead_width", "layer_height")},
                "kgon_sides": int(d.kgon_sides),
                "density_model": d.density_model,
                "wall_measure": d.wall_measure,
                "layer_model": d.layer_model,
                "seed_space": d.seed_space,
                "layers": p.layers,
                "layer_mm": p.layer_mm,
                "topology": "closed",
                "wall_thickness_mm": p.wall_thickness,
                "cell_scale_mm": p.cell_scale,
                "cell_scale_first_estimate_mm": p.first_estimate,
                "target_relative_density": p.target,
                "volume_estimate": p.volume_estimate,
                "scale_iterations": p.iterations,
                "removed_island_voxels": int(self.removed_voxels),
                "seed_count": int(len(self.foam.seeds)),
                "metric": self.foam.metric.describe(),
                "mean_void_chord_mm": [float(v) for v in self.chords],
                "modelled": f"walls one bead thick ({d.wall_measure} to the wall); infill_angle applied "
                            "by the sheet's orientation field; layer_height "
                            + ("as a staircase" if d.layer_model == "staircase" else "not modelled"),
            })
        if self.layer_fractions:
            out["layer_fractions"] = list(self.layer_fractions)
        return out


def design_cell(design: CellDesign, resolution: int | None = None) -> CellResult:
    """Build the unit cell of ``design`` on an ``n^3`` voxel grid.

    Parameters
    ----------
    design : a validated design (:func:`parse_design`).
    resolution : voxels per side; default ``design.resolution``.

    Raises
    ------
    InfeasibleError : the density is out of reach at this resolution, or the foam does not
        hold together (several large pieces) or does not percolate along x, y and z.

    A polyfoam's grid is non-cubic and follows its ``voxel_mm``; ``resolution`` is refused.
    """
    if isinstance(design, PolyfoamDesign):
        if resolution is not None:
            raise ConfigError(f"resolution: {resolution!r}: a polyfoam's grid follows voxel_mm; set that instead")
        return CellResult(**build_polyfoam(design))
    n = design.resolution if resolution is None else int(resolution)
    if not 4 <= n <= 512:
        raise ConfigError(f"resolution: {resolution!r}: expected an integer in [4, 512]")
    size = np.asarray(design.size, dtype=float)
    axis = design.axis - 1
    if isinstance(design, FoamDesign):
        return _design_foam(design, n, size, axis)
    if isinstance(design, LaminateDesign):
        return _design_laminate(design, n, size, axis)
    phases = np.ones((n, n, n), dtype=np.uint8)
    return CellResult(design, phases, size, axis, {1: design.material.material()}, 1.0, None, None,
                      check_percolation(phases))


def _design_foam(design: FoamDesign, n: int, size: np.ndarray, axis: int) -> CellResult:
    metric = design.metric.build(axis)
    sd = design.seeds
    seeds = make_seeds(sd.sampler, sd.count, size, sd.seed, scale=metric.scale, jitter=sd.jitter,
                       min_distance=sd.min_distance)
    sk = SkeletonIndex(seeds, size, metric).distances(voxel_centres(size, n))
    dist = sk.strut if design.topology == "open" else sk.wall
    sol = solve_thickness(seeds, size, metric, design.topology, design.relative_density, n,
                          min_voxels=design.min_voxels, distances=dist)
    foam = Foam(seeds, size, metric, design.topology, sol.thickness, axis)
    offset = foam.thickness if foam.topology == "open" else 0.5 * foam.thickness
    phases = ((dist - offset) < 0.0).astype(np.uint8).reshape(n, n, n)  # == voxelize(foam, n)
    where = f"design {design.name!r} ({design.topology}-cell, resolution {n})"
    phases, report, removed, rho = settle_phases(
        phases, target=design.relative_density, tolerance=design.tolerance,
        max_island_fraction=design.max_island_fraction, setting=f"relative_density: {design.relative_density:g}",
        where=where, hints=("raise relative_density or resolution",
                            "raise relative_density or resolution, or lower the stretch",
                            "raise the resolution"))
    return CellResult(
        design=design, phases=phases, size=size, axis=axis,
        materials={1: design.material.material()}, relative_density=rho, foam=foam, solution=sol,
        connectivity=report, removed_voxels=removed, chords=mean_chord_lengths(phases == 0, size),
    )


def _design_laminate(design: LaminateDesign, n: int, size: np.ndarray, axis: int) -> CellResult:
    fractions = np.array([layer.fraction for layer in design.layers])
    if abs(fractions.sum() - 1.0) > 1e-9:
        raise ConfigError(
            f"design.layers: fractions {fractions.tolist()} sum to {fractions.sum():g}: they must sum to 1"
        )
    bounds = np.rint(np.concatenate([[0.0], np.cumsum(fractions)]) * n).astype(int)
    counts = np.diff(bounds)
    if np.any(counts < 1):
        raise ConfigError(
            f"design.layers: fractions {fractions.tolist()}: a layer gets no voxel at resolution {n}; "
            "raise the resolution"
        )
    profile = np.repeat(np.arange(1, len(counts) + 1, dtype=np.uint8), counts)
    shape = [1, 1, 1]
    shape[axis] = n
    phases = np.broadcast_to(profile.reshape(shape), (n, n, n)).copy()
    materials = {i + 1: layer.material.material() for i, layer in enumerate(design.layers)}
    return CellResult(design, phases, size, axis, materials, 1.0, None, None, check_percolation(phases),
                      layer_fractions=tuple(float(c) / n for c in counts))
