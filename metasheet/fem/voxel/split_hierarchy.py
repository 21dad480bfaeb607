"""The split coarse hierarchy under the finest voxel level: sparse levels, K-cycle, bottom solve.

Level 1 is :func:`~.split.split_prolongation`'s face-split trilinear space, level k >= 2 the same
split on the grid of spacing 2^k (:mod:`.split_levels`). Every level's operator is Galerkin,
``A_k = P_k^T A_(k-1) P_k`` (``A_0 = K``), assembled as 3 x 3 block matrices (:mod:`.blocks`);
level 1's is built from the fine voxels cell by cell, without the fine matrix. Levels are added
until one has at most ``direct_dofs`` unknowns, which is factorised once (SuperLU; on a periodic
cell one copy per connected part of its graph pinned: the translations; on a body with prescribed
dofs nothing, since every solid piece touches one and the operator is non-singular). Prescribed
dofs are not in the fine compact operator's ``free``: level 1 interpolates onto the free dofs
only, and copies that would reach no free dof do not exist. The levels above it are smoothed like the
fine level: Chebyshev of degree ``degree`` on ``D^-1 A`` over ``[1.1 lmax / ratio, 1.1 lmax]``,
the same before and after the coarse correction.

Cycle: a plain V-cycle loses the split levels' gain as levels are added (crop of the paper cell:
25 iterations with level 1 factorised, 44 / 73 / 109 with 2 / 3 / 4 split levels). The default
is Notay and Vassilevski's K-cycle: every split level's correction is two flexible-CG steps
preconditioned by the cycle below (:meth:`SplitHierarchy._kcycle`), 32 to 34 iterations whatever
the depth. The preconditioner then depends on its input (nonlinear), so the outer CG is the
flexible one (:func:`~.pcg.pcg` ``flexible``; :attr:`~.multigrid.Hierarchy.flexible`).

Vectors are (n, 3, m) blocks, m right-hand sides in lockstep; each kernel sums in a fixed order
(:mod:`.blocks`, :mod:`.vectors`), so the bits do not depend on the thread count.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ...errors import ConfigError
from . import vectors as vec
from .blocks import (
    bsr_apply,
    bsr_diagonal,
    csr_apply,
    galerkin_blocks,
    galerkin_voxels,
    to_bsr,
)
from .compact import CompactOperator
from .split import REGULARIZE, _unpinned, split_prolongation
from .split_levels import (
    Copies,
    coarser_grid,
    copy_prolongation,
    fine_grid,
    split_parts,
)

#: Factorise the first level with at most this many unknowns (coarsen further above it).
DIRECT_DOFS = 20_000
#: Stop coarsening when a level keeps more than this fraction of the copies above it.
MIN_REDUCTION = 0.8
#: Refuse to factorise a bottom level larger than this (coarsening stalled: SuperLU's fill would
#: explode; the paper cell's 175k-unknown level had 200M non-zeros in L alone).
MAX_BOTTOM_DOFS = 100_000


@dataclass(frozen=True)
class SparseLevel:
    """Split level k >= 1: its block operator, the transfer from level k-1, the smoother's data.

    Attributes
    ----------
    indptr, indices, data : the (n, n) BSR operator, data (nnzb, 3, 3) [N/mm].
    P : (n_prev, n) csr [-], prolongation from this level to level k-1; R : its transpose, csr.
    dinv : (n, 3) [mm/N], inverse diagonal; lmax : largest eigenvalue estimate of ``D^-1 A`` [-].
    nodes : (3,) this level's node grid.
    """

    indptr: np.ndarray
    indices: np.ndarray
    data: np.ndarray
    P: sp.csr_matrix
    R: sp.csr_matrix
    dinv: np.ndarray
    lmax: float
    nodes: tuple[int, int, int]

    @property
    def size(self) -> int:
        return len(self.indptr) - 1

    def apply(self, x: np.ndarray) -> np.ndarray:
        """``A x``: (n, 3, m) [mm] -> (n, 3, m) [N]."""
        return bsr_apply(self.indptr, self.indices, self.data, x)


@dataclass(frozen=True)
class SplitHierarchy:
    """The split levels under a fine voxel level, coarsest last, and the bottom factor.

    ``keep`` (k,) the bottom level's unpinned flat dofs; ``solve`` (k, m) -> (k, m) its factor;
    ``degree``, ``ratio``: the Chebyshev smoother of the levels above the bottom; ``cycle``: "k"
    (K-cycle, a nonlinear preconditioner: flexible CG) or "v" (V-cycle).
    """

    levels: tuple[SparseLevel, ...]
    keep: np.ndarray
    solve: Callable
    degree: int
    ratio: float
    cycle: str = "k"

    @property
    def positive(self) -> bool:
        """Every pivot of the bottom factor is positive (:func:`positive_pivots`; asked for, not kept)."""
        return positive_pivots(self.solve)

    @property
    def shapes(self) -> tuple[tuple[int, int, int], ...]:
        """Node grid of every split level, first (finest) first."""
        return tuple(lv.nodes for lv in self.levels)

    @property
    def unknowns(self) -> tuple[int, ...]:
        return tuple(3 * lv.size for lv in self.levels)

    def correct(self, x: np.ndarray, free: np.ndarray, r: np.ndarray) -> None:
        """``x += free P_1 V(P_1^T r)`` in place, V one K-cycle (``cycle`` "v": V-cycle) over the split levels;
        x, r : (a, 3, m) compact fine blocks [mm], [N]; free : (a, 3) in {0, 1}."""
        first = self.levels[0]
        rc = csr_apply(first.R, r)
        xc = self._kcycle(0, rc) if self.cycle == "k" and len(self.levels) > 1 else self._cycle(0, rc)
        csr_apply(first.P, xc, out=x, mask=free)

    def _cycle(self, k: int, b: np.ndarray) -> np.ndarray:
        lv = self.levels[k]
        if k == len(self.levels) - 1:
            x = np.zeros_like(b)
            flat, bf = x.reshape(-1, b.shape[2]), b.reshape(-1, b.shape[2])
            flat[self.keep] = self.solve(np.ascontiguousarray(bf[self.keep], dtype=float)).reshape(len(self.keep), -1)
            return x
        x = chebyshev(lv.apply, lv.dinv, lv.lmax, self.degree, self.ratio, None, b)
        r = vec.residual(b, lv.apply(x))
        below = self.levels[k + 1]
        rc = csr_apply(below.R, r)
        xc = self._kcycle(k + 1, rc) if self.cycle == "k" and k + 2 < len(self.levels) else self._cycle(k + 1, rc)
        csr_apply(below.P, xc, out=x)
        return chebyshev(lv.apply, lv.dinv, lv.lmax, self.degree, self.ratio, x, b)

    def _kcycle(self, k: int, b: np.ndarray) -> np.ndarray:
        """Two flexible-CG steps on level k preconditioned by its cycle (Notay and Vassilevski's
        K-cycle, without the residual test), column by column; a nonlinear preconditioner."""
        lv = self.levels[k]
        c1 = self._cycle(k, b)
        v1 = lv.apply(c1)
        rho1, a1 = vec.dots(c1, v1), vec.dots(c1, b)
        t1 = np.where(rho1 > 0, a1 / np.where(rho1 > 0, rho1, 1.0), 0.0)
        r2 = b - t1 * v1
        c2 = self._cycle(k, r2)
        v2 = lv.apply(c2)
        gamma, beta, a2 = vec.dots(c2, v1), vec.dots(c2, v2), vec.dots(c2, r2)
        rho2 = beta - gamma * gamma / np.where(rho1 > 0, rho1, 1.0)
        ok = (rho2 > 1e-14 * beta) & (rho1 > 0)
        t2 = np.where(ok, a2 / np.where(ok, rho2, 1.0), 0.0)
        return (t1 - t2 * gamma / np.where(rho1 > 0, rho1, 1.0)) * c1 + t2 * c2


def build_split_hierarchy(cop: CompactOperator, *, degree: int = 2, ratio: float = 20.0,
                          direct_dofs: int | None = None, max_levels: int = 12, cycle: str = "k",
                          pin_parts: bool | None = None) -> SplitHierarchy:
    """The split levels under ``cop``, down to a direct solve: a periodic cell without prescribed
    dofs, or a non-periodic body whose prescribed dofs (``cop.free`` 0) hold every solid piece.

    Parameters
    ----------
    cop : the finest level on compact vectors; degree, ratio : the sparse levels' Chebyshev smoother.
    pin_parts : pin one copy per connected part of the bottom level (its translations; None: the
        grid is periodic). False: factorise it as it is (held by prescribed dofs).
    direct_dofs : factorise the first level with at most this many unknowns (None: :data:`DIRECT_DOFS`).
    max_levels : at most this many split levels (the last is factorised whatever its size).
    cycle : "k" (K-cycle on every split level, the default) or "v" (V-cycle).

    Raises ConfigError when the coarsening stalls above :data:`MAX_BOTTOM_DOFS` unknowns.
    """
    direct_dofs = DIRECT_DOFS if direct_dofs is None else int(direct_dofs)
    op = cop.op
    occ = np.argwhere(op.index >= 0)
    split = split_prolongation(cop)
    grid = coarser_grid(fine_grid(occ, op.index.shape, op.h), op.periodic)
    sw = op.sweep
    cflat = (grid.cell[:, 0] * grid.shape[1] + grid.cell[:, 1]) * grid.shape[2] + grid.cell[:, 2]
    A = galerkin_voxels(cop.nodes, sw.matrix, sw.scale, op.matrices, cop.free, cflat, split.P)
    if cop.nodes.min() < 0:
        # prescribed corners (compact -1) enter galerkin_voxels' pattern as node 0: empty blocks that
        # would couple node 0's copies to every cell with a prescribed corner, on every level
        A = drop_empty_blocks(*A)
    raw = [(A, split.P, grid.nodes)]
    copies = Copies(split.position.astype(np.int64), split.rep.astype(np.int64))
    while 3 * len(copies.rep) > direct_dofs and len(raw) < max_levels:
        nxt = coarser_grid(grid, op.periodic)
        if nxt is None:
            break
        part, cf = split_parts(op.index, occ, nxt, op.periodic)
        P, new = copy_prolongation(copies, grid, nxt, part, cf, op.periodic)
        if len(new.rep) > MIN_REDUCTION * len(copies.rep):
            break
        A = galerkin_blocks(*A, P)
        raw.append((A, P, nxt.nodes))
        grid, copies = nxt, new
    if 3 * len(copies.rep) > MAX_BOTTOM_DOFS:
        raise ConfigError(f"coarsening 'split': the coarsest split level keeps {3 * len(copies.rep)} unknowns "
                          f"(at most {MAX_BOTTOM_DOFS} are factorised); use coarsening 'trilinear'")
    levels = []
    for k, ((indptr, indices, data), P, nodes) in enumerate(raw):
        smoothed = k < len(raw) - 1
        d = bsr_diagonal(indptr, indices, data)
        dinv = np.where(d > 0, 1.0 / np.where(d > 0, d, 1.0), 0.0)
        lmax = _lambda_max(indptr, indices, data, dinv) if smoothed else 0.0
        levels.append(SparseLevel(indptr, indices, data, P, P.T.tocsr(), dinv, lmax, tuple(int(n) for n in nodes)))
    pin = op.periodic if pin_parts is None else bool(pin_parts)
    keep, solve = factor_pinned(to_bsr(*raw[-1][0]).tocsr(), pin_parts=pin)
    return SplitHierarchy(tuple(levels), keep, solve, int(degree), float(ratio), cycle)


def drop_empty_blocks(indptr, indices, data):
    """The BSR triple without its all-zero off-diagonal blocks (adding 0 changes no product)."""
    n = len(indptr) - 1
    rows = np.repeat(np.arange(n), np.diff(indptr))
    keep = np.any(data != 0, axis=(1, 2)) | (indices == rows)
    ptr = np.zeros(n + 1, np.int64)
    np.cumsum(np.bincount(rows[keep], minlength=n), out=ptr[1:])
    return ptr, np.ascontiguousarray(indices[keep]), np.ascontiguousarray(data[keep])


def factor_pinned(A: sp.csr_matrix, *, pin_parts: bool = True) -> tuple[np.ndarray, Callable]:
    """SuperLU factor of ``A`` with one copy per connected part of its graph pinned (the periodic
    translations; ``pin_parts`` False: none, the prescribed dofs hold every part) and a relative
    diagonal shift (copies can be linearly dependent: fragments that reach a few shared fine nodes;
    the amplified null vector is annihilated by P on the way up). Dofs with a zero diagonal are left
    out either way. Returns (keep (k,) the unpinned dofs, solve (k, m) -> (k, m))."""
    keep = _unpinned(A) if pin_parts else np.flatnonzero(A.diagonal() > 0)
    Ak = A[keep][:, keep]
    Ak = (Ak + sp.diags(REGULARIZE * Ak.diagonal())).tocsc()
    # SPD: diagonal pivots keep the symmetric ordering (fem.solvers.superlu's symmetric mode)
    lu = spla.splu(Ak, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    return keep, lu.solve


def positive_pivots(solve: Callable) -> bool:
    """Whether every pivot of :func:`factor_pinned`'s factor (``solve``, its SuperLU's method) is
    positive: its symmetric diagonal pivots are the D of an LDL^T, whose signs are the matrix's
    inertia (Sylvester), so False means an indefinite level (the Galerkin level of an indefinite
    operator). Extracting U costs a copy of it: asked for by the tangent's multigrid only."""
    lu = getattr(solve, "__self__", None)
    return lu is None or bool(np.all(lu.U.diagonal() > 0))


