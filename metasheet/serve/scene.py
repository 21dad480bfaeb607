"""What the page draws of a robot state: the sheets' surface in colour bands, horns, rod, fibres.

Pure functions of a :class:`.loading.RobotGeometry` and a state's node positions ``x``
(n, 3) [mm]; the page (:mod:`.app`) sends their output to the browser.

* The surface is the sheets' boundary: each boundary face of a tetrahedron once, a quadratic
  (10-node) face split into its 4 sub-triangles through the midside nodes, so the bent
  sheet is drawn as the FEM bends it.
* A field is drawn in :data:`BANDS` colour bands, one single-coloured mesh per band (the
  browser library's meshes carry one colour each; a band per colour keeps each update to
  positions and faces, no texture): like a FEM post-processor's contour plot. Per face:
  the displacement magnitude |x - X| [mm] (mean of its vertices), the element's largest
  principal Green-Lagrange strain [-] against the validity limit (faces beyond it in
  :data:`OVER_LIMIT` red), or the element's fibre axis angle [deg] (cyclic colours).
* Fibres: a segment per element at its centroid along ``F f`` (F the element's deformation
  gradient from its corner nodes, f the fibre at rest), normalised to :data:`FIBER_LENGTH`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: the fields a surface can be coloured by: (label, unit)
FIELDS = {"displacement": ("|u|", "mm"), "strain": ("max principal strain", "-"),
          "fiber angle": ("fibre axis angle", "deg")}
BANDS = 12
OVER_LIMIT = (230, 20, 60)  # faces whose strain exceeds the validity limit [RGB]
FIBER_LENGTH = 4.0  # [mm]
MAX_FIBERS = 1200  # segments drawn at most (every k-th element beyond)

#: a tetrahedron's faces (corner indices) and, for the 10-node one, the midside node of each
#: edge (edges (0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3) -> nodes 4..9, :mod:`metasheet.fem.tet10`)
TET_FACES = np.array([[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]])
MIDSIDE = np.full((4, 4), -1)
for _k, (_i, _j) in enumerate(((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3))):
    MIDSIDE[_i, _j] = MIDSIDE[_j, _i] = 4 + _k


@dataclass(frozen=True)
class Surface:
    """The sheets' boundary as triangles on the robot's nodes.

    nodes : (v,) int, the robot nodes on the boundary; faces : (f, 3) int into ``nodes``;
    element : (f,) int, the element each triangle belongs to.
    """

    nodes: np.ndarray
    faces: np.ndarray
    element: np.ndarray


def surface(tets, rest) -> Surface:
    """The boundary of a tetrahedral mesh ``tets`` (m, 4) or (m, 10) with node positions
    ``rest`` (n, 3) [mm] (see the module docstring), each triangle wound outwards."""
    tets = np.asarray(tets, dtype=np.int64)
    corners = tets[:, TET_FACES].reshape(-1, 3)  # (4 m, 3)
    key = np.sort(corners, axis=1)
    _, inv, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    outer = np.flatnonzero(count[inv.ravel()] == 1)  # faces no other element shares
    elem, local = outer // 4, TET_FACES[outer % 4]
    # wind every face outwards (right-handed about the normal pointing away from the
    # element's fourth corner): the browser's shading normals then agree across the sheet
    X = np.asarray(rest, float)
    opposite = 6 - local.sum(axis=1)  # the corner not on the face (0 + 1 + 2 + 3 = 6)
    a, b, c, d = (X[tets[elem, k]] for k in (local[:, 0], local[:, 1], local[:, 2], opposite))
    inward = np.einsum("ij,ij->i", np.cross(b - a, c - a), d - a) > 0
    local = np.where(inward[:, None], local[:, [0, 2, 1]], local)
    if tets.shape[1] == 10:
        a, b, c = local.T
        ab, bc, ac = MIDSIDE[a, b], MIDSIDE[b, c], MIDSIDE[a, c]
        loc = np.stack([np.stack([a, ab, ac], 1), np.stack([ab, b, bc], 1), np.stack([ac, bc, c], 1),
                        np.stack([ab, bc, ac], 1)], axis=1).reshape(-1, 3)
        elem = np.repeat(elem, 4)
    else:
        loc = local
    tri = tets[elem[:, None], loc]  # (f, 3) robot node indices
    nodes, faces = np.unique(tri, return_inverse=True)
    return Surface(nodes, faces.reshape(-1, 3), elem)


def band_of(values, lo: float, hi: float, bands: int = BANDS) -> np.ndarray:
    """(k,) int band in [0, bands) of ``values`` (k,) on [lo, hi] (clipped)."""
    t = (np.asarray(values, float) - lo) / max(hi - lo, 1e-300)
    return np.clip((t * bands).astype(int), 0, bands - 1)


def band_colors(field: str, bands: int = BANDS) -> np.ndarray:
    """(bands, 3) uint8 RGB of each band of ``field`` (:data:`FIELDS`)."""
    from matplotlib import colormaps

    cmap = colormaps["twilight" if field == "fiber angle" else "viridis"]
    return (255 * np.asarray(cmap((np.arange(bands) + 0.5) / bands))[:, :3]).astype(np.uint8)


def face_values(field: str, surf: Surface, geometry, x, strain=None) -> np.ndarray:
    """(f,) value of ``field`` per surface triangle at positions ``x`` (n, 3) [mm];
    ``strain`` (m,) the elements' largest principal strains (field "strain")."""
    if field == "displacement":
        u = np.linalg.norm(np.asarray(x)[surf.nodes] - geometry.rest[surf.nodes], axis=1)
        return u[surf.faces].mean(axis=1)
    if field == "strain":
        if strain is None:
            return np.full(len(surf.faces), np.nan)
        return np.asarray(strain)[surf.element]
    if field == "fiber angle":
        return geometry.fiber_angle[surf.element]
    raise ValueError(f"field: {field!r}: allowed {', '.join(FIELDS)}")


