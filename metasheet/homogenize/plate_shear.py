"""Transverse-shear stiffness of a periodic plate cell: the next-order cell problem of a sheet
whose bending moment varies in its plane (cylindrical bending, as Whitney's shear correction of
laminates; the bending-gradient plate of Lebee & Sab 2011 in the same two cases).

The Kirchhoff plate cell (:mod:`.plate`) gives the fields ``w_I`` of the six unit generalised
strains and their stresses ``sigma_I = C (e_I(z) + eps(w_I))``: periodic in x and y,
self-equilibrated, free on the faces. Let the generalised strain grow along x_alpha,
``E(x) = x_alpha g`` (g (6,) per mm). The displacement ``u_Kirchhoff(E(x)) + w_I E_I(x) + v``
is an equilibrium of the endless periodic sheet when the periodic ``v`` solves

    int eps(dv) : C (eps(v) + sym(w_g (x) e_alpha)) dV = int dv . sigma_g e_alpha dV   (all periodic dv)

with ``w_g = w_I g_I``, ``sigma_g = sigma_I g_I``: the moment's gradient is the body force
``sigma_g e_alpha``, whose resultant vanishes when g keeps N constant (its membrane part is
``-A^-1 B`` of its curvature part). The second-order stress ``sigma2 = C (eps(v) + sym(w_g (x)
e_alpha))`` is the transverse shear: for a homogeneous sheet the parabola ``3 Q / 2t (1 - 4 z^2 /
t^2)``. Its energy per area, once the uniform Kirchhoff strain that carries its resultants is
taken out (``dE = ABD^-1 <e_I : sigma2>``: N and M are the plate strain's, sigma2 carries
none of them), is ``Q^T H^-1 Q`` with Q the shear force the gradient carries
(``Q_x = dM_xx/dx + dM_xy/dy``, ``Q_y = dM_xy/dx + dM_yy/dy``). Two compatible cases, kappa_xx
growing along x and kappa_yy along y, give the (2, 2) H [N/mm] on (gamma_xz, gamma_yz). A
homogeneous sheet gives ``H = 5/6 G t`` (Reissner), a laminate Whitney's factor: both to O(h^2)
in the voxel height (tests/test_homogenize_plate_shear.py). H does not depend on where the
periodic cell is cut. When a cell is wider than the sheet is thick, most of the second-order
energy can be such a uniform strain (:attr:`PlateShear.kirchhoff_share`); taking out instead
the strain that leaves the least energy is a second reading of the split, and their difference
is stated (:attr:`PlateShear.normalisation_spread`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..fem.hex8 import hex8_box_gauss
from ..mechanics.voigt import IN_PLANE

#: Names of the two transverse shear strains, in the order of :attr:`PlateShear.H`.
SHEAR_STRAINS = ("gamma_xz", "gamma_yz")
#: (2, 6, 3) Voigt strain of ``sym(w (x) e_alpha)`` for alpha = x, y (engineering shear);
#: its transpose picks the traction ``sigma e_alpha`` from a Voigt stress.
_P = np.zeros((2, 6, 3))
_P[0, 0, 0] = _P[0, 5, 1] = _P[0, 4, 2] = 1.0
_P[1, 1, 1] = _P[1, 5, 0] = _P[1, 3, 2] = 1.0


@dataclass(frozen=True)
class PlateShear:
    """The transverse-shear stiffness of a plate cell.

    Attributes
    ----------
    H : (2, 2) float [N/mm] on :data:`SHEAR_STRAINS`: ``Q = H gamma``.
    kirchhoff_share : (2,) share of each case's second-order energy that the uniform Kirchhoff
        strain carrying its resultants holds, left out of H (0 for a homogeneous sheet or a laminate).
    normalisation_spread : largest relative change of H's diagonal when that strain is instead
        the one that leaves the least energy (a second reading of the split; 0 for a laminate).
    balance_error : the body force's resultant over its size (the first-order solve's error).
    """

    H: np.ndarray
    kirchhoff_share: np.ndarray
    normalisation_spread: float
    balance_error: float

    def to_dict(self) -> dict:
        """JSON-ready."""
        return {"H_N_per_mm": self.H.tolist(), "strains": list(SHEAR_STRAINS),
                "kirchhoff_share": self.kirchhoff_share.tolist(), "normalisation_spread": self.normalisation_spread,
                "balance_error": self.balance_error}


def bulk_shear(C, thickness: float) -> np.ndarray:
    """(2, 2) [N/mm] transverse-shear stiffness ``5/6 t G`` of a homogeneous sheet of a bulk
    material C (6, 6) [MPa] (G: the 13 / 23 block on gamma_xz, gamma_yz), thickness t [mm]."""
    C = np.asarray(C, float)
    t = float(thickness)
    if C.shape != (6, 6) or not t > 0:
        raise ConfigError(f"C, thickness: shape {C.shape}, {thickness!r}: expected (6, 6) [MPa] and t > 0 [mm]")
    return 5.0 / 6.0 * t * C[np.ix_([4, 3], [4, 3])]


def shear_gradients(ABD: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The two compatible generalised-strain gradients (kappa_xx along x, kappa_yy along y) with
    N constant: (g (2, 6) per mm, Q (2, 2) [N/mm] whose column c is case c's shear force)."""
    g = np.zeros((2, 6))
    g[0, 3] = g[1, 4] = 1.0
    g[:, :3] = -np.linalg.solve(ABD[:3, :3], ABD[:3, 3:] @ g[:, 3:].T).T
    M = g @ ABD[:, 3:]  # (2, 3): case c's moment gradient (ABD symmetric)
    Q = np.array([[M[0, 0], M[1, 2]], [M[0, 2], M[1, 1]]])
    return g, Q


