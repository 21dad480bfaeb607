"""Matrix-free linear elasticity on voxel grids with geometric-multigrid-preconditioned CG.

- :mod:`.element`: the trilinear voxel's matrices per phase;
- :mod:`.operator`: ``K u`` voxel by voxel (numba, m right-hand sides at once, threads
  without changing bits), periodic or not;
- :mod:`.compact`: vectors on the active nodes only, ``K u`` on them (BLAS on one-matrix levels);
- :mod:`.vectors`: fused CG and smoother updates, fixed-order reductions;
- :mod:`.coarsen`: cells, trilinear transfer (full and compact), Galerkin coarse voxel matrices;
- :mod:`.split`, :mod:`.split_levels`: coarse node copies split by the face-connected fine solid
  of their supports, on the first and the coarser levels;
- :mod:`.blocks`, :mod:`.split_hierarchy`: the split levels' block operators, K-cycle, bottom factor;
- :mod:`.multigrid`: the hierarchy (trilinear or split), Chebyshev/Jacobi smoothers, the V-cycle;
- :mod:`.pcg`: (flexible) CG with the null space projected out, several right-hand sides in lockstep;
- :mod:`.homogenize`: the six periodic load cases -> C*;
- :mod:`.clamped`: clamped and rigid-tied nodes -> a rigid body's condensed 6 x 6 stiffness;
- :mod:`.grips`: several rigid grips -> their condensed 6 B x 6 B stiffness (the printed sheet);
- :mod:`.device`, :mod:`.device_solve`: the split multigrid CG on a CUDA GPU through CuPy
  (``solver = "voxel-gpu"``, optional, imported only when asked), or on numpy for its tests.
"""

from .clamped import RigidBodyStiffness, rigid_body_stiffness
from .grips import GripStiffness, rigid_bodies_stiffness
from .homogenize import VoxelHomogenization, periodic_stiffness

__all__ = ["GripStiffness", "RigidBodyStiffness", "VoxelHomogenization", "periodic_stiffness",
           "rigid_bodies_stiffness", "rigid_body_stiffness"]
