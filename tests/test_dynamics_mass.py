"""Consistent mass matrices, rigid-body inertia and Rayleigh damping against exact integrals."""

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp

from metasheet.dynamics.mass import (P2_REFERENCE, RigidInertia, box_inertia, combine, consistent_mass,
                                     cylinder_inertia, rayleigh_damping, sphere_inertia)
from metasheet.errors import ConfigError
from metasheet.fem.meshes import box_mesh
from metasheet.fem.tet10 import elevate_to_p2
from metasheet.mechanics.material import Isotropic
from metasheet.robot.body import ElasticBody

RHO = 1.19e-9  # [t/mm^3]
SIZE = np.array([6.0, 4.0, 3.0])  # [mm]


def body(element: str) -> ElasticBody:
    P, T = box_mesh(SIZE, (3, 2, 2), jitter=0.2, seed=3)
    if element == "p2":
        P, T = elevate_to_p2(P, T)
    return ElasticBody(P, T, Isotropic(10.0, 0.3).stiffness(), density=RHO, backend="numpy")


@pytest.fixture(scope="module", params=["p1", "p2"])
def case(request):
    b = body(request.param)
    return b, consistent_mass(b)


def box_integral(fun, size=SIZE, order=4) -> float:
    """``int fun(X) dV`` over [0, a] x [0, b] x [0, c] by tensor Gauss-Legendre (exact to degree 2 order - 1)."""
    g, w = np.polynomial.legendre.leggauss(order)
    axes = [(0.5 * s * (g + 1), 0.5 * s * w) for s in size]
    X = np.stack(np.meshgrid(*[a for a, _ in axes], indexing="ij"), -1).reshape(-1, 3)
    W = np.einsum("i,j,k->ijk", *[b for _, b in axes]).ravel()
    return float(W @ fun(X))


def xblock(M: sp.csr_matrix) -> sp.csr_matrix:
    """The scalar mass matrix: M's x-x entries (every axis carries the same one)."""
    return M[::3][:, ::3]


def test_the_p2_reference_is_the_textbook_matrix():
    # Zienkiewicz-Taylor's P2 tet mass matrix, in units of V / 420, this module's node order
    v, e = np.full((4, 4), 1.0) + 5 * np.eye(4), np.full((6, 6), 16.0) + 16 * np.eye(6)
    e[[0, 1, 2, 3, 4, 5], [5, 4, 3, 2, 1, 0]] = 8.0  # edges with no common vertex
    ve = np.array([[-4, -4, -4, -6, -6, -6], [-4, -6, -6, -4, -4, -6],
                   [-6, -4, -6, -4, -6, -4], [-6, -6, -4, -6, -4, -4]], float)
    expected = np.block([[v, ve], [ve.T, e]]) / 420.0
    np.testing.assert_allclose(P2_REFERENCE, expected, rtol=0, atol=1e-15)


def test_the_matrix_lies_on_the_body_pattern_and_is_spd(case):
    b, M = case
    assert M.shape == (3 * b.n_nodes,) * 2
    np.testing.assert_array_equal(M.indptr, b.pattern.indptr)
    np.testing.assert_array_equal(M.indices, b.pattern.indices)
    A = M.toarray()
    assert np.abs(A - A.T).max() <= 1e-15 * np.abs(A).max()
    assert np.linalg.eigvalsh(A).min() > 0
    # no coupling between axes: entry (3p+i, 3q+j) vanishes for i != j
    assert np.abs(A[0::3, 1::3]).max() == 0 and np.abs(A[1::3, 2::3]).max() == 0


def test_total_mass_and_the_lumped_row_sums(case):
    b, M = case
    ex = np.zeros(3 * b.n_nodes)
    ex[0::3] = 1.0
    assert ex @ M @ ex == pytest.approx(RHO * SIZE.prod(), rel=1e-12)
    # rows sum to rho int N_p dV: the body's work-equivalent lumped mass
    np.testing.assert_allclose(xblock(M) @ np.ones(b.n_nodes), b.mass, rtol=0, atol=1e-12 * b.mass.max())


def test_first_moment_of_a_rigid_translation(case):
    b, M = case
    S = xblock(M)
    centroid = SIZE / 2
    np.testing.assert_allclose(np.ones(b.n_nodes) @ S @ b.rest, RHO * SIZE.prod() * centroid, rtol=1e-12)


