"""Periodic tetrahedral meshes of a level-set solid in its unit cell, with gmsh.

What we chose and why. The fully general gmsh path (reclassify an STL into patches, rebuild
a parametrised geometry, ``setPeriodic`` on the cap faces and remesh the surfaces) is fragile
for foams: hundreds of small, disconnected cap patches whose boundary curves must be split
identically on opposite faces. So we build the boundary ourselves and make the faces match
by construction, and let gmsh do only the volume:

1. :func:`metasheet.cells.surface.periodic_isosurface` gives a closed, manifold surface on a
   grid of spacing ``h`` whose caps on opposite box faces are identical triangulations (the
   same grid triangles, the same vertex values, so bit-identical vertices up to the
   translation by the cell size);
2. gmsh (in process, quiet) fills that surface with tetrahedra: the surface triangles go in
   as a discrete surface, a ``geo`` surface loop and volume close it, and the 3D Delaunay
   mesher (``Mesh.Algorithm3D = 1``, then gmsh's optimiser) meshes the inside. Delaunay
   recovers the given boundary without moving it, and HXT was 5x slower here;
3. the result is checked, not trusted: every boundary face of the tet mesh must be one of the
   input triangles (no Steiner points on the boundary), every tet must have positive volume
   (gmsh's few inverted ones are reoriented), the tet volume must equal the surface volume,
   and :func:`periodic_mismatch` must find a partner for every node of every box face within
   1e-9 of the cell size. Any failure is a :class:`~metasheet.errors.MeshError`.

Node pairs (face x_a = 0 node, face x_a = size_a node) per axis are what a periodic FEM
(homogenisation) uses to tie opposite faces.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field as dc_field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from metasheet.cells.surface import Field, check_surface, periodic_isosurface, validate_size
from metasheet.errors import ConfigError, MeshError, check_range

_MODEL_COUNTER = itertools.count()


@dataclass(frozen=True)
class PeriodicTetMesh:
    """A tetrahedral mesh of the solid in the cell box with node-matched opposite faces.

    points : (n, 3) float [mm]
    tets : (m, 4) int, node indices, positively oriented (det[p1-p0, p2-p0, p3-p0] > 0)
    size : (3,) float [mm], the cell box [0, size]
    pairs : dict axis -> (k, 2) int, [node on face x_axis = 0, its image on x_axis = size]
    max_mismatch : float [mm], largest distance between a face node and its partner's image
    volume : float [mm^3], total tet volume
    surface_volume : float [mm^3], volume enclosed by the input surface (equal up to rounding)
    n_surface_triangles : int, boundary triangles (the surface handed to gmsh)
    min_quality : float, smallest 6 sqrt(2) V / l_rms^3 over tets (1 = regular tet)
    n_components : int, connected pieces of the solid with opposite faces glued (1 for a
        solid that holds together periodically; more means floating pieces)
    """

    points: np.ndarray
    tets: np.ndarray
    size: np.ndarray
    pairs: dict = dc_field(repr=False)
    max_mismatch: float = 0.0
    volume: float = 0.0
    surface_volume: float = 0.0
    n_surface_triangles: int = 0
    min_quality: float = 0.0
    n_components: int = 0

    @property
    def relative_density(self) -> float:
        """Solid volume over box volume [-]."""
        return float(self.volume / np.prod(self.size))

    def to_meshio(self):
        """The mesh as a ``meshio.Mesh`` with one ``tetra`` block (for writing ``.vtu``)."""
        import meshio

        return meshio.Mesh(self.points, [("tetra", self.tets)])


def tet_volumes(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Signed volumes [mm^3], (m,), of tets (m, 4) over points (n, 3) [mm]."""
    p = points[tets]
    return np.einsum("ij,ij->i", p[:, 1] - p[:, 0], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0])) / 6.0


