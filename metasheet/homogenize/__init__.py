"""Periodic FEM homogenisation: from a unit cell to its effective (6, 6) stiffness.

- :func:`homogenize_voxels`: voxel grids (trilinear hexahedra, void removed).
- :func:`homogenize_mesh`: node-matched periodic tet meshes (explicit projection P).
- :mod:`.chart`: design chart sweep and its inverse look-up.

Voigt order 11, 22, 33, 23, 13, 12 with engineering shear; stiffness in MPa.
"""

from .mesh import homogenize_mesh, voxels_to_tets
from .result import LOAD_CASES, HomogenizationResult, LoadCase, Localisation
from .voxels import homogenize_voxels

__all__ = [
    "LOAD_CASES",
    "HomogenizationResult",
    "LoadCase",
    "Localisation",
    "homogenize_mesh",
    "homogenize_voxels",
    "voxels_to_tets",
]
