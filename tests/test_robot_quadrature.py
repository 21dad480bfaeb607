"""Quadratic tets and the per-quadrature-point corotational kernel: mesh elevation, quadrature,
equivalence with the P1 kernel, consistent tangent, patch test, objectivity, scikit-fem, beams."""

import numpy as np
import pytest
import scipy.sparse.linalg as spla
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from metasheet.fem.assembly import SparsityPattern
from metasheet.fem.meshes import box_mesh
from metasheet.fem.tet10 import (
    P2_MIRROR_PERM,
    QUAD_P2_BARY,
    TET10_EDGES,
    elevate_to_p2,
    nodal_volume_weights,
    quadrature_points,
    tet4_quadrature,
    tet10_quadrature,
    tet10_shape_values,
)
from metasheet.mechanics.material import Isotropic, TransverseIsotropic
from metasheet.fem.corotational import p1 as kernels
from metasheet.fem.corotational.p2 import (
    corotational_quadrature_numba,
    corotational_quadrature_numpy,
    element_strains,
    max_principal_green_strain,
    voigt_to_tensor,
)
from metasheet.mechanics.voigt import stiffness_along

MAT = TransverseIsotropic(E_t=10.0, E_l=40.0, nu_t=0.4, nu_tl=0.2, mu_l=3.0)  # [MPa]


def _rot(v):
    return Rotation.from_rotvec(v).as_matrix()


def _p2(size=(3.0, 2.0, 1.5), div=(2, 2, 2), jitter=0.2, seed=0):
    P, T = box_mesh(size, div, jitter=jitter, seed=seed)
    return elevate_to_p2(P, T)


def _aniso(m, seed=0, uniform=False):
    rng = np.random.default_rng(seed)
    fib = np.tile([0.3, -0.5, 0.8], (m, 1)) if uniform else rng.normal(size=(m, 3))
    return np.ascontiguousarray(stiffness_along(MAT.stiffness(), fib))


class Model:
    """Forces and tangent of one mesh (P1 or P2) with either backend."""

    def __init__(self, P, T, C):
        self.P, self.T, self.C = P, np.asarray(T, np.int64), np.ascontiguousarray(C)
        quad = tet10_quadrature if self.T.shape[1] == 10 else tet4_quadrature
        self.g, self.w = quad(P, self.T)
        self.pat = SparsityPattern.from_elements(self.T, len(P))

    def numpy(self, x, tangent=True):
        fe, Kt = corotational_quadrature_numpy(x[self.T], self.g, self.w, self.C, tangent=tangent)
        return self.pat.assemble_vector(fe), (self.pat.assemble_data(Kt) if tangent else None)

    def numba(self, x, tangent=True):
        f = np.empty(3 * len(x))
        d = np.empty(self.pat.nnz if tangent else 0)
        corotational_quadrature_numba(np.ascontiguousarray(x), self.T, self.g, self.w, self.C,
                                      self.pat.block_map, f, d, tangent)
        return f, (d if tangent else None)

    def K(self, data):
        return self.pat.matrix(data).toarray()


