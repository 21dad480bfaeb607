"""Finite strain on the voxel grid: a compressible neo-Hookean solid on trilinear voxels.

The law (Ogden's compressible neo-Hookean, as in most FE codes' "neo-Hookean" for rubbers
and TPU at moderate strain)::

    W(F) = mu/2 (tr(F^T F) - 3) - mu ln J + lam/2 (ln J)^2,   J = det F
    P = dW/dF = mu F + (lam ln J - mu) F^-T                     (first Piola-Kirchhoff [MPa])
    dP[dF] = mu dF + lam tr(F^-1 dF) F^-T + (mu - lam ln J) F^-T dF^T F^-T

with the Lame constants of the small-strain modulus E and Poisson ratio nu, so that at F = I
the tangent is the linear voxel element's (:func:`metasheet.fem.hex8.hex8_box_matrices` of the
isotropic C): the linear DNS is this model's rest linearisation.

Every voxel is the same box, integrated with 2 x 2 x 2 Gauss points (the linear element's
rule); local node ``a = ax + 2 ay + 4 az`` (:mod:`metasheet.fem.hex8`). The kernels run over a
list of solid voxels, each given by its eight node numbers in any node numbering, in slabs
along x (:func:`colour_order`): the even slabs at once over the cores, then the odd ones (two
slabs of one colour share no node), each slab's voxels in their order. Every node's sum then
takes its voxels in the same order whatever the thread count, and the energy is summed over the
voxels in their order afterwards. The same bits on any thread count and machine.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from ...errors import ConfigError, check_range
from ...mechanics.material import Isotropic
from ..hex8 import HEX8_CORNERS, _hex8_gradients


@dataclass(frozen=True)
class NeoHookean:
    """The compressible neo-Hookean law with small-strain modulus ``E`` [MPa] and Poisson ratio
    ``nu`` [-] (module docstring)."""

    E: float
    nu: float

    def __post_init__(self):
        check_range("E", self.E, 0.0, 2e6, lo_open=True)
        check_range("nu", self.nu, -1.0, 0.5, lo_open=True, hi_open=True)

    @property
    def mu(self) -> float:
        """Shear modulus [MPa], the small-strain material's."""
        return Isotropic(self.E, self.nu).mu

    @property
    def lam(self) -> float:
        """First Lame parameter [MPa], the small-strain material's."""
        return Isotropic(self.E, self.nu).lam

    def stress(self, F) -> np.ndarray:
        """P (..., 3, 3) [MPa] at deformation gradients F (..., 3, 3) with det F > 0."""
        F = np.asarray(F, float)
        J = np.linalg.det(F)
        if np.any(J <= 0):
            raise ConfigError("F: det F <= 0 (an inverted element): the law is defined for J > 0 only")
        FinvT = np.swapaxes(np.linalg.inv(F), -1, -2)
        return self.mu * F + (self.lam * np.log(J) - self.mu)[..., None, None] * FinvT

    def energy(self, F) -> np.ndarray:
        """W (...) [MPa = mJ/mm^3] at F (..., 3, 3)."""
        F = np.asarray(F, float)
        lnJ = np.log(np.linalg.det(F))
        return 0.5 * self.mu * (np.einsum("...ij,...ij", F, F) - 3.0) - self.mu * lnJ + 0.5 * self.lam * lnJ**2


def gauss_gradients(h) -> tuple[np.ndarray, np.ndarray]:
    """(dN (8, 8, 3) [1/mm], w (8,) [mm^3]): the shape-function gradients of the box with edges
    ``h`` (3,) [mm] at its 2 x 2 x 2 Gauss points (``dN[g, a]``), and the points' weights."""
    h = np.asarray(h, float)
    g = 0.5 / np.sqrt(3.0)
    pts = 0.5 + g * (2 * HEX8_CORNERS - 1)  # the Gauss points in [0, 1]^3, in corner order
    dN = np.stack([_hex8_gradients(p, h) for p in pts])
    return dN, np.full(8, float(np.prod(h)) / 8.0)


