"""Quadratic 10-node tetrahedron (P2) on affine, straight-edged elements; P1 in the same form.

Node ordering (canonical throughout metasheet): the four vertices 0-3 as in the P1 tet, then
the midside nodes 4..9 of the edges (0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)
(:data:`TET10_EDGES`, lexicographic). VTK and Gmsh order the midside nodes differently:
permute on export.

With barycentric coordinates ``L_0..L_3`` (``sum L = 1``) the shape functions are

    N_a = L_a (2 L_a - 1)              vertex a = 0..3
    N_{4+k} = 4 L_i L_j                midside node of edge k = (i, j)

Elements are affine: the midside nodes sit at the edge midpoints, so the geometry is the P1
map of the vertices and ``grad L_c`` are the P1 gradients (:func:`metasheet.fem.tet4.tet4_gradients`).
The P2 stiffness integrand ``grad N_a . C grad N_b`` is then of degree 2, integrated exactly
by the classical symmetric 4-point rule of degree 2 (:data:`QUAD_P2_BARY`).

Quadrature data of both elements share one layout, so one kernel serves P1 and P2:
``grads`` (m, nq, nen, 3) [1/mm] and ``weights`` (m, nq) [mm^3].
"""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError, MeshError
from .tet4 import tet4_gradients

#: (6, 2) vertex pairs of the midside nodes 4..9.
TET10_EDGES = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]], dtype=np.int64)


def _mirror_perm() -> np.ndarray:
    """Columns of a P2 tet after the P1 vertex swap 1 <-> 2 (``tets[:, [0, 2, 1, 3]]``)."""
    vperm = np.array([0, 2, 1, 3])
    # new edge k = (vperm[i], vperm[j]) is an old edge, found by its sorted vertex pair
    old = {tuple(e): 4 + k for k, e in enumerate(TET10_EDGES.tolist())}
    mid = [old[tuple(sorted(vperm[e]))] for e in TET10_EDGES]
    return np.array([*vperm, *mid], dtype=np.int64)


#: (10,) int: ``tets10[:, P2_MIRROR_PERM]`` is the P2 counterpart of the P1 orientation flip
#: ``tets[:, [0, 2, 1, 3]]``; equals [0, 2, 1, 3, 5, 4, 6, 7, 9, 8].
P2_MIRROR_PERM = _mirror_perm()

_A = (5.0 + 3.0 * np.sqrt(5.0)) / 20.0  # 0.5854101966249685
_B = (5.0 - np.sqrt(5.0)) / 20.0  # 0.1381966011250105
#: (4, 4) barycentric coordinates of the degree-2 rule's points (rows).
QUAD_P2_BARY = np.full((4, 4), _B) + np.eye(4) * (_A - _B)
#: (4,) weights of the degree-2 rule, fractions of the element volume (sum 1).
QUAD_P2_WEIGHTS = np.full(4, 0.25)
#: (1, 4) and (1,): the centroid rule, exact for P1 (constant gradients).
QUAD_P1_BARY = np.full((1, 4), 0.25)
QUAD_P1_WEIGHTS = np.ones(1)


# --------------------------------------------------------------------------- shape functions


def tet10_shape_values(bary: np.ndarray) -> np.ndarray:
    """(..., 10) P2 shape functions at barycentric points ``bary`` (..., 4)."""
    L = np.asarray(bary, float)
    N = np.empty(L.shape[:-1] + (10,))
    N[..., :4] = L * (2.0 * L - 1.0)
    N[..., 4:] = 4.0 * L[..., TET10_EDGES[:, 0]] * L[..., TET10_EDGES[:, 1]]
    return N


def tet10_shape_derivatives(bary: np.ndarray) -> np.ndarray:
    """(..., 10, 4) derivatives ``dN_a / dL_c`` at barycentric points ``bary`` (..., 4).

    The ``L_c`` are treated as independent; ``grad N_a = sum_c dN_a/dL_c grad L_c`` is still
    exact because the P1 gradients ``grad L_c`` sum to zero.
    """
    L = np.asarray(bary, float)
    D = np.zeros(L.shape[:-1] + (10, 4))
    for a in range(4):
        D[..., a, a] = 4.0 * L[..., a] - 1.0
    for k, (i, j) in enumerate(TET10_EDGES):
        D[..., 4 + k, i] = 4.0 * L[..., j]
        D[..., 4 + k, j] = 4.0 * L[..., i]
    return D


# --------------------------------------------------------------------------- meshes