def chebyshev_steps(lmax: float, ratio: float, degree: int) -> tuple[float, list[tuple[float, float]]]:
    """Chebyshev's scalars on [1.1 lmax / ratio, 1.1 lmax] (Saad, Iterative Methods, alg. 12.1):
    ``1 / theta`` of the first step ``d = D^-1 r / theta``, and ``(a, b)`` of each of the next
    ``degree - 1`` steps ``d = a d + b D^-1 r`` (after ``r -= A d``)."""
    hi = 1.1 * lmax
    lo = hi / ratio
    theta, delta = 0.5 * (hi + lo), 0.5 * (hi - lo)
    sigma = theta / delta
    rho = 1.0 / sigma
    steps = []
    for _ in range(degree - 1):
        rho_new = 1.0 / (2.0 * sigma - rho)
        steps.append((rho_new * rho, 2.0 * rho_new / delta))
        rho = rho_new
    return theta, steps


def chebyshev(apply: Callable, dinv: np.ndarray, lmax: float, degree: int, ratio: float, x: np.ndarray | None,
              b: np.ndarray) -> np.ndarray:
    """Chebyshev smoothing of ``A x = b`` on ``D^-1 A`` over [1.1 lmax / ratio, 1.1 lmax] from x
    (None: zero); the new x (``x`` updated in place when given). As :func:`.multigrid._smooth`."""
    r = b.copy() if x is None else vec.residual(b, apply(x))
    x = np.zeros_like(b) if x is None else x
    theta, steps = chebyshev_steps(lmax, ratio, degree)
    d = vec.chebyshev_first(x, r, dinv, theta)
    for a, c in steps:
        vec.subtract(r, apply(d))
        vec.chebyshev_next(x, d, r, dinv, a, c)
    return x


def _lambda_max(indptr, indices, data, dinv, steps: int = 12) -> float:
    """Power-iteration estimate of the largest eigenvalue of ``D^-1 A`` from a fixed start."""
    v = np.random.default_rng(12345).standard_normal(dinv.shape)[..., None] * (dinv[..., None] > 0)
    lam = 0.0
    for _ in range(steps):
        nv = np.sqrt(vec.dots(v, v)[0])
        if nv == 0:
            return 1.0
        v = v / nv
        w = dinv[..., None] * bsr_apply(indptr, indices, data, v)
        lam = float(vec.dots(v, w)[0])
        v = w
    return max(lam, float(np.sqrt(vec.dots(v, v)[0])))
