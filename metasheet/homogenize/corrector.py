"""The periodic corrector problem shared by the voxel and the tet routes.

With u = E x + u~ and u~ periodic, the six unit macro strains E_I give

    K u~_I = -f_I,        f_I = int_Y_s B^T C E_I dV                       (corrector)
    C*_IJ = (1/|Y|) int_Y_s (E_I + B u~_I) : C : (E_J + B u~_J) dV         (energy form)

with |Y| the whole box (voids included). The energy form equals
``(C_vol + f^T U + U^T f + U^T K U) / |Y|``: symmetric, and its error is quadratic in
the solver error. The first-order form ``(C_vol + U^T f) / |Y|`` is kept as ``C_raw``
to measure the symmetry error. The fluctuation is defined up to one rigid translation
per connected part: one node per part is pinned (3 dofs), which removes exactly that
null space and changes nothing else.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..errors import ConfigError, InfeasibleError
from ..mechanics.material import Isotropic, TransverseIsotropic, TransverseFit
from ..fem.solvers import solve_spd


def material_stiffness(phase: int, material) -> np.ndarray:
    """(6, 6) Voigt stiffness [MPa] of a phase's material (axis 3 of a TI material = global z)."""
    if isinstance(material, (Isotropic, TransverseIsotropic)):
        return material.stiffness()
    raise ConfigError(
        f"materials[{phase}]: {type(material).__name__}: expected metasheet.mechanics.material.Isotropic "
        "or TransverseIsotropic"
    )


def pinned_dofs(K: sp.csr_matrix) -> np.ndarray:
    """Dofs of one node per connected part of the stiffness graph (3 per part)."""
    Kc = K.tocoo()
    n_nodes = K.shape[0] // 3
    G = sp.coo_matrix((np.ones(Kc.nnz, np.int8), (Kc.row // 3, Kc.col // 3)), shape=(n_nodes, n_nodes))
    n_parts, labels = connected_components(G, directed=False)
    first = np.unique(labels, return_index=True)[1]
    return (3 * first[:, None] + np.arange(3)[None, :]).ravel()


def solve_correctors(K: sp.csr_matrix, F: np.ndarray, c_vol: np.ndarray, volume: float, *,
                     coords: np.ndarray, solver: str, rtol: float):
    """Solve the six correctors and form the effective stiffness.

    Parameters
    ----------
    K : (n, n) periodic stiffness [N/mm] (dofs ``3 node + i``).
    F : (n, 6) unit-macro-strain forces ``int B^T C dV`` [N].
    c_vol : (6, 6) ``sum_e V_e C_e`` [N mm].
    volume : |Y|, the box volume [mm^3].
    coords : (n / 3, 3) node coordinates [mm] (AMG near-null space).
    solver, rtol : see :func:`~metasheet.fem.solvers.solve_spd`.

    Returns
    -------
    C (6, 6) [MPa], C_raw (6, 6) [MPa], U (n, 6) corrector displacements [mm per unit
    strain], :class:`SolveReport`.
    """
    n = K.shape[0]
    pin = pinned_dofs(K)
    free = np.setdiff1d(np.arange(n), pin)
    Kff = K[free][:, free]
    U = np.zeros((n, 6))
    Uf, report = solve_spd(Kff, -F[free], solver=solver, rtol=rtol, coords=np.asarray(coords)[free[::3] // 3]
                           if _whole_nodes(free) else None)
    U[free] = Uf
    C_raw = (c_vol + U.T @ F) / volume
    C = (c_vol + F.T @ U + U.T @ F + U.T @ (K @ U)) / volume
    C = 0.5 * (C + C.T)
    return C, C_raw, U, report


def _whole_nodes(free: np.ndarray) -> bool:
    return len(free) % 3 == 0 and np.all(free[0::3] % 3 == 0)


def check_and_fit(C: np.ndarray, axis) -> TransverseFit:
    """Refuse a singular effective stiffness (the solid does not carry load), then fit TI."""
    w = np.linalg.eigvalsh(C)
    if w[0] <= 1e-9 * w[-1]:
        raise InfeasibleError(
            f"effective stiffness is singular (eigenvalues {w[0]:.3g} .. {w[-1]:.3g} MPa): "
            "the solid does not percolate in every direction"
        )
    return TransverseIsotropic.fit(C, axis=axis)


def symmetry_error(C_raw: np.ndarray) -> float:
    """||C - C^T||_F / ||C||_F."""
    return float(np.linalg.norm(C_raw - C_raw.T) / np.linalg.norm(C_raw))
