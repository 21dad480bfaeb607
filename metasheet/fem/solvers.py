"""Sparse linear solvers: one probe of the optional back-ends, one naming, two uses.

Names, everywhere (reports, settings, statistics):

- ``"cholmod"``: sparse Cholesky of scikit-sparse 0.4.16 on SuiteSparse (optional: needs
  ``apt-get install libsuitesparse-dev``, then ``pip install scikit-sparse==0.4.16``).
- ``"pardiso"``: MKL PARDISO through pypardiso (a pip dependency on x86_64 Linux and
  Windows), for SPD systems: sparse Cholesky of the upper triangle.
- ``"superlu"``: scipy's SuperLU (always there).
- ``"amg-cg"``: smoothed-aggregation AMG (pyamg) preconditioning CG, SPD only (:mod:`.amg`).
- ``"voxel"``: matrix-free geometric-multigrid CG on the voxel grid itself (:mod:`.voxel`), for the
  periodic homogenisation of voxel cells only
  (:func:`metasheet.homogenize.voxel_correctors.solve_voxel_correctors`); named, never "auto".

The direct back-ends are the entries of :data:`BACKENDS`, best first, each probed once at
import (:func:`available`); adding one (e.g. PARDISO through pypardiso) is one more entry.

Two uses:

- :func:`solve_spd`: ``A X = B`` for an SPD ``A`` and several right-hand sides
  (homogenisation's six corrector problems, one factorisation or AMG hierarchy for all).
  ``"auto"`` takes the first available direct back-end up to its size limit
  (:data:`PARDISO_MAX_DOF`, :data:`SUPERLU_MAX_DOF`, ...) whose factor fits in the memory
  available (:func:`factor_fits`), AMG-CG otherwise.
- :class:`~metasheet.fem.factor.SparseSolver` (:mod:`.factor`): repeated factorisations of the robot's free block ``K_ff``, one fixed
  structurally symmetric pattern, slightly non-symmetric values (see :mod:`metasheet.fem.corotational.p1`).
  SuperLU factorises ``K_ff`` itself (every solve exact). CHOLMOD factorises the symmetric part
  ``M = (K_ff + K_ff^T) / 2`` with its symbolic analysis cached for the pattern: ``M^-1`` is a
  *modified-Newton* operator, and :meth:`~metasheet.fem.factor.SparseSolver.solve_exact` restores the exact solve by
  iterative refinement ``y <- y + M^-1 (b - K_ff y)``, falling back to SuperLU of ``K_ff``
  when that does not reach ``refine_tol`` within ``max_refine`` sweeps (a strongly
  non-symmetric tangent far from rest) or ``M`` is not positive definite. Chord steps use
  :meth:`Factor.solve` and are checked on the true residual by the callers
  (:mod:`metasheet.robot.statics`, :mod:`metasheet.robot.inverse`).
"""

from __future__ import annotations

import importlib
import os
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import ConfigError, ConvergenceError
from .amg import amg_cg
from .assembly import transpose_map
from .mkl import tell_pypardiso

# MKL's threaded sums otherwise vary run to run: the homogenised constants differed in the 13th
# digit between two runs of one pipeline, and the reduced model's element sample then by two
# elements. AUTO keeps the machine's code path (measured: no slower, 192k dofs); MKL reads it
# when pypardiso first loads it, which is after this import. A user's own setting wins.
os.environ.setdefault("MKL_CBWR", "AUTO")

#: Largest SPD system SuperLU takes under "auto": its fill-in grows fast in 3D (P1 elasticity
#: cubes, same machine: 0.18 s at 6k dofs, 4.5 s at 26k, 119 s / 6.5 GB at 105k).
SUPERLU_MAX_DOF = 12_000
#: Largest SPD system CHOLMOD takes under "auto", memory permitting (:func:`factor_fits`).
#: Measured on the open-cell 15 % foam (benchmarks/bench_homogenize.py, 2 shared cores, 1 BLAS
#: thread): CHOLMOD 8 s at 105k dofs, 12 s / 1.5 GB at 215k, 103 s / 4.5 GB at 614k, where
#: AMG-CG needs 40-100 iterations per load case (thin voxel struts): 38 s, 57 s, 310 s.
CHOLMOD_MAX_DOF = 2_000_000
#: Largest SPD system PARDISO (MKL, through pypardiso) takes under "auto", memory permitting.
#: On the paper's Polyfoam cell (754k dofs, 3:1 voxels, 1 thread) PARDISO homogenises in 47 s
#: in all (7.5 GB peak) where AMG-CG's six solves took 366 s: a direct solve wins at any size
#: whose factor fits in memory.
PARDISO_MAX_DOF = 2_000_000
#: Peak memory of a whole homogenisation with the back-end [GB] at 1M dofs; it grows like the
#: factor, ~ n^(4/3) on 3D meshes (PARDISO: 1.75 GB at 215k, 7.5 GB at 754k: exponent 1.33).
FACTOR_GB_AT_1M = {"pardiso": 10.9, "cholmod": 8.6}
#: Share of the available memory one factorisation may take under "auto" (decided when it
#: starts: workers that factorise at the same moment share what each of them sees).
MEMORY_SHARE = 0.8