def transverse_shear(cell, U: np.ndarray, ABD: np.ndarray, *, solver: str, rtol: float) -> PlateShear:
    """H of a plate ``cell`` (:class:`~.plate.PlateCell`) from its first-order fields ``U``
    (3n, 6) and ``ABD`` (6, 6)."""
    g, Q = shear_gradients(ABD)
    w_q, xi, N, Bq = hex8_box_gauss(cell.h)
    edofs = (3 * cell.nodes[:, :, None] + np.arange(3)).reshape(len(cell.nodes), 24)
    Nmat = np.zeros((8, 3, 24))
    for i in range(3):
        Nmat[:, i, i::3] = N
    zeta = (xi[:, 2] - 0.5) * cell.h[2]  # (8,) Gauss heights from the element's centre
    layer_z = cell.z_c[cell.kind % len(cell.z_c)]  # (m,)
    Wg = U @ g.T  # (3n, 2): each case's first-order field
    rhs = np.zeros((U.shape[0], 2))
    for c in range(2):
        vec = np.zeros((len(edofs), 24))
        for p, C in enumerate(cell.Cs):
            idx = np.flatnonzero(cell.phase_kind == p)
            M = np.einsum("q,qia,ji,jk,qkb->ab", w_q, Nmat, _P[c], C, Bq)  # int N^T P^T C B
            T0 = np.einsum("q,qia,ji,jk->ak", w_q, Nmat, _P[c], C[:, IN_PLANE])
            T1 = np.einsum("q,qia,ji,jk,q->ak", w_q, Nmat, _P[c], C[:, IN_PLANE], zeta)
            ez = g[c, :3] @ T0.T + np.outer(layer_z[idx], g[c, 3:] @ T0.T) + g[c, 3:] @ T1.T
            # the body force int dv . sigma_g e_alpha (its w part M w, its e(z) part ez) less the
            # gradient's own strain int eps(dv) : C sym(w (x) e_alpha) = M^T w
            vec[idx] = Wg[edofs[idx], c] @ (M - M.T).T + ez
        rhs[:, c] = cell.pattern.assemble_vector(vec)
    resultant = np.abs(rhs.reshape(-1, 3, 2).sum(axis=0)).max()
    balance = float(resultant / max(np.abs(rhs).sum(axis=0).max(), 1e-300))
    V, _ = cell.solve(rhs, solver, rtol)
    W, b, R = _second_order_energy(cell, U, Wg, V, edofs, w_q, Nmat, Bq, zeta, layer_z)
    dE = np.linalg.solve(ABD, R)  # the uniform plate strain that carries sigma2's resultants
    W_shear = W - dE.T @ b - b.T @ dE + dE.T @ ABD @ dE
    H = _stiffness(W_shear, Q)
    H_min = _stiffness(W - b.T @ np.linalg.solve(ABD, b), Q)
    spread = float(np.abs(np.diag(H_min) / np.diag(H) - 1.0).max())
    return PlateShear(H=H, kirchhoff_share=1.0 - np.diag(W_shear) / np.diag(W), normalisation_spread=spread,
                      balance_error=balance)


def _stiffness(W_shear: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """(2, 2) H from the cases' shear energies W (2, 2) and shear forces Q (2, 2) (columns)."""
    Qinv = np.linalg.inv(Q)
    F = Qinv.T @ W_shear @ Qinv
    H = np.linalg.inv(0.5 * (F + F.T))
    return 0.5 * (H + H.T)


def _second_order_energy(cell, U, Wg, V, edofs, w_q, Nmat, Bq, zeta, layer_z):
    """(W (2, 2): ``<eps2_c : C eps2_d>`` per area, b (6, 2): ``<sigma_I : eps2_c>`` per area)."""
    W = np.zeros((2, 2))
    b = np.zeros((6, 2))
    R = np.zeros((6, 2))
    for p, C in enumerate(cell.Cs):
        idx = np.flatnonzero(cell.phase_kind == p)
        e = edofs[idx]
        Ue = U[e]  # (m, 24, 6)
        for q in range(8):
            s = np.stack([Wg[e, c] @ (_P[c] @ Nmat[q]).T + V[e, c] @ Bq[q].T for c in range(2)])  # (2, m, 6)
            sC = s @ C
            W += w_q[q] * np.einsum("cmi,dmi->cd", sC, s)
            ez = np.zeros((len(idx), 6, 6))  # e_I(z) at the Gauss point
            ez[:, :3, IN_PLANE] = np.eye(3)
            ez[:, 3:, IN_PLANE] = (layer_z[idx] + zeta[q])[:, None, None] * np.eye(3)
            R += w_q[q] * np.einsum("mIk,cmk->Ic", ez, sC)
            eps1 = ez + np.einsum("mdI,kd->mIk", Ue, Bq[q])  # (m, 6 I, 6 Voigt)
            b += w_q[q] * np.einsum("mIk,cmk->Ic", eps1, sC)
    return W / cell.area, b / cell.area, R / cell.area
