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
- :mod:`.device`: the split hierarchy and its CG on a CUDA GPU through CuPy (optional,
  imported only when asked), or on numpy for its tests.

The problems solved with this machinery live with their subjects: the periodic cell's six load
cases -> C* (:mod:`metasheet.homogenize.voxel_periodic`, on the GPU:
:mod:`metasheet.homogenize.voxel_periodic_gpu`), a sheet's rigid grips and clamped faces ->
their condensed stiffness (:mod:`metasheet.sheet.voxel_grips`, :mod:`metasheet.sheet.voxel_clamped`).
"""
