"""The sheets' finite element: linear (4-node) or quadratic (10-node) tetrahedra.

The orient stage meshes and writes the sheet with linear tetrahedra (``sheet.vtu``: what the
print map and ParaView read, one fibre and one set of constants per element). The robot
builds its FEM from that mesh in the order the pipeline asks (``[orient] element``): for
``"p2"`` every tetrahedron gets a node at the midpoint of each of its six edges
(:func:`metasheet.fem.tet10.elevate_to_p2`); element i of the quadratic mesh is element i of
the linear one, so fibres and per-element constants carry over unchanged.

Why quadratic: a thin sheet in bending locks with linear tetrahedra (a P1 cantilever of
the sheet gives 0.29 / 0.61 / 0.78 / 0.87 of beam theory with 1 / 2 / 3 / 4 elements
through the thickness), while a quadratic element represents a linear bending strain
through the thickness exactly.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import ConfigError
from .geometry import ATTACH_FREE, SheetMesh

ELEMENTS = ("p1", "p2")
#: nodes per element
NODES = {"p1": 4, "p2": 10}


def check_element(element: str) -> str:
    """``element`` if it names a supported element, else ConfigError naming the allowed values."""
    if element not in ELEMENTS:
        raise ConfigError(f"element: {element!r}: allowed {', '.join(repr(e) for e in ELEMENTS)}")
    return element


def element_of(tets: np.ndarray) -> str:
    """The element ("p1" or "p2") of a connectivity array (m, 4) or (m, 10)."""
    k = np.shape(tets)[1] if np.ndim(tets) == 2 else None
    for name, n in NODES.items():
        if k == n:
            return name
    raise ConfigError(f"tets: shape is {np.shape(tets)}; allowed (m, 4) (p1) or (m, 10) (p2)")


def midside_tags(attach: np.ndarray, tets10: np.ndarray, n_vertices: int) -> np.ndarray:
    """Attach tags (n10,) of a quadratic mesh from the linear mesh's tags ``attach`` (n,).

    A midside node belongs to a rigid set when both ends of its edge do: the coupled nodes
    are then exactly those of the element edges inside the set (every tip box and the centre
    cylinder are convex, so these midpoints lie inside the set too), and no coupled midside
    node hangs off a free vertex.
    """
    from ..fem.tet10 import TET10_EDGES

    n10 = int(tets10.max()) + 1
    tags = np.full(n10, ATTACH_FREE, dtype=attach.dtype)
    tags[:n_vertices] = attach
    for j, (a, b) in enumerate(TET10_EDGES):
        ta, tb = attach[tets10[:, a]], attach[tets10[:, b]]
        tags[tets10[:, 4 + j]] = np.where(ta == tb, ta, ATTACH_FREE)
    return tags


def as_element(sheet: SheetMesh, element: str) -> SheetMesh:
    """``sheet`` (linear) in ``element``: unchanged for "p1", midside nodes added for "p2".

    The quadratic sheet keeps the linear sheet's nodes first (same indices) and its
    elements in the same order. Elevating the mirrored sheet gives the mirror image of the
    elevated sheet (same edges, hence the same new nodes in the same order).
    """
    from ..fem.tet10 import elevate_to_p2

    check_element(element)
    have = element_of(sheet.tets)
    if have == element:
        return sheet
    if have != "p1":
        raise ConfigError(f"element: {element!r}: the sheet is already {have}; only p1 -> p2 is supported")
    points, tets10 = elevate_to_p2(sheet.points, sheet.tets)
    return replace(sheet, points=points, tets=tets10,
                   attach=midside_tags(np.asarray(sheet.attach), tets10, len(sheet.points)))


#: our quadratic node order -> VTK's (edges 01, 12, 02, 03, 13, 23 after the vertices)
VTK_TETRA10 = np.array([0, 1, 2, 3, 4, 7, 5, 6, 8, 9])


def meshio_cells(tets: np.ndarray) -> tuple[str, np.ndarray]:
    """(meshio cell type, connectivity in its node order) of tets (m, 4) or (m, 10)."""
    t = np.asarray(tets)
    return ("tetra", t) if element_of(t) == "p1" else ("tetra10", t[:, VTK_TETRA10])