@njit(cache=True)
def _gradient(v, voxels, e, dN, g, out):
    """``out`` (3, 3): the gradient of the nodal field ``v`` (n, 3) at Gauss point ``g`` of voxel ``e``."""
    for i in range(3):
        for j in range(3):
            s = 0.0
            for a in range(8):
                s += v[voxels[e, a], i] * dN[g, a, j]
            out[i, j] = s


@njit(cache=True)
def _inv_det(F, out):
    a, b, c = F[0, 0], F[0, 1], F[0, 2]
    d, e, f = F[1, 0], F[1, 1], F[1, 2]
    g, h, i = F[2, 0], F[2, 1], F[2, 2]
    A, B, C = e * i - f * h, f * g - d * i, d * h - e * g
    det = a * A + b * B + c * C
    if det <= 0.0:
        return det
    out[0, 0], out[1, 0], out[2, 0] = A / det, B / det, C / det
    out[0, 1], out[1, 1], out[2, 1] = (c * h - b * i) / det, (a * i - c * g) / det, (b * g - a * h) / det
    out[0, 2], out[1, 2], out[2, 2] = (b * f - c * e) / det, (c * d - a * f) / det, (a * e - b * d) / det
    return det


#: slabs per colour a grid is cut into along x (at least one voxel thick each)
SLABS = 64