def tet_quality(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Shape quality 6 sqrt(2) |V| / l_rms^3 in [0, 1] (1 = regular), (m,)."""
    p = points[tets]
    pairs = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
    l2 = sum(np.sum((p[:, a] - p[:, b]) ** 2, axis=1) for a, b in pairs) / 6.0
    return 6.0 * np.sqrt(2.0) * np.abs(tet_volumes(points, tets)) / l2**1.5


def periodic_mismatch(points: np.ndarray, size, tol: float | None = None):
    """Largest periodic node mismatch of a cell mesh, and the matched node pairs.

    points : (n, 3) float [mm], nodes of a mesh of the box [0, size].
    size : (3,) float [mm].
    tol : float [mm], a node is on a box face if within ``tol`` of it
        (default 1e-9 * max(size)).

    Returns ``(max_mismatch, pairs)``: ``max_mismatch`` [mm] is the largest distance between a
    node on one face and the nearest translated node of the opposite face, over both faces of
    all three axes (``inf`` if the faces' nodes cannot be paired one-to-one); ``pairs`` maps
    axis -> (k, 2) int [node on x_axis = 0, nearest node on x_axis = size_axis], sorted by the
    first column. A mesh is periodic when ``max_mismatch`` is ~0 and the pairs are one-to-one.
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ConfigError(f"points: shape is {pts.shape} and should be (n, 3)")
    size = validate_size(size)
    tol = 1e-9 * float(size.max()) if tol is None else float(check_range("tol", tol, 0.0, lo_open=True))
    worst = 0.0
    pairs = {}
    for a in range(3):
        lo = np.flatnonzero(np.abs(pts[:, a]) <= tol)
        hi = np.flatnonzero(np.abs(pts[:, a] - size[a]) <= tol)
        if len(lo) == 0 and len(hi) == 0:
            pairs[a] = np.empty((0, 2), dtype=np.int64)
            continue
        if len(lo) == 0 or len(hi) == 0:
            worst = np.inf
            pairs[a] = np.empty((0, 2), dtype=np.int64)
            continue
        shift = np.zeros(3)
        shift[a] = size[a]
        d_lo, i_hi = cKDTree(pts[hi]).query(pts[lo] + shift)
        d_hi, _ = cKDTree(pts[lo]).query(pts[hi] - shift)
        worst = max(worst, float(d_lo.max()), float(d_hi.max()))
        if len(lo) != len(hi) or len(np.unique(i_hi)) != len(lo):
            worst = np.inf  # not one-to-one: some node has no partner of its own
        pairs[a] = np.stack([lo, hi[i_hi]], axis=1)
    return worst, pairs


def periodic_tet_mesh(
    field: Field,
    size,
    h: float,
    *,
    level: float = 0.0,
    optimize: bool = True,
    threads: int = 1,
) -> PeriodicTetMesh:
    """Tetrahedral mesh of ``{field < level}`` in the box [0, size] with matched opposite faces.

    field : callable, (m, 3) float [mm] -> (m,) float, periodic with period ``size``,
        negative inside the solid.
    size : (3,) float [mm].
    h : float [mm], element size: the surface grid spacing (ceil(size / h) cells per axis)
        and the largest tet edge gmsh aims for inside.
    level : float, iso-value.
    optimize : run gmsh's tet optimiser (better shapes, about 20 % more time).
    threads : gmsh threads, in [1, 64].

    Raises MeshError (empty solid, gmsh failure, a changed boundary, inverted tets,
    non-matching faces) and ConfigError (bad arguments).
    """
    size = validate_size(size)
    h = float(check_range("h", h, 0.0, float(size.min()) / 2.0, lo_open=True))
    threads = int(check_range("threads", threads, 1, 64))
    n = np.ceil(size / h - 1e-9).astype(int)
    if np.prod(n.astype(float)) > 512**3:
        raise ConfigError(f"h: {h!r}: grid of {n.tolist()} cells is too fine; allowed h >= {size.max() / 512:g} mm")
    surf = periodic_isosurface(field, size, n, level=level)
    rep = check_surface(surf)
    if not rep.ok:
        raise MeshError(f"periodic_tet_mesh: the boundary surface is unusable: {rep}")
    verts = np.asarray(surf.vertices, dtype=float)
    faces = np.asarray(surf.faces, dtype=np.int64)

    points, tets = _gmsh_fill(verts, faces, h, optimize=optimize, threads=threads)

    vol = tet_volumes(points, tets)
    scale = h**3
    if np.any(np.abs(vol) <= 1e-12 * scale):
        raise MeshError(f"periodic_tet_mesh: {int(np.sum(np.abs(vol) <= 1e-12 * scale))} degenerate (flat) tets")
    neg = vol < 0
    tets[neg] = tets[neg][:, [0, 2, 1, 3]]  # swap two nodes: reorients without moving anything
    vol = np.abs(vol)

    _check_boundary(tets, faces, len(verts))
    total = float(vol.sum())
    if abs(total - rep.volume) > 1e-6 * rep.volume:
        raise MeshError(f"periodic_tet_mesh: tet volume {total:.6g} != surface volume {rep.volume:.6g} mm^3")
    mismatch, pairs = periodic_mismatch(points, size)
    if not mismatch <= 1e-9 * float(size.max()):
        raise MeshError(
            f"periodic_tet_mesh: opposite faces do not match: largest node mismatch {mismatch:.3g} mm "
            f"> {1e-9 * size.max():.3g} mm"
        )
    return PeriodicTetMesh(
        points=points,
        tets=tets,
        size=size,
        pairs=pairs,
        max_mismatch=float(mismatch),
        volume=total,
        surface_volume=rep.volume,
        n_surface_triangles=len(faces),
        min_quality=float(tet_quality(points, tets).min()),
        n_components=periodic_components(len(points), tets, pairs),
    )


def periodic_components(n_points: int, tets: np.ndarray, pairs: dict) -> int:
    """Connected pieces of a tet mesh whose matched face nodes ``pairs`` are glued."""
    links = [tets[:, [0, k]] for k in (1, 2, 3)] + [p for p in pairs.values() if len(p)]
    e = np.concatenate(links)
    g = sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n_points, n_points))
    _, labels = connected_components(g, directed=False)
    return int(len(np.unique(labels[np.unique(tets)])))


