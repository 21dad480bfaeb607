"""The split multigrid rebuilt on a deformed state's tangent: the Newton steps' preconditioner
away from rest.

The linear body's multigrid (:func:`~.multigrid.build_hierarchy`) is the hyperelastic tangent
at rest. A degree of motor travel turns a printed sheet's thin walls by several degrees and loads
them: their tangent then carries the walls' rotated stiffness and the stress's geometric term,
which the rest hierarchy does not see. Its CG needed 87 to 177 iterations for a tenth of the
residual on the paper's sheet near equilibrium, where the same hierarchy built on that state's
tangent needs 5 to 10 (``docs/performance.md``).

The tangent hierarchy is the same construction on a table of one (24, 24) matrix per solid voxel
(:func:`~.hyperelastic.tangent_matrices`), stored in float32 (a preconditioner's matrices: half
the memory and the bandwidth of every fine-level product; the CG's own products stay the exact
matrix-free tangent). The table is symmetric, so the sweep's transposed copy is the table itself
(the operator holds its transposed view). Built in a fixed order: the same bits on any thread
count.

It is a valid CG preconditioner only where the tangent is positive definite: a buckled state's
tangent makes a Galerkin hierarchy indefinite. :func:`tangent_hierarchy` refuses a bottom level
with a negative pivot, and the trust-region step reports a preconditioner that stops being
positive (:func:`.trust_region.steihaug`'s "indefinite"); the caller then goes back to the rest
hierarchy, which is always positive definite.
"""

from __future__ import annotations

import numpy as np

from .hyperelastic import tangent_matrices
from .multigrid import Hierarchy, build_hierarchy
from .operator import VoxelOperator


def tangent_table(dN: np.ndarray, w: np.ndarray, mu: float, lam: float, Finv: np.ndarray, c: np.ndarray,
                  out: np.ndarray | None = None) -> np.ndarray:
    """(m, 24, 24) float32 [N/mm]: each solid voxel's tangent stiffness at its Gauss points'
    ``Finv`` (m, 8, 3, 3) and ``c = mu - lam ln J`` (m, 8) (:func:`~.hyperelastic.tangent_matrices`,
    summed in float64), written into ``out`` when given (a table of the same shape no hierarchy
    uses any more: its pages are not touched afresh at each rebuild)."""
    shape = (len(Finv), 24, 24)
    if out is None:
        out = np.empty(shape, np.float32)
    elif out.shape != shape or out.dtype != np.float32:
        raise ValueError(f"out: shape {out.shape}, dtype {out.dtype}: must be {shape}, float32")
    tangent_matrices(dN, w, mu, lam, Finv, c, out)
    return out


def tangent_hierarchy(index: np.ndarray, table: np.ndarray, free: np.ndarray, fixed: np.ndarray,
                      h: np.ndarray) -> Hierarchy | None:
    """The split hierarchy of the tangent ``table`` (m, 24, 24) (voxel ``k`` the k-th solid voxel
    of ``index`` in C order), or None where its bottom level is not positive definite.

    index : (nx, ny, nz) int, >= 0 on the solid; free : (Nx, Ny, Nz, 3) float in {0, 1} the
    unknowns; fixed : (Nx, Ny, Nz, 3) bool the prescribed dofs; h : (3,) [mm]. The hierarchy's
    compact numbering is the rest hierarchy's (the same solid, the same free dofs)."""
    rows = np.full(index.shape, -1, np.int64)
    solid = index >= 0
    rows[solid] = np.arange(int(solid.sum()))
    # a symmetric table: its transposed view's contiguous copy (the sweep's) is the table itself
    op = VoxelOperator(rows, table.transpose(0, 2, 1), np.ones(index.shape), False, free, h)
    try:
        H = build_hierarchy(op, fixed, coarsening="split")
    except (ValueError, RuntimeError, np.linalg.LinAlgError):  # a singular bottom level
        return None
    # a small body's dense coarsest level is a pseudo-inverse on the positive eigenvalues only
    return H if H.sparse is None or H.sparse.positive else None
