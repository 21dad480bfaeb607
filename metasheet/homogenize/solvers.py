"""Solve the six corrector problems ``K U = -F`` that share one matrix.

Choice (see ``../shared/reference/SOLVERS.md`` for the measurements behind it):

- ``"direct"``: a sparse Cholesky (scikit-sparse CHOLMOD) when importable, else
  SuperLU (``scipy.sparse.linalg.splu``); one factorisation, all right-hand sides at once.
- ``"amg"``: smoothed-aggregation AMG (pyamg) with the six rigid-body modes as
  near-null space, as a preconditioner of CG; the hierarchy is built once and reused
  by every load case.
- ``"auto"``: direct below :data:`DIRECT_MAX_DOF` dofs (CHOLMOD: :data:`CHOLMOD_MAX_DOF`),
  AMG above.

Whatever ran is reported in a :class:`SolveReport`; a residual above the requested
tolerance raises :class:`~metasheet.errors.ConvergenceError` with the history.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import ConfigError, ConvergenceError

#: Largest system solved by SuperLU under "auto" (splu fill-in grows fast in 3D).
DIRECT_MAX_DOF = 12_000
#: Largest system solved by CHOLMOD under "auto". Measured on the open-cell 15 % foam
#: (benchmarks/bench_homogenize.py, 2 shared cores, 1 BLAS thread): CHOLMOD 8 s at 105k
#: dofs, 12 s / 1.5 GB at 215k, 103 s / 4.5 GB at 614k, where this AMG-CG needs 40-100
#: iterations per load case (thin voxel struts): 38 s, 57 s, 310 s (224k, 3:1 voxels).
#: Above, the factor's memory (~ n^(4/3)) would pass 6 GB: AMG.
CHOLMOD_MAX_DOF = 700_000
SOLVERS = ("auto", "direct", "amg")

try:  # optional: needs SuiteSparse from the system (SOLVERS.md)
    from sksparse.cholmod import cholesky as _cholmod  # type: ignore

    HAVE_CHOLMOD = True
except ImportError:
    _cholmod = None
    HAVE_CHOLMOD = False


@dataclass(frozen=True)
class SolveReport:
    """What the linear solver did.

    Attributes
    ----------
    solver : "cholmod", "splu" or "amg-cg".
    iterations : (r,) CG iterations per right-hand side (0 for direct solvers).
    residuals : (r,) relative residuals ||K u + f|| / ||f|| (0 for a zero right-hand side).
    setup_seconds : factorisation or AMG hierarchy time [s].
    solve_seconds : time for all right-hand sides [s].
    n_dof : size of the solved system.
    """

    solver: str
    iterations: tuple[int, ...]
    residuals: tuple[float, ...]
    setup_seconds: float
    solve_seconds: float
    n_dof: int


def rigid_body_modes(coords: np.ndarray) -> np.ndarray:
    """(3 n, 6) translations and infinitesimal rotations of nodes ``coords`` (n, 3) [mm]."""
    x = np.asarray(coords, float)
    x = x - x.mean(axis=0)
    n = len(x)
    B = np.zeros((3 * n, 6))
    for i in range(3):
        B[i::3, i] = 1.0
    # rotations about axes 0, 1, 2: w x r
    B[1::3, 3], B[2::3, 3] = -x[:, 2], x[:, 1]
    B[0::3, 4], B[2::3, 4] = x[:, 2], -x[:, 0]
    B[0::3, 5], B[1::3, 5] = -x[:, 1], x[:, 0]
    return B


def choose_solver(solver: str, n_dof: int) -> str:
    """The concrete solver ("cholmod", "splu" or "amg-cg") for a request and a size."""
    if solver not in SOLVERS:
        raise ConfigError(f"solver: {solver!r}: allowed values are {', '.join(SOLVERS)}")
    if solver == "amg":
        return "amg-cg"
    if solver == "direct":
        return "cholmod" if HAVE_CHOLMOD else "splu"
    if HAVE_CHOLMOD and n_dof <= CHOLMOD_MAX_DOF:
        return "cholmod"
    if n_dof <= DIRECT_MAX_DOF:
        return "splu"
    return "amg-cg"


def solve_spd(A: sp.spmatrix, B: np.ndarray, *, solver: str = "auto", rtol: float = 1e-8,
              coords: np.ndarray | None = None, maxiter: int = 2000) -> tuple[np.ndarray, SolveReport]:
    """Solve ``A X = B`` for a symmetric positive-definite ``A``.

    Parameters
    ----------
    A : (n, n) sparse SPD matrix.
    B : (n, r) right-hand sides.
    solver : "auto", "direct" or "amg" (see the module docstring).
    rtol : relative residual asked of CG and checked for every solver.
    coords : (n / 3, 3) node coordinates [mm] for the AMG near-null space (needed for "amg").
    maxiter : CG iteration cap.

    Returns
    -------
    X : (n, r) solutions, and the :class:`SolveReport`.
    """
    A = sp.csr_matrix(A)
    B = np.asarray(B, float)
    n = A.shape[0]
    kind = choose_solver(solver, n)
    t0 = time.perf_counter()
    iters = [0] * B.shape[1]
    if kind == "cholmod":
        fac = _cholmod(sp.csc_matrix(A))
        t1 = time.perf_counter()
        X = fac(B)
    elif kind == "splu":
        lu = spla.splu(sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A")
        t1 = time.perf_counter()
        X = lu.solve(B)
    else:
        X, iters, t1 = _amg_cg(A, B, rtol, coords, maxiter, t0)
    t2 = time.perf_counter()
    bn = np.linalg.norm(B, axis=0)
    res = np.linalg.norm(A @ X - B, axis=0) / np.where(bn > 0, bn, 1.0)
    report = SolveReport(kind, tuple(int(i) for i in iters), tuple(float(r) for r in res), t1 - t0, t2 - t1, n)
    limit = max(rtol, 1e-12) * (10.0 if kind == "amg-cg" else 1e4)
    if not np.all(np.isfinite(X)) or np.any(res > limit):
        raise ConvergenceError(
            f"{kind}: relative residuals {np.array2string(res, precision=2)} exceed {limit:g} "
            "(singular stiffness: a floating part or a mechanism in the cell?)",
            history=res.tolist(),
        )
    return X, report


def _amg_cg(A, B, rtol, coords, maxiter, t0):
    import pyamg

    if coords is None:
        raise ConfigError("coords: required by the 'amg' solver (rigid-body near-null space)")
    nullspace = rigid_body_modes(coords)
    # A small coarsest level: pyamg's default (500 unknowns, dense pinv) costs more per
    # V-cycle than the fine level on elasticity; splu on <= 100 unknowns is negligible.
    # Variants measured on 15 % voxel foams (28k-105k dofs, iterations per load case):
    # BSR 3x3 input: same iterations, 1.5-3x slower V-cycles; Jacobi x2 / Chebyshev 2 /
    # forward-backward GS smoothers: 30-110 % more iterations, no faster overall;
    # strength theta 0.1 / 0.25 / "evolution": fewer iterations but operator complexity
    # 7-27 instead of 1.3 (3-40x slower); rigid-body modes unwrapped per aggregate across
    # the periodic seam: no change; pyamg's own CG: same time as scipy's. Kept: CSR, block
    # Gauss-Seidel, theta 0, scipy CG. The 40-100 iterations come from the thin voxel
    # struts (edge-connected voxels act as soft hinges), not from the set-up.
    ml = pyamg.smoothed_aggregation_solver(A, B=nullspace, symmetry="hermitian", max_coarse=100,
                                           coarse_solver="splu")
    t1 = time.perf_counter()
    X = np.zeros_like(B)
    iters = []
    for j in range(B.shape[1]):
        b = B[:, j]
        if not np.any(b):
            iters.append(0)
            continue
        hist: list[float] = []
        M = ml.aspreconditioner()
        # scipy's CG with the AMG V-cycle as preconditioner: several times faster than
        # pyamg's own pure-Python Krylov loop (measured here).
        x, info = spla.cg(A, b, rtol=rtol, maxiter=maxiter, M=M,
                          callback=lambda xk: hist.append(0.0))
        X[:, j] = x
        iters.append(len(hist))
        r = np.linalg.norm(A @ x - b) / np.linalg.norm(b)
        if info != 0 or r > rtol * 10.0:
            raise ConvergenceError(
                f"amg-cg: load case {j}: relative residual {r:.2e} after {len(hist)} iterations, "
                f"asked {rtol:g}", history=[r],
            )
    return X, iters, t1
