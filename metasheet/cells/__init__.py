"""Periodic unit cells: seeds, metrics, Voronoi foams as distance fields, voxels, checks.

- :mod:`.seeds`: periodic seed samplers (uniform, jittered grid, Poisson disk) and images.
- :mod:`.metrics`: stretched Euclidean and polyhedral (k-gon) distances.
- :mod:`.kgon`: the k-gon trapezohedron gauge of IceSL's Polyfoam (:class:`KgonMetric`).
- :mod:`.polyfoam`: the Polyfoam cell: :class:`PolyfoamDesign`, its density solve (one-bead
  walls, cell size from the density) and builder.
- :mod:`.skeleton`: distances to the Voronoi skeleton (walls, struts) and nearest seeds.
- :mod:`.foam`: :class:`Foam`, its level set :func:`foam_field`, :func:`voxelize`.
- :mod:`.thickness`: the strut radius / wall thickness for a relative density
  (:func:`solve_thickness`).
- :mod:`.connectivity`: periodic connectivity and percolation (:func:`check_percolation`).
- :mod:`.design`: the ``cells/*.toml`` designs and :func:`design_cell`; :mod:`.specs`: their
  ``[material]``, ``[seeds]``, ``[metric]`` sub-tables.
- :mod:`.surface`, :mod:`.tetmesh`: watertight surfaces and periodic tet meshes (imported
  on use: they pull in trimesh and gmsh).
"""

from .connectivity import ConnectivityReport, check_percolation
from .catalogue import CellDesign, CellResult, design_cell, parse_design
from .foam import Foam, foam_field, voxelize
from .kgon import KgonMetric
from .metrics import PolyhedralMetric, StretchedMetric
from .polyfoam import PolyfoamDesign
from .thickness import solve_thickness

__all__ = [
    "CellDesign",
    "CellResult",
    "ConnectivityReport",
    "Foam",
    "KgonMetric",
    "PolyfoamDesign",
    "PolyhedralMetric",
    "StretchedMetric",
    "check_percolation",
    "design_cell",
    "foam_field",
    "parse_design",
    "solve_thickness",
    "voxelize",
]