def field(X: np.ndarray, degree: int) -> np.ndarray:
    """(k, 3) a vector field of the given polynomial degree (1 or 2) at points X (k, 3)."""
    x, y, z = X.T
    u = np.stack([0.3 + 0.2 * x - 0.1 * y + 0.4 * z, -0.5 + 0.1 * x + 0.3 * y, 0.2 - 0.2 * z + 0.05 * y], 1)
    if degree == 2:
        u += np.stack([0.07 * x * y - 0.03 * z * z, 0.02 * x * x + 0.05 * y * z, -0.04 * x * z + 0.01 * y * y], 1)
    return u


def test_kinetic_form_is_exact_for_fields_of_the_element_space(case):
    b, M = case
    degree = 1 if b.element == "p1" else 2
    u = field(b.rest, degree).ravel()  # interpolated exactly by the element
    exact = RHO * box_integral(lambda X: (field(X, degree) ** 2).sum(1))
    assert u @ M @ u == pytest.approx(exact, rel=1e-12)


def test_p1_misses_a_quadratic_field():
    # the same quadratic field seen through P1 interpolation misses: the P2 test is not vacuous
    b = body("p1")
    u = field(b.rest, 2).ravel()
    exact = RHO * box_integral(lambda X: (field(X, 2) ** 2).sum(1))
    assert abs(u @ consistent_mass(b) @ u / exact - 1) > 1e-4


def test_inertia_of_the_meshed_box_equals_box_inertia(case):
    b, M = case
    X = b.rest - SIZE / 2
    S = X.T @ (xblock(M) @ X)  # rho int X_j X_k dV, exact for the linear fields X
    I_mesh = np.trace(S) * np.eye(3) - S
    ref = box_inertia(RHO * SIZE.prod(), SIZE, SIZE / 2)
    np.testing.assert_allclose(I_mesh, ref.inertia, rtol=0, atol=1e-12 * np.abs(ref.inertia).max())


def inertia_by_quadrature(points: np.ndarray, weights: np.ndarray, mass: float, centre) -> np.ndarray:
    """(3, 3) ``int rho (|r|^2 I - r r^T) dV`` about ``centre`` from quadrature points (k, 3) and
    weights (k,), the density uniform so that the weights sum to ``mass``."""
    r = points - centre
    w = mass * weights / weights.sum()
    return w @ (r * r).sum(1) * np.eye(3) - np.einsum("k,kj,kl->jl", w, r, r)


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_cylinder_against_quadrature(axis):
    m, R, L, c = 0.02, 3.0, 10.0, np.array([1.0, -2.0, 0.5])
    gr, wr = np.polynomial.legendre.leggauss(3)
    gz, wz = np.polynomial.legendre.leggauss(3)
    th = np.arange(16) * 2 * np.pi / 16  # periodic trapezoid: exact for trigonometric degree < 16
    r, t, z = np.meshgrid(0.5 * R * (gr + 1), th, 0.5 * L * gz, indexing="ij")
    w = np.einsum("i,j,k->ijk", 0.5 * R * wr, np.ones(16), 0.5 * L * wz) * r  # Jacobian r
    local = np.stack([r * np.cos(t), r * np.sin(t), z], -1).reshape(-1, 3)
    P = np.empty_like(local)
    P[:, axis], P[:, (axis + 1) % 3], P[:, (axis + 2) % 3] = local[:, 2], local[:, 0], local[:, 1]
    ref = inertia_by_quadrature(P + c, w.ravel(), m, c)
    got = cylinder_inertia(m, R, L, axis=axis, centre=c)
    np.testing.assert_allclose(got.inertia, ref, rtol=0, atol=1e-13 * np.abs(ref).max())
    np.testing.assert_array_equal(got.com, c)


def test_sphere_and_box_against_quadrature():
    m, R = 0.003, 4.0
    gr, wr = np.polynomial.legendre.leggauss(3)
    gu, wu = np.polynomial.legendre.leggauss(3)  # u = cos(polar angle)
    th = np.arange(8) * 2 * np.pi / 8
    r, u, t = np.meshgrid(0.5 * R * (gr + 1), gu, th, indexing="ij")
    w = np.einsum("i,j,k->ijk", 0.5 * R * wr, wu, np.ones(8)) * r**2
    s = np.sqrt(1 - u**2)
    P = np.stack([r * s * np.cos(t), r * s * np.sin(t), r * u], -1).reshape(-1, 3)
    np.testing.assert_allclose(sphere_inertia(m, R).inertia, inertia_by_quadrature(P, w.ravel(), m, 0),
                               rtol=0, atol=1e-14 * m * R**2)
    # a box by tensor Gauss, about its centre
    size = np.array([2.0, 5.0, 3.0])
    g, wg = np.polynomial.legendre.leggauss(2)
    axes = [0.5 * s_ * g for s_ in size]
    Q = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    Wq = np.einsum("i,j,k->ijk", wg, wg, wg).ravel()
    np.testing.assert_allclose(box_inertia(m, size).inertia, inertia_by_quadrature(Q, Wq, m, 0),
                               rtol=0, atol=1e-14 * m * 25)