def _check_boundary(tets: np.ndarray, faces: np.ndarray, n_surface_nodes: int) -> None:
    """Raise MeshError unless the tets' boundary faces are exactly the input triangles."""
    tf = np.sort(tets[:, [0, 1, 2, 0, 1, 3, 0, 2, 3, 1, 2, 3]].reshape(-1, 3), axis=1)
    uniq, counts = np.unique(_tri_keys(tf, int(tets.max()) + 1), return_counts=True)
    if np.any(counts > 2):
        raise MeshError("periodic_tet_mesh: a triangle is shared by more than two tets (non-manifold mesh)")
    bnd = uniq[counts == 1]
    given = np.unique(_tri_keys(np.sort(faces, axis=1), int(tets.max()) + 1))
    if len(bnd) != len(given) or not np.array_equal(bnd, given):
        raise MeshError(
            f"periodic_tet_mesh: gmsh changed the boundary ({len(bnd)} boundary faces for "
            f"{len(given)} input triangles): node matching would be lost"
        )


def _tri_keys(tri: np.ndarray, n_nodes: int):
    """One sortable key per sorted node triple (an int64 when it fits, else a row view)."""
    if n_nodes < 2**21:
        tri = tri.astype(np.int64)
        return (tri[:, 0] << 42) | (tri[:, 1] << 21) | tri[:, 2]
    tri = np.ascontiguousarray(tri, dtype=np.int64)
    return tri.view([("a", np.int64), ("b", np.int64), ("c", np.int64)]).ravel()


