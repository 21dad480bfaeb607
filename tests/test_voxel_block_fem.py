"""A solid block gripped rigidly at both ends (issue 42): the voxel condensation
(:func:`metasheet.sheet.voxel_grips.rigid_bodies_stiffness`) against the quadratic tet FEM of the
same block (scikit-fem), an independent discretisation of the same problem.

The block is 4 x 4 x 8 mm of TPU, its x = 0 and x = 8 mm faces tied to two rigid grips; the
comparison is the 6 x 6 stiffness of the far grip with the near one held, read as the 6
generalised eigenvalues of (K_voxel, K_fem): scale-free, 1 where the two agree. Trilinear voxels
are stiffer than the limit (conforming, and they lock in bending), so the eigenvalues sit above
1 and come down under refinement. Measured, largest |log eigenvalue| against P2 tets of 0.5 mm:
0.066, 0.019 and 0.0038 for voxels of 1, 0.5 and 0.25 mm (second order); the P2 FEM itself moves
by 0.008 from 1 to 0.5 mm tets. The test uses P2 tets of 2/3 mm (seconds): 0.064 and 0.017.
"""

import metasheet  # noqa: F401  (pins numpy's code paths before numpy is imported)

# isort: split
import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse.linalg as spla
from skfem import Basis, ElementTetP2, ElementVector, MeshTet, asm
from skfem.models.elasticity import lame_parameters, linear_elasticity

from metasheet.sheet.voxel_grips import rigid_bodies_stiffness
from metasheet.mechanics.material import Isotropic

E, NU = 12.0, 0.3  # [MPa] TPU
SIZE = (8.0, 4.0, 4.0)  # [mm]


def _skew(d):
    return np.array([[0.0, -d[2], d[1]], [d[2], 0.0, -d[0]], [-d[1], d[0], 0.0]])


def _rigid(points, ref) -> np.ndarray:
    """(3 n, 6): displacement of ``points`` (n, 3) under a rigid motion (t, omega) about ``ref``."""
    T = np.zeros((len(points), 3, 6))
    T[:, :, :3] = np.eye(3)
    for i, p in enumerate(points):
        T[i, :, 3:] = -_skew(p - ref)  # omega x (p - ref)
    return T.reshape(-1, 6)


def fem_grip_stiffness(h: float) -> np.ndarray:
    """(6, 6) stiffness of the x = L grip about its face centre, the x = 0 grip held: P2 tets ~h [mm]."""
    n = [max(1, round(s / h)) for s in SIZE]
    mesh = MeshTet.init_tensor(*(np.linspace(0.0, s, k + 1) for s, k in zip(SIZE, n)))
    basis = Basis(mesh, ElementVector(ElementTetP2()), intorder=2)  # exact for P2 stiffness (P1 gradients)
    K = asm(linear_elasticity(*lame_parameters(E, NU)), basis).tocsr()
    x = basis.doflocs.T  # (ndofs, 3): each dof's location; dofs of one location are x, y, z in order
    near = np.flatnonzero(np.isclose(x[:, 0], 0.0))
    far = np.flatnonzero(np.isclose(x[:, 0], SIZE[0]))
    free = np.setdiff1d(np.arange(K.shape[0]), np.concatenate([near, far]))
    ref = np.array([SIZE[0], SIZE[1] / 2, SIZE[2] / 2])
    pts = x[far].reshape(-1, 3, 3)[:, 0]  # the far dofs come in (x, y, z) triples at one location
    assert np.allclose(x[far].reshape(-1, 3, 3), pts[:, None, :])
    T = _rigid(pts, ref)  # (len(far), 6)
    B = K[free][:, far] @ T  # (free, 6): the interior's load when the grip moves
    return T.T @ (K[far][:, far] @ T) - B.T @ spla.splu(K[free][:, free].tocsc()).solve(B)


def voxel_grip_stiffness(h: float) -> np.ndarray:
    """(6, 6) the same from voxels of edge h [mm]."""
    n = tuple(round(s / h) for s in SIZE)
    phases = np.ones(n, np.int64)
    bodies = np.zeros(tuple(k + 1 for k in n), np.int64)
    bodies[0] = 1
    bodies[-1] = 2
    refs = np.array([[0.0, SIZE[1] / 2, SIZE[2] / 2], [SIZE[0], SIZE[1] / 2, SIZE[2] / 2]])
    r = rigid_bodies_stiffness(phases, SIZE, {1: Isotropic(E, NU).stiffness()}, bodies=bodies, references=refs,
                               rtol=1e-10)
    return r.K[6:, 6:]  # the far grip's block: the near grip held


def _log_eigs(A, B) -> np.ndarray:
    return np.log(sla.eigh(A, B, eigvals_only=True))


@pytest.fixture(scope="module")
def reference():
    return fem_grip_stiffness(2.0 / 3.0)


def test_tet_fem_is_converged_well_below_the_voxels_error(reference):
    """The reference's own discretisation error (bounded by its change from 1 mm tets; measured
    0.005) is a third of the finer voxels' difference (0.017)."""
    assert np.max(np.abs(_log_eigs(fem_grip_stiffness(1.0), reference))) < 0.008


def test_block_condensation_converges_to_the_tet_fem(reference):
    coarse, K = voxel_grip_stiffness(1.0), voxel_grip_stiffness(0.5)
    errs = [float(np.max(np.abs(_log_eigs(k, reference)))) for k in (coarse, K)]
    assert errs[0] < 0.08 and errs[1] < 0.025  # measured 0.064 and 0.017
    assert errs[1] < 0.4 * errs[0]  # converging at about second order (measured ratio 3.8)
    assert np.allclose(K, K.T, rtol=0, atol=1e-9 * np.abs(K).max())
    # axial stiffness between the bounds of a bar whose ends cannot contract: EA/L < k < M A/L
    A, L = SIZE[1] * SIZE[2], SIZE[0]
    M = E * (1 - NU) / ((1 + NU) * (1 - 2 * NU))  # the P-wave (constrained) modulus [MPa]
    assert E * A / L < K[0, 0] < M * A / L