def _deformed(P, seed=0, strain=0.15, noise=0.03):
    """A strongly deformed state: large rotation, ~``strain`` stretch, random node noise [mm]."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(3, 3))
    U = np.eye(3) + strain * np.diag([1.0, -0.6, 0.4]) + 0.05 * (A + A.T)
    Q = _rot([0.9, -1.3, 0.5])
    x = P @ (Q @ U).T + noise * rng.normal(size=P.shape) + np.array([1.0, 2.0, -0.5])
    return x


# --------------------------------------------------------------------------- mesh elevation


def test_elevate_shares_edges_and_places_exact_midpoints():
    P, T = box_mesh((3.0, 2.0, 1.5), (2, 2, 2), jitter=0.2, seed=3)
    P10, T10 = elevate_to_p2(P, T)
    edges = {tuple(sorted(e)) for t in T for e in t[TET10_EDGES].tolist()}
    assert len(P10) == len(P) + len(edges) and T10.shape == (len(T), 10)
    np.testing.assert_array_equal(P10[: len(P)], P)
    np.testing.assert_array_equal(T10[:, :4], T)
    node_of = {}
    for t, t10 in zip(T, T10):
        for k, (i, j) in enumerate(TET10_EDGES):
            key = tuple(sorted((t[i], t[j])))
            assert node_of.setdefault(key, t10[4 + k]) == t10[4 + k]  # one node per shared edge
            np.testing.assert_array_equal(P10[t10[4 + k]], 0.5 * (P[t[i]] + P[t[j]]))  # exact
    assert sorted(node_of.values()) == list(range(len(P), len(P10)))  # a bijection onto new nodes
    keys = sorted(node_of)  # new nodes follow the sorted edge keys
    assert [node_of[k] for k in keys] == list(range(len(P), len(P10)))


def test_mirror_permutation_matches_reflected_mesh():
    vperm = [0, 2, 1, 3]
    np.testing.assert_array_equal(P2_MIRROR_PERM, [0, 2, 1, 3, 5, 4, 6, 7, 9, 8])
    P, T = box_mesh((3.0, 2.0, 1.5), (2, 2, 2), jitter=0.2, seed=4)
    P10, T10 = elevate_to_p2(P, T)
    Pm, P10m = P * [-1.0, 1.0, 1.0], P10 * [-1.0, 1.0, 1.0]  # reflection: every tet inverts
    Tm, T10m = T[:, vperm], T10[:, P2_MIRROR_PERM]
    X = Pm[Tm]
    assert np.all(np.linalg.det(X[:, 1:] - X[:, :1]) > 0)
    X10 = P10m[T10m]  # midside nodes still at the midpoints of the canonical edges
    np.testing.assert_array_equal(X10[:, 4:], 0.5 * (X10[:, TET10_EDGES[:, 0]] + X10[:, TET10_EDGES[:, 1]]))
    np.testing.assert_array_equal(elevate_to_p2(Pm, Tm)[1], T10m)  # same as elevating the flipped P1 mesh
    _, w = tet10_quadrature(P10m, T10m)
    assert np.isclose(w.sum(), 9.0, rtol=1e-12)


# --------------------------------------------------------------------------- quadrature


def test_weights_partition_of_unity_and_nodal_volumes():
    P, T = box_mesh((3.0, 2.0, 1.5), (2, 2, 2), jitter=0.25, seed=5)
    P10, T10 = elevate_to_p2(P, T)
    for pts, el, quad, nen in ((P, T, tet4_quadrature, 4), (P10, T10, tet10_quadrature, 10)):
        g, w = quad(pts, el)
        assert g.shape[2:] == (nen, 3) and w.shape == g.shape[:2]
        assert np.isclose(w.sum(), 9.0, rtol=1e-13)
        assert np.abs(g.sum(axis=2)).max() < 1e-12 * np.abs(g).max()
        vol = w.sum(axis=1)
        nw = nodal_volume_weights(vol, nen)
        np.testing.assert_allclose(nw.sum(axis=1), vol, rtol=1e-13)
    # P2: int N_a dV by the rule (exact for degree 2) = -V/20 at vertices, V/5 at midside nodes
    exact = w @ tet10_shape_values(QUAD_P2_BARY)
    np.testing.assert_allclose(exact, nw, rtol=1e-12, atol=1e-14 * vol.max())


def test_p2_basis_reproduces_quadratic_fields():
    rng = np.random.default_rng(6)
    P10, T10 = _p2(jitter=0.25, seed=6)
    c, b, A = rng.normal(), rng.normal(size=3), rng.normal(size=(3, 3))
    u = c + P10 @ b + np.einsum("ni,ij,nj->n", P10, A, P10)
    g, _ = tet10_quadrature(P10, T10)
    Xq = quadrature_points(P10, T10)
    grad = np.einsum("ma,mqai->mqi", u[T10], g)
    exact = b + Xq @ (A + A.T).T
    assert np.abs(grad - exact).max() < 1e-11 * np.abs(exact).max()


# --------------------------------------------------------------------------- kernel correctness


def test_p1_layout_equals_element_corotational_kernels():
    P, T = box_mesh((3.0, 2.0, 1.5), (2, 2, 2), jitter=0.2, seed=7)
    C = _aniso(len(T), seed=7)
    x = _deformed(P, seed=7)
    model = Model(P, T, C)
    grads, vol, _ = kernels.shape_gradients(P, T)
    Ke = kernels.element_stiffness(grads, vol, C)
    X_e = np.ascontiguousarray(P[T])
    fe_ref, Kt_ref = kernels.corotational_numpy(x[T], X_e, grads, Ke)
    fe, Kt = corotational_quadrature_numpy(x[T], model.g, model.w, C)
    assert np.abs(fe - fe_ref).max() <= 1e-12 * np.abs(fe_ref).max()
    assert np.abs(Kt - Kt_ref).max() <= 1e-12 * np.abs(Kt_ref).max()
    f_ref, d_ref = np.empty(3 * len(P)), np.empty(model.pat.nnz)
    kernels.corotational_numba(x, T, X_e, grads, Ke, model.pat.block_map, f_ref, d_ref, True)
    f, d = model.numba(x)
    assert np.abs(f - f_ref).max() <= 1e-12 * np.abs(f_ref).max()
    assert np.abs(d - d_ref).max() <= 1e-12 * np.abs(d_ref).max()


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_tangent_matches_central_differences(backend):
    P10, T10 = _p2(size=(2.0, 1.5, 1.0), div=(1, 1, 1), jitter=0.0)
    model = Model(P10, T10, _aniso(len(T10), seed=8))
    x = _deformed(P10, seed=8, noise=0.01)
    strain = np.abs(element_strains(x, T10, model.g)).max()
    assert 0.1 < strain < 0.4  # strongly deformed, as intended
    evaluate = getattr(model, backend)
    _, data = evaluate(x)
    K = model.K(data)
    h = 1e-6
    Kfd = np.empty_like(K)
    for j in range(x.size):
        d = np.zeros(x.size)
        d[j] = h
        fp, _ = evaluate((x.ravel() + d).reshape(-1, 3), tangent=False)
        fm, _ = evaluate((x.ravel() - d).reshape(-1, 3), tangent=False)
        Kfd[:, j] = (fp - fm) / (2 * h)
    assert np.linalg.norm(K - Kfd) <= 1e-6 * np.linalg.norm(K)
    assert np.linalg.norm(K - K.T) > 1e-3 * np.linalg.norm(K)  # anisotropic, away from rest


def test_numba_equals_numpy_p2():
    P10, T10 = _p2(seed=9)
    model = Model(P10, T10, _aniso(len(T10), seed=9))
    x = _deformed(P10, seed=9)
    f0, d0 = model.numpy(x)
    f1, d1 = model.numba(x)
    assert np.abs(f1 - f0).max() <= 1e-12 * np.abs(f0).max()
    assert np.abs(d1 - d0).max() <= 1e-12 * np.abs(d0).max()
    f2, _ = model.numba(x, tangent=False)
    np.testing.assert_array_equal(f2, f1)


def _boundary_triangles(pts, el):
    """Boundary faces of a P1 (m, 4) or P2 (m, 10) mesh: ``loaded`` (k, 3) nodes whose consistent
    load is a third of a uniform traction's resultant (P1: the vertices; P2: the midside nodes,
    whose triangle weights are A/3 while the vertices' are 0), outward unit normals (k, 3), areas (k,)."""
    local = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])
    faces = np.sort(el[:, :4][:, local], axis=2).reshape(-1, 3)
    _, inv, cnt = np.unique(faces, axis=0, return_inverse=True, return_counts=True)
    once = cnt[inv.ravel()] == 1
    loc, e = np.tile(local, (len(el), 1))[once], np.repeat(np.arange(len(el)), 4)[once]
    X = pts[el[e[:, None], loc]]  # (k, 3, 3)
    n = np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0])
    opposite = pts[el[e, 6 - loc.sum(axis=1)]]
    n[np.einsum("ki,ki->k", n, opposite - X[:, 0]) > 0] *= -1.0  # outward
    area = 0.5 * np.linalg.norm(n, axis=1)
    if el.shape[1] == 4:
        loaded = el[e[:, None], loc]
    else:
        edge_node = {tuple(p): 4 + k for k, p in enumerate(TET10_EDGES.tolist())}
        cols = np.array([[edge_node[(a, b)] for a, b in ((r[0], r[1]), (r[0], r[2]), (r[1], r[2]))] for r in loc])
        loaded = el[e[:, None], cols]
    return loaded, n / (2.0 * area[:, None]), area


