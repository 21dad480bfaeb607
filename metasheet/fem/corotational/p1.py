"""Element kernels of the corotational linear tetrahedron (the hot loop of the robot FEM).

Per element ``e`` with rest nodes ``X_e`` (4, 3) and current nodes ``x_e`` (4, 3):

    F = Ds Dm^-1 = sum_a x_a g_a^T            deformation gradient, g_a = grad N_a (rest)
    F = R S                                   polar decomposition, R rotation, S symmetric
    f_e = R K_e (R^T x_e - X_e)               element force [N], K_e = V B^T C B (rest frame)

``C`` is the element's (6, 6) Voigt stiffness in global axes [MPa], order 11, 22, 33, 23, 13,
12 with engineering shear (:mod:`metasheet.conventions`). This is the force of SOFA's
``TetrahedronFEMForceField`` with ``method="polar"`` (Mueller & Gross 2004).

Consistent tangent (derivation in :func:`corotational_numpy`): with ``Omega = R^T dR = [w]x``,
the skew part of ``R^T dF = Omega S + dS`` gives ``(tr(S) I - S) w = 2 axial(skew(R^T dF))
= sum_a g_a x (R^T dx_a)``, so ``w = Z dy`` with ``Z = G^-1 [[g_0]x ... [g_3]x]``,
``G = tr(S) I - S`` and ``dy_a = R^T dx_a``. Differentiating ``f_e`` gives, in the
corotated frame,

    K_loc = K_e + L Z,   L_a = -[q_a]x + sum_b K_e,ab [p_b]x,   q = K_e (p - X), p_b = R^T x_b

and ``K_t = blockdiag(R) K_loc blockdiag(R)^T``. ``K_t`` is symmetric for isotropic ``C``
(then ``f_e`` is the gradient of the corotated energy) and slightly non-symmetric for an
anisotropic one away from rest: the polar-corotated force is not conservative when the
stress does not commute with ``S``.

Two implementations with the same maths: a batched numpy reference (SVD polar, slow but
plain) and a fused numba kernel (Higham's scaled Newton polar iteration, scatter straight into
the CSR data array) used in the hot loop.
"""

from __future__ import annotations

import numpy as np

from ..hex8 import strain_operator
from ..tet4 import tet4_gradients

try:  # numba is a declared dependency; the numpy path stays as a fallback and reference.
    import numba

    HAVE_NUMBA = True
except ImportError:  # pragma: no cover
    HAVE_NUMBA = False


# --------------------------------------------------------------------------- rest geometry


