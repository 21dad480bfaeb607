"""Dirichlet static Newton solver of an ElasticBody: quadratic convergence, failures reported, prescribed motion."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from metasheet.errors import ConfigError, ConvergenceError
from metasheet.mechanics.material import TransverseIsotropic
from metasheet.fem.meshes import box_mesh
from metasheet.robot.body import ElasticBody
from metasheet.robot.dirichlet import solve_static

MAT = TransverseIsotropic(E_t=1.0, E_l=0.4, nu_t=0.3, nu_tl=0.2, mu_l=0.5)
L, H = 50.0, 5.0


@pytest.fixture(scope="module")
def beam():
    P, T = box_mesh((L, H, H), (40, 2, 4))
    # Oblique fibres: an anisotropic, non-symmetric tangent and a 3D bending response.
    body = ElasticBody.from_material(P, T, MAT, np.tile([0.3, 0.5, 0.8], (len(T), 1)))
    root = np.flatnonzero(P[:, 0] < 1e-9)
    tip = np.flatnonzero(P[:, 0] > L - 1e-9)
    return body, root, tip


def _tip_loads(body, tip, total):
    loads = np.zeros((body.n_nodes, 3))
    loads[tip, 2] = -total / len(tip)
    return loads


def test_large_deflection_converges_quadratically(beam):
    body, root, tip = beam
    res = solve_static(body, root, loads=_tip_loads(body, tip, 1e-2), tol=1e-9)
    r = np.array(res.residuals)
    deflection = body.rest[tip, 2].mean() - res.x[tip, 2].mean()
    assert deflection > 0.1 * L  # really nonlinear: 6 mm on 50 mm
    assert r[-1] <= 1e-9 and res.iterations == len(r) - 1
    free = np.setdiff1d(np.arange(body.n_nodes), root)
    balance = body.forces(res.x)[free] - _tip_loads(body, tip, 1e-2)[free]
    assert np.linalg.norm(balance) < 1e-8 * 1e-2  # equilibrium holds, checked independently
    # Quadratic: once in the basin (r < 1e-2) at most 3 more iterations, and one step
    # squares the residual (a linearly converging solver cannot do r_k+1 < 10 r_k^2 there).
    first = int(np.argmax(r < 1e-2))
    assert len(r) - 1 - first <= 3
    quad = [r[k + 1] < 10 * r[k] ** 2 for k in range(first, len(r) - 1) if r[k] < 1e-2]
    assert any(quad), r
    assert res.time > 0


def test_too_few_iterations_raise_with_history(beam):
    body, root, tip = beam
    with pytest.raises(ConvergenceError) as err:
        solve_static(body, root, loads=_tip_loads(body, tip, 1e-2), max_iter=2)
    assert "max_iter=2" in str(err.value)
    assert len(err.value.history) == 3 and 0.5 < err.value.history[0] <= 1.0
    assert err.value.history[-1] > 1e-8


def test_prescribed_large_rotation_gives_rigid_motion(beam):
    body, root, _ = beam
    R = Rotation.from_rotvec([0.0, 1.0, 0.3]).as_matrix()  # 60 degrees
    shift = np.array([5.0, -2.0, 1.0])
    res = solve_static(body, root, x_fixed=body.rest[root] @ R.T + shift, tol=1e-10)
    assert np.abs(res.x - (body.rest @ R.T + shift)).max() < 1e-5 * L


def test_warm_start_and_no_load_at_rest(beam):
    body, root, tip = beam
    res0 = solve_static(body, root)
    assert res0.iterations == 0 and np.array_equal(res0.x, body.rest)
    loads = _tip_loads(body, tip, 1e-3)
    res = solve_static(body, root, loads=loads)
    again = solve_static(body, root, loads=loads, x0=res.x)
    assert again.iterations <= 1 and np.abs(again.x - res.x).max() < 1e-8


def test_unused_node_is_held_and_bad_input_rejected():
    P, T = box_mesh((4.0, 2.0, 2.0), (2, 1, 1))
    P = np.vstack([P, [[10.0, 10.0, 10.0]]])  # a node no element uses (gmsh leaves such points)
    body = ElasticBody.from_material(P, T, MAT, np.tile([0, 0, 1.0], (len(T), 1)))
    root = np.flatnonzero(P[:, 0] < 1e-9)
    loads = np.zeros_like(P)
    loads[:-1][P[:-1, 0] > 3.9, 2] = -1e-4
    res = solve_static(body, root, loads=loads)
    assert np.array_equal(res.x[-1], P[-1]) and res.x[5, 2] < P[5, 2]
    with pytest.raises(ConfigError, match="fixed"):
        solve_static(body, [0, 999])
    with pytest.raises(ConfigError, match="fixed"):
        solve_static(body, [0, 0])
    with pytest.raises(ConfigError, match="x_fixed"):
        solve_static(body, root, x_fixed=np.zeros((1, 3)))
    with pytest.raises(ConfigError, match="loads"):
        solve_static(body, root, loads=np.zeros((3, 3)))
    with pytest.raises(ConfigError, match="max_iter"):
        solve_static(body, root, max_iter=0)
    bad = loads.copy()
    bad[-1, 0] = 1.0
    with pytest.raises(ConfigError, match="no element"):
        solve_static(body, root, loads=bad)
