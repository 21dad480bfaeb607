"""Periodic homogenisation with the split multigrid run on an array device (:mod:`.device`).

:func:`periodic_stiffness_device` sets the cell up on the host as the CPU path does
(:func:`.homogenize.prepare_cell`), moves the hierarchy to the device (:class:`DeviceHierarchy`)
and runs the same flexible CG, preconditioned by the same cycle: Chebyshev on the fine voxels,
the split levels' K-cycle (two flexible-CG steps per level, Notay and Vassilevski), the bottom
solve. The correctors come back to the host for the energy form of C*.
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp

from ..errors import ConfigError
from ..fem.voxel.device import (
    Backend,
    Bottom,
    FineLevel,
    SparseLevel,
    backend,
    chebyshev,
    dots,
    transfer,
)
from .voxel_periodic import (
    VoxelHomogenization,
    _periodic_stiffness,
    check_converged,
    energy_form,
    prepare_cell,
)
from ..fem.voxel.pcg import PCGResult


class DeviceHierarchy:
    """A split :class:`~.multigrid.Hierarchy` on the device: fine level, split levels, bottom."""

    def __init__(self, be: Backend, H):
        if H.sparse is None:
            raise ConfigError("voxel-gpu: the cell's hierarchy has no split levels (a small cell or "
                              "coarsening 'trilinear'); the CPU path solves it")
        lv = H.levels[0]
        self.be = be
        self.fine = FineLevel(be, lv.cop, lv.dinv, lv.lmax)
        self.levels = [SparseLevel(be, s) for s in H.sparse.levels]
        self.bottom = Bottom(be, H.sparse)
        self.degree, self.ratio = H.degree, H.ratio
        self.sparse_degree, self.sparse_ratio = H.sparse.degree, H.sparse.ratio
        self.kcycle = H.sparse.cycle == "k"

    def precondition(self, r):
        """One cycle from zero on compact r (a, 3, m) [N] -> z [mm], as :meth:`.multigrid.Hierarchy.precondition`."""
        xp, f = self.be.xp, self.fine
        x = chebyshev(xp, f.apply, f.dinv, f.lmax, self.degree, self.ratio, None, r)
        res = r - f.apply(x)
        first = self.levels[0]
        rc = transfer(first.R, res)
        del res
        xc = self._kcycle(0, rc) if self.kcycle and len(self.levels) > 1 else self._cycle(0, rc)
        x += f.free[..., None] * transfer(first.P, xc)
        return chebyshev(xp, f.apply, f.dinv, f.lmax, self.degree, self.ratio, x, r)

    def _cycle(self, k: int, b):
        if k == len(self.levels) - 1:
            return self.bottom.solve(b)
        xp, lv = self.be.xp, self.levels[k]
        x = chebyshev(xp, lv.apply, lv.dinv, lv.lmax, self.sparse_degree, self.sparse_ratio, None, b)
        below = self.levels[k + 1]
        rc = transfer(below.R, b - lv.apply(x))
        go_k = self.kcycle and k + 2 < len(self.levels)
        xc = self._kcycle(k + 1, rc) if go_k else self._cycle(k + 1, rc)
        x += transfer(below.P, xc)
        return chebyshev(xp, lv.apply, lv.dinv, lv.lmax, self.sparse_degree, self.sparse_ratio, x, b)

    def _kcycle(self, k: int, b):
        """Two flexible-CG steps on level k preconditioned by its cycle (:meth:`.split_hierarchy.SplitHierarchy._kcycle`)."""
        xp, lv = self.be.xp, self.levels[k]
        c1 = self._cycle(k, b)
        v1 = lv.apply(c1)
        rho1, a1 = dots(xp, c1, v1), dots(xp, c1, b)
        pos = rho1 > 0
        safe1 = xp.where(pos, rho1, 1.0)
        t1 = xp.where(pos, a1 / safe1, 0.0)
        r2 = b - t1 * v1
        c2 = self._cycle(k, r2)
        v2 = lv.apply(c2)
        gamma, beta, a2 = dots(xp, c2, v1), dots(xp, c2, v2), dots(xp, c2, r2)
        rho2 = beta - gamma * gamma / safe1
        ok = (rho2 > 1e-14 * beta) & pos
        t2 = xp.where(ok, a2 / xp.where(ok, rho2, 1.0), 0.0)
        return (t1 - t2 * gamma / safe1) * c1 + t2 * c2


def projector(be: Backend, labels: np.ndarray, n_parts: int):
    """v -> v without each part's mean displacement (per component and column), as
    :func:`.pcg.translation_projector`; the means by one sparse product (no atomics)."""
    lab = np.asarray(labels).reshape(-1)
    on = np.flatnonzero(lab >= 0)
    count = np.bincount(lab[on], minlength=n_parts).astype(float)
    mean = be.put(sp.csr_matrix((1.0 / np.maximum(count, 1.0)[lab[on]], (lab[on], on)), shape=(n_parts, len(lab))))
    spread = be.put(sp.csr_matrix((np.ones(len(on)), (on, lab[on])), shape=(len(lab), n_parts)))

    def project(v):
        a, _, m = v.shape
        flat = v.reshape(a, 3 * m)
        return (flat - spread @ (mean @ flat)).reshape(a, 3, m)

    return project


def flexible_pcg(be: Backend, apply, b, precondition, project, *, rtol: float, maxiter: int) -> PCGResult:
    """Flexible CG on the device from x = 0, every column on its own, as :func:`.pcg.pcg` with
    ``flexible=True``; arrays come back to the host in the result (x stays on the device as ``x``)."""
    xp = be.xp
    b = project(b)
    m = b.shape[2]
    x = xp.zeros_like(b)
    bn = xp.sqrt(dots(xp, b, b))
    scale = xp.where(bn > 0, bn, 1.0)
    r = b.copy()
    active = bn > 0
    iterations = xp.zeros(m, np.int64)
    hist = [xp.where(active, 1.0, 0.0)]
    z = project(precondition(r))
    p = z.copy()
    rz = dots(xp, r, z)
    while bool(active.any()) and int(iterations.max()) < maxiter:
        q = apply(p)
        pq = dots(xp, p, q)
        alpha = xp.where(active, rz / xp.where(active, pq, 1.0), 0.0)
        x += alpha * p
        r -= alpha * q
        iterations += active
        hist.append(xp.where(active, xp.sqrt(dots(xp, r, r)) / scale, hist[-1]))
        active = active & (hist[-1] > rtol) & (iterations < maxiter)
        if not bool(active.any()):
            break
        z = project(precondition(r))
        rz_new = dots(xp, r, z)
        beta = xp.where(active, -dots(xp, z, q) / xp.where(active, pq, 1.0), 0.0)
        p = z + beta * p
        rz = xp.where(active, rz_new, rz)
    rb = project(b - apply(x))
    res = be.get(xp.sqrt(dots(xp, rb, rb)) / scale)
    return PCGResult(x, be.get(iterations), res, res <= rtol * 10.0, np.array([be.get(h) for h in hist]))


def periodic_stiffness_device(phases, size, stiffnesses: dict, *, scale=None, rtol: float = 1e-8,
                              maxiter: int = 500, degree: int = 2, device: str = "cupy",
                              direct_dofs: int | None = None) -> VoxelHomogenization:
    """Effective stiffness of a periodic voxel cell, the split multigrid CG run on ``device``.

    Parameters as :func:`.homogenize.periodic_stiffness` (the coarsening is "split"), and
    device : "cupy" (a CUDA GPU; ConfigError when CuPy or the GPU is missing) or "numpy" (the
    same array code on the host: the tests' reference for the GPU path).

    Returns
    -------
    :class:`~.homogenize.VoxelHomogenization` with ``device`` (the GPU's name or "host") and
    ``device_bytes`` (the CuPy memory pool's high-water mark; 0 on numpy). A cell too small for
    split levels (at most 1000 unknowns) is solved by the CPU path.
    """
    if not (0 < float(rtol) < 1e-3):
        raise ConfigError(f"rtol: {rtol!r}: allowed range is (0, 1e-3)")
    if int(maxiter) != maxiter or maxiter < 1:
        raise ConfigError(f"maxiter: {maxiter!r}: must be a positive integer")
    be = backend(device)
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):  # the host set-up's bits, as the CPU path
        cell = prepare_cell(phases, size, stiffnesses, scale, "chebyshev", degree, "split", direct_dofs)
        if cell.H.sparse is None:
            return _periodic_stiffness(phases, size, stiffnesses, scale, rtol, maxiter, "chebyshev", degree, "split",
                                       direct_dofs)
    t1 = time.perf_counter()
    DH = DeviceHierarchy(be, cell.H)
    project = projector(be, cell.labels, cell.n_parts)
    out = flexible_pcg(be, DH.fine.apply, be.put(-cell.F), DH.precondition, project, rtol=rtol, maxiter=maxiter)
    check_converged(out, rtol)
    X, KX = be.get(out.x), be.get(DH.fine.apply(out.x))
    C, C_raw = energy_form(cell, size, X, KX)
    t2 = time.perf_counter()
    return VoxelHomogenization(0.5 * (C + C.T), C_raw, cell.H.fine.to_full(X), tuple(out.iterations.tolist()),
                               tuple(out.residual.tolist()), cell.setup_seconds, t2 - t1, cell.op.n_free,
                               cell.H.shapes, be.device, be.memory())
