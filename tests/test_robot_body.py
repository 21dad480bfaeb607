"""Corotational tet FEM core: patch test, rigid motions, consistent tangent, gravity, validation."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from metasheet.errors import ConfigError, MeshError
from metasheet.mechanics.material import Isotropic, TransverseIsotropic
from metasheet.mechanics.voigt import stiffness_along
from metasheet.fem.meshes import box_mesh
from metasheet.robot.body import ElasticBody
from metasheet.fem.corotational.p1 import element_stiffness, shape_gradients

FOAM = TransverseIsotropic(E_t=1.39, E_l=0.0942, nu_t=0.3, nu_tl=0.05, mu_l=0.08)


def _foam_body(div=(4, 3, 2), jitter=0.2, seed=0, backend="numba", uniform=False):
    P, T = box_mesh((8.0, 6.0, 4.0), div, jitter=jitter, seed=seed)
    rng = np.random.default_rng(seed)
    if uniform:  # one oblique fibre: a homogeneous material, as the patch test needs
        fibers = np.tile([0.3, -0.5, 0.8], (len(T), 1))
    else:  # a different fibre per element: the general case
        fibers = rng.normal(size=(len(T), 3))
    return ElasticBody.from_material(P, T, FOAM, fibers, backend=backend)


def _fd_tangent(body, x, h=1e-6):
    n = x.size
    K = np.empty((n, n))
    for j in range(n):
        d = np.zeros(n)
        d[j] = h
        K[:, j] = (body.forces(x.ravel() + d) - body.forces(x.ravel() - d)).ravel() / (2 * h)
    return K


def test_box_mesh_volume_and_orientation():
    P, T = box_mesh((3.0, 2.0, 1.0), (3, 2, 2), jitter=0.25, seed=1)
    X = P[T]
    det = np.linalg.det(X[:, 1:] - X[:, :1])
    assert np.all(det > 0)
    assert np.isclose(det.sum() / 6.0, 6.0, rtol=1e-12)


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_patch_test_linear_field_zero_interior_forces_constant_stress(backend):
    body = _foam_body(jitter=0.25, backend=backend, uniform=True)
    P = body.rest
    A = np.array([[0.010, 0.004, -0.002], [0.001, -0.006, 0.003], [0.002, 0.005, 0.008]])
    A = 0.5 * (A + A.T)  # symmetric: no rotation, so the stress is exactly C : A
    x = P + P @ A.T + np.array([1.0, -2.0, 0.5])
    f = body.forces(x)
    size = np.ptp(P, axis=0)
    interior = np.all((P > 1e-9) & (P < size - 1e-9), axis=1)
    assert interior.sum() >= 6
    scale = np.abs(f).max()
    assert np.abs(f[interior]).max() < 1e-10 * scale
    eps = np.array([A[0, 0], A[1, 1], A[2, 2], 2 * A[1, 2], 2 * A[0, 2], 2 * A[0, 1]])
    expected = np.einsum("mij,j->mi", body.stiffness, eps)
    # F = I + A is symmetric: R = I and S - I = A exactly, so the stress is linear in A.
    assert np.allclose(body.stresses(x), expected, rtol=1e-9, atol=1e-12 * np.abs(expected).max())


def test_patch_test_large_linear_field_uniform_stress():
    """A large homogeneous deformation: same F everywhere, so interior nodes stay balanced."""
    body = _foam_body(jitter=0.25, uniform=True)
    P = body.rest
    Fh = Rotation.from_rotvec([0.3, -0.5, 0.9]).as_matrix() @ np.array(
        [[1.2, 0.1, 0.0], [0.1, 0.85, 0.05], [0.0, 0.05, 1.1]]
    )
    x = P @ Fh.T
    f = body.forces(x)
    size = np.ptp(P, axis=0)
    interior = np.all((P > 1e-9) & (P < size - 1e-9), axis=1)
    assert np.abs(f[interior]).max() < 1e-10 * np.abs(f).max()
    s = body.stresses(x)
    assert np.allclose(s, s[0], atol=1e-10 * np.abs(s).max())


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_rigid_motion_gives_zero_force(seed):
    body = _foam_body(seed=seed)
    rot = Rotation.random(random_state=seed).as_matrix()  # large rotations
    x = body.rest @ rot.T + np.array([10.0, -3.0, 7.0])
    stretch = body.rest * np.array([1.05, 1.0, 1.0])
    f_ref = np.abs(body.forces(stretch)).max()
    assert f_ref > 0
    assert np.abs(body.forces(x)).max() < 1e-11 * f_ref
    f, K = body.forces_and_tangent(x)
    assert np.abs(f).max() < 1e-11 * f_ref
    # A rigid motion is also a null vector of the tangent (translations and infinitesimal rotations).
    t = np.tile([1.0, 2.0, -1.0], body.n_nodes)
    w = np.cross(np.array([0.3, -0.2, 0.5]), x).ravel()
    assert np.abs(K @ t).max() < 1e-10 * abs(K).max() * 3
    assert np.abs(K @ w).max() < 1e-9 * abs(K).max() * np.abs(x).max()


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_tangent_matches_central_differences(backend):
    body = _foam_body(div=(2, 2, 1), backend=backend)
    rng = np.random.default_rng(3)
    rot = Rotation.from_rotvec([0.4, 1.1, -0.7]).as_matrix()
    x = body.rest @ rot.T + 0.4 * rng.normal(size=body.rest.shape)  # ~10 % strains plus rotation
    f, K = body.forces_and_tangent(x)
    K_fd = _fd_tangent(body, x)
    err = np.abs(K.toarray() - K_fd).max() / np.abs(K_fd).max()
    assert err < 1e-6
    assert np.allclose(f, body.forces(x).ravel(), rtol=0, atol=1e-14 * np.abs(f).max())
    # Anisotropic and deformed: the exact tangent is not symmetric (documented); symmetric=True is.
    Kd = K.toarray()
    assert np.abs(Kd - Kd.T).max() > 1e-6 * np.abs(Kd).max()
    _, Ks = body.forces_and_tangent(x, symmetric=True)
    assert np.allclose(Ks.toarray(), 0.5 * (Kd + Kd.T), rtol=0, atol=1e-15 * np.abs(Kd).max())


def test_isotropic_tangent_is_symmetric_everywhere():
    P, T = box_mesh((3.0, 2.0, 2.0), (2, 2, 2), jitter=0.2, seed=4)
    body = ElasticBody.from_material(P, T, Isotropic(2.0, 0.4))
    rng = np.random.default_rng(4)
    x = P @ Rotation.random(random_state=4).as_matrix().T + 0.3 * rng.normal(size=P.shape)
    _, K = body.forces_and_tangent(x)
    Kd = K.toarray()
    assert np.abs(Kd - Kd.T).max() < 1e-12 * np.abs(Kd).max()
    assert np.abs(Kd - _fd_tangent(body, x)).max() < 1e-6 * np.abs(Kd).max()


def test_tangent_pattern_is_cached_and_rest_tangent_is_linear_stiffness():
    body = _foam_body()
    _, K0 = body.forces_and_tangent(body.rest)
    _, K1 = body.forces_and_tangent(body.rest + 0.1)
    assert np.array_equal(K0.indptr, K1.indptr) and np.array_equal(K0.indices, K1.indices)
    # At rest R = I: the tangent is the linear stiffness sum_e V B^T C B, symmetric PSD.
    g, V, _ = shape_gradients(body.rest, body.tets)
    Ke = element_stiffness(g, V, body.stiffness)
    dense = np.zeros((3 * body.n_nodes,) * 2)
    for e, t in enumerate(body.tets):
        d = (3 * t[:, None] + np.arange(3)).ravel()
        dense[np.ix_(d, d)] += Ke[e]
    assert np.allclose(K0.toarray(), dense, rtol=0, atol=1e-13 * np.abs(dense).max())
    assert np.linalg.eigvalsh(dense).min() > -1e-12 * np.abs(dense).max()


def test_numpy_reference_matches_numba_on_inverted_element():
    """An inverted element (det F < 0): both polar paths keep det R = +1 and agree."""
    body = _foam_body(div=(2, 1, 1), jitter=0.0)
    x = body.rest.copy()
    x[body.tets[0, 0]] = body.rest[body.tets[0, 1:]].mean(0) * 2 - body.rest[body.tets[0, 0]]
    ref = ElasticBody(body.rest, body.tets, body.stiffness, backend="numpy")
    f1, K1 = body.forces_and_tangent(x)
    f2, K2 = ref.forces_and_tangent(x)
    assert np.allclose(f1, f2, atol=1e-12 * np.abs(f2).max())
    assert abs(K1 - K2).max() < 1e-10 * abs(K2).max()


def test_gravity_total_is_mg_and_mass_is_lumped():
    P, T = box_mesh((10.0, 4.0, 2.0), (5, 2, 2), jitter=0.2)
    body = ElasticBody.from_material(P, T, Isotropic(1.0, 0.3), density=1.19e-9)
    m = 80.0 * 1.19e-9
    assert np.isclose(body.mass.sum(), m, rtol=1e-12)
    assert np.isclose(body.volumes.sum(), 80.0, rtol=1e-12)
    G = body.gravity()
    assert np.allclose(G.sum(0), [0.0, 0.0, -9810.0 * m], rtol=1e-12)
    assert np.allclose(body.gravity((9810.0, 0, 0)).sum(0), [9810.0 * m, 0, 0], rtol=1e-12)


def test_material_per_element_and_constants_equivalent():
    P, T = box_mesh((2.0, 2.0, 2.0), (1, 1, 1))
    fib = np.tile([0.0, 1.0, 0.0], (len(T), 1))
    a = ElasticBody.from_material(P, T, FOAM, fib)
    b = ElasticBody(P, T, stiffness_along(FOAM.stiffness(), fib))
    c = ElasticBody.from_material(P, T, [FOAM] * len(T), fib)
    x = P + 0.1 * np.sin(P)
    assert np.allclose(a.forces(x), b.forces(x)) and np.allclose(a.forces(x), c.forces(x))


def test_bad_input_names_the_field():
    P, T = box_mesh((2.0, 2.0, 2.0), (1, 1, 1))
    with pytest.raises(ConfigError, match="points"):
        ElasticBody(P[:, :2], T, Isotropic(1, 0.3).stiffness())
    with pytest.raises(ConfigError, match="tets"):
        ElasticBody(P, T + 100, Isotropic(1, 0.3).stiffness())
    with pytest.raises(ConfigError, match="stiffness"):
        ElasticBody(P, T, np.eye(5))
    with pytest.raises(ConfigError, match=r"stiffness\[0\].*positive definite"):
        ElasticBody(P, T, -np.eye(6))
    with pytest.raises(ConfigError, match="density"):
        ElasticBody(P, T, np.eye(6), density=-1.0)
    with pytest.raises(ConfigError, match="fibers"):
        ElasticBody.from_material(P, T, FOAM)
    with pytest.raises(ConfigError, match="x: shape"):
        ElasticBody(P, T, np.eye(6)).forces(P[:3])
    mid = 0.5 * (P[T[0, 0]] + P[T[0, 1]])  # collinear with two corners: zero volume
    with pytest.raises(MeshError, match=r"tets\[6\]: degenerate"):
        ElasticBody(np.vstack([P, mid]), np.vstack([T, [[T[0, 0], T[0, 1], T[0, 2], len(P)]]]), np.eye(6))
