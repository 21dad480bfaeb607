"""The tripod sheet: a Y-shaped plate with a central hole, tetrahedralised with gmsh.

Frame (binding for the robot code): the sheet's centre is the origin, its mid-plane is
z = 0 and it spans z in [-t/2, t/2]; arm k (k = 0, 1, 2) points along the angle
120 deg * k from +x, so arm 0 lies along +x. The outline is symmetric under the
reflection y -> -y, which maps the sheet onto itself and swaps arms 1 and 2; the
mirrored sheet of the second tripod is that reflection (:func:`mirror_sheet`).

Node tags (``SheetMesh.attach``): 0 free, k + 1 for the nodes in the tip box of arm k
(where a servo horn holds the arm), 4 for the central nodes tied to the effector.
The shape itself (:class:`~.outline.SheetParams`, the arms' directions, the outline) is
:mod:`.outline`'s.

The centre set is the cylinder r_xy <= centre_radius through the thickness, not the authors'
sphere of 7.5 mm (FACTS.md): the mesh conforms to the cylinder
(:func:`metasheet.sheet.mesh_control.conforming_pieces`) and the print's solid ring is that
cylinder (:func:`metasheet.sheet.icesl.solid_mask`); a sphere's border is resolved by no mesh,
so its node set grew with every refinement towards it (rod compliance -12 % from 3 mm to
0.7 mm grips, a first-order error that looked like convergence).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import MeshError
from .mesh_control import GRIP_GROWTH, conforming_pieces, grip_size_field
from .outline import ARM_ANGLES, SheetParams, outline_corners, outline_polygon

ATTACH_FREE = 0
ATTACH_CENTRE = 4


@dataclass(frozen=True)
class MeshQuality:
    """Quality of a tet mesh.

    ``worst_aspect`` is the largest circumradius / (3 inradius) over the elements
    (1 for a regular tetrahedron, large for slivers); ``min_volume`` the smallest
    signed volume [mm^3] (> 0: no inverted element); ``volume`` the total [mm^3].
    """

    n_points: int
    n_tets: int
    worst_aspect: float
    mean_aspect: float
    min_volume: float
    volume: float

    def to_dict(self) -> dict:
        return dict(self.__dict__)


@dataclass(frozen=True)
class SheetMesh:
    """The tetrahedralised sheet.

    Attributes
    ----------
    points : (n, 3) float [mm].
    tets : (m, 4) int, positively oriented (det[p1-p0, p2-p0, p3-p0] > 0).
    attach : (n,) int node tags: 0 free, k + 1 tip box of arm k, 4 centre (effector).
    arm_angles : (3,) float [rad], arm k along 2 pi k / 3 from +x.
    quality : :class:`MeshQuality`, or None for a sheet read back from a file.
    params : the :class:`SheetParams` it was built from.
    mirrored : True for the reflection y -> -y of the built sheet.
    """

    points: np.ndarray
    tets: np.ndarray
    attach: np.ndarray
    arm_angles: np.ndarray
    quality: MeshQuality | None = None
    params: SheetParams = field(default_factory=SheetParams)
    mirrored: bool = False

    def centroids(self) -> np.ndarray:
        """Element centroids, (m, 3) float [mm]."""
        return self.points[self.tets].mean(axis=1)

    def volumes(self) -> np.ndarray:
        """Signed element volumes, (m,) float [mm^3]."""
        return tet_volumes(self.points, self.tets)

    def node_set(self, tag: int) -> np.ndarray:
        """Indices of the nodes with attach tag ``tag``, (k,) int."""
        return np.flatnonzero(self.attach == tag)


def tet_volumes(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Signed volumes (m,) [mm^3] of tets (m, 4) over points (n, 3)."""
    p = points[tets]
    return np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0]) / 6.0


def mesh_quality(points: np.ndarray, tets: np.ndarray) -> MeshQuality:
    """Quality report of a tet mesh (see :class:`MeshQuality`)."""
    p = points[tets]
    vol = tet_volumes(points, tets)
    faces = [(1, 2, 3), (0, 2, 3), (0, 1, 3), (0, 1, 2)]
    area = sum(0.5 * np.linalg.norm(np.cross(p[:, b] - p[:, a], p[:, c] - p[:, a]), axis=1) for a, b, c in faces)
    r_in = 3.0 * np.abs(vol) / area
    # circumradius from the lengths: R = sqrt((aA+bB+cC)(aA+bB-cC)(aA-bB+cC)(-aA+bB+cC)) / (24 V)
    def d(i, j):
        return np.linalg.norm(p[:, i] - p[:, j], axis=1)

    aA, bB, cC = d(0, 1) * d(2, 3), d(0, 2) * d(1, 3), d(0, 3) * d(1, 2)
    prod = (aA + bB + cC) * (aA + bB - cC) * (aA - bB + cC) * (-aA + bB + cC)
    R = np.sqrt(np.maximum(prod, 0.0)) / (24.0 * np.maximum(np.abs(vol), 1e-300))
    aspect = R / (3.0 * r_in)
    return MeshQuality(
        n_points=int(len(points)), n_tets=int(len(tets)),
        worst_aspect=float(aspect.max()), mean_aspect=float(aspect.mean()),
        min_volume=float(vol.min()), volume=float(vol.sum()),
    )