@pytest.mark.parametrize("cut", [0.5, 0.25])
def test_combine_two_halves_of_a_box(cut):
    size, c, m = np.array([4.0, 2.0, 6.0]), np.array([1.0, 2.0, 3.0]), 2.0
    a = cut * size[0]
    left = box_inertia(m * cut, [a, 2.0, 6.0], c + [(a - size[0]) / 2, 0, 0])
    right = box_inertia(m * (1 - cut), [size[0] - a, 2.0, 6.0], c + [a / 2, 0, 0])
    whole = combine(left, right)
    ref = box_inertia(m, size, c)
    assert whole.mass == pytest.approx(m, rel=1e-15)
    np.testing.assert_allclose(whole.com, c, rtol=1e-15)
    np.testing.assert_allclose(whole.inertia, ref.inertia, rtol=1e-14)


def test_about_is_the_parallel_axis_theorem():
    s = sphere_inertia(0.5, 1.0, centre=(1.0, 0.0, 0.0))
    # about the origin: the sphere's 2/5 m r^2 plus m d^2 on the two axes normal to d = x
    np.testing.assert_allclose(s.about((0, 0, 0)), np.diag([0.2, 0.2 + 0.5, 0.2 + 0.5]), rtol=1e-15)
    b = box_inertia(1.0, (1.0, 2.0, 3.0), centre=(0.5, 1.0, 1.5))  # the box [0,1]x[0,2]x[0,3]
    corner = b.about((0, 0, 0))  # products of inertia -m ab/4 at a corner
    assert corner[0, 1] == pytest.approx(-0.5) and corner[0, 2] == pytest.approx(-0.75)
    assert corner[0, 0] == pytest.approx((4 + 9) / 3)


def test_rayleigh_damping_ratio_of_each_mode():
    M = np.diag([1.0, 2.0])
    K = np.array([[300.0, -100.0], [-100.0, 100.0]])
    alpha, beta = 0.8, 2e-3
    C = rayleigh_damping(M, K, alpha, beta)
    w2, phi = sla.eigh(K, M)
    w = np.sqrt(w2)
    np.testing.assert_allclose(np.diag(phi.T @ C @ phi) / (2 * w), alpha / (2 * w) + beta * w / 2, rtol=1e-13)
    Cs = rayleigh_damping(sp.csr_matrix(M), sp.csr_matrix(K), alpha, beta)
    assert sp.issparse(Cs) and np.abs(Cs.toarray() - C).max() < 1e-14
    assert isinstance(rayleigh_damping(sp.csr_matrix(M), K, alpha, beta), np.ndarray)


@pytest.mark.parametrize("make, match", [
    (lambda: RigidInertia(0.0), "mass"),
    (lambda: RigidInertia(1.0, com=(0, 0)), "com"),
    (lambda: RigidInertia(1.0, inertia=np.eye(2)), "inertia: shape"),
    (lambda: RigidInertia(1.0, inertia=[[1, 0.5, 0], [0, 1, 0], [0, 0, 1]]), "asymmetry"),
    (lambda: RigidInertia(1.0, inertia=np.diag([1.0, 1.0, -1.0])), "semidefinite"),
    (lambda: RigidInertia(1.0, inertia=np.diag([1.0, 1.0, 3.0])), "I1 \\+ I2 >= I3"),
    (lambda: box_inertia(1.0, (1.0, -1.0, 1.0)), "size"),
    (lambda: cylinder_inertia(1.0, 1.0, 1.0, axis=3), "axis"),
    (lambda: sphere_inertia(1.0, -1.0), "radius"),
    (lambda: combine(), "parts"),
    (lambda: combine(sphere_inertia(1.0, 1.0), 2.0), "parts\\[1\\]"),
    (lambda: rayleigh_damping(np.eye(2), np.eye(2), -1.0, 0.0), "alpha"),
    (lambda: rayleigh_damping(np.eye(2), np.eye(3), 1.0, 0.0), "M, K"),
])
def test_validation_names_the_field(make, match):
    with pytest.raises(ConfigError, match=match):
        make()


def test_the_rigid_inertia_is_frozen_and_read_only():
    s = sphere_inertia(1.0, 1.0)
    with pytest.raises(AttributeError):
        s.mass = 2.0
    with pytest.raises(ValueError):
        s.inertia[0, 0] = 5.0
    # a rod sits on the triangle bound and is accepted
    assert cylinder_inertia(1.0, 0.0, 10.0).inertia[0, 0] == 0.0
