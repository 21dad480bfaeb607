"""Independent cross-check: SfePy's homogenisation of the SAME voxel mesh agrees to 1e-6.

SfePy (optional: ``pip install sfepy``) assembles, ties opposite faces and solves with
its own code (``tests/sfepy_reference.py``, one subprocess per cell). The cells have
identical first and last voxel slices along every axis, so SfePy's non-periodic mesh
plus its periodic conditions is exactly our periodic mesh (see ``faces_match``).
Skipped, with the reason, when SfePy is not importable.
"""

import sys
from pathlib import Path

import numpy as np
import pytest

from metasheet.homogenize import homogenize_voxels
from metasheet.homogenize.percolation import percolating_solid
from metasheet.mechanics.material import Isotropic, TransverseIsotropic

sys.path.insert(0, str(Path(__file__).resolve().parent))
from homogenize_samples import edge_foam  # noqa: E402
from sfepy_reference import faces_match, sfepy_available, sfepy_stiffness  # noqa: E402

pytestmark = pytest.mark.skipif(not sfepy_available(),
                                reason="sfepy is not importable (optional cross-check: pip install sfepy)")

TPU = Isotropic(12.0, 0.3)
TI = TransverseIsotropic(E_t=10.0, E_l=3.0, nu_t=0.3, nu_tl=0.25, mu_l=1.2)
RTOL = 1e-6


def orthotropic_lattice() -> np.ndarray:
    """(10, 10, 10) lattice with struts 4, 2, 2 voxels wide along x, y, z; z-struts are phase 2.

    Bands are centred, so the first and last slices along every axis are equal.
    """
    n = 10
    band = lambda w: np.isin(np.arange(n), np.arange((n - w) // 2, (n + w) // 2))  # noqa: E731
    wide, thin = band(4), band(2)
    X, Y, Z = np.meshgrid(np.arange(n), np.arange(n), np.arange(n), indexing="ij")
    xs = wide[Y] & wide[Z]      # struts along x, 4 x 4 voxels
    ys = thin[X] & thin[Z]      # along y, 2 x 2
    zs = thin[X] & thin[Y]      # along z, 2 x 2, second material
    ph = np.zeros((n, n, n), np.int64)
    ph[zs] = 2
    ph[xs | ys] = 1
    return ph


def matched_foam() -> np.ndarray:
    """A small open foam whose last slices are copies of the first ones (islands removed)."""
    ph = edge_foam(12, 0.3, seeds=4, rng_seed=3)
    ph[-1] = ph[0]
    ph[:, -1] = ph[:, 0]
    ph[:, :, -1] = ph[:, :, 0]
    keep, _ = percolating_solid(ph > 0)
    return keep.astype(np.int64)


def _reference(ph, size, materials):
    assert faces_match(ph > 0), "test cell must have equal first/last slices"
    keep, _ = percolating_solid(ph > 0)
    assert np.array_equal(keep, ph > 0), "test cell must have no islands (SfePy would keep them)"
    C_ref, info = sfepy_stiffness(ph, size, {k: m.stiffness() for k, m in materials.items()})
    print(f"sfepy {info}")
    return C_ref


def _compare(ph, size, materials, solver, C_ref):
    ours = homogenize_voxels(ph, size, materials, solver=solver, rtol=1e-10, localise=False)
    err = np.abs(ours.C - C_ref).max() / np.abs(C_ref).max()
    print(f"{ours.solver}: max |C - C_sfepy| / max |C_sfepy| = {err:.2e}")
    return ours.C, err


@pytest.fixture(scope="module")
def foam_reference():
    ph = matched_foam()
    return ph, _reference(ph, (1.0, 1.0, 1.0), {1: TPU})


def test_orthotropic_two_phase_lattice_matches_sfepy():
    """Two materials (one transverse-isotropic), a non-cubic box, three strut widths."""
    ph, size, mats = orthotropic_lattice(), (1.0, 1.25, 0.8), {1: TPU, 2: TI}
    C_ref = _reference(ph, size, mats)
    C, err = _compare(ph, size, mats, "direct", C_ref)
    assert err < RTOL
    # not a trivially symmetric case: the three axial stiffnesses differ
    assert np.ptp(np.diag(C_ref)[:3]) > 0.05 * np.diag(C_ref)[:3].max()


@pytest.mark.parametrize("solver", ["direct", "amg"])
def test_porous_foam_matches_sfepy(solver, foam_reference):
    """Box volume (voids included) normalises both; the AMG route agrees as well."""
    ph, C_ref = foam_reference
    assert 0.2 < ph.mean() < 0.4
    C, err = _compare(ph, (1.0, 1.0, 1.0), {1: TPU}, solver, C_ref)
    assert err < RTOL
    assert C_ref[0, 0] < 0.5 * TPU.stiffness()[0, 0]  # porous: far below the solid