def tripod_sheet(params: SheetParams | None = None) -> SheetMesh:
    """Build and tetrahedralise the tripod sheet with gmsh (deterministic, one thread).

    Raises :class:`MeshError` if gmsh fails or leaves inverted elements.
    """
    import gmsh

    from ..runtime.gmsh_start import initialize as start_gmsh

    params = params or SheetParams()
    t, h = float(params.thickness), float(params.mesh_size)
    was_init = not start_gmsh(interruptible=False)
    try:
        gmsh.model.add("tripod_sheet")
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.option.setNumber("Mesh.RandomSeed", 1)
        gmsh.option.setNumber("Mesh.MeshSizeMax", h)
        gmsh.option.setNumber("Mesh.MeshSizeMin", 0.4 * h)
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
        gmsh.option.setNumber("Mesh.Algorithm3D", 1)
        gmsh.option.setNumber("Mesh.Optimize", 1)
        # plain Delaunay left slivers (aspect > 100) at some sizes; Netgen's pass removes them
        gmsh.option.setNumber("Mesh.OptimizeNetgen", 1)
        occ = gmsh.model.occ
        seq = outline_corners(params)
        z0 = -0.5 * t
        start = occ.addPoint(*seq[-1][1], z0)
        first, curves = start, []
        for i, (kind, pt, centre) in enumerate(seq):
            end = first if i == len(seq) - 1 else occ.addPoint(*pt, z0)
            if kind == "line":
                curves.append(occ.addLine(start, end))
            else:
                c = occ.addPoint(*centre, z0)
                curves.append(occ.addCircleArc(start, c, end))
            start = end
        loops = [occ.addCurveLoop(curves)]
        if params.hole_radius > 0:
            circle = occ.addCircle(0.0, 0.0, z0, float(params.hole_radius))
            loops.append(occ.addCurveLoop([circle]))
        surf = occ.addPlaneSurface(loops)
        pieces = conforming_pieces(occ, surf, params)
        if params.layers:  # structured layers: gmsh meshes the surface, then stacks prisms split in tets
            occ.extrude(pieces, 0.0, 0.0, t, numElements=[params.layers])
        else:
            occ.extrude(pieces, 0.0, 0.0, t)
        occ.synchronize()
        if params.grip_size:
            grip_size_field(gmsh, params)
        gmsh.model.mesh.generate(3)
        tags, coords, _ = gmsh.model.mesh.getNodes()
        etags, enodes = gmsh.model.mesh.getElementsByType(4)
    except Exception as exc:  # gmsh raises bare Exceptions
        raise MeshError(f"gmsh failed to mesh the tripod sheet ({params}): {exc}") from exc
    finally:
        gmsh.model.remove()
        if not was_init:
            gmsh.finalize()
    return _assemble(params, tags, coords, enodes)


