"""The multigrid rebuilt on a deformed state's tangent (metasheet/fem/voxel/tangent_multigrid.py):
its element table against the matrix-free tangent, its CG against the rest multigrid's on a
bent body, the Newton solve with it against the solve without, and the way back when it is
not positive definite."""

import numpy as np
import pytest
import scipy.sparse as sp

from metasheet.fem.voxel import nonlinear
from metasheet.fem.voxel.hyperelastic import NeoHookean, gauss_gradients, tangent_matrices
from metasheet.fem.voxel.nonlinear import HyperelasticBody, _Body, law_table
from metasheet.fem.voxel.pcg import pcg
from metasheet.fem.voxel.split_hierarchy import factor_pinned, positive_pivots
from metasheet.fem.voxel.tangent_multigrid import tangent_table

TPU = NeoHookean(12.0, 0.3)
H = np.array([0.3, 0.25, 0.2])


def _assembled(body: _Body, K_e: np.ndarray) -> np.ndarray:
    n = 3 * len(body.nodes)
    K = np.zeros((n, n))
    for e, nodes in enumerate(body.voxels):
        dofs = (3 * nodes[:, None] + np.arange(3)).ravel()
        K[np.ix_(dofs, dofs)] += K_e[e]
    return K


def test_the_element_table_is_the_matrix_free_tangent_and_the_linear_element_at_rest():
    rng = np.random.default_rng(3)
    index = np.where(rng.random((5, 4, 3)) < 0.7, 0, -1)
    body = _Body(index, H, TPU)
    body.forces(np.zeros((len(body.nodes), 3)))
    rest = np.empty((len(body.voxels), 24, 24))
    tangent_matrices(body.dN, body.w, body.mu, body.lam, body.Finv, body.c, rest)
    np.testing.assert_allclose(rest, np.broadcast_to(law_table(TPU, H)[0], rest.shape), rtol=0,
                               atol=1e-12 * np.abs(rest).max())
    u = 0.03 * rng.standard_normal((len(body.nodes), 3))  # strains of ~20 %
    f, _, bad = body.forces(u)
    assert bad == 0
    K_e = np.empty_like(rest)
    tangent_matrices(body.dN, body.w, body.mu, body.lam, body.Finv, body.c, K_e)
    v = rng.standard_normal((len(body.nodes), 3))
    want = body.tangent(v)
    got = (_assembled(body, K_e) @ v.ravel()).reshape(v.shape)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * np.abs(want).max())
    np.testing.assert_allclose(K_e, K_e.transpose(0, 2, 1), rtol=0, atol=1e-13 * np.abs(K_e).max())
    table = tangent_table(body.dN, body.w, body.mu, body.lam, body.Finv, body.c)
    assert table.dtype == np.float32
    np.testing.assert_allclose(table, K_e, rtol=0, atol=1e-6 * np.abs(K_e).max())


def _plate(nx=24, ny=6, nz=4):
    """A plate clamped at x = 0, its end x = L turned by 40 deg about y and pulled along x: walls
    bent and stretched well past the linear range (> 1,000 unknowns: a split hierarchy)."""
    phases = np.ones((nx, ny, nz), np.int64)
    phases[8:16, 2:4, :] = 0  # a window: the load goes round it
    size = np.array([nx, ny, nz]) * H
    N = (nx + 1, ny + 1, nz + 1)
    fixed = np.zeros(N + (3,), bool)
    fixed[0] = fixed[-1] = True
    X = np.stack(np.indices(N), -1) * H
    end = X[-1] - X[-1].mean(axis=(0, 1))
    t = np.radians(40.0)
    R = np.array([[np.cos(t), 0, np.sin(t)], [0, 1, 0], [-np.sin(t), 0, np.cos(t)]])
    values = np.zeros(N + (3,))
    values[-1] = end @ R.T - end + np.array([0.1 * size[0], 0.0, 0.0])
    return phases, size, fixed, values


def test_the_tangents_multigrid_needs_fewer_iterations_on_a_bent_body_for_the_same_answer():
    phases, size, fixed, values = _plate()
    hb = HyperelasticBody(phases, size, TPU, fixed)
    assert hb.H.sparse is not None  # the split hierarchy, as on a printed sheet
    sol = hb.solve(values, rtol=1e-8, probe=False)
    hb.body.forces(sol.u)  # the bent state's tangent
    Ht = hb.tangent_hierarchy()
    assert Ht is not None and Ht.sparse.positive
    assert np.array_equal(Ht.fine.active, hb.H.fine.active)

    def apply(v):
        return np.stack([hb.on_free(hb.body.tangent(hb.to_body(v[..., k]))) for k in range(v.shape[2])], -1)

    b = hb.on_free(np.random.default_rng(0).standard_normal((len(hb.body.nodes), 3)))
    runs = [pcg(apply, b, M.precondition, rtol=1e-8, maxiter=500, flexible=M.flexible) for M in (hb.H, Ht)]
    assert all(r.converged[0] for r in runs)
    rest, tangent = (int(r.iterations[0]) for r in runs)
    assert tangent < 0.6 * rest, (rest, tangent)
    x0, x1 = (r.x[..., 0] for r in runs)
    np.testing.assert_allclose(x1, x0, rtol=0, atol=1e-6 * np.abs(x0).max())


