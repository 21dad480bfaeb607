"""The workers' kernel warm-up (metasheet.pipeline.warmup): which stages ask for it, that a run
submits it once, and that it compiles the kernel signatures the stages' own paths call."""

import importlib
import pkgutil
import threading
from concurrent.futures import Future

import numpy as np
import pytest

from metasheet.pipeline import warmup


def test_families_follow_the_stages():
    assert warmup.families(["cell"]) == ()
    assert warmup.families(["cell", "homogenize"]) == ("voxel",)
    assert warmup.families(["homogenize", "workspace", "maze"]) == ("corotational", "voxel")


def test_downstream_closure_of_a_diamond():
    up = {"a": (), "b": ("a",), "c": ("a",), "d": ("b", "c"), "e": ()}
    down = warmup.downstream_closure("abcde", lambda n: up[n])
    assert down == {"a": ("a", "b", "c", "d"), "b": ("b", "d"), "c": ("c", "d"), "d": ("d",), "e": ("e",)}


class _Pool:
    def __init__(self):
        self.calls, self.lock = [], threading.Lock()

    def submit(self, priority, fn, item):
        with self.lock:
            self.calls.append((priority, fn, item))
        fut = Future()
        fut.set_exception(RuntimeError("no worker"))  # a failed warm-up is logged, not raised
        return fut


def test_warmer_submits_each_family_once_before_every_stage():
    pool = _Pool()
    down = {"cell": ("cell", "homogenize", "robot"), "homogenize": ("homogenize",), "robot": ("robot",)}
    w = warmup.Warmer(pool, down)
    w.starting("cell")
    w.starting("homogenize")
    w.starting("robot")
    assert sorted(item for _, _, item in pool.calls) == ["corotational", "voxel"]
    assert all(p == warmup.PRIORITY < 0 and fn is warmup.warm for p, fn, _ in pool.calls)
    warmup.Warmer(None, down).starting("cell")  # a serial run: nothing to do, no error


def test_warmer_waits_for_a_stage_that_computes():
    pool = _Pool()
    w = warmup.Warmer(pool, {"report": ("report",), "robot": ("robot", "report")})
    w.starting("report")
    assert pool.calls == []
    w.starting("robot")
    assert [item for *_, item in pool.calls] == ["corotational"]


def test_unknown_family_is_refused():
    with pytest.raises(ValueError, match="family"):
        warmup.warm("gpu")


def test_lattice_percolates_and_cube_tets_fill_the_cube():
    from metasheet.homogenize.percolation import percolating_solid

    ph = warmup.lattice_phases()
    keep, _ = percolating_solid(ph > 0)
    assert keep.sum() == (ph > 0).sum()
    pts, tets = warmup.cube_tets()
    X = pts[tets]
    vol = np.linalg.det(X[:, 1:] - X[:, :1]) / 6
    assert np.allclose(np.abs(vol), 1 / 6) and np.isclose(np.abs(vol).sum(), 1.0)


def _signatures() -> dict[str, set[str]]:
    from numba.core.registry import CPUDispatcher

    import metasheet.fem.corotational as fc
    import metasheet.fem.voxel as fv

    out = {}
    modules = [f"{pkg.__name__}.{m.name}" for pkg in (fv, fc) for m in pkgutil.iter_modules(pkg.__path__)
               if m.name != "device"]  # device: CuPy, not numba
    for name in [*modules, "metasheet.rom.ecsw"]:
        for k, v in vars(importlib.import_module(name)).items():
            if isinstance(v, CPUDispatcher):
                out[f"{name}.{k}"] = {str(s) for s in v.signatures}
    return out


def test_warm_up_compiles_the_signatures_the_stages_call(quick_outputs, foam_robot_14):
    """After the warm-up, a realisation's voxel homogenisation (the quick pipeline's cell), a P1
    and a P2 robot's equilibrium and an ECSW fit that drops elements call no kernel signature the
    warm-up did not compile: in a fresh run they load every kernel from the cache it wrote."""
    from metasheet.homogenize.voxels import homogenize_voxels
    from metasheet.published import paper
    from metasheet.robot.builder import SheetPair, six_dof_robot
    from metasheet.robot.equilibrium import solve_equilibrium
    from metasheet.sheet.geometry import SheetParams

    warmup.warm("voxel")
    warmup.warm("corotational")
    before = _signatures()
    assert sum(map(len, before.values())) >= 20  # the warm-up reached the solver's kernels

    with np.load(quick_outputs / "quick" / "cell" / "voxels.npz") as d:
        phases, size = d["phases"], d["size"]
    from metasheet.mechanics.material import Isotropic

    homogenize_voxels(phases, size, {1: Isotropic(12.0, 0.3)}, solver="voxel", rtol=1e-6, localise=False)
    p2 = six_dof_robot(SheetPair.spiral(SheetParams(mesh_size=14), element="p2"), paper.PAPER_FOAM,
                       density=paper.FOAM_DENSITY)
    for robot in (foam_robot_14, p2):
        solve_equilibrium(robot, robot.coupling.rest_angles + 0.02, tol=1e-8)
    from metasheet.rom.ecsw import ecsw

    rng = np.random.default_rng(0)
    A = rng.random((40, 60))
    ecsw(A, 1e-6, b=A[:, :5] @ np.array([1.0, 2.0, 0.5, 1.5, 3.0]), batch=0.5)  # batches enter and drop
    after = _signatures()
    new = {k: v - before.get(k, set()) for k, v in after.items() if v - before.get(k, set())}
    assert new == {}
