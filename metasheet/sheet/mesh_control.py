"""How the tripod sheet is meshed around its rigid sets: a face that conforms to them, and an
element size graded towards their clamped edges (:func:`metasheet.sheet.geometry.tripod_sheet`).
"""

from __future__ import annotations

import numpy as np

from .outline import ARM_ANGLES, SheetParams


#: growth of the element size away from the grip borders [mm per mm]
GRIP_GROWTH = 0.5


def grip_size_field(gmsh, params: SheetParams) -> None:
    """Element size ``grip_size + GRIP_GROWTH * d`` (capped at ``mesh_size``), d the distance to
    the nearest grip border: |r - centre_radius| or, per arm, |s - (reach - tip_box[0] / 2)|
    along the arm (the grip's cut; no other arm reaches that s), and to the concave corners
    when they are sharp (no fillet)."""
    def num(v) -> str:  # parenthesised: gmsh's expression parser takes no "*-"
        return f"({float(v):.17g})"

    cut = params.reach - 0.5 * params.tip_box[0]
    dists = [f"Fabs(Sqrt(x*x+y*y)-{num(params.centre_radius)})"]
    dists += [f"Fabs(x*{num(np.cos(a))}+y*{num(np.sin(a))}-{num(cut)})" for a in ARM_ANGLES]
    if not params.fillet_radius:  # a sharp concave corner is a singular point too
        rc = params.arm_width / np.sqrt(3.0)
        dists += [f"Sqrt((x-{num(rc * np.cos(a + np.pi / 3))})^2+(y-{num(rc * np.sin(a + np.pi / 3))})^2)"
                  for a in ARM_ANGLES]
    d = dists[0]
    for e in dists[1:]:
        d = f"Min({d},{e})"
    f = gmsh.model.mesh.field.add("MathEval")
    gmsh.model.mesh.field.setString(f, "F", f"Min({num(params.mesh_size)},{num(params.grip_size)}+{num(GRIP_GROWTH)}*{d})")
    gmsh.model.mesh.field.setAsBackgroundMesh(f)
    gmsh.option.setNumber("Mesh.MeshSizeMin", min(params.grip_size, 0.4 * params.mesh_size))
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)


def conforming_pieces(occ, surf: int, params: SheetParams) -> list[tuple[int, int]]:
    """The sheet's face split along the borders of its rigid sets (the centre disk and each
    arm's tip box), as (2, tag) pieces of one conforming face.

    Without the split, which nodes fall in a rigid set depends on where the mesh puts them:
    the rigid hub and grips grow and shrink from mesh to mesh (by up to an element), a
    first-order error that hid the elements' own convergence. With it every mesh has
    element faces on the sets' borders, so the coupled region is the same on every mesh.
    """
    half = 0.5 * np.asarray(params.tip_box)
    tools = []
    if params.centre_radius > params.hole_radius:
        tools.append((2, occ.addDisk(0.0, 0.0, -0.5 * params.thickness, params.centre_radius, params.centre_radius)))
    for a in ARM_ANGLES:
        r = occ.addRectangle(params.reach - half[0], -half[1], -0.5 * params.thickness, 2 * half[0], 2 * half[1])
        occ.rotate([(2, r)], 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, float(a))
        tools.append((2, r))
    _, children = occ.fragment([(2, surf)], tools)
    pieces = children[0]  # what became of the sheet's own face; the tools' outside parts go
    occ.remove([d for d in occ.getEntities(2) if d not in pieces], recursive=True)
    return pieces
