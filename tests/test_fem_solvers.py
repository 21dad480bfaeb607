"""The solver layer: one naming, one probe of the optional back-ends, and the fallbacks.

"direct" means the first available of PARDISO (pip, x86_64), CHOLMOD (optional, apt) and
SuperLU (always); these tests hide back-ends (monkeypatch
:func:`metasheet.fem.solvers.available`) so that every route runs wherever the tests run,
and check that every route gives the same tensor.
"""

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from metasheet.errors import ConfigError
from metasheet.fem import factor, solvers
from metasheet.homogenize import homogenize_voxels
from metasheet.mechanics.material import Isotropic

from homogenize_bounds import backus_laminate
from homogenize_samples import edge_foam, laminate

TPU = Isotropic(12.0, 0.3)
SOFT = Isotropic(1.5, 0.45)


def _cholmod(monkeypatch, have: bool, pardiso: bool = False):
    """Pretend CHOLMOD is (not) installed and PARDISO is (not): only SuperLU keeps its real probe."""
    real = solvers.available
    present = {"cholmod": have, "pardiso": pardiso}
    monkeypatch.setattr(solvers, "available", lambda name: present.get(name, real(name)))


needs_pardiso = pytest.mark.skipif(not solvers.available("pardiso"),
                                   reason="pypardiso (MKL) has no wheel for this platform")


def _nonsymmetric(n=120, seed=0):
    """Structurally symmetric, diagonally dominant, non-symmetric values (like the robot's K_ff)."""
    rng = np.random.default_rng(seed)
    A = sp.random(n, n, density=0.05, random_state=seed, format="csr")
    A = A + A.T + sp.diags(4.0 + rng.uniform(size=n))
    A = A.tocsr()
    A.data = A.data * (1.0 + 0.05 * rng.uniform(-1, 1, A.nnz))
    A.sort_indices()
    return A


def test_one_naming():
    assert tuple(solvers.BACKENDS) == ("pardiso", "cholmod", "superlu")  # best first (measured)
    assert factor.FACTOR_SOLVERS == ("auto", "cholmod", "superlu")  # PARDISO: SPD systems only
    assert solvers.SPD_SOLVERS == ("auto", "direct", "amg", "pardiso", "cholmod", "superlu")
    assert solvers.available("superlu")  # scipy: always there
    assert solvers.HAVE_CHOLMOD == solvers.available("cholmod")


@pytest.mark.parametrize("have", [False, True])
def test_choose_solver_thresholds(monkeypatch, have):
    _cholmod(monkeypatch, have)
    small, mid, big = solvers.SUPERLU_MAX_DOF, solvers.SUPERLU_MAX_DOF + 1, solvers.CHOLMOD_MAX_DOF + 1
    assert solvers.choose_solver("auto", small) == ("cholmod" if have else "superlu")
    assert solvers.choose_solver("auto", mid) == ("cholmod" if have else "amg-cg")
    assert solvers.choose_solver("auto", big) == "amg-cg"
    assert solvers.choose_solver("direct", big) == ("cholmod" if have else "superlu")
    assert solvers.choose_solver("amg", small) == "amg-cg"


def test_unknown_names_are_config_errors():
    with pytest.raises(ConfigError, match="solver: 'umfpack'"):
        solvers.choose_solver("umfpack", 10)
    with pytest.raises(ConfigError, match="linear_solver: 'splu'"):
        factor.resolve("splu")
    with pytest.raises(ConfigError, match="linear_solver: 'pardiso'"):
        factor.resolve("pardiso")
    assert solvers.choose_solver("superlu", 10**7) == "superlu"  # a back-end by name: no size policy


@pytest.mark.parametrize("have", [False, True])
def test_resolve_follows_the_probe(monkeypatch, have):
    _cholmod(monkeypatch, have)
    assert factor.resolve("auto") == ("cholmod" if have else "superlu")
    assert factor.resolve("superlu") == "superlu"
    if have:
        assert factor.resolve("cholmod") == "cholmod"
    else:
        with pytest.raises(ConfigError, match=r"scikit-sparse is not installed .*allowed here: 'auto' or 'superlu'"):
            factor.resolve("cholmod")


