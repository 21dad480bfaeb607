"""Sparse factorisation of the robot's free block ``K_ff``: CHOLMOD when installed, else SuperLU.

The corotational tangent of an anisotropic body is slightly non-symmetric (:mod:`.kernels`),
so two strategies exist:

* ``"superlu"`` (always available, scipy): LU of ``K_ff`` itself; every solve is exact.
* ``"cholmod"`` (optional, scikit-sparse 0.4.16 on SuiteSparse; imported lazily): Cholesky of
  the symmetric part ``M = (K_ff + K_ff^T) / 2`` with the symbolic analysis cached for the
  fixed sparsity pattern. ``M^-1`` is then a *modified-Newton* operator:
  :meth:`SparseSolver.solve_exact` restores the exact solve of ``K_ff`` by iterative
  refinement ``y <- y + M^-1 (b - K_ff y)`` and, when that does not reach ``refine_tol``
  within ``max_refine`` sweeps (a strongly non-symmetric tangent far from rest) or ``M`` is not
  positive definite, falls back to SuperLU of ``K_ff`` for that matrix. Chord steps use
  :meth:`Factor.solve` (``M^-1`` or ``LU^-1``) and are checked on the true residual by the
  callers (:mod:`.statics`, :mod:`.inverse`).

``"auto"`` picks CHOLMOD if importable. :attr:`SparseSolver.stats` counts what actually ran.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import ConfigError

SOLVERS = ("auto", "cholmod", "superlu")
_CHOLMOD = None  # the module once imported, False when unavailable


def cholmod_module():
    """``sksparse.cholmod`` or None (import attempted once)."""
    global _CHOLMOD
    if _CHOLMOD is None:
        try:
            from sksparse import cholmod

            _CHOLMOD = cholmod
        except ImportError:
            _CHOLMOD = False
    return _CHOLMOD or None


def have_cholmod() -> bool:
    """True when scikit-sparse's CHOLMOD can be imported."""
    return cholmod_module() is not None


def resolve(solver: str) -> str:
    """``"cholmod"`` or ``"superlu"`` for a requested ``solver`` in :data:`SOLVERS`."""
    if solver not in SOLVERS:
        raise ConfigError(f"linear_solver: {solver!r}: allowed {SOLVERS}")
    if solver == "auto":
        return "cholmod" if have_cholmod() else "superlu"
    if solver == "cholmod" and not have_cholmod():
        raise ConfigError("linear_solver: 'cholmod': scikit-sparse is not installed "
                          "(apt-get install libsuitesparse-dev; pip install scikit-sparse==0.4.16); "
                          "allowed here: 'auto' or 'superlu'")
    return solver


@dataclass
class Factor:
    """One factorised matrix. ``name``: "cholmod" (of the symmetric part) or "superlu" (exact)."""

    name: str
    _solve: object
    symmetric: bool

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """``M^-1 rhs`` for rhs (n,) or (n, k); M is the factorised matrix (see :attr:`symmetric`)."""
        return self._solve(rhs)


def _superlu(A: sp.spmatrix) -> Factor:
    # symmetric-mode ordering on A + A^T: K_ff is structurally symmetric and nearly so in value
    lu = spla.splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    return Factor("superlu", lu.solve, False)


class SparseSolver:
    """Factorises matrices of one fixed sparsity pattern (CSR, structurally symmetric).

    Parameters
    ----------
    solver : "auto" | "cholmod" | "superlu" (:data:`SOLVERS`).
    refine_tol : relative residual (Frobenius, per right-hand-side block) an exact solve must reach.
    max_refine : refinement sweeps before falling back to SuperLU.
    """

    def __init__(self, solver: str = "auto", *, refine_tol: float = 1e-10, max_refine: int = 8):
        self.name = resolve(solver)
        self.refine_tol = float(refine_tol)
        self.max_refine = int(max_refine)
        self._symbolic = None  # CHOLMOD analysis of the pattern
        self._pattern = None
        self._tmap = None
        self.stats = {"cholmod": 0, "superlu": 0, "fallbacks": 0, "refine_sweeps": 0, "exact_solves": 0}

    def _transpose_map(self, A: sp.csr_matrix) -> np.ndarray:
        key = (A.shape, A.nnz, A.indptr.tobytes(), A.indices.tobytes())
        if self._pattern != key:
            tag = sp.csr_matrix((np.arange(1, A.nnz + 1, dtype=float), A.indices, A.indptr), shape=A.shape)
            t = tag.T.tocsr()
            t.sort_indices()
            if t.nnz != A.nnz or not np.array_equal(t.indices, A.indices):
                raise ConfigError("K_ff: pattern is not structurally symmetric: allowed only symmetric patterns")
            self._tmap = t.data.astype(np.int64) - 1
            self._pattern = key
            self._symbolic = None
        return self._tmap

    def factorize(self, A: sp.csr_matrix) -> Factor:
        """Factor of ``A`` (CSR, sorted indices): LU of A, or Cholesky of its symmetric part."""
        A = A.tocsr()
        if self.name == "cholmod":
            A.sort_indices()
            tmap = self._transpose_map(A)
            # (A + A^T)/2 on A's own pattern; its CSR arrays are also its CSC arrays (symmetric)
            M = sp.csc_matrix((0.5 * (A.data + A.data[tmap]), A.indices, A.indptr), shape=A.shape)
            chol = cholmod_module()
            try:
                if self._symbolic is None:
                    self._symbolic = chol.analyze(M)
                f = self._symbolic.cholesky(M)  # numeric factorisation on the cached analysis
                self.stats["cholmod"] += 1
                return Factor("cholmod", f.solve_A, True)
            except chol.CholmodNotPositiveDefiniteError:
                self.stats["fallbacks"] += 1
        self.stats["superlu"] += 1
        return _superlu(A)

    def solve_exact(self, factor: Factor, A: sp.csr_matrix, rhs: np.ndarray) -> tuple[np.ndarray, Factor]:
        """``A^-1 rhs`` to ``refine_tol`` using ``factor`` (of A or of its symmetric part).

        Returns the solution and the factor to keep using (a SuperLU factor of ``A`` after a
        fallback, so that later chord solves are exact too).
        """
        self.stats["exact_solves"] += 1
        y = factor.solve(rhs)
        if not factor.symmetric:
            return y, factor
        nb = max(float(np.linalg.norm(rhs)), 1e-300)
        prev = np.inf
        for sweep in range(self.max_refine + 1):
            r = rhs - A @ y
            nr = float(np.linalg.norm(r))
            if nr <= self.refine_tol * nb:
                return y, factor
            if sweep == self.max_refine or nr > 0.5 * prev:  # slow contraction: asymmetry not small
                break
            prev = nr
            y = y + factor.solve(r)
            self.stats["refine_sweeps"] += 1
        self.stats["fallbacks"] += 1
        self.stats["superlu"] += 1
        lu = _superlu(A)
        return lu.solve(rhs), lu
