"""The orient stage's sheets meshed again.

The orient stage meshes the sheet pair once. The robot stage's mesh-convergence levels, a
study's own ``mesh_size`` and the reproduction column (the authors' kind of mesh:
:data:`metasheet.pipeline.column.REPRODUCTION_MESH`) mesh the same geometry and fibre law again.
"""

from __future__ import annotations

from dataclasses import replace

from .artefacts import OrientFile


def remesh(orient: OrientFile, mesh_size: float, layers: int | None = None, element: str | None = None,
           grip_size: float | None = None):
    """The orient sheet pair re-meshed at ``mesh_size`` [mm] (``layers`` through the thickness,
    ``element`` and ``grip_size`` [mm], None: orient's) with the same geometry and fibre law;
    per-element constants (when the sheets carry them) carried over by nearest centroid."""
    from scipy.spatial import cKDTree

    from ..robot.builder import SheetPair

    sp = replace(orient.sheet_params, mesh_size=float(mesh_size),
                 **({} if layers is None else {"layers": int(layers)}),
                 **({} if grip_size is None else {"grip_size": float(grip_size)}))
    element = orient.element if element is None else element
    fresh = SheetPair.spiral(sp, element, **orient.fiber_settings)
    meshes, consts = [], []
    for new, old in ((fresh.sheet, orient.normal), (fresh.mirrored, orient.mirrored)):
        c = old.constants
        if c is not None:
            c = c[cKDTree(old.mesh.centroids()).query(new.centroids())[1]]
        consts.append(c)
        # the arm directions as the orient stage recorded them (degrees in sheet.json)
        meshes.append(replace(new, arm_angles=old.mesh.arm_angles))
    fibers = (fresh.fibers, fresh.fibers_mirrored) if orient.fibre_field is None else \
        (orient.fibers_at(meshes[0].centroids(), False), orient.fibers_at(meshes[1].centroids(), True))
    return SheetPair(*meshes, *fibers, *consts, element)

