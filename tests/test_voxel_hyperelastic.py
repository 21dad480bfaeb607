"""The neo-Hookean voxel body (metasheet/fem/voxel/hyperelastic.py, nonlinear.py) against exact
answers: the linear element at rest, zero force under rigid motion, the tangent against finite
differences of the forces, and homogeneous uniaxial stretch of a voxel bar (exact for trilinear
voxels) against the law's closed form."""

import numpy as np
import pytest
from scipy.optimize import brentq

from metasheet.errors import ConfigError
from metasheet.fem.hex8 import HEX8_CORNERS
from metasheet.fem.voxel.hyperelastic import NeoHookean, colour_order, gauss_gradients, internal_forces, tangent_apply
from metasheet.fem.voxel.nonlinear import law_table, solve_hyperelastic

TPU = NeoHookean(12.0, 0.3)  # NinjaFlex's tensile modulus (the paper), a rubber-like Poisson ratio
H = np.array([0.3, 0.25, 0.2])
ONE = np.arange(8).reshape(1, 8)  # one voxel, nodes in corner order


def _colours(voxels):
    """One block and one colour per voxel: the voxels of these tests share nodes in any pattern."""
    every = np.arange(len(voxels) + 1, dtype=np.int64)
    return every[:-1], every, every


def _forces(u, voxels=ONE, h=H, law=TPU):
    dN, w = gauss_gradients(h)
    F = np.empty((len(voxels), 8, 3, 3))
    Finv, c = np.empty_like(F), np.empty((len(voxels), 8))
    f = np.zeros_like(u)
    energy, bad = internal_forces(u, voxels, *_colours(voxels), dN, w, law.mu, law.lam, F, Finv, c, f)
    return f, energy, bad, (F, Finv, c)


def _tangent(v, state, voxels=ONE, h=H, law=TPU):
    dN, w = gauss_gradients(h)
    y = np.zeros_like(v)
    tangent_apply(v, voxels, *_colours(voxels), dN, w, law.mu, law.lam, state[1], state[2], y)
    return y


def test_the_tangent_at_rest_is_the_linear_voxel_element():
    _, energy, bad, F = _forces(np.zeros((8, 3)))
    assert energy == 0.0 and bad == 0
    K = np.stack([_tangent(e.reshape(8, 3), F).ravel() for e in np.eye(24)], axis=1)
    K_lin = law_table(TPU, H)[0]
    np.testing.assert_allclose(K, K_lin, rtol=0, atol=1e-12 * np.abs(K_lin).max())


def test_a_rigid_motion_costs_no_energy_and_no_force():
    X = HEX8_CORNERS * H
    a = np.radians(35.0)
    R = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]]) @ \
        np.array([[1, 0, 0], [0, np.cos(1.1), -np.sin(1.1)], [0, np.sin(1.1), np.cos(1.1)]])
    u = X @ R.T + np.array([1.0, -2.0, 0.5]) - X
    f, energy, bad, _ = _forces(u)
    scale = TPU.E * H.prod() ** (2 / 3)
    assert bad == 0 and abs(energy) < 1e-13 * scale * H.mean() and np.abs(f).max() < 1e-13 * scale


def test_the_tangent_is_the_derivative_of_the_forces_and_the_forces_of_the_energy():
    rng = np.random.default_rng(7)
    u = 0.08 * rng.normal(size=(8, 3))  # strains of tens of percent
    f, energy, bad, F = _forces(u)
    assert bad == 0
    v = rng.normal(size=(8, 3))
    eps = 1e-6
    fd = (_forces(u + eps * v)[0] - _forces(u - eps * v)[0]) / (2 * eps)
    np.testing.assert_allclose(_tangent(v, F), fd, rtol=0, atol=1e-7 * np.abs(fd).max())
    de = (_forces(u + eps * v)[1] - _forces(u - eps * v)[1]) / (2 * eps)
    assert de == pytest.approx(np.sum(f * v), rel=1e-7)  # f = dE/du
    F0 = F[0][0, 0]
    P = TPU.stress(F0)  # the law's closed form against its energy
    dF = rng.normal(size=(3, 3))
    dW = (TPU.energy(F0 + eps * dF) - TPU.energy(F0 - eps * dF)) / (2 * eps)
    assert dW == pytest.approx(np.sum(P * dF), rel=1e-7)


