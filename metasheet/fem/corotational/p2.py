"""Corotational FEM evaluated per quadrature point, for P1 (4-node) and P2 (10-node) tets.

At each quadrature point ``q`` of element ``e``, with rest gradients ``g_a = grad N_a``
(:func:`metasheet.fem.tet10.tet10_quadrature`, :func:`~metasheet.fem.tet10.tet4_quadrature`):

    F = sum_a x_a g_a^T                   deformation gradient at q
    F = R S                               polar decomposition, det R = +1
    eps = voigt(S - I)                    corotated strain, engineering shear
    sigma = C_e eps                       C_e (6, 6) global axes [MPa], order 11 22 33 23 13 12
    P = R sigma                           first Piola stress [MPa]
    f_a += w_q P g_a                      internal nodal force [N]

For P1 (one point, ``w = V``) this is exactly the element force ``f = R K_e (R^T x - X)`` of
:mod:`metasheet.fem.corotational.p1` (``B (R^T x - X) = voigt(S - I)`` and ``(B^T sigma)_a = sigma g_a``).

Why per quadrature point. The continuum model behind the P1 kernel is corotated linear
elasticity: stress ``P = R C:(S - I)`` from the pointwise polar decomposition of ``F``; the P1
element evaluates it exactly because its ``F`` is constant. Evaluating the same constitutive
law at the quadrature points of a P2 element is the standard consistent discretisation of that
same model (it reduces to P1's for constant ``F``), so P1 and P2 meshes of one sheet converge
to one limit and a convergence study compares like with like. One rotation per *element* for
P2 would instead mix rotations across a bending element and converge to a different (and
mesh-dependent) model. Evaluating per point keeps objectivity exact: under ``x -> Q x + t``,
``F -> Q F``, ``R -> Q R``, ``S`` is unchanged, so ``f -> Q f`` and a rigid motion of the rest
shape gives zero force. With an anisotropic ``C`` the stress does not commute with ``S`` and
the force is not the gradient of an energy (as in SOFA's polar ``TetrahedronFEMForceField`` and
our P1 kernel): the consistent tangent is non-symmetric away from rest and is factorised by LU.

Consistent tangent. With ``H = R^T dF`` and ``R^T dR = [w]x``, ``H = [w]x S + dS`` (dS
symmetric); its skew part gives ``(tr(S) I - S) w = 2 axial(skew(H))``. Then
``dS = sym(H) - sym([w]x S)`` and ``dP = R ([w]x sigma + mat(C voigt(dS)))``, and
``K_ab = sum_q w_q sum_{k,l} g_a,k A[i k, j l] g_b,l`` with ``A = dP/dF`` (9 x 9).

Two implementations of the same maths: a batched numpy reference and a fused numba kernel
scattering into the CSR data of :class:`metasheet.fem.assembly.SparsityPattern`.
Dofs are node-major, ``3 a + i``.
"""

from __future__ import annotations

import numpy as np

from .p1 import HAVE_NUMBA, polar_numpy

if HAVE_NUMBA:
    import numba

    from .p1 import _inv3, _polar3

#: Levi-Civita symbol eps_ijk.
LEVI = np.zeros((3, 3, 3))
LEVI[0, 1, 2] = LEVI[1, 2, 0] = LEVI[2, 0, 1] = 1.0
LEVI[0, 2, 1] = LEVI[2, 1, 0] = LEVI[1, 0, 2] = -1.0

_VI = np.array([0, 1, 2, 1, 0, 0])  # Voigt index -> (i, j), order 11 22 33 23 13 12
_VJ = np.array([0, 1, 2, 2, 2, 1])
_ENG = np.array([1.0, 1.0, 1.0, 2.0, 2.0, 2.0])  # engineering shear


def voigt_strain(E: np.ndarray) -> np.ndarray:
    """(..., 6) Voigt vector of symmetric tensors (..., 3, 3), engineering shear (2 E_23...)."""
    return E[..., _VI, _VJ] * _ENG


