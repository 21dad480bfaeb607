"""The split multigrid's solve on an array device: CuPy on a CUDA GPU (optional), numpy to test it.

The set-up is the CPU path's (:func:`.homogenize.prepare_cell`: the operator, the split hierarchy,
the right-hand sides), so the device solves the same preconditioned system. Each piece then moves to
the device as arrays of the array module ``xp`` (``cupy`` or ``numpy``):

- **fine level**: ``K u`` voxel by voxel with no loop in Python over voxels: gather the 8 corners'
  compact values (v, 24, m), multiply by each phase's (24, 24) matrix (batched GEMM), scale, and
  sum into the nodes by a *gather*: each compact node reads its (up to) 8 voxels' contributions,
  one corner slot at a time in a fixed order. A scatter-add would need atomics, whose order (and
  so bits) changes from run to run on a GPU;
- **split levels**: the BSR operators as scalar CSR (3n, 3n), the transfers as the node CSR (one
  product serves the 3 components and m columns), multiplied by a CUDA kernel that sums each row
  in its stored order (:class:`Csr`);
- **bottom level**: a dense Cholesky factor of the same pinned, shifted matrix the CPU path hands
  to SuperLU (at most :data:`DENSE_BOTTOM` unknowns; above, the host's SuperLU factor, with the
  right-hand sides copied over and back);
- Chebyshev smoothing, the K-cycle and flexible CG with the translations projected out: the CPU
  path's formulas (:mod:`.multigrid`, :mod:`.split_hierarchy`, :mod:`.pcg`) in ``xp`` operations.

The bits differ from the CPU path's (other summation orders): the tests hold the two to 1e-10 on
C* and to the same iteration counts within one. On a GPU every sum is a CuPy reduction, a cuBLAS
GEMM or :class:`Csr`'s kernel, none with atomics, so a run repeats its own bits on the same card
(tested where a GPU is present); "auto" never picks the device, so a pipeline's bytes never depend
on one.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import ModuleType

import numpy as np
import scipy.sparse as sp

from ...errors import ConfigError
from .blocks import to_bsr
from .split import REGULARIZE
from .split_hierarchy import chebyshev_steps

#: Factorise the bottom level densely on the device up to this many unknowns ((n, n) float64: 5 GB).
DENSE_BOTTOM = 25_000
#: The array back-ends accepted by :func:`periodic_stiffness_device`.
BACKENDS = ("cupy", "numpy")


@dataclass(frozen=True)
class Backend:
    """An array module: numpy or cupy.

    name : "numpy" or "cupy"; xp : the array module; device : what runs it, in words (the GPU's
    name, or "host")."""

    name: str
    xp: ModuleType
    device: str

    def put(self, a) -> object:
        """A host array on the device; a scipy sparse matrix as a :class:`Csr`."""
        if sp.issparse(a):
            return Csr(self, a)
        return self.xp.asarray(np.ascontiguousarray(a))

    def get(self, a) -> np.ndarray:
        """A device array on the host."""
        return a.get() if self.name == "cupy" else np.asarray(a)

    def memory(self) -> int:
        """Bytes the device's memory pool holds (cupy: its high-water mark; numpy: 0)."""
        if self.name != "cupy":
            return 0
        return int(self.xp.get_default_memory_pool().total_bytes())


def backend(name: str = "cupy") -> Backend:
    """The named back-end; ConfigError when CuPy or a CUDA GPU is missing (never an ImportError)."""
    if name == "numpy":
        return Backend("numpy", np, "host")
    if name != "cupy":
        raise ConfigError(f"backend: {name!r}: allowed values are {', '.join(BACKENDS)}")
    try:
        import cupy

        count = cupy.cuda.runtime.getDeviceCount()
    except Exception as exc:  # noqa: BLE001  (ImportError, CUDARuntimeError...: one message for all)
        raise ConfigError("solver 'voxel-gpu': needs CuPy and a CUDA GPU (pip install cupy-cuda12x or "
                          f"cupy-cuda13x); CuPy said: {exc}. Use solver 'voxel' (the CPU path)") from None
    if count < 1:
        raise ConfigError("solver 'voxel-gpu': CuPy sees no CUDA GPU; use solver 'voxel' (the CPU path)")
    props = cupy.cuda.runtime.getDeviceProperties(cupy.cuda.Device().id)
    return Backend("cupy", cupy, props["name"].decode() if isinstance(props["name"], bytes) else props["name"])


