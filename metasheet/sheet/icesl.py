"""IceSL print map: the foam's setting fields on a 64^3 grid, their files and the solid parts.

IceSL (https://icesl.loria.fr) varies print settings in space through 3D textures made in
its Lua modelling script: ``tex = tex3d_r8f(64, 64, 64)``, ``tex:set(i, j, k, v(x, 0, 0))``
and ``set_setting_value(name, tex, v(xmin, ymin, zmin), v(xmax, ymax, zmax))``, the box in
world millimetres, i, j, k along x, y, z. Texture values lie in [0, 1].

Texture scales (:data:`FIELD_SCALE`; setting value = scale * texture value):

- ``infill_percentage`` [%]: value / 100 (0 = 0 %, 1 = 100 %).
- ``infill_angle`` [deg]: value / 360 (1 = 360 deg). The angle is that of the foam's soft
  axis l (the k-gon's shrunk local x) in the print plane; an axis, so only the angle
  modulo 180 deg matters. How its branch is chosen: :mod:`metasheet.sheet.angles`.
- ``kgon_x_shrink`` [-]: the ratio itself. Assumption (ICESL.md: the ranges of the settings
  are not documented): IceSL maps a shrink texture linearly onto [0, 1].

``tex3d_r8f`` stores 8 bits: IceSL holds :func:`quantise` (v) = round(255 v) / 255, an error
of at most 1 / 510 of the scale (0.196 %, 0.706 deg, 0.00196). The files hold 4 decimals.

Texel (i, j, k) is sampled at its centre ``lo + (i + 1/2) (hi - lo) / 64``; the slicer is
taken to interpolate trilinearly between texel centres, clamped at the box faces
(:func:`sample`). Texels whose centre lies outside the part take the value of the nearest
inside texel (Euclidean distance in mm), so the interpolation at the boundary sees no
spurious values.

Field files are text: 64 numbers per line (i = 0..63), lines ordered j fastest then k,
so value number c (from 0) is texel (c mod 64, (c // 64) mod 64, c // 4096).

Solid parts (:func:`solid_mask`, :func:`solid_parts_mesh`): the centre ring (r <= the sheet's
``centre_radius``, where the model ties the nodes to the effector) and the arm-end tabs (the
``tip_box`` of each arm, where the servo horn holds it) print solid, as brush 1; the rest
of the sheet is the foam, brush 0. The Lua script (:mod:`metasheet.sheet.icesl_lua`) splits
the sheet with IceSL's CSG (``difference`` / ``intersection`` of the sheet and
``solid.stl``), as IceSL's own two-brush "paint brushes" effect does
(shapeforge/icesl-effects, paintbrush.lua), so the result does not depend on how IceSL
resolves overlapping brushes.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from ..errors import ConfigError
from .angles import AngleBranch, choose_branch
from .fibers import fiber_angles
from .grid import GridBox, N, grid_box
from .outline import ARM_ANGLES, SheetParams

LEVELS = 255  # tex3d_r8f: 8 bits per texel

FIELD_SCALE = {"infill_percentage": 100.0, "infill_angle": 360.0, "kgon_x_shrink": 1.0}
FIELD_UNITS = {"infill_percentage": "%", "infill_angle": "deg", "kgon_x_shrink": "-"}
ANGLE = "infill_angle"
#: IceSL's defaults of the Polyfoam settings (ICESL.md); a setting equal to its default is not written
POLYFOAM_DEFAULTS = {"infill_percentage": 20.0, "infill_angle": 0.0, "kgon_x_shrink": 1.0,
                     "kgon_min_angle": 45.0, "kgon_norm_alpha": 0.5}
#: the foam brush prints no skin: no perimeter, no shells, no top/bottom cover (ICESL.md)
FOAM_BRUSH = {"print_perimeter": False, "num_shells": 0, "cover_thickness_mm": 0.0}
FOAM, SOLID = 0, 1  # brush numbers


def locate(points: np.ndarray, tets: np.ndarray, box: GridBox) -> np.ndarray:
    """Element (n, n, n) int containing each texel centre, -1 outside (VTK cell locator)."""
    import pyvista as pv

    grid = pv.UnstructuredGrid({pv.CellType.TETRA: np.asarray(tets)}, np.asarray(points, dtype=float))
    cell = grid.find_containing_cell(box.centers().reshape(-1, 3))
    return np.asarray(cell, dtype=np.int64).reshape((box.n,) * 3)


def nearest_inside(inside: np.ndarray, spacing: np.ndarray) -> tuple[np.ndarray, ...]:
    """Index arrays of the nearest inside texel of every texel (inside (n, n, n) bool, spacing (3,) [mm])."""
    if not inside.any():
        raise ConfigError("inside: no texel centre lies inside the part; the grid misses the mesh")
    _, idx = ndimage.distance_transform_edt(~inside, sampling=spacing, return_indices=True)
    return tuple(idx)


def extend_nearest(values: np.ndarray, inside: np.ndarray, spacing: np.ndarray) -> np.ndarray:
    """Copy of ``values`` (n, n, n) where outside texels take their nearest inside value.

    ``inside`` (n, n, n) bool must hold at least one True; distance measured in mm
    with the texel ``spacing`` (3,).
    """
    return values[nearest_inside(inside, spacing)]


def quantise(values: np.ndarray) -> np.ndarray:
    """What a ``tex3d_r8f`` texel holds for texture values in [0, 1]: round(255 v) / 255."""
    return np.round(np.asarray(values, dtype=float) * LEVELS) / LEVELS


def sample(texture: np.ndarray, box: GridBox, points: np.ndarray) -> np.ndarray:
    """Trilinear interpolation (m,) of a texture (n, n, n) at points (m, 3) [mm].

    Between texel centres (``lo + (i + 1/2) h``), clamped to the edge texels outside them,
    as a GPU sampler with linear filtering and clamp-to-edge does.
    """
    u = box.texel_coordinates(points)
    return ndimage.map_coordinates(np.asarray(texture, dtype=float), u.T, order=1, mode="nearest")


def stencil_span(texture: np.ndarray, box: GridBox, points: np.ndarray) -> np.ndarray:
    """max - min (m,) of the 8 texels :func:`sample` interpolates between at each point (m, 3)."""
    u = box.texel_coordinates(points)
    i0 = np.clip(np.floor(u).astype(np.int64), 0, box.n - 1)
    i1 = np.clip(i0 + 1, 0, box.n - 1)
    vals = np.stack([texture[a[:, 0], b[:, 1], c[:, 2]]
                     for a in (i0, i1) for b in (i0, i1) for c in (i0, i1)], axis=1)
    return vals.max(axis=1) - vals.min(axis=1)


# ---------------------------------------------------------------------- solid parts

def solid_mask(points: np.ndarray, params: SheetParams) -> np.ndarray:
    """(m,) bool: points (m, 3) [mm] in the solid parts: the centre ring (r_xy <= centre_radius)
    or an arm-end tab (the tip box of an arm, as ``geometry.attach_tags``). Symmetric under
    y -> -y, so it serves the mirrored sheet too."""
    p = np.asarray(points, dtype=float)
    tol = 1e-9  # as attach_tags: the sheet is meshed conforming to these borders, nodes sit on them
    out = np.hypot(p[:, 0], p[:, 1]) <= params.centre_radius + tol
    half = 0.5 * np.asarray(params.tip_box) + tol
    for a in ARM_ANGLES:
        s = p[:, 0] * np.cos(a) + p[:, 1] * np.sin(a)
        q = -p[:, 0] * np.sin(a) + p[:, 1] * np.cos(a)
        out |= (np.abs(s - params.reach) <= half[0]) & (np.abs(q) <= half[1]) & (np.abs(p[:, 2]) <= half[2])
    return out


def solid_parts_mesh(params: SheetParams, *, sections: int = 96) -> tuple[np.ndarray, np.ndarray]:
    """``solid.stl``: the solid regions as closed, disjoint shells (vertices (k, 3) [mm], faces (f, 3)).

    A prism circumscribing the cylinder r <= centre_radius and the three tip boxes, all taller
    than the sheet; the Lua script intersects them with the sheet (the hole stays a hole).
    """
    import trimesh

    t = float(params.thickness)
    height = t + 2.0
    r = params.centre_radius / np.cos(np.pi / sections)  # circumscribed polygon
    parts = [trimesh.creation.cylinder(radius=r, height=height, sections=sections)]
    box = np.array(params.tip_box, dtype=float)
    box[2] = max(box[2], height)
    for a in ARM_ANGLES:
        m = trimesh.creation.box(extents=box)
        rot = trimesh.transformations.rotation_matrix(a, [0, 0, 1])
        m.apply_transform(rot @ trimesh.transformations.translation_matrix([params.reach, 0.0, 0.0]))
        parts.append(m)
    # the ring and the tabs must not overlap: one STL of overlapping shells is ambiguous
    corner = 0.5 * np.hypot(box[0], box[1])
    if params.reach - corner <= r:
        raise ConfigError(
            f"tip_box: {tuple(params.tip_box)!r}: the tip boxes reach the centre ring "
            f"(centre_radius {params.centre_radius:g} mm, reach {params.reach:g} mm)")
    verts, faces, off = [], [], 0
    for m in parts:
        verts.append(np.asarray(m.vertices))
        faces.append(np.asarray(m.faces) + off)
        off += len(m.vertices)
    return np.concatenate(verts), np.concatenate(faces)


# --------------------------------------------------------------------- the fields

@dataclass(frozen=True)
class PrintFields:
    """Texture fields of one sheet.

    box : the :class:`GridBox`; cell : (n, n, n) int, element containing each texel centre
    (-1 outside); solid : (n, n, n) bool, texel centres in the solid parts; textures :
    setting (no brush suffix) -> (n, n, n) float in [0, 1] (unquantised); branch : the
    :class:`AngleBranch` of ``infill_angle``.
    """

    box: GridBox
    cell: np.ndarray
    solid: np.ndarray
    textures: dict[str, np.ndarray]
    branch: AngleBranch

    @property
    def inside(self) -> np.ndarray:
        return self.cell >= 0

    @property
    def foam(self) -> np.ndarray:
        """(n, n, n) bool: texel centres printed as foam (brush 0)."""
        return self.inside & ~self.solid

    def values(self, name: str) -> np.ndarray:
        """Field ``name`` in IceSL units (percent, degrees, ratio), unquantised."""
        return self.textures[name] * FIELD_SCALE[name]


def to_texture(name: str, values: np.ndarray) -> np.ndarray:
    """Texture values (value / scale) of setting ``name``; an error unless all lie in [0, 1]."""
    if name not in FIELD_SCALE:
        raise ConfigError(f"field {name!r}: no texture scale; known fields are {sorted(FIELD_SCALE)}")
    v = np.asarray(values, dtype=float) / FIELD_SCALE[name]
    if not np.all(np.isfinite(v)) or v.min() < 0.0 or v.max() > 1.0:
        s = FIELD_SCALE[name]
        raise ConfigError(f"{name}: values in [{np.nanmin(v) * s:g}, {np.nanmax(v) * s:g}] "
                          f"{FIELD_UNITS[name]}: allowed range is [0, {s:g}]")
    return v


def print_fields(
    points: np.ndarray,
    tets: np.ndarray,
    *,
    element_settings: Mapping[str, np.ndarray],
    fiber_fn: Callable[[np.ndarray], np.ndarray],
    params: SheetParams,
    n: int = N,
    branch: AngleBranch | None = None,
) -> PrintFields:
    """Sample a sheet's print settings on the n^3 texture grid over its bounding box.

    Parameters
    ----------
    points : (k, 3) float [mm]; tets : (m, 4) int.
    element_settings : setting -> (m,) value per element in IceSL units (percent, ratio);
        each texel takes the value of the element containing its centre.
    fiber_fn : fibre field, points (q, 3) [mm] -> unit fibres (q, 3); evaluated at every
        texel centre (inside the part and, continued, outside it), so the texture resolves
        the continuous field rather than the element-wise constant one. Its in-plane angle
        becomes ``infill_angle``.
    params : the sheet geometry (its solid parts, :func:`solid_mask`).
    branch : the angle branch; default :func:`choose_branch` (fewest seam texels in foam).
    """
    tets = np.asarray(tets)
    for name, v in element_settings.items():
        if np.shape(v) != (len(tets),):
            raise ConfigError(f"element_settings[{name!r}]: shape is {np.shape(v)} and should be ({len(tets)},)")
    box = grid_box(points, n)
    cell = locate(points, tets, box)
    inside = cell >= 0
    idx = nearest_inside(inside, box.spacing)
    centres = box.centers()
    solid = solid_mask(centres.reshape(-1, 3), params).reshape(inside.shape)
    textures = {}
    for name, v in element_settings.items():
        full = np.zeros(inside.shape)
        full[inside] = np.asarray(v, dtype=float)[cell[inside]]
        textures[name] = to_texture(name, full[idx])
    # the fibre field is continuous across the part's boundary: texels outside take its value
    # too (not the nearest inside one), so the interpolation there follows the field
    theta, _ = fiber_angles(fiber_fn(centres.reshape(-1, 3)))
    theta_deg = np.degrees(theta).reshape(inside.shape)
    if branch is None:
        branch, _ = choose_branch(theta_deg, inside & ~solid)
    textures[ANGLE] = to_texture(ANGLE, branch.write(theta_deg))
    return PrintFields(box, cell, solid, textures, branch)


def field_text(values: np.ndarray) -> str:
    """Text of one field file (layout in the module doc), 4 decimals per value."""
    v = np.asarray(values, dtype=float)
    if v.ndim != 3 or len(set(v.shape)) != 1:
        raise ConfigError(f"values: shape is {v.shape} and should be (n, n, n)")
    if np.any((v < 0) | (v > 1)) or not np.all(np.isfinite(v)):
        raise ConfigError(f"values: range [{np.nanmin(v):g}, {np.nanmax(v):g}]: allowed range is [0, 1]")
    rows = v.transpose(2, 1, 0).reshape(-1, v.shape[0])  # row (k, j) holds i = 0..n-1
    return "\n".join(" ".join(f"{x:.4f}" for x in row) for row in rows) + "\n"


def parse_field_text(text: str, n: int = N) -> np.ndarray:
    """The (n, n, n) texture a field file holds (inverse of :func:`field_text`)."""
    flat = np.array(text.split(), dtype=float)
    if flat.size != n**3:
        raise ConfigError(f"field text: {flat.size} values: expected {n**3}")
    return flat.reshape(n, n, n).transpose(2, 1, 0)


def surface(points: np.ndarray, tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Boundary triangles of a positively oriented tet mesh, outward normals.

    Returns vertices (k, 3) [mm] (only those on the surface) and faces (f, 3) int.
    """
    t = np.asarray(tets)
    # for a positive tet the faces below are counter-clockwise seen from outside
    faces = np.concatenate([t[:, [0, 2, 1]], t[:, [0, 1, 3]], t[:, [1, 2, 3]], t[:, [0, 3, 2]]])
    key = np.sort(faces, axis=1)
    _, first, count = np.unique(key, axis=0, return_index=True, return_counts=True)
    bnd = faces[np.sort(first[count == 1])]
    used, inv = np.unique(bnd, return_inverse=True)
    return np.asarray(points, dtype=float)[used], inv.reshape(-1, 3)
