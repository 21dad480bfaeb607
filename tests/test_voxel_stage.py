"""The homogenize stage with ``solver = "voxel"`` against the direct solver, and the operator's
bits against the thread count.

The stage (metasheet.pipeline.stages.homogenize) reads a cell artefact and writes
constants.json; on a small random foam the matrix-free multigrid path must give the direct
path's constants (C* to 1e-8 relative, Frobenius, at tolerance 1e-10). The operator sweeps
slabs of one parity in parallel (numba prange), so 1 and 2 threads must give the same bits.
"""

import json

import numba
import numpy as np
import pytest
from homogenize_samples import edge_foam

from metasheet.homogenize.voxel_periodic import periodic_stiffness
from metasheet.fem.voxel.element import phase_table
from metasheet.fem.voxel.operator import VoxelOperator, apply_full, touched_nodes
from metasheet.homogenize.percolation import percolating_solid
from metasheet.mechanics.material import Isotropic
from metasheet.pipeline.registry import StageContext
from metasheet.pipeline.stages import homogenize as stage

TPU = Isotropic(12.0, 0.3)


def _foam(n: int, seed: int) -> np.ndarray:
    ph = edge_foam(n, 0.3, seeds=5, rng_seed=seed)
    keep, _ = percolating_solid(ph > 0)
    return np.where(keep, ph, 0)


def _run_stage(tmp_path, ph, solver: str) -> dict:
    cell = tmp_path / f"cell_{solver}"
    cell.mkdir()
    np.savez(cell / "voxels.npz", phases=ph.astype(np.uint8), size=np.array([1.5, 1.5, 1.5]),
             axis=np.array([0.0, 0.0, 1.0]))
    (cell / "cell.json").write_text(json.dumps({"name": "foam", "materials": {"1": {"E": 12.0, "nu": 0.3}}}))
    work = tmp_path / f"work_{solver}"
    work.mkdir()
    # no homogenize.png: the picture is two thirds of this test's time and the same with either
    # solver (tests/test_homogenize_stage.py draws it); fields.vtu stays, it reads each solver's U
    params = stage.HomogenizeParams(tolerance=1e-10, solver=solver, picture=False)
    stage.run(StageContext("homogenize", params, work, {"cell": cell}, tmp_path))
    assert (work / "fields.vtu").stat().st_size > 0 and not (work / "homogenize.png").exists()
    return json.loads((work / "constants.json").read_text())


def test_stage_voxel_solver_matches_direct(tmp_path):
    ph = _foam(14, 5)
    direct = _run_stage(tmp_path, ph, "direct")
    voxel = _run_stage(tmp_path, ph, "voxel")
    C, C_ref = np.array(voxel["C"]), np.array(direct["C"])
    assert voxel["solver"] == "voxel" and direct["solver"] != "voxel"
    assert np.linalg.norm(C - C_ref) / np.linalg.norm(C_ref) < 1e-8
    for k in ("E_t", "E_l", "nu_t", "nu_tl", "mu_l", "relative_density"):
        assert voxel[k] == pytest.approx(direct[k], rel=1e-7), k


@pytest.mark.parametrize("shape, periodic", [((7, 6, 5), True), ((8, 5, 6), True), ((6, 5, 4), False)])
def test_operator_same_bits_on_one_and_two_threads(shape, periodic):
    """Odd and even periodic slab counts (the odd one sweeps its last slab alone) and a
    non-periodic grid, six right-hand sides at once."""
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba was started with one thread")
    rng = np.random.default_rng(4)
    index = np.where(rng.random(shape) < 0.7, 0, -1).astype(np.int64)
    table = phase_table(TPU.stiffness(), np.array([0.5, 0.4, 0.3]))
    free = np.repeat(touched_nodes(index, periodic)[..., None], 3, axis=3).astype(float)
    op = VoxelOperator(index, table.K, rng.uniform(0.5, 2.0, shape), periodic, free, table.h)
    u = rng.standard_normal(free.shape + (6,))
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = op.apply(u), apply_full(op, u)
        numba.set_num_threads(2)
        two = op.apply(u), apply_full(op, u)
    finally:
        numba.set_num_threads(before)
    assert all(np.array_equal(a, b) for a, b in zip(one, two))
    # and each column equals the operator on that column alone
    assert all(np.array_equal(one[0][..., l], op.apply(np.ascontiguousarray(u[..., l]))) for l in range(6))


def test_homogenisation_same_bits_on_one_and_two_threads():
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba was started with one thread")
    ph = _foam(12, 6)
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        a = periodic_stiffness(ph, (1.0, 1.0, 1.0), {1: TPU.stiffness()})
        numba.set_num_threads(2)
        b = periodic_stiffness(ph, (1.0, 1.0, 1.0), {1: TPU.stiffness()})
    finally:
        numba.set_num_threads(before)
    assert np.array_equal(a.C, b.C) and np.array_equal(a.U, b.U) and a.iterations == b.iterations


def test_auto_goes_matrix_free_from_the_threshold(monkeypatch):
    """"auto" picks the voxel solver from VOXEL_AUTO_DOFS unknowns, with the direct path's C*."""
    from metasheet.homogenize import voxels as hv
    from metasheet.homogenize.voxels import homogenize_voxels

    ph = _foam(12, 3)
    size = np.array([1.5, 1.5, 1.5])
    below = homogenize_voxels(ph, size, {1: TPU}, solver="auto", rtol=1e-10, localise=False)
    monkeypatch.setattr(hv, "VOXEL_AUTO_DOFS", 10)
    above = homogenize_voxels(ph, size, {1: TPU}, solver="auto", rtol=1e-10, localise=False)
    assert below.solver != "voxel" and above.solver == "voxel"
    assert np.linalg.norm(above.C - below.C) / np.linalg.norm(below.C) < 1e-8