#: the smallest displacement colour range [mm]: the rest pose's sag (~0.01 mm) is not coloured as noise
MIN_DISPLACEMENT = 1.0


def field_range(field: str, values, strain_limit: float) -> tuple[float, float]:
    """The colour range [lo, hi] of ``field``: displacement from 0 to its maximum rounded
    up (1, 2 or 5 times a power of ten, at least :data:`MIN_DISPLACEMENT`) so the bands do
    not flicker; strain 0 to the limit; fibre angle 0 to 180 deg."""
    if field == "strain":
        return 0.0, float(strain_limit)
    if field == "fiber angle":
        return 0.0, 180.0
    top = float(np.nanmax(values)) if np.size(values) and np.any(np.isfinite(values)) else 0.0
    if top <= MIN_DISPLACEMENT:
        return 0.0, MIN_DISPLACEMENT
    p = 10.0 ** np.floor(np.log10(top))
    return 0.0, float(next(k * p for k in (1, 2, 5, 10) if k * p >= top))


def band_meshes(surf: Surface, x, values, lo: float, hi: float, *, limit: float | None = None,
                bands: int = BANDS) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per band, (vertices (k, 3) [mm], faces (j, 3)) of the triangles whose value falls in
    it; with ``limit``, one more band (last) for the values above it; NaN values: band 0."""
    v = np.nan_to_num(np.asarray(values, float), nan=lo)
    band = band_of(v, lo, hi, bands)
    if limit is not None:
        band = np.where(v > limit, bands, band)
    xs = np.asarray(x)[surf.nodes]
    out = []
    for k in range(bands + (limit is not None)):
        f = surf.faces[band == k]
        used, local = np.unique(f, return_inverse=True)
        out.append((xs[used], local.reshape(-1, 3)))
    return out


def horn_segments(geometry, x) -> np.ndarray:
    """(na, 2, 3) [mm]: each servo horn from its pivot to the centre of the nodes it holds."""
    tips = np.stack([np.asarray(x)[n].mean(axis=0) for n in geometry.horn_nodes])
    return np.stack([geometry.pivots, tips], axis=1)


def rod_segment(geometry, p, R) -> np.ndarray:
    """(1, 2, 3) [mm]: the rod, ``rod_length`` along the effector's axis through ``p``."""
    d = 0.5 * geometry.rod_length * (np.asarray(R) @ geometry.axis)
    return np.stack([p - d, p + d])[None]


def fiber_segments(geometry, x, *, length: float = FIBER_LENGTH, max_count: int = MAX_FIBERS) -> np.ndarray:
    """(k, 2, 3) [mm]: fibre segments at element centroids along the deformed fibre ``F f``."""
    step = max(1, int(np.ceil(len(geometry.tets) / max_count)))
    t, f = geometry.tets[::step, :4], geometry.fibers[::step]
    X, xx = geometry.rest[t], np.asarray(x)[t]  # (k, 4, 3) [mm]
    DX = np.transpose(X[:, 1:] - X[:, :1], (0, 2, 1))  # columns: edges from corner 0
    Dx = np.transpose(xx[:, 1:] - xx[:, :1], (0, 2, 1))
    F = Dx @ np.linalg.inv(DX)
    d = np.einsum("kij,kj->ki", F, f)
    d *= 0.5 * length / np.linalg.norm(d, axis=1, keepdims=True)
    c = xx.mean(axis=1)
    return np.stack([c - d, c + d], axis=1)


def strain_flag(strain, limit: float) -> tuple[float, bool]:
    """(largest principal strain over the elements [-], whether it is within ``limit``)."""
    if strain is None or len(strain) == 0:
        return float("nan"), True
    top = float(np.max(strain))
    return top, top <= limit
