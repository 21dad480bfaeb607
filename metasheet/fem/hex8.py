"""Trilinear 8-node hexahedron on an axis-aligned box: the voxel element.

Every voxel of a grid is the same box, so its matrices are computed once per
material with 2 x 2 x 2 Gauss quadrature (exact for the trilinear box) and then
scattered; this is the whole trick that makes voxel homogenisation fast.

Local node ``a = ax + 2 ay + 4 az`` sits at ``(ax hx, ay hy, az hz)`` with
``ax, ay, az`` in {0, 1}; local dof ``3 a + i``.
"""

from __future__ import annotations

import numpy as np

#: (8, 3) local node offsets in {0, 1}^3, node a = ax + 2 ay + 4 az.
HEX8_CORNERS = np.array([[a & 1, (a >> 1) & 1, (a >> 2) & 1] for a in range(8)], dtype=np.int64)


def strain_operator(grads: np.ndarray) -> np.ndarray:
    """Voigt strain-displacement matrices from shape-function gradients.

    Parameters
    ----------
    grads : (..., m, 3) float [1/mm], ``grads[..., a, :] = grad N_a``.

    Returns
    -------
    B : (..., 6, 3 m) float [1/mm], ``eps = B u`` with eps in Voigt order
        11, 22, 33, 23, 13, 12 (engineering shear) and u ordered ``3 a + i``.
    """
    g = np.asarray(grads, float)
    m = g.shape[-2]
    B = np.zeros(g.shape[:-2] + (6, 3 * m))
    gx, gy, gz = g[..., 0], g[..., 1], g[..., 2]
    B[..., 0, 0::3] = gx
    B[..., 1, 1::3] = gy
    B[..., 2, 2::3] = gz
    B[..., 3, 1::3] = gz  # gamma_23 = du2/dx3 + du3/dx2
    B[..., 3, 2::3] = gy
    B[..., 4, 0::3] = gz  # gamma_13
    B[..., 4, 2::3] = gx
    B[..., 5, 0::3] = gy  # gamma_12
    B[..., 5, 1::3] = gx
    return B


def _hex8_gradients(xi: np.ndarray, h: np.ndarray) -> np.ndarray:
    """(8, 3) physical gradients of the 8 shape functions at reference point ``xi`` in [0, 1]^3."""
    c = HEX8_CORNERS
    # N_a = prod_k (c_ak xi_k + (1 - c_ak)(1 - xi_k)); d/dxi_k flips factor k to +-1.
    f = np.where(c == 1, xi[None, :], 1.0 - xi[None, :])  # (8, 3)
    s = np.where(c == 1, 1.0, -1.0)
    g = np.empty((8, 3))
    g[:, 0] = s[:, 0] * f[:, 1] * f[:, 2] / h[0]
    g[:, 1] = f[:, 0] * s[:, 1] * f[:, 2] / h[1]
    g[:, 2] = f[:, 0] * f[:, 1] * s[:, 2] / h[2]
    return g


def hex8_box_matrices(C: np.ndarray, h) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Element matrices of one box element of edge lengths ``h``.

    Parameters
    ----------
    C : (6, 6) float [MPa], Voigt stiffness in global axes.
    h : (3,) float [mm], the box's edge lengths.

    Returns
    -------
    K : (24, 24) float [N/mm], stiffness ``int B^T C B dV``.
    F : (24, 6) float [N], nodal forces of unit macro strains ``int B^T C dV``.
    B_mean : (6, 24) float [1/mm], volume-averaged strain operator (= B at the centre).
    """
    C = np.asarray(C, float)
    h = np.asarray(h, float)
    vol = float(np.prod(h))
    gp = 0.5 + np.array([-0.5, 0.5]) / np.sqrt(3.0)
    K = np.zeros((24, 24))
    F = np.zeros((24, 6))
    w = vol / 8.0
    for x in gp:
        for y in gp:
            for z in gp:
                B = strain_operator(_hex8_gradients(np.array([x, y, z]), h))
                K += w * B.T @ C @ B
                F += w * B.T @ C
    B_mean = strain_operator(_hex8_gradients(np.full(3, 0.5), h))
    return 0.5 * (K + K.T), F, B_mean


def hex8_box_moment(C: np.ndarray, h) -> np.ndarray:
    """(24, 6) float [N mm]: ``int B^T C (z - z_c) dV`` over one box element of edge lengths
    ``h`` (3,) [mm] with centre height ``z_c``: the nodal forces of a unit macro strain that
    grows linearly through the element's height (a plate's curvature load, :mod:`metasheet.
    homogenize.plate`). Two Gauss points per direction integrate it exactly (degree 2 in z)."""
    C = np.asarray(C, float)
    h = np.asarray(h, float)
    w = float(np.prod(h)) / 8.0
    gp = 0.5 + np.array([-0.5, 0.5]) / np.sqrt(3.0)
    G = np.zeros((24, 6))
    for x in gp:
        for y in gp:
            for z in gp:
                B = strain_operator(_hex8_gradients(np.array([x, y, z]), h))
                G += w * (z - 0.5) * h[2] * B.T @ C
    return G


def hex8_box_gauss(h) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The 2 x 2 x 2 Gauss rule on one box element of edge lengths ``h`` (3,) [mm], as the
    element matrices above use it.

    Returns (w (8,) weights [mm^3], xi (8, 3) reference points in [0, 1]^3, N (8, 8) shape
    values ``N[q, a]``, B (8, 6, 24) strain operators [1/mm])."""
    h = np.asarray(h, float)
    gp = 0.5 + np.array([-0.5, 0.5]) / np.sqrt(3.0)
    xi = np.array([[x, y, z] for x in gp for y in gp for z in gp])
    f = np.where(HEX8_CORNERS[None, :, :] == 1, xi[:, None, :], 1.0 - xi[:, None, :])  # (8 q, 8 a, 3)
    N = f.prod(axis=2)
    B = np.array([strain_operator(_hex8_gradients(p, h)) for p in xi])
    return np.full(8, float(np.prod(h)) / 8.0), xi, N, B
