"""Element kernels shared by homogenisation (and usable by the robot FEM).

- :mod:`.hex8`: trilinear hexahedron on an axis-aligned box (the voxel element).
- :mod:`.tet4`: linear tetrahedron (constant strain) on arbitrary points.
- :mod:`.assembly`: vectorised COO scatter of per-element matrices into CSR.

Voigt order 11, 22, 33, 23, 13, 12 with engineering shear strains, dofs ordered
``3 * node + component``.
"""

from .assembly import assemble_matrix, assemble_vectors
from .hex8 import hex8_box_matrices
from .tet4 import tet4_matrices

__all__ = ["assemble_matrix", "assemble_vectors", "hex8_box_matrices", "tet4_matrices"]