def test_the_newton_solve_with_the_rebuilt_multigrid_finds_the_same_equilibrium(monkeypatch):
    phases, size, fixed, values = _plate()
    hb = HyperelasticBody(phases, size, TPU, fixed)
    plain = hb.solve(values, rtol=1e-8)
    monkeypatch.setattr(nonlinear, "REBUILD_ITERATIONS", 0)  # rebuild after every step
    built = []
    original = hb.tangent_hierarchy
    monkeypatch.setattr(hb, "tangent_hierarchy", lambda: built.append(1) or original())
    rebuilt = hb.solve(values, rtol=1e-8)
    assert built and rebuilt.residual <= 1e-8 and plain.residual <= 1e-8 and rebuilt.stable
    reactions = plain.full(plain.forces)[-1]
    np.testing.assert_allclose(rebuilt.full(rebuilt.forces)[-1], reactions, rtol=0,
                               atol=1e-6 * np.abs(reactions).max())
    np.testing.assert_allclose(rebuilt.u, plain.u, rtol=0, atol=1e-6 * np.abs(plain.u).max())
    assert sum(rebuilt.cg) < sum(plain.cg)


def test_a_buckled_column_is_still_found_with_the_rebuilt_multigrid(monkeypatch):
    """The 24 x 3 x 3 column pressed by 20 %, far past Euler's strain: the straight state's tangent
    is indefinite, so its multigrid is refused or found indefinite, and the solve goes back to the
    rest multigrid and still leaves the straight saddle for a bent minimum."""
    nx = 24
    phases = np.ones((nx, 3, 3), np.int64)
    size = np.array([nx, 3, 3]) * H
    N = (nx + 1, 4, 4)
    fixed = np.zeros(N + (3,), bool)
    fixed[0] = fixed[-1] = True
    values = np.zeros(N + (3,))
    values[-1, :, :, 0] = -0.2 * size[0]
    monkeypatch.setattr(nonlinear, "REBUILD_ITERATIONS", 0)
    sol = HyperelasticBody(phases, size, TPU, fixed).solve(values, rtol=1e-8)
    assert sol.residual <= 1e-8 and sol.stable
    X = np.stack(np.unravel_index(sol.nodes, N), 1) * H
    mid = X[:, 0] == (nx // 2) * H[0]
    assert np.abs(sol.u[mid][:, 1:]).max() > 0.2 * size[1]  # bent, not pressed straight


def test_the_bottom_factor_reports_an_indefinite_level():
    A = sp.csr_matrix(np.diag([4.0, 3.0, 2.0, 1.0]) + 0.1)
    assert positive_pivots(factor_pinned(A, pin_parts=False)[1])
    B = sp.csr_matrix(np.array([[1.0, 2, 0, 0], [2, 1, 0, 0], [0, 0, 2, 0], [0, 0, 0, 1]]))  # eigenvalue -1
    assert not positive_pivots(factor_pinned(B, pin_parts=False)[1])


def test_the_table_is_the_float64_sums_rounded_once_and_reuses_a_given_buffer():
    rng = np.random.default_rng(1)
    dN, w = gauss_gradients(H)
    Finv = np.eye(3) + 0.1 * rng.standard_normal((500, 8, 3, 3))
    c = TPU.mu + 0.1 * rng.standard_normal(Finv.shape[:2])
    whole = np.empty((len(Finv), 24, 24))
    tangent_matrices(dN, w, TPU.mu, TPU.lam, Finv, c, whole)
    fresh = tangent_table(dN, w, TPU.mu, TPU.lam, Finv, c)
    np.testing.assert_array_equal(fresh, whole.astype(np.float32))
    buffer = np.full_like(fresh, np.nan)
    assert tangent_table(dN, w, TPU.mu, TPU.lam, Finv, c, buffer) is buffer
    np.testing.assert_array_equal(buffer, fresh)
    with pytest.raises(ValueError, match="out: shape"):
        tangent_table(dN, w, TPU.mu, TPU.lam, Finv, c, np.empty((3, 24, 24), np.float32))