def test_superlu_keeps_its_options():
    """Same SuperLU options as before the solver layer: results bitwise equal to scipy called directly."""
    A = _nonsymmetric()
    b = np.random.default_rng(1).normal(size=(A.shape[0], 3))
    sym = spla.splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    plain = spla.splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A")
    assert np.array_equal(solvers.superlu(A, symmetric_mode=True).solve(b), sym.solve(b))
    assert np.array_equal(solvers.superlu(A).solve(b), plain.solve(b))
    s = factor.SparseSolver("superlu")
    fac = s.factorize(A)
    assert fac.name == "superlu" and not fac.symmetric
    assert np.array_equal(fac.solve(b), sym.solve(b))
    y, fac2 = s.solve_exact(fac, A, b)
    assert fac2 is fac and np.array_equal(y, sym.solve(b))
    assert s.stats == {"cholmod": 0, "superlu": 1, "fallbacks": 0, "refine_sweeps": 0, "exact_solves": 1}


def test_solve_spd_direct_reports_superlu(monkeypatch):
    _cholmod(monkeypatch, False)
    A = _nonsymmetric(seed=2)
    A = (0.5 * (A + A.T)).tocsr()  # SPD: diagonally dominant
    B = np.random.default_rng(2).normal(size=(A.shape[0], 6))
    X, report = solvers.solve_spd(A, B, solver="direct")
    assert report.solver == "superlu" and report.iterations == (0,) * 6 and report.n_dof == A.shape[0]
    assert np.array_equal(X, spla.splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A").solve(B))
    assert max(report.residuals) < 1e-12


def test_pip_only_direct_is_superlu_and_exact(monkeypatch):
    """Without CHOLMOD, "direct" runs SuperLU and still returns the exact Backus laminate."""
    _cholmod(monkeypatch, False)
    r = homogenize_voxels(laminate(6, 0.5), (1.0, 1.0, 1.0), {1: TPU, 2: SOFT}, solver="direct")
    assert r.solver == "superlu"
    C = backus_laminate([TPU.stiffness(), SOFT.stiffness()], [0.5, 0.5])
    np.testing.assert_allclose(r.C, C, rtol=0, atol=1e-6 * np.abs(C).max())


def test_pip_only_routes_agree_on_a_foam(monkeypatch):
    """SuperLU, AMG-CG (and CHOLMOD when installed) give one tensor on a porous foam."""
    ph = edge_foam(14, 0.3, seeds=5, rng_seed=1)
    ref = homogenize_voxels(ph, (1.0, 1.0, 1.0), {1: TPU}, solver="direct", localise=False)
    _cholmod(monkeypatch, False)
    lu = homogenize_voxels(ph, (1.0, 1.0, 1.0), {1: TPU}, solver="direct", localise=False)
    amg = homogenize_voxels(ph, (1.0, 1.0, 1.0), {1: TPU}, solver="amg", rtol=1e-10, localise=False)
    assert lu.solver == "superlu" and amg.solver == "amg-cg"
    scale = np.abs(lu.C).max()
    assert np.abs(lu.C - ref.C).max() < 1e-10 * scale
    assert np.abs(amg.C - lu.C).max() < 1e-8 * scale
    assert all(0 < lc.iterations < 200 for lc in amg.load_cases)


@pytest.mark.parametrize("have_cholmod", [False, True])
def test_pardiso_is_the_pip_only_direct_solver(monkeypatch, have_cholmod):
    """With pypardiso (a pip dependency), "auto" takes PARDISO up to its limit, CHOLMOD or not."""
    _cholmod(monkeypatch, have_cholmod, pardiso=True)
    mid, big = solvers.SUPERLU_MAX_DOF + 1, solvers.PARDISO_MAX_DOF + 1
    first = "pardiso"
    assert solvers.choose_solver("auto", 100) == first
    assert solvers.choose_solver("auto", mid) == first
    assert solvers.choose_solver("auto", big) == "amg-cg"
    assert solvers.choose_solver("direct", big) == first
    assert factor.resolve("auto") == ("cholmod" if have_cholmod else "superlu")  # the robot's K_ff


def test_auto_takes_a_direct_solver_only_when_its_factor_fits_in_memory(monkeypatch):
    """The paper's Polyfoam cell (754k dofs: 7.5 GB peak with PARDISO) is factorised when its
    share (MEMORY_SHARE) of the available memory holds it, and goes to AMG-CG on a small machine."""
    _cholmod(monkeypatch, False, pardiso=True)
    n = 754_407
    need = solvers.FACTOR_GB_AT_1M["pardiso"] * (n / 1e6) ** (4 / 3)
    assert 7.0 < need < 8.0
    assert solvers.choose_solver("auto", n, free_gb=need / solvers.MEMORY_SHARE * 1.01) == "pardiso"
    assert solvers.choose_solver("auto", n, free_gb=need / solvers.MEMORY_SHARE * 0.99) == "amg-cg"
    assert solvers.choose_solver("auto", 5_000, free_gb=0.001) == "superlu"  # no estimate: small is cheap
    assert solvers.choose_solver("direct", n, free_gb=0.001) == "pardiso"  # asked by name: no policy
    assert solvers.available_gb() > 0


@needs_pardiso
def test_pardiso_frees_its_factor_after_the_solve(monkeypatch):
    """MKL holds a factor until told: solve_spd frees it, or a worker keeps every cell's."""
    import pypardiso

    _cholmod(monkeypatch, False, pardiso=True)
    freed = []
    real = pypardiso.PyPardisoSolver.free_memory
    monkeypatch.setattr(pypardiso.PyPardisoSolver, "free_memory",
                        lambda self, everything=False: (freed.append(everything), real(self, everything))[1])
    A = _nonsymmetric(seed=4)
    A = (0.5 * (A + A.T)).tocsr()
    X, report = solvers.solve_spd(A, np.ones((A.shape[0], 2)), solver="pardiso")
    assert report.solver == "pardiso" and max(report.residuals) < 1e-12 and freed == [True]


@needs_pardiso
def test_pardiso_solves_spd_exactly_and_agrees_with_superlu(monkeypatch):
    _cholmod(monkeypatch, False, pardiso=True)
    A = _nonsymmetric(seed=3)
    A = (0.5 * (A + A.T)).tocsr()
    B = np.random.default_rng(3).normal(size=(A.shape[0], 6))
    X, report = solvers.solve_spd(A, B, solver="direct")
    assert report.solver == "pardiso" and max(report.residuals) < 1e-12
    ref = spla.splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A").solve(B)
    assert np.abs(X - ref).max() < 1e-12 * np.abs(ref).max()
    r = homogenize_voxels(laminate(6, 0.5), (1.0, 1.0, 1.0), {1: TPU, 2: SOFT}, solver="direct")
    assert r.solver == "pardiso"
    C = backus_laminate([TPU.stiffness(), SOFT.stiffness()], [0.5, 0.5])
    np.testing.assert_allclose(r.C, C, rtol=0, atol=1e-6 * np.abs(C).max())


@needs_pardiso
@pytest.mark.bytes
@pytest.mark.parametrize("nodes", [12, pytest.param(28, marks=pytest.mark.slow)])
def test_pardiso_gives_the_same_bits_every_time(nodes):
    """MKL's threaded sums vary run to run unless its conditional numerical reproducibility is
    on (``MKL_CBWR``, set when the solvers load): without it the same 65k-dof solve differed by
    2e-13 between repeats on 2 threads, and the homogenised constants between pipeline runs.
    The slow 28^3-node (65k-dof) case's default-selection sibling: the 12^3-node (5k-dof) case."""
    import os

    from skfem import Basis, ElementTetP1, ElementVector, MeshTet, asm
    from skfem.models.elasticity import lame_parameters, linear_elasticity

    assert os.environ.get("MKL_CBWR")
    mesh = MeshTet.init_tensor(*[np.linspace(0.0, 1.0, nodes)] * 3)
    basis = Basis(mesh, ElementVector(ElementTetP1()))
    K = (asm(linear_elasticity(*lame_parameters(1.0, 0.3)), basis) + 1e-3 * sp.identity(basis.N)).tocsc()
    B = np.random.default_rng(0).normal(size=(basis.N, 3))
    x = [solvers.solve_spd(K, B, solver="pardiso")[0] for _ in range(3)]
    assert np.array_equal(x[0], x[1]) and np.array_equal(x[0], x[2])
    assert np.abs(K @ x[0] - B).max() < 1e-8 * np.abs(B).max()