def colour_order(ijk: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(order (m,), starts (b + 1,), colours (3,)) int64: the voxels ``ijk`` (m, 3) in slabs along
    x, alternately coloured 0 and 1; block k is ``order[starts[k]:starts[k + 1]]`` (its voxels in
    their own order: the memory stays local), colour c's blocks ``colours[c]:colours[c + 1]``.
    Two slabs of one colour are a slab apart: they share no node, and run at once. The cut
    depends on the grid only, not on the thread count."""
    ijk = np.asarray(ijk, np.int64)
    nx = int(ijk[:, 0].max()) + 1 if len(ijk) else 1
    width = max(1, -(-nx // (2 * SLABS)))
    slab = ijk[:, 0] // width
    key = (slab % 2) * (nx + 1) + slab  # colour-major, then slab
    order = np.argsort(key, kind="stable").astype(np.int64)
    blocks, starts = np.unique(key[order], return_index=True)
    colours = np.searchsorted(blocks, [0, nx + 1, 2 * (nx + 1)])
    return order, np.append(starts, len(order)).astype(np.int64), colours.astype(np.int64)


@njit(cache=True, parallel=True)
def internal_forces(u, voxels, order, starts, colours, dN, w, mu, lam, F_out, Finv_out, c_out, f):
    """Internal nodal forces of displacements ``u`` (n, 3) [mm] on the solid ``voxels`` (m, 8)
    (node numbers, in coloured blocks ``order``, ``starts``, ``colours``: :func:`colour_order`), added into ``f``
    (n, 3) [N]; each Gauss point's F, F^-1 and ``mu - lam ln J`` written to ``F_out``,
    ``Finv_out`` (m, 8, 3, 3) and ``c_out`` (m, 8) (what :func:`tangent_apply` needs). Returns
    (strain energy [mJ], the number of Gauss points with det F <= 0: then the energy and forces
    are meaningless and the caller must step back).

    The stress is evaluated from the displacement gradient ``H = F - I`` without differences of
    O(1) terms, ``P = mu (H + F^-T H^T) + lam ln J F^-T`` with ``ln J = log1p(tr H + I2(H) +
    det H)``, so its relative error stays at round-off however small the strain (the forms
    with F lose the digits of |H| / 1 at small motions)."""
    m = voxels.shape[0]
    energies = np.zeros(m)
    bads = np.zeros(m, np.int64)
    for col in range(len(colours) - 1):
        for b in prange(colours[col], colours[col + 1]):
            Finv = np.empty((3, 3))
            F = np.empty((3, 3))
            Hg = np.empty((3, 3))
            P = np.empty((3, 3))
            for k in range(starts[b], starts[b + 1]):
                e = order[k]
                energies[e], bads[e] = _voxel_forces(u, voxels, e, dN, w, mu, lam, F_out, Finv_out, c_out, f,
                                                     Finv, F, Hg, P)
    energy = 0.0
    bad = 0
    for e in range(m):  # the voxels' order: the same sum on any thread count
        energy += energies[e]
        bad += bads[e]
    return energy, bad


@njit(cache=True)
def _voxel_forces(u, voxels, e, dN, w, mu, lam, F_out, Finv_out, c_out, f, Finv, F, Hg, P):
    """Voxel ``e``'s share of :func:`internal_forces`: (its energy [mJ], its inverted Gauss
    points); ``Finv``, ``F``, ``Hg``, ``P`` (3, 3) scratch."""
    energy = 0.0
    bad = 0
    for g in range(8):
        _gradient(u, voxels, e, dN, g, Hg)
        for i in range(3):
            for j in range(3):
                F[i, j] = Hg[i, j] + (1.0 if i == j else 0.0)
                F_out[e, g, i, j] = F[i, j]
        J = _inv_det(F, Finv)
        if J <= 0.0:
            bad += 1
            continue
        trH = Hg[0, 0] + Hg[1, 1] + Hg[2, 2]
        i2 = (Hg[0, 0] * Hg[1, 1] + Hg[1, 1] * Hg[2, 2] + Hg[0, 0] * Hg[2, 2]
              - Hg[0, 1] * Hg[1, 0] - Hg[1, 2] * Hg[2, 1] - Hg[0, 2] * Hg[2, 0])
        detH = (Hg[0, 0] * (Hg[1, 1] * Hg[2, 2] - Hg[1, 2] * Hg[2, 1])
                - Hg[0, 1] * (Hg[1, 0] * Hg[2, 2] - Hg[1, 2] * Hg[2, 0])
                + Hg[0, 2] * (Hg[1, 0] * Hg[2, 1] - Hg[1, 1] * Hg[2, 0]))
        lnJ = np.log1p(trH + i2 + detH)
        hh = 0.0
        for i in range(3):
            for j in range(3):
                hh += Hg[i, j] * Hg[i, j]
        # tr(F^T F) - 3 = 2 tr H + |H|^2
        energy += w[g] * (0.5 * mu * (2.0 * trH + hh) - mu * lnJ + 0.5 * lam * lnJ * lnJ)
        for i in range(3):
            for j in range(3):
                fh = 0.0  # (F^-T H^T)_ij = sum_k Finv[k, i] H[j, k]
                for k in range(3):
                    fh += Finv[k, i] * Hg[j, k]
                P[i, j] = w[g] * (mu * (Hg[i, j] + fh) + lam * lnJ * Finv[j, i])
                Finv_out[e, g, i, j] = Finv[i, j]
        c_out[e, g] = mu - lam * lnJ
        _scatter(P, voxels, e, dN, g, f)
    return energy, bad


@njit(cache=True)
def _scatter(P, voxels, e, dN, g, f):
    """``f[node a] += P . grad N_a`` at Gauss point ``g`` of voxel ``e`` (P already weighted)."""
    for a in range(8):
        n = voxels[e, a]
        for i in range(3):
            f[n, i] += P[i, 0] * dN[g, a, 0] + P[i, 1] * dN[g, a, 1] + P[i, 2] * dN[g, a, 2]


@njit(cache=True, parallel=True)
def tangent_apply(v, voxels, order, starts, colours, dN, w, mu, lam, Finv_s, c_s, y):
    """``y += K_t v``: the tangent stiffness at the Gauss points' ``F^-1`` (m, 8, 3, 3) and
    ``mu - lam ln J`` (m, 8) (from :func:`internal_forces`, all with det F > 0) applied to ``v``
    (n, 3) [mm], into ``y`` (n, 3) [N]; voxels coloured as :func:`internal_forces`'s."""
    for col in range(len(colours) - 1):
        for b in prange(colours[col], colours[col + 1]):
            dF = np.empty((3, 3))
            A = np.empty((3, 3))
            dP = np.empty((3, 3))
            for k in range(starts[b], starts[b + 1]):
                _voxel_tangent(v, voxels, order[k], dN, w, mu, lam, Finv_s, c_s, y, dF, A, dP)