@dataclass
class Factor:
    """One factorised matrix. ``name``: the back-end; ``symmetric``: True when it factorises
    the symmetric part ``(A + A^T) / 2`` rather than ``A`` itself (then not an exact inverse)."""

    name: str
    _solve: object
    symmetric: bool

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """``M^-1 rhs`` for rhs (n,) or (n, k); M is the factorised matrix (see :attr:`symmetric`)."""
        return self._solve(rhs)


# --------------------------------------------------------------------------- back-ends


def superlu(A: sp.spmatrix, *, symmetric_mode: bool = False) -> Factor:
    """SuperLU factor of ``A`` (n, n), columns ordered by minimum degree on ``A^T + A``.

    ``symmetric_mode``: diagonal pivots only (``diag_pivot_thresh=0``, SuperLU's
    ``SymmetricMode``), for a structurally symmetric matrix that is nearly symmetric in value
    (the robot's ``K_ff``): the symmetric ordering is then kept.
    """
    if symmetric_mode:
        lu = spla.splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                       options={"SymmetricMode": True})
    else:
        lu = spla.splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A")
    return Factor("superlu", lu.solve, False)


def _superlu(A: sp.spmatrix) -> Factor:
    return superlu(A, symmetric_mode=True)


def _superlu_spd(_module, A: sp.csc_matrix) -> Callable:
    return superlu(A).solve


def _superlu_general(_module) -> Callable:
    return _superlu


def _pardiso_spd(pypardiso, A: sp.csc_matrix) -> Callable:
    # mtype 2: real symmetric positive definite, given by its upper triangle
    solver = pypardiso.PyPardisoSolver(mtype=2)
    U = sp.triu(A, format="csr")
    U.sort_indices()
    solver.factorize(U)

    def solve_once(B):
        # MKL keeps the factor until told (pypardiso frees nothing on garbage collection): a
        # worker homogenising cell after cell would hold every factor (5 GB at 754k dofs)
        try:
            return solver.solve(U, np.asarray(B, float))
        finally:
            solver.free_memory(everything=True)

    return solve_once


def _cholmod_spd(cholmod, A: sp.csc_matrix) -> Callable:
    return cholmod.cholesky(A)  # the returned factor solves when called


class _CholmodSymmetricPart:
    """Cholesky of ``(A + A^T) / 2`` on ``A``'s own pattern, the symbolic analysis cached."""

    def __init__(self, cholmod):
        self.cholmod = cholmod
        self._key = None
        self._tmap = None
        self._symbolic = None

    def __call__(self, A: sp.csr_matrix) -> Factor | None:
        """The factor, or None when the symmetric part is not positive definite."""
        A.sort_indices()
        key = (A.shape, A.nnz, A.indptr.tobytes(), A.indices.tobytes())
        if self._key != key:
            self._tmap = transpose_map(A, name="K_ff")
            self._key = key
            self._symbolic = None
        # its CSR arrays are also its CSC arrays (symmetric)
        M = sp.csc_matrix((0.5 * (A.data + A.data[self._tmap]), A.indices, A.indptr), shape=A.shape)
        try:
            if self._symbolic is None:
                self._symbolic = self.cholmod.analyze(M)
            f = self._symbolic.cholesky(M)  # numeric factorisation on the cached analysis
            return Factor("cholmod", f.solve_A, True)
        except self.cholmod.CholmodNotPositiveDefiniteError:
            return None


@dataclass(frozen=True)
class Backend:
    """A sparse direct solver.

    name : its name in reports and settings.
    module : what to import ("" for scipy's own); package, install : for the error when missing.
    max_spd_dof : largest SPD system :func:`solve_spd` gives it under "auto".
    spd : (module, A csc SPD) -> solve(B), one factorisation for many right-hand sides, solved
        once (the factor may be freed after it).
    general : module -> factorise(A csr, structurally symmetric) -> :class:`Factor` or None
        (None: cannot, SuperLU takes over); called once per :class:`SparseSolver`, may cache.
        None when the back-end serves only SPD systems.
    """

    name: str
    module: str
    package: str
    install: str
    max_spd_dof: int
    spd: Callable
    general: Callable | None


#: Direct back-ends, best first: "auto" and "direct" take the first available one. PARDISO
#: before CHOLMOD: on the 15 % foam (benchmarks/bench_homogenize.py, same machine, quiet)
#: 2.07 vs 2.33 s at 105k dofs and 4.84 vs 6.41 s at 215k (AMG-CG: 12.7 s and 32.8 s).
BACKENDS = {
    b.name: b for b in (
        Backend("pardiso", "pypardiso", "pypardiso", "pip install pypardiso (x86_64 Linux and Windows)",
                PARDISO_MAX_DOF, _pardiso_spd, None),
        Backend("cholmod", "sksparse.cholmod", "scikit-sparse",
                "apt-get install libsuitesparse-dev; pip install scikit-sparse==0.4.16",
                CHOLMOD_MAX_DOF, _cholmod_spd, _CholmodSymmetricPart),
        Backend("superlu", "", "scipy", "", SUPERLU_MAX_DOF, _superlu_spd, _superlu_general),
    )
}


