"""Solver choice and the pip-only fallback (SuperLU / AMG) when CHOLMOD is installed too.

On a machine with scikit-sparse, "direct" always means CHOLMOD; these tests hide it
(monkeypatch ``HAVE_CHOLMOD``) so that the path of a pip-only install is exercised here
as well, and check that every route gives the same tensor.
"""

import numpy as np
import pytest

from metasheet.homogenize import homogenize_voxels, solvers
from metasheet.homogenize.bounds import backus_laminate
from metasheet.homogenize.samples import edge_foam, laminate
from metasheet.material import Isotropic

TPU = Isotropic(12.0, 0.3)
SOFT = Isotropic(1.5, 0.45)


@pytest.mark.parametrize("have", [False, True])
def test_choose_solver_thresholds(monkeypatch, have):
    monkeypatch.setattr(solvers, "HAVE_CHOLMOD", have)
    small, mid, big = solvers.DIRECT_MAX_DOF, solvers.DIRECT_MAX_DOF + 1, solvers.CHOLMOD_MAX_DOF + 1
    assert solvers.choose_solver("auto", small) == ("cholmod" if have else "splu")
    assert solvers.choose_solver("auto", mid) == ("cholmod" if have else "amg-cg")
    assert solvers.choose_solver("auto", big) == "amg-cg"
    assert solvers.choose_solver("direct", big) == ("cholmod" if have else "splu")
    assert solvers.choose_solver("amg", small) == "amg-cg"


def test_pip_only_direct_is_superlu_and_exact(monkeypatch):
    """Without CHOLMOD, "direct" runs SuperLU and still returns the exact Backus laminate."""
    monkeypatch.setattr(solvers, "HAVE_CHOLMOD", False)
    r = homogenize_voxels(laminate(6, 0.5), (1.0, 1.0, 1.0), {1: TPU, 2: SOFT}, solver="direct")
    assert r.solver == "splu"
    C = backus_laminate([TPU.stiffness(), SOFT.stiffness()], [0.5, 0.5])
    np.testing.assert_allclose(r.C, C, rtol=0, atol=1e-6 * np.abs(C).max())


def test_pip_only_routes_agree_on_a_foam(monkeypatch):
    """SuperLU, AMG-CG (and CHOLMOD when installed) give one tensor on a porous foam."""
    ph = edge_foam(14, 0.3, seeds=5, rng_seed=1)
    ref = homogenize_voxels(ph, (1.0, 1.0, 1.0), {1: TPU}, solver="direct", localise=False)
    monkeypatch.setattr(solvers, "HAVE_CHOLMOD", False)
    lu = homogenize_voxels(ph, (1.0, 1.0, 1.0), {1: TPU}, solver="direct", localise=False)
    amg = homogenize_voxels(ph, (1.0, 1.0, 1.0), {1: TPU}, solver="amg", rtol=1e-10, localise=False)
    assert lu.solver == "splu" and amg.solver == "amg-cg"
    scale = np.abs(lu.C).max()
    assert np.abs(lu.C - ref.C).max() < 1e-10 * scale
    assert np.abs(amg.C - lu.C).max() < 1e-8 * scale
    assert all(0 < lc.iterations < 200 for lc in amg.load_cases)