def shape_gradients(points: np.ndarray, tets: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rest-state gradients of the four linear shape functions (shared P1 kernel, :mod:`metasheet.fem.tet4`).

    Parameters
    ----------
    points : (n, 3) float [mm]
    tets : (m, 4) int

    Returns
    -------
    grads : (m, 4, 3) float [1/mm], ``grads[e, a] = grad N_a``; rows sum to zero.
    volumes : (m,) float [mm^3], unsigned.
    dm_inv : (m, 3, 3) float [1/mm], inverse of ``Dm = [X1-X0, X2-X0, X3-X0]`` (columns);
        its row ``a - 1`` is ``grad N_a``.
    """
    grads, volumes = tet4_gradients(points, tets)
    return grads, volumes, grads[:, 1:].copy()


def element_stiffness(grads: np.ndarray, volumes: np.ndarray, C: np.ndarray) -> np.ndarray:
    """(m, 12, 12) linear element stiffness ``V B^T C B`` [N/mm]; ``C`` (m, 6, 6) or (6, 6) [MPa]."""
    B = strain_operator(grads)
    C = np.broadcast_to(C, (len(grads), 6, 6))
    Ke = np.einsum("mki,mkl,mlj->mij", B, C, B, optimize=True) * volumes[:, None, None]
    return 0.5 * (Ke + np.transpose(Ke, (0, 2, 1)))


# --------------------------------------------------------------------------- numpy reference


def _skew_stack(v: np.ndarray) -> np.ndarray:
    """(..., 3, 3) cross-product matrices [v]x of (..., 3) vectors."""
    S = np.zeros(v.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2] = -v[..., 2], v[..., 1]
    S[..., 1, 0], S[..., 1, 2] = v[..., 2], -v[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -v[..., 1], v[..., 0]
    return S


def polar_numpy(F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Batched polar decomposition ``F = R S`` (m, 3, 3) with ``det R = +1``.

    For an inverted element (det F < 0) the smallest principal stretch turns negative
    so that R stays a rotation (S is then symmetric but indefinite).
    """
    U, s, Vt = np.linalg.svd(F)
    d = np.sign(np.linalg.det(U @ Vt))
    d[d == 0] = 1.0
    U[:, :, 2] *= d[:, None]
    s[:, 2] *= d
    R = U @ Vt
    S = np.einsum("mki,mk,mkj->mij", Vt, s, Vt)
    return R, 0.5 * (S + np.transpose(S, (0, 2, 1)))


def corotational_numpy(x_e, X_e, grads, Ke, *, tangent=True):
    """Element forces and consistent tangents, batched numpy (the readable reference).

    Parameters
    ----------
    x_e, X_e : (m, 4, 3) current and rest element nodes [mm]
    grads : (m, 4, 3) rest shape-function gradients [1/mm]
    Ke : (m, 12, 12) rest-frame element stiffness [N/mm]

    Returns
    -------
    fe : (m, 12) element nodal forces [N], node-major.
    Kt : (m, 12, 12) consistent tangents d fe / d x_e [N/mm] (None if not ``tangent``).
    """
    m = len(x_e)
    F = np.einsum("mai,maj->mij", x_e, grads)
    R, S = polar_numpy(F)
    p = np.einsum("mji,maj->mai", R, x_e)  # p_a = R^T x_a, (m, 4, 3)
    q = np.einsum("mij,mj->mi", Ke, (p - X_e).reshape(m, 12))  # local forces (m, 12)
    fe = np.einsum("mij,maj->mai", R, q.reshape(m, 4, 3)).reshape(m, 12)
    if not tangent:
        return fe, None
    G = np.trace(S, axis1=1, axis2=2)[:, None, None] * np.eye(3) - S
    Z = np.einsum("mij,majk->miak", np.linalg.inv(G), _skew_stack(grads)).reshape(m, 3, 12)
    P = _skew_stack(p).reshape(m, 12, 3)
    L = Ke @ P - _skew_stack(q.reshape(m, 4, 3)).reshape(m, 12, 3)
    Kloc = (Ke + L @ Z).reshape(m, 4, 3, 4, 3)
    Kt = np.einsum("mij,majbk,mlk->maibl", R, Kloc, R).reshape(m, 12, 12)
    return fe, Kt


# --------------------------------------------------------------------------- numba kernel

if HAVE_NUMBA:

    @numba.njit(cache=True, inline="always")
    def _inv3(A, out):
        """Inverse of a 3x3 by cofactors into ``out``; returns the determinant."""
        c00 = A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1]
        c01 = A[1, 2] * A[2, 0] - A[1, 0] * A[2, 2]
        c02 = A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0]
        det = A[0, 0] * c00 + A[0, 1] * c01 + A[0, 2] * c02
        r = 1.0 / det
        out[0, 0] = c00 * r
        out[1, 0] = c01 * r
        out[2, 0] = c02 * r
        out[0, 1] = (A[0, 2] * A[2, 1] - A[0, 1] * A[2, 2]) * r
        out[1, 1] = (A[0, 0] * A[2, 2] - A[0, 2] * A[2, 0]) * r
        out[2, 1] = (A[0, 1] * A[2, 0] - A[0, 0] * A[2, 1]) * r
        out[0, 2] = (A[0, 1] * A[1, 2] - A[0, 2] * A[1, 1]) * r
        out[1, 2] = (A[0, 2] * A[1, 0] - A[0, 0] * A[1, 2]) * r
        out[2, 2] = (A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]) * r
        return det

    @numba.njit(cache=True, nogil=True)
    def _polar3(F, R, S, Xi):
        """Polar decomposition F = R S (3x3) into R, S; Xi is 3x3 scratch.

        Higham's scaled Newton iteration R <- (z R + R^-T / z) / 2 converges quadratically
        to the orthogonal factor when det F > 0; inverted elements fall back to an SVD
        with the smallest stretch made negative so that R stays a proper rotation.
        """
        det = _inv3(F, Xi)
        if det > 0.0:
            for i in range(3):
                for j in range(3):
                    R[i, j] = F[i, j]
            for it in range(60):
                _inv3(R, Xi)
                scale = 1.0
                if it < 8:  # Frobenius scaling speeds up the far-from-orthogonal start
                    na = 0.0
                    nb = 0.0
                    for i in range(3):
                        for j in range(3):
                            na += R[i, j] * R[i, j]
                            nb += Xi[i, j] * Xi[i, j]
                    scale = np.sqrt(np.sqrt(nb / na))
                diff = 0.0
                for i in range(3):
                    for j in range(3):
                        v = 0.5 * (scale * R[i, j] + Xi[j, i] / scale)
                        diff += (v - R[i, j]) ** 2
                        R[i, j] = v
                if diff < 1e-15:  # quadratic: the new iterate is then accurate to ~1e-16
                    break
        else:
            U, s, Vt = np.linalg.svd(F)
            d = np.linalg.det(U @ Vt)
            if d < 0.0:
                for i in range(3):
                    U[i, 2] = -U[i, 2]
            for i in range(3):
                for j in range(3):
                    R[i, j] = U[i, 0] * Vt[0, j] + U[i, 1] * Vt[1, j] + U[i, 2] * Vt[2, j]
        for i in range(3):  # S = sym(R^T F)
            for j in range(3):
                S[i, j] = R[0, i] * F[0, j] + R[1, i] * F[1, j] + R[2, i] * F[2, j]
        for i in range(3):
            for j in range(i + 1, 3):
                v = 0.5 * (S[i, j] + S[j, i])
                S[i, j] = v
                S[j, i] = v

    @numba.njit(cache=True, nogil=True)
    def _skew_into(v0, v1, v2, M, r, c, sign):
        """Add sign * [v]x into M[r:r+3, c:c+3]."""
        M[r + 0, c + 1] -= sign * v2
        M[r + 0, c + 2] += sign * v1
        M[r + 1, c + 0] += sign * v2
        M[r + 1, c + 2] -= sign * v0
        M[r + 2, c + 0] -= sign * v1
        M[r + 2, c + 1] += sign * v0

    # No fastmath: with it, the freshly compiled kernel and the one numba loads from its cache
    # rounded differently (forces 1e-13 apart), so a first run and a second run wrote different
    # bytes (issue 15). Without it: the same bits every run, no measurable cost (2.3 ms per
    # tangent on the quick sheets, both ways).
    @numba.njit(cache=True, nogil=True, error_model="numpy")
    def corotational_numba(x, tets, X_e, grads, Ke, block_map, f_out, data_out, tangent):
        """Fused kernel: global forces and CSR data of the consistent tangent.

        Parameters
        ----------
        x : (n, 3) current positions [mm]; tets (m, 4) int64; X_e (m, 4, 3) rest nodes;
        grads (m, 4, 3); Ke (m, 12, 12); block_map (m, 144) int64 (:class:`metasheet.fem.assembly.SparsityPattern`).
        f_out : (3n,) zeroed and filled with forces [N].
        data_out : (nnz,) zeroed and filled with the tangent's CSR data if ``tangent``.
        """
        m = tets.shape[0]
        f_out[:] = 0.0
        if tangent:
            data_out[:] = 0.0
        F = np.empty((3, 3))
        R = np.empty((3, 3))
        S = np.empty((3, 3))
        G = np.empty((3, 3))
        Gi = np.empty((3, 3))
        xe = np.empty((4, 3))
        p = np.empty((4, 3))
        u = np.empty(12)
        q = np.empty(12)
        Z = np.empty((3, 12))
        P = np.empty((12, 3))
        L = np.empty((12, 3))
        Kl = np.empty((12, 12))
        M = np.empty((12, 12))
        for e in range(m):
            for a in range(4):
                for i in range(3):
                    xe[a, i] = x[tets[e, a], i]
            for i in range(3):
                for j in range(3):
                    F[i, j] = (
                        xe[0, i] * grads[e, 0, j]
                        + xe[1, i] * grads[e, 1, j]
                        + xe[2, i] * grads[e, 2, j]
                        + xe[3, i] * grads[e, 3, j]
                    )
            _polar3(F, R, S, Gi)
            for a in range(4):  # p_a = R^T x_a, u = p - X
                for i in range(3):
                    p[a, i] = R[0, i] * xe[a, 0] + R[1, i] * xe[a, 1] + R[2, i] * xe[a, 2]
                    u[3 * a + i] = p[a, i] - X_e[e, a, i]
            for i in range(12):
                acc = 0.0
                for j in range(12):
                    acc += Ke[e, i, j] * u[j]
                q[i] = acc
            for a in range(4):  # f_a = R q_a
                for i in range(3):
                    f_out[3 * tets[e, a] + i] += R[i, 0] * q[3 * a] + R[i, 1] * q[3 * a + 1] + R[i, 2] * q[3 * a + 2]
            if not tangent:
                continue
            tr = S[0, 0] + S[1, 1] + S[2, 2]
            for i in range(3):
                for j in range(3):
                    G[i, j] = -S[i, j]
                G[i, i] += tr
            _inv3(G, Gi)
            # Z = G^-1 [[g_0]x ... [g_3]x]  (3 x 12): w = Z (R^T dx)
            for i in range(3):
                for c in range(4):
                    g0 = grads[e, c, 0]
                    g1 = grads[e, c, 1]
                    g2 = grads[e, c, 2]
                    # row i of Gi times [g]x: ([g]x)^T Gi[i] = -[g]x Gi[i] = Gi[i] x g
                    Z[i, 3 * c + 0] = Gi[i, 1] * g2 - Gi[i, 2] * g1
                    Z[i, 3 * c + 1] = Gi[i, 2] * g0 - Gi[i, 0] * g2
                    Z[i, 3 * c + 2] = Gi[i, 0] * g1 - Gi[i, 1] * g0
            # P = stacked [p_b]x (12 x 3); L = Ke P - blockdiag [q_a]x
            P[:, :] = 0.0
            for b in range(4):
                _skew_into(p[b, 0], p[b, 1], p[b, 2], P, 3 * b, 0, 1.0)
            for i in range(12):
                for k in range(3):
                    acc = 0.0
                    for j in range(12):
                        acc += Ke[e, i, j] * P[j, k]
                    L[i, k] = acc
            for a in range(4):
                _skew_into(q[3 * a], q[3 * a + 1], q[3 * a + 2], L, 3 * a, 0, -1.0)
            for i in range(12):  # Kl = Ke + L Z
                for j in range(12):
                    Kl[i, j] = Ke[e, i, j] + L[i, 0] * Z[0, j] + L[i, 1] * Z[1, j] + L[i, 2] * Z[2, j]
            for a in range(4):  # M = blockdiag(R) Kl
                for i in range(3):
                    for j in range(12):
                        M[3 * a + i, j] = (
                            R[i, 0] * Kl[3 * a, j] + R[i, 1] * Kl[3 * a + 1, j] + R[i, 2] * Kl[3 * a + 2, j]
                        )
            for r in range(12):  # Kt = M blockdiag(R)^T, scattered straight into the CSR data
                for b in range(4):
                    for l in range(3):
                        v = M[r, 3 * b] * R[l, 0] + M[r, 3 * b + 1] * R[l, 1] + M[r, 3 * b + 2] * R[l, 2]
                        data_out[block_map[e, 12 * r + 3 * b + l]] += v