def test_patch_test_uniform_deformation():
    P10, T10 = _p2(size=(3.0, 2.0, 1.5), div=(3, 2, 2), jitter=0.25, seed=10)
    model = Model(P10, T10, _aniso(len(T10), uniform=True))  # homogeneous material
    U0 = np.array([[1.12, 0.03, -0.02], [0.03, 0.93, 0.04], [-0.02, 0.04, 1.05]])
    Q0 = _rot([0.4, 0.8, -0.3])
    x = P10 @ (Q0 @ U0).T + np.array([0.5, -1.0, 2.0])
    eps = element_strains(x, T10, model.g)
    eps0 = np.array([U0[0, 0] - 1, U0[1, 1] - 1, U0[2, 2] - 1, 2 * U0[1, 2], 2 * U0[0, 2], 2 * U0[0, 1]])
    assert np.abs(eps - eps0).max() < 1e-13  # the same stress at every quadrature point
    P0 = Q0 @ voigt_to_tensor(model.C[0] @ eps0)  # first Piola stress [MPa]
    f, _ = model.numba(x, tangent=False)
    f = f.reshape(-1, 3)
    # exact traction integrals: int_face N_a P0 n dA is A/3 at a P2 triangle's midside nodes, 0 at vertices
    loaded, normal, area = _boundary_triangles(P10, T10)
    t = (normal @ P0.T) * area[:, None]  # P0 n A per triangle [N]
    expected = np.zeros_like(f)
    for c in range(3):
        np.add.at(expected, loaded[:, c], t / 3.0)
    scale = np.abs(f).max()
    assert np.abs(f - expected).max() < 1e-10 * scale
    size = np.array([3.0, 2.0, 1.5])
    on_box = np.any((np.abs(P10) < 1e-9) | (np.abs(P10 - size) < 1e-9), axis=1)
    assert (~on_box).sum() > 10 and np.abs(f[~on_box]).max() < 1e-10 * scale  # interior nodes
    for k, face_area in enumerate((3.0, 4.5, 6.0)):  # sum over a box face = P0 * area * normal
        for s in (1.0, -1.0):
            on_face = np.abs(normal[:, k] - s) < 1e-9
            nrm = s * np.eye(3)[k]
            np.testing.assert_allclose(area[on_face].sum(), face_area, rtol=1e-12)
            np.testing.assert_allclose(t[on_face].sum(axis=0), P0 @ nrm * face_area, rtol=1e-12, atol=1e-12 * scale)


