"""Natural frequencies and mode shapes: ``K phi = w^2 M phi`` on the free dofs.

Small problems (free size <= :data:`DENSE_MAX`) go to LAPACK's dense generalised solver;
larger ones to ARPACK in shift-invert mode about 0 (the lowest modes), started from a fixed
vector so that two runs give the same bytes. Shapes are M-normalised and their signs fixed
(the entry of largest magnitude positive; among entries tied to 1e-6, the first), so they are
comparable run to run.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import ConfigError

#: Largest free size solved dense (a 3000 x 3000 generalised eigenproblem: a few seconds).
DENSE_MAX = 3000
#: Relative margin within which entries count as tied for the largest (sign convention).
SIGN_TIE = 1e-6


@dataclass(frozen=True)
class Modes:
    """The lowest natural modes.

    frequencies_hz : (n,) [Hz], ascending; omega : (n,) circular frequencies [rad/s]
    (``sqrt(max(lambda, 0))``: rigid modes of round-off size read 0); eigenvalues : (n,)
    ``w^2`` [1/s^2] as solved (may be slightly negative for rigid modes); shapes : (N, n)
    [1/sqrt(t)], ``shapes^T M shapes = I`` on the free dofs, zero on the fixed ones.
    """

    frequencies_hz: np.ndarray
    omega: np.ndarray
    eigenvalues: np.ndarray
    shapes: np.ndarray


def _square(name: str, A) -> int:
    shape = getattr(A, "shape", None)
    if shape is None or len(shape) != 2 or shape[0] != shape[1]:
        raise ConfigError(f"{name}: shape is {shape} and should be (N, N)")
    return shape[0]


def _free_dofs(free, N: int) -> np.ndarray:
    if free is None:
        return np.arange(N)
    f = np.asarray(free)
    if f.dtype == bool:
        if f.shape != (N,):
            raise ConfigError(f"free: boolean mask of shape {f.shape}, expected ({N},)")
        return np.flatnonzero(f)
    if f.ndim != 1 or not np.issubdtype(f.dtype, np.integer):
        raise ConfigError(f"free: shape {f.shape}, dtype {f.dtype}: expected (k,) int dofs or an (N,) bool mask")
    if len(f) and (f.min() < 0 or f.max() >= N):
        raise ConfigError(f"free: dofs span [{f.min()}, {f.max()}], allowed [0, {N - 1}]")
    u = np.unique(f)
    if len(u) != len(f):
        raise ConfigError("free: repeated dofs: allowed each dof once")
    return u


def _sub(A, idx: np.ndarray):
    return A.tocsr()[idx][:, idx] if sp.issparse(A) else np.asarray(A, float)[np.ix_(idx, idx)]


def _signs(phi: np.ndarray) -> np.ndarray:
    """(n,) +-1 making each column's largest entry in magnitude positive. Symmetric bodies give
    shapes with entries of equal magnitude and opposite signs, told apart only by round-off; the
    first entry within :data:`SIGN_TIE` of the largest is taken instead, so that solvers and BLAS
    builds that differ in round-off still agree on the sign."""
    mag = np.abs(phi)
    first = np.argmax(mag >= (1 - SIGN_TIE) * mag.max(axis=0), axis=0)
    return np.where(phi[first, np.arange(phi.shape[1])] < 0, -1.0, 1.0)


def natural_modes(K, M, *, free=None, n: int = 10) -> Modes:
    """The ``n`` lowest modes of ``K phi = w^2 M phi`` restricted to the ``free`` dofs.

    K [N/mm], M [t] : (N, N) symmetric, sparse or dense (M positive definite on the free dofs;
    K too for the sparse path, which shifts about 0: clamp the rigid motions there).
    free : (k,) int dofs or (N,) bool mask (None: all). n : 1 <= n < k.
    Returns :class:`Modes`.
    """
    N = _square("K", K)
    if _square("M", M) != N:
        raise ConfigError(f"M: shape {M.shape} differs from K's {K.shape}")
    idx = _free_dofs(free, N)
    k = len(idx)
    if int(n) != n or not 1 <= n < k:
        raise ConfigError(f"n: {n!r}: allowed an integer in [1, {k - 1}] (below the {k} free dofs)")
    n = int(n)
    Kf, Mf = _sub(K, idx), _sub(M, idx)
    if k <= DENSE_MAX:
        Kd = Kf.toarray() if sp.issparse(Kf) else Kf
        Md = Mf.toarray() if sp.issparse(Mf) else Mf
        lam, phi = sla.eigh(0.5 * (Kd + Kd.T), 0.5 * (Md + Md.T), subset_by_index=[0, n - 1])
    else:
        Ks, Ms = sp.csc_matrix(Kf), sp.csc_matrix(Mf)
        lam, phi = spla.eigsh(0.5 * (Ks + Ks.T), k=n, M=0.5 * (Ms + Ms.T), sigma=0.0, which="LM",
                              v0=np.ones(k))
    order = np.argsort(lam, kind="stable")
    lam, phi = lam[order], phi[:, order]
    # M-normalise (ARPACK's are close to it; make it exact) and fix the sign
    phi = phi / np.sqrt(np.einsum("ij,ij->j", phi, Mf @ phi))
    phi = phi * _signs(phi)
    shapes = np.zeros((N, n))
    shapes[idx] = phi
    omega = np.sqrt(np.maximum(lam, 0.0))
    return Modes(omega / (2 * np.pi), omega, lam, shapes)
