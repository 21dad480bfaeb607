"""Geometric multigrid on the voxel hierarchy: one symmetric V-cycle, CG's preconditioner.

Choices (measured iteration counts in ``docs/voxel.md``):

- coarse operators: Galerkin ``P^T K P`` with trilinear ``P`` (:mod:`.coarsen`), built voxel
  by voxel, so thin walls and edge hinges keep their true coarse stiffness;
- smoother: Chebyshev polynomial of the Jacobi-preconditioned operator ``D^-1 K`` (degree 2
  by default) on ``[1.1 lambda_max / ratio, 1.1 lambda_max]``, ``lambda_max`` from a fixed-start
  power iteration; damped Jacobi is kept as the simple alternative. Both are symmetric, the
  same pre and post, so the V-cycle is a symmetric preconditioner;
- coarsening "split" (the default of :func:`~.homogenize.periodic_stiffness`; periodic cells
  without prescribed dofs, or non-periodic bodies whose prescribed dofs hold every face-connected
  solid piece; this function's default stays "trilinear"): below the finest level, sparse levels whose
  trilinear coarse nodes (spacing 2^k) are split by the face-connected fine solid of their
  supports, Galerkin, Chebyshev-smoothed, the last one factorised (:mod:`.split_hierarchy`);
  far fewer iterations on thin walls;
- coarsest level: a dense pseudo-inverse (eigen-decomposition) of the few hundred coarse
  unknowns. It is pseudo- rather than plain inverse because the periodic operator is
  singular: translations are exactly interpolated by ``P``, so every level keeps them in its
  null space, and the right-hand sides, orthogonal to them on the fine level, stay so.

The V-cycle runs on compact vectors, each level's active nodes only (:mod:`.compact`), with the
smoother's updates fused (:mod:`.vectors`). Every sum has a fixed order (the operator's slab
sweep; serial restriction; fixed-block reductions; one BLAS thread for the dense coarsest solve
and the one-matrix sweep): the same bits on every run and thread count.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from ...errors import ConfigError
from . import vectors as vec
from .coarsen import (
    choose_directions,
    coarse_operator,
    prolong_add_compact,
    restrict_compact,
)
from .compact import CompactOperator, compact
from .operator import VoxelOperator, diagonal
from .split_hierarchy import SplitHierarchy, build_split_hierarchy, chebyshev_steps

#: Smoothers accepted by :func:`build_hierarchy`.
SMOOTHERS = ("chebyshev", "jacobi")
#: Coarse spaces accepted by :func:`build_hierarchy`.
COARSENINGS = ("trilinear", "split")
#: Coarsen until at most this many unknowns remain, then solve densely.
COARSEST_UNKNOWNS = 1000
#: Refuse a dense coarsest level above this many unknowns (a grid that cannot be coarsened).
COARSEST_LIMIT = 6000


@dataclass(frozen=True)
class Level:
    """One level above the coarsest: its operator, smoother data and the way down."""

    op: VoxelOperator
    cop: CompactOperator  # op on the level's active nodes: every V-cycle vector is compact
    dinv: np.ndarray  # (a, 3) free / diag [mm/N] on the active nodes
    lmax: float  # largest eigenvalue estimate of D^-1 K [-]
    transfer: tuple  # 1D interpolations to the next coarser level (:mod:`.coarsen`)
    coarse_nodes: tuple


@dataclass(frozen=True)
class Hierarchy:
    """A multigrid hierarchy, finest level first.

    Attributes
    ----------
    levels : the smoothed levels; coarsest : the last operator, ccoarsest : it on compact vectors;
    coarse_dofs : (c,) free dofs of the coarsest level, flat in its compact (a, 3) block;
    coarse_inverse : (c, c) pseudo-inverse;
    smoother, degree, ratio, omega : the smoother's settings;
    sparse : coarsening "split": the sparse split levels under the one voxel level (then
        coarsest, ccoarsest, coarse_dofs and coarse_inverse are None).
    """

    levels: tuple[Level, ...]
    coarsest: VoxelOperator
    ccoarsest: CompactOperator
    coarse_dofs: np.ndarray
    coarse_inverse: np.ndarray
    smoother: str
    degree: int
    ratio: float
    omega: float
    sparse: SplitHierarchy | None = None

    @property
    def shapes(self) -> tuple[tuple[int, int, int], ...]:
        """Voxel grid shape of every level, finest first (split: the node grids of the split levels)."""
        last = self.sparse.shapes if self.sparse is not None else (self.coarsest.index.shape,)
        return tuple(lv.op.index.shape for lv in self.levels) + last

    @property
    def unknowns(self) -> tuple[int, ...]:
        last = self.sparse.unknowns if self.sparse is not None else (self.coarsest.n_free,)
        return tuple(lv.op.n_free for lv in self.levels) + last

    @property
    def flexible(self) -> bool:
        """The preconditioner varies with its input (split levels with K-cycles): CG must be flexible."""
        return self.sparse is not None and self.sparse.cycle == "k"

    @property
    def fine(self) -> CompactOperator:
        """The finest level on compact vectors: the numbering of :meth:`precondition`."""
        return self.levels[0].cop if self.levels else self.ccoarsest

    def precondition(self, r: np.ndarray) -> np.ndarray:
        """One V-cycle from zero: ``z ~ K^-1 r`` for compact ``r`` (a, 3[, m]) [N] -> [mm]
        on the finest level's active nodes (:attr:`fine`).

        ``m`` right-hand sides go down and up the hierarchy together, column by column the
        same arithmetic as one at a time."""
        z = _vcycle(self, 0, np.ascontiguousarray(r if r.ndim == 3 else r[..., None], dtype=float))
        return z if r.ndim == 3 else z[..., 0]


def build_hierarchy(op: VoxelOperator, fixed: np.ndarray | None = None, *, smoother: str = "chebyshev",
                    degree: int = 2, ratio: float = 20.0, omega: float = 2.0 / 3.0,
                    coarsest_unknowns: int = COARSEST_UNKNOWNS, coarsening: str = "trilinear",
                    direct_dofs: int | None = None) -> Hierarchy:
    """Coarsen ``op`` into a Galerkin hierarchy with its smoothers and coarse pseudo-inverse.

    Parameters
    ----------
    op : the finest level.
    fixed : (Nx, Ny, Nz, 3) bool prescribed dofs (None: none).
    smoother : "chebyshev" or "jacobi"; degree : polynomial degree or number of Jacobi sweeps, >= 1.
    ratio : Chebyshev's smoothing range ``lambda_max / lambda_min`` (> 1).
    omega : Jacobi's step as a fraction of the stable ``2 / lambda_max``, in (0, 1].
    coarsest_unknowns : stop coarsening at this many unknowns.
    coarsening : "trilinear" (voxel grids down to a dense coarsest solve) or "split" (sparse split
        levels down to a factorised one, :func:`~.split_hierarchy.build_split_hierarchy`; periodic
        without ``fixed`` dofs, or non-periodic with ``fixed`` dofs on every face-connected solid piece).
    direct_dofs : "split": factorise the first split level with at most this many unknowns
        (None: :data:`~.split_hierarchy.DIRECT_DOFS`).
    """
    if coarsening not in COARSENINGS:
        raise ConfigError(f"coarsening: {coarsening!r}: allowed values are {', '.join(COARSENINGS)}")
    if smoother not in SMOOTHERS:
        raise ConfigError(f"smoother: {smoother!r}: allowed values are {', '.join(SMOOTHERS)}")
    if int(degree) != degree or not 1 <= degree <= 10:
        raise ConfigError(f"degree: {degree!r}: allowed integers 1 to 10")
    if not ratio > 1:
        raise ConfigError(f"ratio: {ratio!r}: must be > 1")
    if not 0 < omega <= 1:
        raise ConfigError(f"omega: {omega!r}: allowed range (0, 1]")
    fixed = np.zeros(op.node_shape + (3,), bool) if fixed is None else np.asarray(fixed, bool)
    if coarsening == "split":
        return _split_hierarchy(op, fixed, smoother, int(degree), float(ratio), float(omega), direct_dofs,
                                coarsest_unknowns)
    levels = []
    while op.n_free > coarsest_unknowns:
        dirs = choose_directions(op.index.shape, op.h, op.periodic)
        if not any(dirs):
            break
        coarse, fixed_c, transfer = coarse_operator(op, fixed, dirs)
        levels.append(_level(op, transfer, coarse.node_shape))
        op, fixed = coarse, fixed_c
    if op.n_free > COARSEST_LIMIT:
        raise ConfigError(f"grid {op.index.shape}: cannot be coarsened below {op.n_free} unknowns "
                          f"(dense coarsest solve allows {COARSEST_LIMIT}); use more voxels per direction")
    dofs, pinv = _coarse_pseudo_inverse(op)
    cop = compact(op)
    dofs = 3 * cop.node_map[dofs // 3] + dofs % 3  # full flat dof -> compact flat dof
    return Hierarchy(tuple(levels), op, cop, dofs, pinv, smoother, int(degree), float(ratio), float(omega))


def _level(op: VoxelOperator, transfer, coarse_nodes) -> Level:
    """A smoothed level: compact operator, Jacobi scaling and its largest eigenvalue."""
    d = diagonal(op)
    dinv = np.where(d > 0, op.free / np.where(d > 0, d, 1.0), 0.0)
    cop = compact(op)
    dc = np.ascontiguousarray(cop.to_compact(dinv))
    return Level(op, cop, dc, _lambda_max(cop, dc), transfer, coarse_nodes)


def _split_hierarchy(op, fixed, smoother, degree, ratio, omega, direct_dofs, coarsest_unknowns) -> Hierarchy:
    """``op`` smoothed, and the split levels under it (the sparse ones always Chebyshev). A periodic
    cell's bottom level pins each part's translations; a body held by prescribed dofs pins nothing."""
    if op.periodic == bool(fixed.any()):
        raise ConfigError("coarsening 'split': periodic cells without prescribed dofs, or non-periodic grids "
                          "with prescribed (clamped or tied) dofs only; use 'trilinear'")
    if not op.periodic:
        _check_held(op.index, fixed)
    if op.n_free <= coarsest_unknowns or not any(choose_directions(op.index.shape, op.h, op.periodic)):
        # small enough (or too small to coarsen): one dense level, as the trilinear hierarchy
        return build_hierarchy(op, fixed, smoother=smoother, degree=degree, ratio=ratio, omega=omega,
                               coarsest_unknowns=coarsest_unknowns)
    lv = _level(op, None, None)
    sparse = build_split_hierarchy(lv.cop, degree=degree, ratio=ratio, direct_dofs=direct_dofs,
                                   pin_parts=op.periodic)
    return Hierarchy((Level(op, lv.cop, lv.dinv, lv.lmax, None, sparse.shapes[0]),), None, None, None, None,
                     smoother, degree, ratio, omega, sparse)


def _check_held(index: np.ndarray, fixed: np.ndarray) -> None:
    """Refuse a non-periodic grid with a face-connected solid piece that touches no prescribed dof.

    Such a piece floats (or hangs on an edge or corner hinge): the operator is singular, and the
    split bottom level, factorised without pinning, would be too. The caller drops those pieces
    first (:func:`~.grips.held_solid`); this is the assertion that it did."""
    solid = index >= 0
    label, n = ndimage.label(solid)  # 6-connectivity: pieces joined through faces only
    held = np.zeros(n + 1, bool)
    touching = fixed.any(axis=3)
    nx, ny, nz = index.shape
    for a in range(8):  # the voxels whose corner a is prescribed
        ax, ay, az = a & 1, (a >> 1) & 1, (a >> 2) & 1
        held[label[touching[ax:ax + nx, ay:ay + ny, az:az + nz] & solid]] = True
    loose = int(n - held[1:].sum())
    if loose:
        raise ConfigError(f"coarsening 'split': {loose} of {n} face-connected solid pieces touch no prescribed "
                          "dof (they float: a singular operator); keep only the held pieces "
                          "(metasheet.sheet.voxel_grips.held_solid) or use 'trilinear'")


def _lambda_max(cop, dinv: np.ndarray, steps: int = 12) -> float:
    """Power-iteration estimate of the largest eigenvalue of ``D^-1 K`` from a fixed start, on
    the compact vectors of ``cop`` (dinv (a, 3)); the start is the full grid's seeded draw on the
    active nodes, so the estimate does not depend on how the grid is stored."""
    op = cop.op
    v = cop.to_compact(op.free * np.random.default_rng(12345).standard_normal(op.free.shape))[..., None]
    lam = 0.0
    for _ in range(steps):
        nv = np.linalg.norm(v)
        if nv == 0:
            return 1.0
        v = v / nv
        w = dinv[..., None] * cop.apply(v)
        lam = float(np.vdot(v, w))
        v = w
    return max(lam, float(np.linalg.norm(v)))


def _coarse_pseudo_inverse(op: VoxelOperator) -> tuple[np.ndarray, np.ndarray]:
    """Dense pseudo-inverse of the coarsest operator on its free dofs."""
    N = op.node_shape
    n = 3 * int(np.prod(N))
    occupied = np.argwhere(op.index >= 0)
    corners = np.array([[a & 1, (a >> 1) & 1, (a >> 2) & 1] for a in range(8)])
    nodes = (occupied[:, None, :] + corners[None]) % np.array(N)
    flat = (nodes[..., 0] * N[1] + nodes[..., 1]) * N[2] + nodes[..., 2]
    dofs = (3 * flat[..., None] + np.arange(3)).reshape(len(occupied), 24)
    Ke = op.matrices[op.index[tuple(occupied.T)]] * op.scale[tuple(occupied.T)][:, None, None]
    A = np.zeros((n, n))
    np.add.at(A, (dofs[:, :, None], dofs[:, None, :]), Ke)
    free = np.flatnonzero(op.free.ravel() > 0)
    A = A[np.ix_(free, free)]
    w, V = np.linalg.eigh(0.5 * (A + A.T))
    keep = w > 1e-11 * max(w[-1], 0.0) if len(w) else np.zeros(0, bool)
    pinv = (V[:, keep] / w[keep]) @ V[:, keep].T
    return free, pinv


def _smooth(H: Hierarchy, lv: Level, x: np.ndarray | None, b: np.ndarray) -> np.ndarray:
    """A few smoothing steps on ``K x = b`` (a, 3, m) from ``x`` (None: zero); the new x
    (``x`` itself, updated in place, when given). Fused kernels (:mod:`.vectors`), the same
    arithmetic per entry as the numpy expressions in the comments."""
    r = b.copy() if x is None else vec.residual(b, lv.cop.apply(x))  # r = b - K x
    x = np.zeros_like(b) if x is None else x
    if H.smoother == "jacobi":
        for s in range(H.degree):
            dx = vec.jacobi_step(x, r, lv.dinv, 2.0 * H.omega / lv.lmax)  # omega of the stable range 2 / lmax
            if s + 1 < H.degree:
                vec.subtract(r, lv.cop.apply(dx))
        return x
    # Chebyshev on [1.1 lmax / ratio, 1.1 lmax] (Saad, Iterative Methods, alg. 12.1; Adams et al. 2003)
    theta, steps = chebyshev_steps(lv.lmax, H.ratio, H.degree)
    d = vec.chebyshev_first(x, r, lv.dinv, theta)  # d = dinv r / theta; x += d
    for a, c in steps:
        vec.subtract(r, lv.cop.apply(d))  # r -= K d
        vec.chebyshev_next(x, d, r, lv.dinv, a, c)  # d = a d + c dinv r; x += d
    return x


def _vcycle(H: Hierarchy, k: int, b: np.ndarray) -> np.ndarray:
    """V-cycle from level k on compact ``b`` (a_k, 3, m)."""
    m = b.shape[2]
    if k == len(H.levels):
        x = np.zeros((H.ccoarsest.size, 3, m))
        flat = x.reshape(-1, m)
        flat[H.coarse_dofs] = H.coarse_inverse @ b.reshape(-1, m)[H.coarse_dofs]
        return x
    lv = H.levels[k]
    below = H.levels[k + 1].cop if k + 1 < len(H.levels) else H.ccoarsest
    x = _smooth(H, lv, None, b)
    r = vec.residual(b, lv.cop.apply(x))
    if H.sparse is not None:  # the split level: x += free P A^+ P^T r
        H.sparse.correct(x, lv.cop.free, r)
        return _smooth(H, lv, x, b)
    rc = restrict_compact(r, lv.transfer, lv.cop.node_map, lv.op.node_shape, below.node_map, below.op.node_shape,
                          below.free)
    del r
    xc = _vcycle(H, k + 1, rc)
    prolong_add_compact(x, lv.cop.free, xc, lv.transfer, lv.cop.node_map, lv.op.node_shape, below.node_map,
                        below.op.node_shape)  # x += free P xc
    return _smooth(H, lv, x, b)