def test_objectivity_rigid_motions():
    P10, T10 = _p2(seed=11)
    model = Model(P10, T10, _aniso(len(T10), seed=11))
    x = _deformed(P10, seed=11, strain=0.1)
    Q, t = _rot([-0.7, 2.1, 1.2]), np.array([3.0, -1.0, 4.0])
    f, d = model.numba(x)
    fq, dq = model.numba(x @ Q.T + t)
    scale = np.abs(f).max()
    assert np.abs(fq.reshape(-1, 3) - f.reshape(-1, 3) @ Q.T).max() < 1e-10 * scale
    BQ = np.kron(np.eye(len(x)), Q)
    K, KQ = model.K(d), model.K(dq)
    assert np.abs(KQ - BQ @ K @ BQ.T).max() < 1e-10 * np.abs(K).max()
    f_rigid, _ = model.numba(P10 @ Q.T + t, tangent=False)
    assert np.abs(f_rigid).max() < 1e-11 * scale
    f_np, _ = model.numpy(P10 @ Q.T + t, tangent=False)
    assert np.abs(f_np).max() < 1e-11 * scale


def _newton(model, free, x0, f_ext, iters=25, tol=1e-10):
    """Equilibrium ``f(x) = f_ext`` on the ``free`` dofs; stops on a residual below ``tol`` of the
    load or on a step at round-off (1e-12 of the mesh size) [mm]."""
    x = x0.copy().ravel()
    size = np.abs(x0).max()
    for _ in range(iters):
        f, d = model.numba(x.reshape(-1, 3))
        r = (f_ext - f)[free]
        if np.linalg.norm(r) < tol * np.linalg.norm(f_ext):
            return x.reshape(-1, 3)
        K = model.pat.matrix(d)[free][:, free].tocsc()
        dx = spla.spsolve(K, r)  # non-symmetric tangent: LU
        x[free] += dx
        if np.abs(dx).max() < 1e-12 * size:
            return x.reshape(-1, 3)
    raise AssertionError(f"Newton: residual {np.linalg.norm(r):.3g} after {iters} iterations")


def test_loaded_cantilever_equilibrium_is_rotation_invariant():
    P, T = box_mesh((20.0, 4.0, 2.0), (5, 2, 1))
    P10, T10 = elevate_to_p2(P, T)
    model = Model(P10, T10, _aniso(len(T10), uniform=True))
    clamp = P10[:, 0] < 1e-9
    free = np.repeat(~clamp, 3)
    tip = np.abs(P10[:, 0] - 20.0) < 1e-9
    f_ext = np.zeros_like(P10)
    f_ext[tip, 2] = -0.1 / tip.sum()  # [N]: a large deflection
    x = _newton(model, free, P10, f_ext.ravel())
    assert np.abs(x[tip, 2] - P10[tip, 2]).mean() > 1.0  # geometrically nonlinear [mm]
    Q, t = _rot([0.3, -2.0, 1.1]), np.array([5.0, 1.0, -2.0])
    f, _ = model.numba(x, tangent=False)
    fq, _ = model.numba(x @ Q.T + t, tangent=False)
    r = (fq.reshape(-1, 3) - f_ext @ Q.T).ravel()[free]
    assert np.linalg.norm(r) < 1e-9 * np.linalg.norm(f_ext)
    assert np.linalg.norm(fq.reshape(-1, 3) - f.reshape(-1, 3) @ Q.T) < 1e-11 * np.linalg.norm(f)