def test_an_inverted_gauss_point_is_counted_not_hidden():
    u = np.zeros((8, 3))
    u[HEX8_CORNERS[:, 0] == 1, 0] = -2.0 * H[0]  # the voxel turned inside out along x
    assert _forces(u)[2] == 8


def _bar(nx=6, ny=2, nz=2):
    phases = np.ones((nx, ny, nz), np.int64)
    N = (nx + 1, ny + 1, nz + 1)
    return phases, np.array([nx, ny, nz]) * H, N


def _uniaxial(stretch):
    """The bar's exact state: stretch along x, free lateral faces (P22 = P33 = 0)."""
    def p22(l2):
        J = stretch * l2 * l2
        return TPU.mu * l2 + (TPU.lam * np.log(J) - TPU.mu) / l2

    l2 = brentq(p22, 0.2, 2.0)
    P11 = TPU.mu * stretch + (TPU.lam * np.log(stretch * l2 * l2) - TPU.mu) / stretch
    return l2, P11


def _bar_ends(N, L, stretch):
    fixed = np.zeros(N + (3,), bool)
    values = np.zeros(N + (3,))
    fixed[0, :, :, 0] = True   # the end x = 0 slides on its plane
    fixed[-1, :, :, 0] = True  # the end x = L pulled along x, free to contract
    values[-1, :, :, 0] = (stretch - 1.0) * L
    fixed[0, 0, :, 1] = True   # no rigid motion: the lines y = 0 and z = 0 of the end x = 0
    fixed[0, :, 0, 2] = True
    return fixed, values


@pytest.mark.parametrize("stretch", [1.5, 0.95])
def test_a_voxel_bar_in_uniaxial_stretch_meets_the_closed_form(stretch):
    """In tension, and in compression below the bar's buckling strain (next test)."""
    phases, size, N = _bar()
    L = size[0]
    fixed, values = _bar_ends(N, L, stretch)
    sol = solve_hyperelastic(phases, size, TPU, prescribed=fixed, values=values, rtol=1e-10)
    l2, P11 = _uniaxial(stretch)
    X = np.stack(np.unravel_index(sol.nodes, N), 1) * H
    exact = X * np.array([stretch - 1.0, l2 - 1.0, l2 - 1.0])
    np.testing.assert_allclose(sol.u, exact, rtol=0, atol=1e-8 * L)  # homogeneous: trilinear is exact
    end = sol.full(sol.forces)[-1, :, :, 0].sum()
    assert end == pytest.approx(P11 * size[1] * size[2], rel=1e-8)
    # the walls' strain: Green-Lagrange along the bar, (stretch^2 - 1) / 2, or laterally in compression
    want = max(stretch**2 - 1.0, l2**2 - 1.0) / 2
    np.testing.assert_allclose(sol.strain, want, rtol=1e-7)
    assert sol.residual <= 1e-10 and sol.steps >= 1 and sol.stable


def test_a_bar_compressed_past_eulers_strain_buckles():
    """The 6 x 2 x 2 voxel bar, its ends kept from turning (their x fixed), is a column of
    slenderness L / r = 6 sqrt(12) / 2 = 10.4: Euler's strain for ends that cannot turn is
    pi^2 (r / L)^2 = 9.1 %. Pressed by 20 %, the uniform state (the closed form) is an equilibrium
    but not a minimum: the solver leaves it along the tangent's negative curvature and finds a
    bent equilibrium of lower energy; pressed by 5 % (the test above) it stays straight."""
    phases, size, N = _bar()
    L = size[0]
    fixed, values = _bar_ends(N, L, 0.8)
    sol = solve_hyperelastic(phases, size, TPU, prescribed=fixed, values=values, rtol=1e-10)
    l2, _ = _uniaxial(0.8)
    X = np.stack(np.unravel_index(sol.nodes, N), 1) * H
    uniform = X * np.array([-0.2, l2 - 1.0, l2 - 1.0])
    W = float(TPU.energy(np.diag([0.8, l2, l2])))  # the uniform state's energy density [mJ/mm^3]
    assert sol.residual <= 1e-10 and sol.stable
    assert sol.energy < W * np.prod(size) * (1 - 1e-3)  # lower than the straight column's
    mid = X[:, 0] == 3 * H[0]
    lateral = np.hypot(*(sol.u - uniform)[mid][:, 1:].T).max()
    assert lateral > 0.2 * size[1]  # bent by more than a fifth of its width at mid-length