def _probe(module: str):
    if not module:
        return spla
    if module == "pypardiso":
        tell_pypardiso()  # before its import, which makes a solver and so searches once
    try:
        return importlib.import_module(module)
    except ImportError:
        return None


_MODULES = {name: _probe(b.module) for name, b in BACKENDS.items()}


def available(name: str) -> bool:
    """True when the direct back-end ``name`` (a key of :data:`BACKENDS`) can be used here."""
    return _MODULES.get(name) is not None


HAVE_CHOLMOD = available("cholmod")


# --------------------------------------------------------------------------- SPD solve

#: What :func:`solve_spd` accepts: a policy, or one back-end by name (benchmarks, comparisons).
SPD_SOLVERS = ("auto", "direct", "amg", *BACKENDS)
#: Matrix-free solvers of voxel grids (:mod:`metasheet.fem.voxel`): they never see an assembled
#: matrix, so they are chosen before assembly (:func:`metasheet.homogenize.voxel_correctors.solve_voxel_correctors`).
GRID_SOLVERS = ("voxel", "voxel-gpu")
#: What the voxel homogenisation accepts: the SPD solvers and the grid solvers.
HOMOGENIZE_SOLVERS = (*SPD_SOLVERS, *GRID_SOLVERS)


@dataclass(frozen=True)
class SolveReport:
    """What the linear solver did.

    Attributes
    ----------
    solver : "cholmod", "pardiso", "superlu" or "amg-cg".
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


def available_gb() -> float:
    """Memory available to a new process [GB] (Linux ``MemAvailable``; elsewhere free pages)."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024 / 1e9
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE") / 1e9
    except (ValueError, OSError, AttributeError):
        return float("inf")  # unknown: the size limits alone decide


def factor_fits(name: str, n_dof: int, free_gb: float | None = None) -> bool:
    """True when the back-end ``name``'s estimated peak memory for ``n_dof`` unknowns
    (:data:`FACTOR_GB_AT_1M` x (n / 1M)^(4/3)) is within :data:`MEMORY_SHARE` of ``free_gb``
    (default: :func:`available_gb`). Back-ends without an estimate always fit."""
    per = FACTOR_GB_AT_1M.get(name)
    if per is None:
        return True
    need = per * (n_dof / 1e6) ** (4.0 / 3.0)
    return need <= MEMORY_SHARE * (available_gb() if free_gb is None else free_gb)


def choose_solver(solver: str, n_dof: int, free_gb: float | None = None) -> str:
    """The concrete solver (a key of :data:`BACKENDS` or "amg-cg") for a request in :data:`SPD_SOLVERS`
    and a system size; ``free_gb``: the memory to plan with (default: what is available now)."""
    if solver in GRID_SOLVERS:
        raise ConfigError(f"solver: {solver!r}: matrix-free on a voxel grid, not for an assembled matrix "
                          f"(a voxel cell's homogenisation takes them); allowed here: {', '.join(SPD_SOLVERS)}")
    if solver not in SPD_SOLVERS:
        raise ConfigError(f"solver: {solver!r}: allowed values are {', '.join(SPD_SOLVERS)}")
    if solver == "amg":
        return "amg-cg"
    if solver in BACKENDS:
        if not available(solver):
            b = BACKENDS[solver]
            raise ConfigError(f"solver: {solver!r}: {b.package} is not installed ({b.install})")
        return solver
    direct = [b for name, b in BACKENDS.items() if available(name)]
    if solver == "direct":
        return direct[0].name
    for b in direct:
        if n_dof <= b.max_spd_dof and factor_fits(b.name, n_dof, free_gb):
            return b.name
    return "amg-cg"


def solve_spd(A: sp.spmatrix, B: np.ndarray, *, solver: str = "auto", rtol: float = 1e-8,
              coords: np.ndarray | None = None, maxiter: int = 2000) -> tuple[np.ndarray, SolveReport]:
    """Solve ``A X = B`` for a symmetric positive-definite ``A``.

    Parameters
    ----------
    A : (n, n) sparse SPD matrix.
    B : (n, r) right-hand sides.
    solver : "auto", "direct" or "amg" (:func:`choose_solver`).
    rtol : relative residual asked of CG and checked for every solver.
    coords : (n / 3, 3) node coordinates [mm] for the AMG near-null space (needed for "amg").
    maxiter : CG iteration cap.

    Returns
    -------
    X : (n, r) solutions, and the :class:`SolveReport`.

    Raises
    ------
    ConvergenceError : a residual above the tolerance (with the residuals as history).
    """
    A = sp.csr_matrix(A)
    B = np.asarray(B, float)
    n = A.shape[0]
    kind = choose_solver(solver, n)
    t0 = time.perf_counter()
    iters = [0] * B.shape[1]
    if kind == "amg-cg":
        X, iters, t1 = amg_cg(A, B, rtol, coords, maxiter)
    else:
        solve = BACKENDS[kind].spd(_MODULES[kind], sp.csc_matrix(A))
        t1 = time.perf_counter()
        X = solve(B)
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