def test_rest_tangent_equals_scikit_fem_p2_stiffness():
    skfem = pytest.importorskip("skfem")
    from skfem.helpers import sym_grad

    P10, T10 = _p2(seed=12)
    C = _aniso(1, seed=12)[0]
    model = Model(P10, T10, np.tile(C, (len(T10), 1, 1)))
    _, d = model.numba(P10.copy())
    K = model.K(d)

    P = P10[: T10[:, :4].max() + 1]
    mesh = skfem.MeshTet(P.T, T10[:, :4].T)
    basis = skfem.Basis(mesh, skfem.ElementVector(skfem.ElementTetP2()))

    @skfem.BilinearForm
    def elasticity(u, v, _):
        eu, ev = sym_grad(u), sym_grad(v)
        EU = [eu[0, 0], eu[1, 1], eu[2, 2], 2 * eu[1, 2], 2 * eu[0, 2], 2 * eu[0, 1]]
        EV = [ev[0, 0], ev[1, 1], ev[2, 2], 2 * ev[1, 2], 2 * ev[0, 2], 2 * ev[0, 1]]
        return sum(C[i, j] * EU[j] * EV[i] for i in range(6) for j in range(6))

    Ks = skfem.asm(elasticity, basis).toarray()
    comp = np.empty(basis.N, int)  # axis of each skfem dof
    for dofs in (basis.nodal_dofs, basis.edge_dofs):
        for c in range(3):
            comp[dofs[c]] = c
    dist, node = cKDTree(P10).query(basis.doflocs.T)
    assert dist.max() < 1e-12 and len(np.unique(3 * node + comp)) == 3 * len(P10)
    perm = 3 * node + comp  # skfem dof -> our dof
    assert np.abs(K[np.ix_(perm, perm)] - Ks).max() < 1e-10 * np.abs(Ks).max()


def test_cantilever_tip_deflection_matches_timoshenko():
    L, b, h, E, load = 66.0, 30.0, 5.0, 100.0, 0.1  # [mm, mm, mm, MPa, N]: deflection ~ 0.3 mm
    C = Isotropic(E=E, nu=0.0).stiffness()
    I, G, kappa = b * h**3 / 12.0, E / 2.0, 5.0 / 6.0
    timo = load * L**3 / (3 * E * I) + load * L / (kappa * G * b * h)
    ratios = {}
    for nz in (1, 2):
        P, T = box_mesh((L, b, h), (22, 6, nz))
        for name, (pts, el) in (("P1", (P, T)), ("P2", elevate_to_p2(P, T))):
            model = Model(pts, el, np.tile(C, (len(el), 1, 1)))
            free = np.repeat(pts[:, 0] > 1e-9, 3)
            f_ext = np.zeros_like(pts)
            # uniform end shear traction, consistent nodal loads of the end-face triangles
            loaded, normal, area = _boundary_triangles(pts, el)
            end_tri = normal[:, 0] > 1.0 - 1e-9
            for c in range(3):
                np.add.at(f_ext[:, 2], loaded[end_tri, c], -load / (b * h) * area[end_tri] / 3.0)
            end = np.abs(pts[:, 0] - L) < 1e-9
            x = _newton(model, free, pts, f_ext.ravel(), tol=1e-9)
            ratios[(name, nz)] = -(x[end, 2] - pts[end, 2]).mean() / timo
    print("tip deflection / Timoshenko:", {f"{k[0]} nz={k[1]}": round(float(v), 4) for k, v in ratios.items()})
    assert abs(ratios[("P2", 2)] - 1.0) < 0.03
    assert ratios[("P1", 2)] < 0.9  # P1 locks in bending: why P2


def test_strain_measures_of_a_uniform_stretch():
    P10, T10 = _p2(seed=13)
    g, _ = tet10_quadrature(P10, T10)
    U = np.diag([1.2, 0.9, 1.0])
    x = P10 @ (_rot([0.3, 0.2, -1.0]) @ U).T
    eps = element_strains(x, T10, g)
    np.testing.assert_allclose(eps, np.broadcast_to([0.2, -0.1, 0, 0, 0, 0], eps.shape), atol=1e-12)
    np.testing.assert_allclose(max_principal_green_strain(x, T10, g), 0.5 * (1.2**2 - 1), rtol=1e-12)