def voigt_to_tensor(s: np.ndarray) -> np.ndarray:
    """(..., 3, 3) symmetric tensor of a Voigt stress (..., 6) (no shear factor)."""
    T = np.empty(s.shape[:-1] + (3, 3))
    T[..., _VI, _VJ] = s
    T[..., _VJ, _VI] = s
    return T


def _sym(A: np.ndarray) -> np.ndarray:
    return 0.5 * (A + np.swapaxes(A, -1, -2))


# --------------------------------------------------------------------------- numpy reference


def corotational_quadrature_numpy(x_e, grads, weights, C, *, tangent=True):
    """Element forces and consistent tangents, batched numpy (the readable reference).

    Parameters
    ----------
    x_e : (m, nen, 3) current element nodes [mm]
    grads : (m, nq, nen, 3) rest shape-function gradients at the quadrature points [1/mm]
    weights : (m, nq) quadrature weights [mm^3]
    C : (m, 6, 6) element stiffness in global axes [MPa] (or (6, 6), broadcast)

    Returns
    -------
    fe : (m, 3 nen) element nodal forces [N], node-major ``3 a + i``.
    Kt : (m, 3 nen, 3 nen) consistent tangents ``d fe / d x_e`` [N/mm] (None if not ``tangent``).
    """
    m, nq, nen, _ = grads.shape
    C = np.broadcast_to(C, (m, 6, 6))
    F = np.einsum("mai,mqaj->mqij", x_e, grads)
    R, S = polar_numpy(F.reshape(-1, 3, 3))
    R, S = R.reshape(m, nq, 3, 3), S.reshape(m, nq, 3, 3)
    eps = voigt_strain(S - np.eye(3))  # (m, nq, 6)
    sig = voigt_to_tensor(np.einsum("mIJ,mqJ->mqI", C, eps))
    P = R @ sig
    fe = np.einsum("mq,mqik,mqak->mai", weights, P, grads).reshape(m, 3 * nen)
    if not tangent:
        return fe, None
    # Directional derivatives along the 9 unit directions dF = e_j e_l^T, all at once:
    # axes (m, q, j, l, ...). H = R^T dF has H_ab = R_ja delta_lb.
    H = np.einsum("mqja,lb->mqjlab", R, np.eye(3))
    h = np.einsum("pab,mqjlba->mqjlp", LEVI, H)  # 2 axial(skew(H))
    G = np.trace(S, axis1=2, axis2=3)[..., None, None] * np.eye(3) - S
    w = np.einsum("mqpr,mqjlr->mqjlp", np.linalg.inv(G), h)
    W = np.einsum("ipk,mqjlp->mqjlik", LEVI, w)  # [w]x
    dS = _sym(H) - _sym(np.einsum("mqjlik,mqkn->mqjlin", W, S))
    dsig = voigt_to_tensor(np.einsum("mIJ,mqjlJ->mqjlI", C, voigt_strain(dS)))
    dPi = np.einsum("mqjlik,mqkn->mqjlin", W, sig) + dsig
    A = np.einsum("mqai,mqjlik->mqjlak", R, dPi)  # A[.., j, l, i, k] = dP_ik / dF_jl
    Kt = np.einsum("mq,mqak,mqjlik,mqbl->maibj", weights, grads, A, grads, optimize=True)
    return fe, Kt.reshape(m, 3 * nen, 3 * nen)


# --------------------------------------------------------------------------- strain measures


def deformation_gradients(x: np.ndarray, elems: np.ndarray, grads: np.ndarray) -> np.ndarray:
    """(m, nq, 3, 3) deformation gradients at the quadrature points; x (n, 3) [mm], elems (m, nen)."""
    return np.einsum("mai,mqaj->mqij", np.asarray(x, float)[elems], grads)


def element_strains(x: np.ndarray, elems: np.ndarray, grads: np.ndarray) -> np.ndarray:
    """(m, nq, 6) corotated strains ``voigt(S - I)`` [-] (engineering shear) at each quadrature point.

    x : (n, 3) [mm]; elems : (m, nen) int; grads : (m, nq, nen, 3) [1/mm].
    """
    F = deformation_gradients(x, elems, grads)
    _, S = polar_numpy(F.reshape(-1, 3, 3))
    return voigt_strain(S.reshape(F.shape) - np.eye(3))