def elevate_to_p2(points: np.ndarray, tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """P2 mesh of a P1 mesh: one midside node per edge, at its exact midpoint.

    Parameters
    ----------
    points : (n, 3) float [mm]
    tets : (m, 4) int

    Returns
    -------
    points10 : (n + E, 3) float [mm]; the n input points first and unchanged, then one node
        per unique edge, ordered by the sorted edge key ``(min vertex, max vertex)``.
    tets10 : (m, 10) int64, canonical ordering (module docstring).
    """
    P = np.asarray(points, float)
    T = np.asarray(tets, np.int64)
    if P.ndim != 2 or P.shape[1] != 3:
        raise MeshError(f"points: shape is {P.shape} and should be (n, 3)")
    if T.ndim != 2 or T.shape[1] != 4:
        raise MeshError(f"tets: shape is {T.shape} and should be (m, 4)")
    n = len(P)
    ends = np.sort(T[:, TET10_EDGES], axis=2)  # (m, 6, 2)
    keys = ends[..., 0] * n + ends[..., 1]  # unique per undirected edge
    uniq, inverse = np.unique(keys.ravel(), return_inverse=True)  # sorted keys
    lo, hi = uniq // n, uniq % n
    mid = 0.5 * (P[lo] + P[hi])
    tets10 = np.concatenate([T, n + inverse.reshape(len(T), 6)], axis=1)
    return np.concatenate([P, mid]), tets10


# --------------------------------------------------------------------------- quadrature


def _check_affine(points: np.ndarray, tets10: np.ndarray) -> None:
    """Raise :class:`MeshError` if a midside node is off its edge midpoint (curved P2 is unsupported)."""
    X = points[tets10]
    mid = 0.5 * (X[:, TET10_EDGES[:, 0]] + X[:, TET10_EDGES[:, 1]])
    off = np.linalg.norm(X[:, 4:] - mid, axis=2).max(axis=1)
    size = np.linalg.norm(X[:, 1:4] - X[:, :1], axis=2).max(axis=1)
    bad = off > 1e-9 * size
    if np.any(bad):
        e = int(np.argmax(bad))
        raise MeshError(f"tets10: {int(bad.sum())} elements with a midside node off its edge midpoint "
                        f"(first {e}, off by {off[e]:.3g} mm): only straight-edged P2 is supported")


def tet10_quadrature(points: np.ndarray, tets10: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rest-state quadrature data of affine P2 tets (4-point degree-2 rule).

    Parameters
    ----------
    points : (n, 3) float [mm]
    tets10 : (m, 10) int, canonical ordering; midside nodes at edge midpoints (checked).

    Returns
    -------
    grads : (m, 4, 10, 3) float [1/mm], ``grads[e, q, a] = grad N_a`` at point q (rest frame).
    weights : (m, 4) float [mm^3], ``|V_e| * QUAD_P2_WEIGHTS``.
    """
    P = np.asarray(points, float)
    T = np.asarray(tets10, np.int64)
    if T.ndim != 2 or T.shape[1] != 10:
        raise MeshError(f"tets10: shape is {T.shape} and should be (m, 10)")
    _check_affine(P, T)
    gradL, vol = tet4_gradients(P, T[:, :4])  # (m, 4, 3), (m,)
    D = tet10_shape_derivatives(QUAD_P2_BARY)  # (4, 10, 4)
    # C-contiguous: the numba kernel is compiled for (and cached as) contiguous arrays
    grads = np.ascontiguousarray(np.einsum("qac,mci->mqai", D, gradL, optimize=True))
    return grads, vol[:, None] * QUAD_P2_WEIGHTS


def tet4_quadrature(points: np.ndarray, tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """P1 data in the layout of :func:`tet10_quadrature`: one point per element.

    Returns grads (m, 1, 4, 3) [1/mm] and weights (m, 1) [mm^3] (the volumes).
    """
    grads, vol = tet4_gradients(points, tets)
    return grads[:, None], vol[:, None].copy()


def quadrature_points(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """(m, nq, 3) rest positions [mm] of the quadrature points of P1 (m, 4) or P2 (m, 10) tets."""
    T = np.asarray(tets, np.int64)
    bary = QUAD_P2_BARY if T.shape[1] == 10 else QUAD_P1_BARY
    return np.einsum("qc,mci->mqi", bary, np.asarray(points, float)[T[:, :4]])


def nodal_volume_weights(volumes: np.ndarray, nen: int) -> np.ndarray:
    """(m, nen) integrals ``int N_a dV`` [mm^3] of each shape function, for consistent body loads.

    P1 (``nen`` = 4): ``V / 4`` at each vertex. P2 (``nen`` = 10): ``-V / 20`` at the vertices
    and ``V / 5`` at the midside nodes; the vertex weights are negative (a property of P2, not
    a bug), so a consistent gravity load pushes P2 vertices slightly upwards. Rows sum to V.
    """
    V = np.asarray(volumes, float)[:, None]
    if nen == 4:
        return np.repeat(V / 4.0, 4, axis=1)
    if nen == 10:
        return V * np.array([-0.05] * 4 + [0.2] * 6)
    raise ConfigError(f"nen: {nen}: allowed 4 (P1) or 10 (P2)")
