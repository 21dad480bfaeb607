"""Watertight periodic surfaces of a level-set solid clipped to its unit cell.

The solid is ``{x in [0, size] : field(x) < level}`` for a periodic level-set ``field``.

Method: marching tetrahedra on the Kuhn (Freudenthal) subdivision of a regular node grid
that has nodes ON the six box faces. Each grid cube is cut into the 6 tetrahedra along its
(0,0,0)-(1,1,1) diagonal; the wall is the zero set of the piecewise-linear interpolant, and
the caps on the box faces are the same interpolant's negative region clipped on the face
triangles of that subdivision. We chose this over

- ``skimage.measure.marching_cubes`` with a padded grid: the padding puts the caps half a cell
  outside the box (or needs vertex snapping that collapses triangles at box edges) and the cap
  triangulations on opposite faces differ, and
- ``manifold3d.Manifold.level_set``: it calls the field once per point from C++ (slow for a
  vectorised foam field) and cannot give matching caps,

because marching tetrahedra has no ambiguous cases (the surface is a 2-manifold by
construction), every vertex is keyed by the grid edge or grid node it lies on (so the mesh
is welded exactly, without a float tolerance), and the subdivision is translation invariant:
the face x = 0 and the face x = size_x carry the same triangles, and since the grid values on
the last node layer are copies of the first, their cap vertices are bit-identical up to the
translation. The tet mesher (:mod:`metasheet.cells.tetmesh`) relies on that.

Linear interpolation of a convex distance (a strut) puts vertices inside the true surface
and shrinks struts a couple of cells thick by several per cent, so each vertex is refined on
its grid edge with a few Illinois steps on the true field (``refine``); vertices are kept
``T_CLAMP`` of an edge away from grid nodes to avoid slivers. Checks (watertight, manifold,
volume) are in :mod:`metasheet.cells.surface_check`.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
import trimesh

from metasheet.cells.surface_check import SurfaceReport, check_surface  # noqa: F401 (re-export)
from metasheet.errors import ConfigError, MeshError, check_range

Field = Callable[[np.ndarray], np.ndarray]

# The 6 Kuhn tetrahedra of the unit cube: monotone lattice paths (0,0,0) -> (1,1,1).
_PERMS = ((0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0))
_TET_OFFSETS = np.array(
    [
        [(0, 0, 0), np.eye(3, dtype=int)[p[0]], np.eye(3, dtype=int)[p[0]] + np.eye(3, dtype=int)[p[1]], (1, 1, 1)]
        for p in _PERMS
    ],
    dtype=np.int64,
)  # (6, 4, 3): vertices of each tet, in path (componentwise increasing) order

# Marching-tetrahedra table: inside-mask code (bit i = vertex i inside) -> one polygon, the
# cyclic list of tet edges (i, j), i < j, it crosses: a triangle (one vertex separated) or a
# quad (two and two). Quads are split along their shorter diagonal once the vertices are known;
# orientation is fixed afterwards, geometrically.
def _mt_polygon(code: int) -> tuple[tuple[int, int], ...]:
    ins = [i for i in range(4) if code >> i & 1]
    out = [i for i in range(4) if not code >> i & 1]

    def e(a, b):
        return (min(a, b), max(a, b))

    if len(ins) == 1 or len(out) == 1:
        a = ins[0] if len(ins) == 1 else out[0]
        return tuple(e(a, o) for o in range(4) if o != a)
    (i, j), (k, l) = ins, out
    return (e(i, k), e(i, l), e(j, l), e(j, k))


_MT_TABLE = {code: _mt_polygon(code) for code in range(1, 15)}

# Vertices are kept at least this fraction of their grid edge away from its end nodes, so
# there are no near-degenerate triangles; the clamp moves vertices both ways (no volume bias).
T_CLAMP = 0.05


def validate_size(size) -> np.ndarray:
    """``size`` as a (3,) float array [mm], every entry finite and > 0, else ConfigError."""
    s = np.asarray(size, dtype=float)
    if s.shape != (3,) or not np.all(np.isfinite(s)) or np.any(s <= 0):
        raise ConfigError(f"size: {size!r}: expected 3 finite lengths > 0 [mm]")
    return s


def grid_counts(n) -> np.ndarray:
    """``n`` (int or 3 ints) as a (3,) int array, each in [2, 1024], else ConfigError."""
    arr = np.atleast_1d(np.asarray(n))
    if arr.shape == (1,):
        arr = np.repeat(arr, 3)
    if arr.shape != (3,) or not np.all(np.equal(np.mod(arr, 1), 0)):
        raise ConfigError(f"n: {n!r}: expected an integer or 3 integers in [2, 1024]")
    arr = arr.astype(np.int64)
    if np.any(arr < 2) or np.any(arr > 1024):
        raise ConfigError(f"n: {n!r}: allowed range is [2, 1024] cells per axis")
    return arr


def sample_periodic(field: Field, size, n) -> np.ndarray:
    """Field values on the node grid, the last layer copied from the first.

    Returns (n0 + 1, n1 + 1, n2 + 1) float: value at node (i, j, k) = field((i, j, k) * size / n).
    The copy (instead of a second evaluation at x = size) makes opposite faces bit-identical.
    """
    size, n = validate_size(size), grid_counts(n)
    axes = [np.arange(n[a]) * (size[a] / n[a]) for a in range(3)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    vals = np.asarray(field(pts), dtype=float)
    if vals.shape != (len(pts),):
        raise ConfigError(f"field: returned shape {vals.shape}, expected ({len(pts)},) for (n, 3) points")
    if not np.all(np.isfinite(vals)):
        raise ConfigError("field: returned non-finite values")
    vals = vals.reshape(tuple(n))
    return np.pad(vals, ((0, 1), (0, 1), (0, 1)), mode="wrap")


def periodic_isosurface(
    field: Field, size, n, *, level: float = 0.0, refine: int = 3
) -> trimesh.Trimesh:
    """Closed, oriented triangle surface of ``{field < level}`` clipped to the box [0, size].

    field : callable, (m, 3) float [mm] -> (m,) float, periodic with period ``size``, < level
        inside the solid.
    size : (3,) float [mm], the cell box.
    n : int or (3,) int, grid cells per axis (grid spacing size / n), each in [2, 1024].
    level : float, iso-value (same unit as the field).
    refine : int in [0, 10], root-finding steps (Illinois) per vertex on its grid edge with
        the true field. 0 keeps the linear interpolation of the grid values, which shrinks
        thin convex parts (a strut of radius 2 cells loses ~5 % of its volume); 3 puts the
        vertices on the level set to ~1e-4 of a cell for a smooth field.

    Returns a ``trimesh.Trimesh`` (vertices [mm], outward normals) that is watertight and
    manifold, including the cap faces on the box faces; opposite caps are identical up to the
    translation by ``size``. Raises MeshError when the solid is empty at this resolution.
    """
    size, n = validate_size(size), grid_counts(n)
    level = float(check_range("level", level))
    refine = int(check_range("refine", refine, 0, 10))
    vals = sample_periodic(field, size, n) - level
    return surface_from_grid(vals, size, field=field if refine else None, level=level, refine=refine)


def surface_from_grid(
    vals: np.ndarray, size, *, field: Field | None = None, level: float = 0.0, refine: int = 0
) -> trimesh.Trimesh:
    """Marching-tetrahedra surface of ``{vals < 0}`` on a node grid spanning [0, size].

    vals : (n0 + 1, n1 + 1, n2 + 1) float, node values (negative inside); the last layer of
        each axis must equal the first for opposite caps to match.
    size : (3,) float [mm].
    field, level, refine : optional root refinement of the vertices (see
        :func:`periodic_isosurface`); ``vals`` must then be ``field - level`` at the nodes.
    """
    size = validate_size(size)
    vals = np.array(vals, dtype=float)
    shape = np.array(vals.shape, dtype=np.int64)
    n = shape - 1
    h = size / n
    vals[vals == 0] = np.finfo(float).tiny  # exact zeros count as outside
    inside = vals < 0
    if not inside.any():
        raise MeshError("periodic_isosurface: the solid {field < level} is empty at this grid resolution")

    strides = np.array([shape[1] * shape[2], shape[2], 1], dtype=np.int64)
    flat = vals.ravel()
    n_nodes = flat.size

    # --- wall: marching tetrahedra in the cubes whose corners change sign -------------------
    cube_any = np.zeros(tuple(n), dtype=bool)
    cube_all = np.ones(tuple(n), dtype=bool)
    for c in np.ndindex(2, 2, 2):
        sl = inside[c[0] : c[0] + n[0], c[1] : c[1] + n[1], c[2] : c[2] + n[2]]
        cube_any |= sl
        cube_all &= sl
    cubes = np.argwhere(cube_any & ~cube_all)  # (c, 3)
    polys, refs = [], []  # (k, 4) vertex keys (-1 pads a triangle), (k, 3) outward directions
    if len(cubes):
        ijk = (cubes[:, None, None, :] + _TET_OFFSETS[None]).reshape(-1, 4, 3)  # (m, 4, 3)
        v = flat[ijk @ strides]  # (m, 4)
        code = ((v < 0) * (1 << np.arange(4))).sum(axis=1)
        for cd, poly in _MT_TABLE.items():
            sel = np.flatnonzero(code == cd)
            if not len(sel):
                continue
            pts = ijk[sel] * h  # (s, 4, 3) node positions [mm]
            out = (v[sel] > 0)[..., None]
            n_out = out.sum(axis=1)
            # direction from the inside nodes' centroid to the outside nodes' centroid
            refs.append((out * pts).sum(1) / n_out - (~out * pts).sum(1) / (4 - n_out))
            k = np.full((len(sel), 4), -1, dtype=np.int64)
            for col, (a, b) in enumerate(poly):
                k[:, col] = _edge_key(ijk[sel, a], ijk[sel, b], strides)
            polys.append(k)

    # --- caps: the negative region on the face triangles of the six box faces ---------------
    for axis in range(3):
        for side in (0, 1):
            k, ref = _cap_polygons(inside, strides, shape, axis, side, n_nodes)
            polys.append(k)
            refs.append(ref)
    polys = np.concatenate(polys)
    refs = np.concatenate(refs)
    if not len(polys):
        raise MeshError("periodic_isosurface: no surface triangles (empty solid)")

    uniq, poly_v = np.unique(polys, return_inverse=True)
    poly_v = poly_v.reshape(-1, 4) - (1 if uniq[0] == -1 else 0)
    uniq = uniq[uniq >= 0]
    verts = _key_positions(uniq, flat, strides, shape, size, field, level, refine)
    faces, _ = _split_polygons(poly_v, refs, verts)
    return trimesh.Trimesh(vertices=verts, faces=faces, process=False, validate=False)


def _edge_key(a_ijk: np.ndarray, b_ijk: np.ndarray, strides: np.ndarray) -> np.ndarray:
    """Key of the Kuhn grid edge a -> b (b - a in {0, 1}^3 \\ 0): 7 * node(a) + type."""
    d = b_ijk - a_ijk
    typ = d[:, 0] + 2 * d[:, 1] + 4 * d[:, 2] - 1
    return (a_ijk @ strides) * 7 + typ


def _cap_polygons(inside, strides, shape, axis, side, n_nodes):
    """Clip the face triangles of one box face by the negative region.

    Face squares are split along their (0,0)-(1,1) diagonal, as the Kuhn tets' faces are, so the
    cap edges are grid edges shared with the wall. Returns (k, 4) cyclic vertex keys (edge keys,
    or 7 * n_nodes + node for grid nodes; -1 pads triangles) and (k, 3) outward directions.
    """
    u, w = [a for a in range(3) if a != axis]
    iu, iw = np.meshgrid(np.arange(shape[u] - 1), np.arange(shape[w] - 1), indexing="ij")
    base = np.zeros((iu.size, 3), dtype=np.int64)
    base[:, axis] = side * (shape[axis] - 1)
    base[:, u], base[:, w] = iu.ravel(), iw.ravel()
    eu, ew = np.eye(3, dtype=np.int64)[u], np.eye(3, dtype=np.int64)[w]
    polys = []
    for mid in (eu, ew):
        corners = np.stack([base, base + mid, base + eu + ew], axis=1)  # (q, 3, 3) monotone
        node = corners @ strides
        code = (inside.ravel()[node] * np.array([1, 2, 4])).sum(axis=1)
        for cd in range(1, 8):
            sel = np.flatnonzero(code == cd)
            if not len(sel):
                continue
            c, nd = corners[sel], node[sel]
            il = [i for i in range(3) if cd >> i & 1]
            ol = [i for i in range(3) if not cd >> i & 1]

            def ek(a, b):
                return _edge_key(c[:, min(a, b)], c[:, max(a, b)], strides)

            def nk(a):
                return 7 * n_nodes + nd[:, a]

            pad = np.full(len(sel), -1, dtype=np.int64)
            if len(il) == 3:
                cols = [nk(0), nk(1), nk(2), pad]
            elif len(il) == 1:
                a = il[0]
                cols = [nk(a), ek(a, ol[0]), ek(a, ol[1]), pad]
            else:
                (a, b), o = il, ol[0]
                cols = [nk(a), nk(b), ek(b, o), ek(a, o)]
            polys.append(np.stack(cols, axis=1))
    keys = np.concatenate(polys) if polys else np.empty((0, 4), dtype=np.int64)
    ref = np.zeros((len(keys), 3))
    ref[:, axis] = 1.0 if side else -1.0
    return keys, ref


def _split_polygons(poly_v, refs, verts):
    """Triangles (t, 3) from polygons (k, 4) (-1 pads triangles), quads cut along the shorter
    diagonal, every triangle turned so its normal points along its polygon's ``refs`` row."""
    is_quad = poly_v[:, 3] >= 0
    tri = poly_v[~is_quad, :3]
    q = poly_v[is_quad]
    p = verts[q]
    d02 = np.sum((p[:, 2] - p[:, 0]) ** 2, axis=1)
    d13 = np.sum((p[:, 3] - p[:, 1]) ** 2, axis=1)
    use02 = (d02 <= d13)[:, None]
    t1 = np.where(use02, q[:, [0, 1, 2]], q[:, [0, 1, 3]])
    t2 = np.where(use02, q[:, [0, 2, 3]], q[:, [1, 2, 3]])
    faces = np.concatenate([tri, t1, t2])
    ref_vec = np.concatenate([refs[~is_quad], refs[is_quad], refs[is_quad]])
    x = verts[faces]
    normal = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    flip = np.einsum("ij,ij->i", normal, ref_vec) < 0
    faces[flip] = faces[flip][:, ::-1]
    return faces, ref_vec


