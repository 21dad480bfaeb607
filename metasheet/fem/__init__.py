"""Finite-element building blocks shared by homogenisation and the robot FEM.

- :mod:`.hex8`: trilinear hexahedron on an axis-aligned box (the voxel element).
- :mod:`.tet4`: linear tetrahedron (constant strain) on arbitrary points.
- :mod:`.assembly`: the cached sparsity pattern, vectorised scatter and CSR index maps.
- :mod:`.solvers`: the sparse linear solvers (SPD solve, general factorisation) and their back-ends.
- :mod:`.meshes`: structured test meshes.

Voigt order 11, 22, 33, 23, 13, 12 with engineering shear strains, dofs ordered
``3 * node + component``.
"""

from .assembly import SparsityPattern, element_dofs, submatrix_map, transpose_map
from .hex8 import hex8_box_matrices
from .tet4 import tet4_matrices

__all__ = ["SparsityPattern", "element_dofs", "hex8_box_matrices", "submatrix_map", "tet4_matrices",
           "transpose_map"]