@njit(cache=True)
def _voxel_tangent(v, voxels, e, dN, w, mu, lam, Finv_s, c_s, y, dF, A, dP):
    for g in range(8):
        Fi = Finv_s[e, g]
        _gradient(v, voxels, e, dN, g, dF)
        tr = 0.0
        for i in range(3):
            for j in range(3):
                tr += Fi[i, j] * dF[j, i]
        for i in range(3):  # A = F^-T dF^T: (i, l) = sum_k Finv[k, i] dF[l, k]
            for l in range(3):
                A[i, l] = Fi[0, i] * dF[l, 0] + Fi[1, i] * dF[l, 1] + Fi[2, i] * dF[l, 2]
        c = c_s[e, g]
        for i in range(3):
            for j in range(3):
                m = A[i, 0] * Fi[j, 0] + A[i, 1] * Fi[j, 1] + A[i, 2] * Fi[j, 2]  # (F^-T dF^T F^-T)_ij
                dP[i, j] = w[g] * (mu * dF[i, j] + lam * tr * Fi[j, i] + c * m)
        _scatter(dP, voxels, e, dN, g, y)


@njit(cache=True)
def max_principal_strain(Fs, out):
    """``out`` (m,): each voxel's largest principal Green-Lagrange strain over its Gauss points'
    F (m, 8, 3, 3): the largest eigenvalue of ``(F^T F - I) / 2`` [-]."""
    C = np.empty((3, 3))
    for e in range(Fs.shape[0]):
        best = -np.inf
        for g in range(8):
            for i in range(3):
                for j in range(3):
                    s = 0.0
                    for k in range(3):
                        s += Fs[e, g, k, i] * Fs[e, g, k, j]
                    C[i, j] = 0.5 * (s - (1.0 if i == j else 0.0))
            lam = np.linalg.eigvalsh(C)
            if lam[2] > best:
                best = lam[2]
        out[e] = best


@njit(cache=True, parallel=True)
def tangent_matrices(dN, w, mu, lam, Finv_s, c_s, out):
    """``out`` (m, 24, 24) [N/mm]: each voxel's tangent stiffness at its Gauss points' ``F^-1``
    (m, 8, 3, 3) and ``mu - lam ln J`` (m, 8) (from :func:`internal_forces`), dof ``3 a + i`` of
    local node ``a``: the matrix whose product :func:`tangent_apply` forms without it,

        K[3a + i, 3b + k] = sum_g w_g sum_jl dN[g, a, j] A_g[i, j, k, l] dN[g, b, l],
        A_ijkl = mu d_ik d_jl + lam F^-1_lk F^-1_ji + (mu - lam ln J) F^-1_li F^-1_jk.

    Each voxel's matrix is its own sum in float64 (no reduction across voxels), stored in
    ``out``'s dtype (float32 for a preconditioner's table): the same bits on any thread count."""
    for e in prange(out.shape[0]):
        K = np.zeros((24, 24))
        B = np.empty((3, 3, 3, 8))  # B[i, j, k, b] = sum_l A_ijkl dN[g, b, l]
        for g in range(8):
            Fi = Finv_s[e, g]
            c = c_s[e, g]
            for i in range(3):
                for j in range(3):
                    for k in range(3):
                        for b in range(8):
                            s = 0.0
                            for l in range(3):
                                a_ijkl = lam * Fi[l, k] * Fi[j, i] + c * Fi[l, i] * Fi[j, k]
                                if i == k and j == l:
                                    a_ijkl += mu
                                s += a_ijkl * dN[g, b, l]
                            B[i, j, k, b] = s
            for a in range(8):
                for i in range(3):
                    for b in range(8):
                        for k in range(3):
                            s = 0.0
                            for j in range(3):
                                s += dN[g, a, j] * B[i, j, k, b]
                            K[3 * a + i, 3 * b + k] += w[g] * s
        for r in range(24):
            for q in range(24):
                out[e, r, q] = K[r, q]