def _linear_solve(phases, size, fixed, values):
    """The linear elastic body's reactions, assembled and solved directly (a second method)."""
    N = tuple(s + 1 for s in phases.shape)
    K_e = law_table(TPU, H)[0]
    n = int(np.prod(N)) * 3
    K = np.zeros((n, n))
    for ijk in np.argwhere(phases > 0):
        nodes = np.ravel_multi_index(tuple((ijk + HEX8_CORNERS).T), N)
        dofs = (3 * nodes[:, None] + np.arange(3)).ravel()
        K[np.ix_(dofs, dofs)] += K_e
    p = fixed.ravel()
    u = values.ravel().copy()
    u[~p] = np.linalg.solve(K[np.ix_(~p, ~p)], -K[np.ix_(~p, p)] @ u[p])
    return (K @ u).reshape(N + (3,))


def test_small_motions_give_the_linear_bodys_reactions():
    phases, size, N = _bar(5, 2, 2)
    phases[2, 1, :] = 0  # a notch: not a homogeneous state
    fixed = np.zeros(N + (3,), bool)
    fixed[0] = fixed[-1] = True
    values = np.zeros(N + (3,))
    values[-1, :, :, 2] = 1.0  # the end x = L moved across, the end x = 0 clamped
    values[-1, :, :, 0] = 0.3
    lin = _linear_solve(phases, size, fixed, values)[-1]
    d = 1e-4  # mm: central differences, O(d^2) from the nonlinearity
    plus = solve_hyperelastic(phases, size, TPU, prescribed=fixed, values=d * values, rtol=1e-9)
    minus = solve_hyperelastic(phases, size, TPU, prescribed=fixed, values=-d * values, rtol=1e-9)
    tangent = (plus.full(plus.forces) - minus.full(minus.forces))[-1] / (2 * d)
    np.testing.assert_allclose(tangent, lin, rtol=0, atol=1e-6 * np.abs(lin).max())


def test_bad_input_is_named():
    phases, size, N = _bar(3, 2, 2)
    fixed = np.zeros(N + (3,), bool)
    with pytest.raises(ConfigError, match="prescribed: no prescribed dof"):
        solve_hyperelastic(phases, size, TPU, prescribed=fixed, values=np.zeros(N + (3,)))
    fixed[0] = True
    with pytest.raises(ConfigError, match=r"values: shape \(2, 2\)"):
        solve_hyperelastic(phases, size, TPU, prescribed=fixed, values=np.zeros((2, 2)))
    with pytest.raises(ConfigError, match="rtol"):
        solve_hyperelastic(phases, size, TPU, prescribed=fixed, values=np.zeros(N + (3,)), rtol=0.5)
    with pytest.raises(ConfigError, match="nu"):
        NeoHookean(12.0, 0.5)


def test_coloured_kernels_give_the_same_bits_on_one_thread_and_two():
    """Two slabs of one colour share no node, and the forces, energy
    and tangent product of a random foam-like body are the same bits on 1 and 2 numba threads."""
    import numba

    from metasheet.fem.voxel.nonlinear import _Body

    rng = np.random.default_rng(3)
    index = np.where(rng.random((9, 6, 5)) < 0.6, 0, -1)
    body = _Body(index, H, TPU)
    assert len(body.colours) == 3 and body.colours[1] > 1  # two colours of several slabs
    for c in range(2):
        blocks = [set(body.voxels[body.order[body.starts[b]:body.starts[b + 1]]].ravel())
                  for b in range(body.colours[c], body.colours[c + 1])]
        assert all(not (x & y) for i, x in enumerate(blocks) for y in blocks[i + 1:])
    u = 0.02 * rng.standard_normal((len(body.nodes), 3))
    v = rng.standard_normal((len(body.nodes), 3))
    out = []
    before = numba.get_num_threads()
    try:
        for threads in (1, min(2, numba.config.NUMBA_NUM_THREADS)):
            numba.set_num_threads(threads)
            f, energy, bad = body.forces(u)
            out.append((f.tobytes(), energy, bad, body.tangent(v).tobytes()))
    finally:
        numba.set_num_threads(before)
    assert out[0] == out[1] and out[0][2] == 0