#: ``Y = T X`` for a CSR ``T`` and a C-ordered (cols, m) ``X``: one thread per output entry, the
#: row's stored entries summed in order (no atomics: the same bits every run). cupyx's CSR product
#: (cuSPARSE SpMM) was used first: two runs gave different bits, and the paper cell took 225 CG
#: iterations instead of the CPU's 36 (measured on an H200; docs/voxel.md).
_CSR_MM = r"""
extern "C" __global__
void csr_mm(const long long* indptr, const long long* indices, const double* data,
            const double* x, double* y, const long long rows, const int m) {
    long long t = (long long)blockIdx.x * blockDim.x + threadIdx.x;
    if (t >= rows * m) return;
    long long i = t / m;
    int c = (int)(t - i * m);
    double s = 0.0;
    for (long long k = indptr[i]; k < indptr[i + 1]; ++k) s += data[k] * x[indices[k] * m + c];
    y[t] = s;
}
"""
_KERNELS: dict = {}


class Csr:
    """A sparse matrix on the device: ``T @ X`` for dense (cols, m) X -> (rows, m).

    numpy: the scipy CSR product (each row's entries summed in stored order); cupy: the same loop
    as a CUDA kernel (:data:`_CSR_MM`)."""

    def __init__(self, be: Backend, T):
        T = sp.csr_matrix(T)
        self.be, self.shape = be, T.shape
        if be.name == "cupy":
            xp = be.xp
            self.indptr = xp.asarray(T.indptr.astype(np.int64))
            self.indices = xp.asarray(T.indices.astype(np.int64))
            self.data = xp.asarray(T.data.astype(np.float64))
        else:
            self.T = T

    def __matmul__(self, X):
        if self.be.name != "cupy":
            return self.T @ X
        xp = self.be.xp
        if "csr_mm" not in _KERNELS:
            _KERNELS["csr_mm"] = xp.RawKernel(_CSR_MM, "csr_mm")
        X = xp.ascontiguousarray(X, dtype=xp.float64)
        rows, m = self.shape[0], X.shape[1]
        Y = xp.empty((rows, m))
        if rows * m:
            _KERNELS["csr_mm"](((rows * m + 255) // 256,), (256,),
                               (self.indptr, self.indices, self.data, X, Y, np.int64(rows), np.int32(m)))
        return Y


class FineLevel:
    """The finest voxel level on the device: ``free * K (free * u)`` for compact (a, 3, m) blocks."""

    def __init__(self, be: Backend, cop, dinv: np.ndarray, lmax: float):
        sw = cop.op.sweep
        a, v = cop.size, len(sw.matrix)
        order = np.argsort(sw.matrix, kind="stable")  # voxels grouped by element matrix
        nodes = np.where(cop.nodes[order] >= 0, cop.nodes[order], a)  # -1 -> the zero row a
        inc = np.full((a + 1, 8), v, np.int64)  # voxel (sorted) whose corner c is node n; v: the zero row
        for c in range(8):
            inc[nodes[:, c], c] = np.arange(v)
        mats = sw.matrix[order]
        bounds = np.searchsorted(mats, np.arange(len(sw.matrices_t) + 1))
        self.be, self.size = be, a
        self.groups = [(int(bounds[q]), int(bounds[q + 1]), be.put(sw.matrices_t[q].T))
                       for q in range(len(sw.matrices_t)) if bounds[q + 1] > bounds[q]]
        self.nodes = be.put(nodes)
        self.inc = be.put(inc[:a])
        self.scale = be.put(sw.scale[order])
        self.free = be.put(cop.free)
        self.dinv = be.put(dinv)
        self.lmax = float(lmax)
        self.n_voxels = v

    def apply(self, u):
        """``free * K (free * u)``: (a, 3, m) [mm] -> (a, 3, m) [N]."""
        xp, a, v = self.be.xp, self.size, self.n_voxels
        m = u.shape[2]
        up = xp.zeros((a + 1, m, 3))  # row a: the inactive corners' zero
        up[:a] = (u * self.free[..., None]).transpose(0, 2, 1)
        # rows (voxel, column) of the 24 corner dofs: one plain GEMM per phase, no broadcast batch
        ue = up[self.nodes].transpose(0, 2, 1, 3).reshape(v * m, 24)
        del up
        ye = xp.zeros((v + 1, m, 24))  # row v: the zero read by a node's missing voxels
        for lo, hi, K in self.groups:
            ye[lo:hi] = (ue[lo * m:hi * m] @ K.T).reshape(hi - lo, m, 24) * self.scale[lo:hi, None, None]
        del ue
        ye = ye.reshape(v + 1, m, 8, 3)
        y = ye[self.inc[:, 0], :, 0]  # (a, m, 3)
        for c in range(1, 8):  # a gather in a fixed order, not an atomic scatter: the same bits every run
            y += ye[self.inc[:, c], :, c]
        return y.transpose(0, 2, 1) * self.free[..., None]


class SparseLevel:
    """A split level on the device: its operator (3n, 3n), the transfer P from it to the level above."""

    def __init__(self, be: Backend, lv):
        self.be, self.size = be, lv.size
        self.A = be.put(to_bsr(lv.indptr, lv.indices, lv.data).tocsr())
        self.P, self.R = be.put(lv.P), be.put(lv.R)
        self.dinv = be.put(lv.dinv)
        self.lmax = float(lv.lmax)

    def apply(self, x):
        n, _, m = x.shape
        return (self.A @ x.reshape(3 * n, m)).reshape(n, 3, m)


def transfer(T, x):
    """``T x`` per component for a node CSR ``T`` (r, c) and x (c, 3, m) -> (r, 3, m)."""
    n, _, m = x.shape
    return (T @ x.reshape(n, 3 * m)).reshape(T.shape[0], 3, m)


class Bottom:
    """The bottom level's solve: the CPU path's pinned, shifted matrix, Cholesky on the device
    (at most :data:`DENSE_BOTTOM` unknowns) or the host's SuperLU factor."""

    def __init__(self, be: Backend, sh):
        self.be, self.keep_host = be, sh.keep
        self.keep = be.put(sh.keep)
        self.host_solve = sh.solve
        self.L = None
        if len(sh.keep) <= DENSE_BOTTOM:
            last = sh.levels[-1]
            A = to_bsr(last.indptr, last.indices, last.data).tocsr()[sh.keep][:, sh.keep]
            A = (A + sp.diags(REGULARIZE * A.diagonal())).toarray()
            L = be.xp.linalg.cholesky(be.put(A))
            if bool(be.xp.all(be.xp.isfinite(L))):  # cupy returns NaN rather than raising
                self.L = L

    def solve(self, b):
        xp = self.be.xp
        n, _, m = b.shape
        x = xp.zeros_like(b)
        flat, bf = x.reshape(3 * n, m), b.reshape(3 * n, m)
        rhs = bf[self.keep]
        if self.L is not None:
            flat[self.keep] = _cho_solve(self.be, self.L, rhs)
        else:
            flat[self.keep] = self.be.put(self.host_solve(np.ascontiguousarray(self.be.get(rhs))))
        return x


def _cho_solve(be: Backend, L, b):
    if be.name == "cupy":
        from cupyx.scipy.linalg import solve_triangular
    else:
        from scipy.linalg import solve_triangular
    return solve_triangular(L.T, solve_triangular(L, b, lower=True), lower=False)


def dots(xp, a, b):
    """(m,) column dot products of two (n, 3, m) blocks."""
    return xp.einsum("ijk,ijk->k", a, b)


def chebyshev(xp, apply, dinv, lmax: float, degree: int, ratio: float, x, b):
    """Chebyshev smoothing of ``A x = b`` on ``D^-1 A``, as :func:`.split_hierarchy.chebyshev`."""
    r = b.copy() if x is None else b - apply(x)
    x = xp.zeros_like(b) if x is None else x
    theta, steps = chebyshev_steps(lmax, ratio, degree)
    d = dinv[..., None] * r / theta
    x += d
    for a, c in steps:
        r -= apply(d)
        d = a * d + c * (dinv[..., None] * r)
        x += d
    return x