def _assemble(params, tags, coords, enodes) -> SheetMesh:
    index = np.full(int(tags.max()) + 1, -1, dtype=np.int64)
    index[tags.astype(np.int64)] = np.arange(len(tags))
    pts = coords.reshape(-1, 3)
    tets = index[enodes.astype(np.int64).reshape(-1, 4)]
    used = np.unique(tets)
    remap = np.full(len(pts), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    points, tets = pts[used].copy(), remap[tets]
    vol = tet_volumes(points, tets)
    neg = vol < 0
    tets[neg] = tets[neg][:, [0, 2, 1, 3]]  # one swap flips the orientation
    quality = mesh_quality(points, tets)
    if quality.min_volume <= 0:
        raise MeshError(f"tripod sheet: degenerate element of volume {quality.min_volume:g} mm^3")
    attach = attach_tags(points, params)
    for tag in (1, 2, 3, ATTACH_CENTRE):
        if not np.any(attach == tag):
            raise MeshError(
                f"tripod sheet: attachment set {tag} is empty; enlarge tip_box / centre_radius "
                f"or refine mesh_size ({params.mesh_size:g} mm)"
            )
    return SheetMesh(points, tets, attach, ARM_ANGLES.copy(), quality, params, False)


def attach_tags(points: np.ndarray, params: SheetParams) -> np.ndarray:
    """Node tags (n,) int for points (n, 3) [mm] of an unmirrored sheet (see module doc)."""
    attach = np.zeros(len(points), dtype=np.int64)
    tol = 1e-9  # the mesh conforms to every set's border: nodes sit on it to round-off
    r = np.hypot(points[:, 0], points[:, 1])
    attach[r <= params.centre_radius + tol] = ATTACH_CENTRE
    half = 0.5 * np.asarray(params.tip_box)
    for k, a in enumerate(ARM_ANGLES):
        s = points[:, 0] * np.cos(a) + points[:, 1] * np.sin(a)
        q = -points[:, 0] * np.sin(a) + points[:, 1] * np.cos(a)
        inside = (
            (np.abs(s - params.reach) <= half[0] + tol)
            & (np.abs(q) <= half[1] + tol)
            & (np.abs(points[:, 2]) <= half[2] + tol)
        )
        attach[inside] = k + 1
    return attach


REFLECT = np.diag([1.0, -1.0, 1.0])  # the mirror y -> -y, about the plane containing arm 0


def mirror_sheet(sheet: SheetMesh) -> SheetMesh:
    """The reflection y -> -y of ``sheet`` (the second tripod's sheet).

    Points are reflected, each tet's orientation is restored by swapping two nodes,
    and the tip tags of arms 1 and 2 are swapped so that tag k + 1 still names the
    arm along 120 deg * k. Element i of the result is the image of element i.
    """
    points = sheet.points @ REFLECT
    tets = sheet.tets[:, [0, 2, 1, 3]].copy()
    attach = sheet.attach.copy()
    attach[sheet.attach == 2], attach[sheet.attach == 3] = 3, 2
    return SheetMesh(
        points, tets, attach, sheet.arm_angles.copy(), mesh_quality(points, tets),
        sheet.params, not sheet.mirrored,
    )


#: Tetrahedra per unit of sheet area of a mesh of size s [mm] (:func:`estimated_tets`), fitted to
#: gmsh meshes of the default sheet (A = 5,476 mm^2, t = 5 mm): free mesh, s <= t: C_VOL t / s^3
#: (h = 2.5 mm: 12,808 tets, 7.3; h = 1.5: 45,919, 5.7; t = 20, h = 2.5: 36,168, 5.2); s > t: the
#: sheet is one element thick, C_THIN / s^2 (h = 5: 3,586 tets, 16.4; t = 1, h = 5: 3,110, 14.2;
#: h = 10: 1,512, 27.6); k layers: C_LAYER k / s^2 (h = 5, 3 layers: 5,949 tets, 9.1 per layer).
#: Estimate / gmsh: 0.72 to 1.41 over these, 0.76 / 0.86 with 0.7 / 3 mm grips at h = 10 (28,369 / 3,373).
C_VOL, C_THIN, C_LAYER = 7.0, 20.0, 9.0


def estimated_tets(params: SheetParams) -> int:
    """About how many tetrahedra :func:`tripod_sheet` makes of ``params`` (within 1.5x), from the
    sheet's area, thickness and mesh size, and the graded band around the grips
    (``grip_size``: size g + d / 2 at distance d from the centre circle and the tip cuts, both
    sides, and from sharp corners); no meshing, so a size can be refused before it is tried."""
    h, g, t, n = float(params.mesh_size), float(params.grip_size), float(params.thickness), params.layers

    def per_area(s):  # tets per mm^2 at element size s [mm]
        return C_LAYER * n / s**2 if n else np.maximum(C_THIN / s**2, C_VOL * t / s**3)

    xy = outline_polygon(params, 16)
    area = 0.5 * abs(np.dot(xy[:, 0], np.roll(xy[:, 1], -1)) - np.dot(xy[:, 1], np.roll(xy[:, 0], -1)))
    total = (area - np.pi * float(params.hole_radius) ** 2) * per_area(h)
    if g and g < h:  # extra tets of the graded band, integrated over the distance d [mm]
        d = (h - g) / GRIP_GROWTH * np.linspace(0.0, 1.0, 400) ** 2  # dense where the size is small
        extra = per_area(g + GRIP_GROWTH * d) - per_area(h)
        lines = 2.0 * (2.0 * np.pi * float(params.centre_radius) + 3.0 * float(params.arm_width))
        corners = 0.0 if params.fillet_radius else 3.0 * (4.0 * np.pi / 3.0)  # sharp: 240 deg of sheet each
        total += np.trapezoid(extra * (lines + corners * d), d)
    return int(round(total))
