"""The robot's repeated factorisations of one sparsity pattern: :class:`SparseSolver` and the
names it accepts (:data:`FACTOR_SOLVERS`, :func:`resolve`), on the back-ends of
:mod:`.solvers` (SuperLU of ``K_ff`` itself, or CHOLMOD of its symmetric part with iterative
refinement to an exact solve; the reasoning is in :mod:`.solvers`' docstring).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..errors import ConfigError
from . import solvers
from .solvers import _MODULES, BACKENDS, Factor, _superlu

#: What :class:`SparseSolver` (and the robot's ``linear_solver`` setting) accepts.
FACTOR_SOLVERS = ("auto", *(name for name, b in BACKENDS.items() if b.general is not None))


def resolve(solver: str) -> str:
    """The back-end that runs for a requested ``solver`` in :data:`FACTOR_SOLVERS`."""
    if solver not in FACTOR_SOLVERS:
        raise ConfigError(f"linear_solver: {solver!r}: allowed {FACTOR_SOLVERS}")
    here = [name for name in FACTOR_SOLVERS[1:] if solvers.available(name)]  # looked up when called: tests stub the probe
    if solver == "auto":
        return here[0]
    if solver not in here:
        b = BACKENDS[solver]
        raise ConfigError(f"linear_solver: {solver!r}: {b.package} is not installed ({b.install}); "
                          f"allowed here: {' or '.join(repr(s) for s in ('auto', *here))}")
    return solver


class SparseSolver:
    """Factorises matrices of one fixed sparsity pattern (CSR, structurally symmetric).

    Parameters
    ----------
    solver : "auto" | "cholmod" | "superlu" (:data:`FACTOR_SOLVERS`).
    refine_tol : relative residual (Frobenius, per right-hand-side block) an exact solve must reach.
    max_refine : refinement sweeps before falling back to SuperLU.

    :attr:`stats` counts what actually ran: factorisations per back-end, fallbacks,
    refinement sweeps and exact solves.
    """

    def __init__(self, solver: str = "auto", *, refine_tol: float = 1e-10, max_refine: int = 8):
        self.name = resolve(solver)
        self.refine_tol = float(refine_tol)
        self.max_refine = int(max_refine)
        self._factorize = BACKENDS[self.name].general(_MODULES[self.name])
        self.stats = {**{name: 0 for name in FACTOR_SOLVERS[1:]}, "fallbacks": 0, "refine_sweeps": 0, "exact_solves": 0}

    def factorize(self, A: sp.csr_matrix) -> Factor:
        """Factor of ``A`` (CSR, sorted indices): LU of A, or Cholesky of its symmetric part."""
        A = A.tocsr()
        factor = self._factorize(A)
        if factor is None:
            self.stats["fallbacks"] += 1
            factor = _superlu(A)
        self.stats[factor.name] += 1
        return factor

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
