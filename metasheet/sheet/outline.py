"""The tripod sheet's shape, before any mesh: its parameters, the arms' directions, its outline.

Frame: the sheet's centre is the origin, its mid-plane z = 0; arm k (k = 0, 1, 2) points
along the angle 120 deg * k from +x (:data:`ARM_ANGLES`), so arm 0 lies along +x, and the
outline is symmetric under y -> -y. Defaults follow the authors' 6-DOF scene (FACTS.md):
arms 30 mm wide reaching 66 mm, 5 mm thick, hole radius 5 mm, tip box 45 x 15 x 30 mm,
centre radius 7.5 mm.

The mesh of this shape is :mod:`.geometry`'s, graded towards the rigid sets by
:mod:`.mesh_control`, which it calls; both read the shape from here, so the mesh control
never imports the mesher back.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, check_range

#: the arms' directions [rad] from +x, counter-clockwise
ARM_ANGLES = np.deg2rad([0.0, 120.0, 240.0])


@dataclass(frozen=True)
class SheetParams:
    """Geometry and mesh size of the tripod sheet (all lengths [mm]).

    Attributes
    ----------
    arm_width : width of each arm [mm].
    reach : distance from the centre to the flat end of each arm [mm].
    thickness : plate thickness along z [mm].
    hole_radius : radius of the central through hole [mm] (0 for no hole).
    fillet_radius : radius of the fillets in the three concave corners between arms [mm].
    mesh_size : target tetrahedron edge length h [mm]; the default 5 mm gives ~2,900 tets.
    layers : elements through the thickness: 0 leaves it to gmsh's free 3D mesh (about one
        element through 5 mm at h = 5 mm); k > 0 extrudes the in-plane triangle mesh in k
        structured layers (each prism split into three tets), the explicit control the
        bending of a thin sheet needs.
    grip_size : element size at the borders of the rigid sets (the centre disk's circle and
        each grip's cut across its arm) and at sharp concave corners [mm], growing by half the
        distance away from them up to ``mesh_size``; 0 for a uniform mesh. The sheet is clamped
        along these lines, where the strains are singular: a uniform mesh converges slowly
        there, whatever its order.
    tip_box : (along the arm, across the arm, along z) size of the box centred on each
        arm's end whose nodes the servo horn holds [mm].
    centre_radius : nodes within this distance of the rod axis (r_xy) are tied to the effector [mm].
    """

    arm_width: float = 30.0
    reach: float = 66.0
    thickness: float = 5.0
    hole_radius: float = 5.0
    fillet_radius: float = 5.0
    mesh_size: float = 5.0
    layers: int = 0
    grip_size: float = 0.0
    tip_box: tuple[float, float, float] = (15.0, 45.0, 30.0)
    centre_radius: float = 7.5

    def __post_init__(self):
        check_range("arm_width", self.arm_width, 2.0, 200.0)
        w = float(self.arm_width)
        corner = w / np.sqrt(3.0)  # distance of the concave corners from the centre
        check_range("reach", self.reach, corner + 2.0, 1000.0)
        check_range("thickness", self.thickness, 0.3, 100.0)
        check_range("hole_radius", self.hole_radius, 0.0, 0.9 * w / 2.0)
        fmax = np.sqrt(3.0) * (float(self.reach) - corner) * 0.5
        check_range("fillet_radius", self.fillet_radius, 0.0, min(fmax, 3.0 * w))
        check_range("mesh_size", self.mesh_size, 0.3, 50.0)
        if isinstance(self.layers, bool) or not isinstance(self.layers, (int, np.integer)):
            raise ConfigError(f"layers: {self.layers!r}: expected an integer in [0, 16]")
        check_range("layers", self.layers, 0, 16)
        if self.grip_size:
            check_range("grip_size", self.grip_size, 0.2, self.mesh_size)
        object.__setattr__(self, "layers", int(self.layers))
        if len(self.tip_box) != 3:
            raise ConfigError(f"tip_box: {self.tip_box!r}: expected 3 sizes [mm]")
        for i, s in enumerate(self.tip_box):
            check_range(f"tip_box[{i}]", s, 0.0, 1000.0, lo_open=True)
        check_range("centre_radius", self.centre_radius, float(self.hole_radius), 1000.0, lo_open=True)
        object.__setattr__(self, "tip_box", tuple(float(s) for s in self.tip_box))

    def to_dict(self) -> dict:
        return {
            "arm_width": self.arm_width, "reach": self.reach, "thickness": self.thickness,
            "hole_radius": self.hole_radius, "fillet_radius": self.fillet_radius,
            "mesh_size": self.mesh_size, "layers": self.layers, "grip_size": self.grip_size,
            "tip_box": list(self.tip_box),
            "centre_radius": self.centre_radius,
        }


def outline_corners(params: SheetParams) -> list[tuple[str, np.ndarray, np.ndarray | None]]:
    """The 2D outline, counter-clockwise, as a list of (kind, point (2,), centre (2,) or None).

    ``kind`` is "line" (straight segment ending at ``point``) or "arc" (fillet arc ending
    at ``point`` around ``centre``). The sequence is closed: it ends where it starts.
    """
    w, L, rho = float(params.arm_width), float(params.reach), float(params.fillet_radius)
    out = []
    for k in range(3):
        a = ARM_ANGLES[k]
        d = np.array([np.cos(a), np.sin(a)])
        n = np.array([-np.sin(a), np.cos(a)])
        b = a + np.pi / 3  # bisector of the concave corner between arm k and arm k + 1
        ub = np.array([np.cos(b), np.sin(b)])
        dn = np.array([np.cos(a + 2 * np.pi / 3), np.sin(a + 2 * np.pi / 3)])
        corner = (w / np.sqrt(3.0)) * ub
        out.append(("line", L * d - 0.5 * w * n, None))  # up the right side of arm k
        out.append(("line", L * d + 0.5 * w * n, None))  # across the flat end
        if rho > 0:
            # fillet tangent to both sides; its centre lies in the gap on the bisector
            t1 = corner + (rho / np.sqrt(3.0)) * d
            t2 = corner + (rho / np.sqrt(3.0)) * dn
            c = corner + (rho / np.sin(np.pi / 3)) * ub
            out.append(("line", t1, None))
            out.append(("arc", t2, c))
        else:
            out.append(("line", corner, None))
    return out


def outline_polygon(params: SheetParams, n_arc: int = 10) -> np.ndarray:
    """The sheet's outer outline as a closed polygon (k, 2) [mm], counter-clockwise.

    Fillet arcs are sampled with ``n_arc`` segments (for pictures and inside tests).
    """
    seq = outline_corners(params)
    pts = [seq[-1][1]]
    for kind, pt, centre in seq:
        if kind == "arc":
            a0 = np.arctan2(*(pts[-1] - centre)[::-1])
            a1 = np.arctan2(*(pt - centre)[::-1])
            da = (a1 - a0 + np.pi) % (2 * np.pi) - np.pi  # the short way round (60 deg)
            rad = np.linalg.norm(pt - centre)
            s = a0 + da * np.linspace(0, 1, n_arc + 1)[1:]
            pts.extend(centre + rad * np.stack([np.cos(s), np.sin(s)], axis=1))
        else:
            pts.append(pt)
    return np.array(pts)