def max_principal_green_strain(x: np.ndarray, elems: np.ndarray, grads: np.ndarray) -> np.ndarray:
    """(m,) largest principal Green-Lagrange strain ``eig((F^T F - I) / 2)`` [-] over each
    element's quadrature points (the measure of a strain-validity flag)."""
    F = deformation_gradients(x, elems, grads)
    E = 0.5 * (np.swapaxes(F, -1, -2) @ F - np.eye(3))
    return np.linalg.eigvalsh(E)[..., -1].max(axis=1)


# --------------------------------------------------------------------------- numba kernel

if HAVE_NUMBA:

    @numba.njit(cache=True, inline="always")
    def _voigt_stress(C, e, eps, s, out):
        """``out`` (3, 3) = tensor of ``C[e] @ eps`` (Voigt); ``s`` (6,) is scratch."""
        for I in range(6):
            acc = 0.0
            for J in range(6):
                acc += C[e, I, J] * eps[J]
            s[I] = acc
        out[0, 0] = s[0]
        out[1, 1] = s[1]
        out[2, 2] = s[2]
        out[1, 2] = out[2, 1] = s[3]
        out[0, 2] = out[2, 0] = s[4]
        out[0, 1] = out[1, 0] = s[5]

    # No fastmath, as in kernels.corotational_numba: bit-identical results on every run.
    @numba.njit(cache=True, nogil=True, error_model="numpy")
    def corotational_quadrature_numba(x, elems, grads, weights, C, block_map, f_out, data_out, tangent):
        """Fused kernel: global forces and CSR data of the consistent tangent, any ``nen``.

        Parameters
        ----------
        x : (n, 3) current positions [mm]; elems (m, nen) int64; grads (m, nq, nen, 3) [1/mm];
        weights (m, nq) [mm^3]; C (m, 6, 6) [MPa] (C-contiguous, one per element);
        block_map (m, (3 nen)^2) int64 (:class:`metasheet.fem.assembly.SparsityPattern`).
        f_out : (3n,) zeroed and filled with forces [N].
        data_out : (nnz,) zeroed and filled with the tangent's CSR data [N/mm] if ``tangent``.
        """
        m, nen = elems.shape
        nq = grads.shape[1]
        nd = 3 * nen
        f_out[:] = 0.0
        if tangent:
            data_out[:] = 0.0
        xe = np.empty((nen, 3))
        F = np.empty((3, 3))
        R = np.empty((3, 3))
        S = np.empty((3, 3))
        Xi = np.empty((3, 3))
        G = np.empty((3, 3))
        Gi = np.empty((3, 3))
        sig = np.empty((3, 3))
        H = np.empty((3, 3))
        W = np.empty((3, 3))
        dS = np.empty((3, 3))
        dPi = np.empty((3, 3))
        eps = np.empty(6)
        s = np.empty(6)
        A = np.empty((3, 3, 3, 3))  # A[i, k, j, l] = w_q dP_ik / dF_jl
        T = np.empty((nen, 3, 3, 3))  # T[a, i, j, l] = sum_k g_a,k A[i, k, j, l]
        Ke = np.empty((nd, nd))
        for e in range(m):
            for a in range(nen):
                for i in range(3):
                    xe[a, i] = x[elems[e, a], i]
            if tangent:
                Ke[:, :] = 0.0
            for q in range(nq):
                wq = weights[e, q]
                for i in range(3):
                    for j in range(3):
                        acc = 0.0
                        for a in range(nen):
                            acc += xe[a, i] * grads[e, q, a, j]
                        F[i, j] = acc
                _polar3(F, R, S, Xi)
                eps[0] = S[0, 0] - 1.0
                eps[1] = S[1, 1] - 1.0
                eps[2] = S[2, 2] - 1.0
                eps[3] = 2.0 * S[1, 2]
                eps[4] = 2.0 * S[0, 2]
                eps[5] = 2.0 * S[0, 1]
                _voigt_stress(C, e, eps, s, sig)
                for i in range(3):  # f_a += w P g_a with P = R sig
                    for k in range(3):
                        Pik = wq * (R[i, 0] * sig[0, k] + R[i, 1] * sig[1, k] + R[i, 2] * sig[2, k])
                        for a in range(nen):
                            f_out[3 * elems[e, a] + i] += Pik * grads[e, q, a, k]
                if not tangent:
                    continue
                tr = S[0, 0] + S[1, 1] + S[2, 2]
                for i in range(3):
                    for j in range(3):
                        G[i, j] = -S[i, j]
                    G[i, i] += tr
                _inv3(G, Gi)
                for j in range(3):  # direction dF = e_j e_l^T: H = R^T dF, H_ab = R_ja delta_lb
                    for l in range(3):
                        for a in range(3):
                            for b in range(3):
                                H[a, b] = R[j, a] if b == l else 0.0
                        h0 = H[2, 1] - H[1, 2]  # 2 axial(skew(H))
                        h1 = H[0, 2] - H[2, 0]
                        h2 = H[1, 0] - H[0, 1]
                        w0 = Gi[0, 0] * h0 + Gi[0, 1] * h1 + Gi[0, 2] * h2
                        w1 = Gi[1, 0] * h0 + Gi[1, 1] * h1 + Gi[1, 2] * h2
                        w2 = Gi[2, 0] * h0 + Gi[2, 1] * h1 + Gi[2, 2] * h2
                        W[0, 0] = 0.0
                        W[0, 1] = -w2
                        W[0, 2] = w1
                        W[1, 0] = w2
                        W[1, 1] = 0.0
                        W[1, 2] = -w0
                        W[2, 0] = -w1
                        W[2, 1] = w0
                        W[2, 2] = 0.0
                        for a in range(3):  # dS = sym(H - W S)
                            for b in range(3):
                                dS[a, b] = H[a, b] - (W[a, 0] * S[0, b] + W[a, 1] * S[1, b] + W[a, 2] * S[2, b])
                        eps[0] = dS[0, 0]
                        eps[1] = dS[1, 1]
                        eps[2] = dS[2, 2]
                        eps[3] = dS[1, 2] + dS[2, 1]  # 2 sym(dS)_23
                        eps[4] = dS[0, 2] + dS[2, 0]
                        eps[5] = dS[0, 1] + dS[1, 0]
                        _voigt_stress(C, e, eps, s, dPi)
                        for a in range(3):  # dPi = W sig + C:dS
                            for b in range(3):
                                dPi[a, b] += W[a, 0] * sig[0, b] + W[a, 1] * sig[1, b] + W[a, 2] * sig[2, b]
                        for i in range(3):  # A = w_q R dPi
                            for k in range(3):
                                A[i, k, j, l] = wq * (R[i, 0] * dPi[0, k] + R[i, 1] * dPi[1, k] + R[i, 2] * dPi[2, k])
                for a in range(nen):
                    g0 = grads[e, q, a, 0]
                    g1 = grads[e, q, a, 1]
                    g2 = grads[e, q, a, 2]
                    for i in range(3):
                        for j in range(3):
                            for l in range(3):
                                T[a, i, j, l] = g0 * A[i, 0, j, l] + g1 * A[i, 1, j, l] + g2 * A[i, 2, j, l]
                for b in range(nen):
                    g0 = grads[e, q, b, 0]
                    g1 = grads[e, q, b, 1]
                    g2 = grads[e, q, b, 2]
                    for a in range(nen):
                        for i in range(3):
                            for j in range(3):
                                Ke[3 * a + i, 3 * b + j] += T[a, i, j, 0] * g0 + T[a, i, j, 1] * g1 + T[a, i, j, 2] * g2
            if tangent:
                for r in range(nd):
                    for c in range(nd):
                        data_out[block_map[e, nd * r + c]] += Ke[r, c]