def _key_positions(keys, flat, strides, shape, size, field=None, level=0.0, refine=0):
    """Vertex positions [mm] of edge keys (zero crossing) and node keys (the node).

    Positions are computed in the first periodic copy of the grid (node layer n -> 0) and
    shifted back by exactly ``size``, so a vertex on a far box face is the bit-exact
    translate of its partner on the near face.
    """
    n = shape - 1
    h = size / n
    n_nodes = int(np.prod(shape))
    pos = np.empty((len(keys), 3))
    is_node = keys >= 7 * n_nodes

    def ijk_of(node):
        return np.stack([node // strides[0], (node // strides[1]) % shape[1], node % shape[2]], axis=1)

    ijk = ijk_of(keys[is_node] - 7 * n_nodes)
    far = ijk == n
    pos[is_node] = (ijk - far * n) * h + far * size
    ek = keys[~is_node]
    a = ek // 7
    typ = ek % 7 + 1
    d = np.stack([typ & 1, (typ >> 1) & 1, (typ >> 2) & 1], axis=1)
    a_ijk = ijk_of(a)
    far = a_ijk == n  # the whole edge lies in a far face layer
    pa = (a_ijk - far * n) * h
    pb = pa + d * h
    fa, fb = flat[a], flat[(a_ijk + d) @ strides]
    t = _edge_roots(pa, pb, fa, fb, field, level, refine)
    pos[~is_node] = (pa + t[:, None] * (pb - pa)) + far * size
    return pos


def _edge_roots(pa, pb, fa, fb, field, level, refine):
    """Zero crossing t in [T_CLAMP, 1 - T_CLAMP] of the field on the segments pa -> pb.

    fa, fb : values at the ends (opposite signs). With ``refine`` > 0, Illinois (modified
    regula falsi) steps on the true field, all segments at once (one field call per step).
    """
    ta, tb = np.zeros(len(fa)), np.ones(len(fa))
    fa, fb = fa.copy(), fb.copy()
    last = np.zeros(len(fa), dtype=np.int8)  # which end was replaced last (-1 a, +1 b)
    for _ in range(refine if field is not None else 0):
        t = (ta * fb - tb * fa) / (fb - fa)
        ft = np.asarray(field(pa + t[:, None] * (pb - pa)), dtype=float) - level
        on_a = np.sign(ft) == np.sign(fa)
        # Illinois: halve the kept end's value when the same end is replaced twice in a row
        fb = np.where(on_a & (last == -1), 0.5 * fb, fb)
        fa = np.where(~on_a & (last == 1), 0.5 * fa, fa)
        ta, fa = np.where(on_a, t, ta), np.where(on_a, ft, fa)
        tb, fb = np.where(on_a, tb, t), np.where(on_a, fb, ft)
        last = np.where(on_a, -1, 1).astype(np.int8)
    t = (ta * fb - tb * fa) / (fb - fa)
    return np.clip(t, T_CLAMP, 1.0 - T_CLAMP)