def _gmsh_fill(verts, faces, h, *, optimize, threads):
    """Fill a closed surface with tets in gmsh; returns points (n, 3) [mm] and tets (m, 4).

    Surface nodes keep their order: points[:len(verts)] == verts.
    """
    import gmsh

    from ..runtime.gmsh_start import initialize as start_gmsh

    was_init = not start_gmsh(argv=[], readConfigFiles=False, run=False, interruptible=False)
    opts = {
        "General.Terminal": 0,
        "General.NumThreads": threads,
        "Mesh.Algorithm3D": 1,
        "Mesh.MeshSizeMax": h,
        "Mesh.Optimize": int(bool(optimize)),
        "Mesh.OptimizeNetgen": 0,
    }
    saved = {k: gmsh.option.getNumber(k) for k in opts}
    name = f"metasheet_cell_{next(_MODEL_COUNTER)}"
    gmsh.logger.start()
    try:
        for k, v in opts.items():
            gmsh.option.setNumber(k, v)
        gmsh.model.add(name)
        gmsh.model.addDiscreteEntity(2, 1)
        tags = np.arange(1, len(verts) + 1, dtype=np.uint64)
        gmsh.model.mesh.addNodes(2, 1, tags, verts.ravel())
        gmsh.model.mesh.addElementsByType(1, 2, [], (faces + 1).astype(np.uint64).ravel())
        loop = gmsh.model.geo.addSurfaceLoop([1])
        gmsh.model.geo.addVolume([loop])
        gmsh.model.geo.synchronize()
        gmsh.model.mesh.generate(3)
        node_tags, coords, _ = gmsh.model.mesh.getNodes()
        _, _, tet_nodes = gmsh.model.mesh.getElements(3)
    except Exception as exc:  # gmsh raises bare Exceptions carrying its last error
        log = [m for m in gmsh.logger.get() if m.startswith("Error")]
        raise MeshError(f"periodic_tet_mesh: gmsh failed: {exc}; {' | '.join(log[-3:])}") from None
    finally:
        gmsh.logger.stop()
        try:
            gmsh.model.remove()
        finally:
            if was_init:
                for k, v in saved.items():
                    gmsh.option.setNumber(k, v)
            else:
                gmsh.finalize()
    if not len(tet_nodes) or not len(tet_nodes[0]):
        raise MeshError("periodic_tet_mesh: gmsh made no tetrahedra")
    node_tags = np.asarray(node_tags, dtype=np.int64)
    coords = np.asarray(coords, dtype=float).reshape(-1, 3)
    # surface nodes first, in input order, then gmsh's interior nodes by tag
    order = np.argsort(node_tags, kind="stable")
    node_tags, coords = node_tags[order], coords[order]
    if len(node_tags) < len(verts) or not np.array_equal(node_tags[: len(verts)], tags.astype(np.int64)):
        raise MeshError("periodic_tet_mesh: gmsh dropped or renumbered surface nodes")
    if not np.array_equal(coords[: len(verts)], verts):
        raise MeshError("periodic_tet_mesh: gmsh moved surface nodes")
    index = np.full(int(node_tags.max()) + 1, -1, dtype=np.int64)
    index[node_tags] = np.arange(len(node_tags))
    tets = index[np.asarray(tet_nodes[0], dtype=np.int64).reshape(-1, 4)]
    used = np.unique(tets)
    if used[0] < 0:
        raise MeshError("periodic_tet_mesh: gmsh tets reference unknown nodes")
    # drop nodes no tet uses (none expected; keeps the arrays consistent if gmsh leaves any)
    if len(used) != len(coords):
        if np.any(used[: len(verts)] != np.arange(len(verts))):
            raise MeshError("periodic_tet_mesh: some surface nodes are not in any tet")
        remap = np.full(len(coords), -1, dtype=np.int64)
        remap[used] = np.arange(len(used))
        coords, tets = coords[used], remap[tets]
    return coords, tets
