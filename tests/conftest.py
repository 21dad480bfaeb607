"""Shared pytest options and the expensive fixtures several test files share, each computed
once per session. Keep this file small and general."""

import os
import sys

import pytest

# before anything loads numpy: the test processes compute on the code path a pipeline run and
# its workers pin (metasheet.runtime.cpu); a test module that imported numpy first used to make
# its whole process compute on this CPU's own kernels (AVX-512 here), so a test's numbers
# depended on which file pytest collected first
import metasheet  # noqa: F401, E402

# bytecode caches for the test session, where PYTHONDONTWRITEBYTECODE turns them off: without
# them every test process compiles the test modules again (pytest's assertion rewriting: 9 of
# a worker's 16 s of collection) and every `metasheet` subprocess the sources it imports (about
# 0.5 s each); the caches go to the git-ignored __pycache__ folders (docs/performance.md)
sys.dont_write_bytecode = False
os.environ.pop("PYTHONDONTWRITEBYTECODE", None)

# idle OpenMP threads (numba's kernels) sleep instead of spinning: xdist fills the cores with
# test processes, and spinning threads took CPU from them (scheduling only: same results)
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

# pytest-xdist's `-n auto` (pyproject addopts) asks for one worker per core; more than four buys
# little here (the heavy tests run solvers with their own threads) and costs memory
MAX_XDIST_WORKERS = 4


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_auto_num_workers(config):
    return max(1, min(os.cpu_count() or 1, MAX_XDIST_WORKERS))


@pytest.hookimpl(tryfirst=True)  # before xdist's own hook, which reads the groups
def pytest_collection_modifyitems(config, items):
    """Under xdist (``--dist loadgroup``) a test file runs in one worker, so its module-scoped
    fixtures are computed once, and every file holding a byte-comparing test runs in one shared
    worker, one after another: the tests that compare bytes stay serial, each at the thread and
    worker counts it asks for, never beside another byte comparison."""
    bytes_files = {item.nodeid.split("::")[0] for item in items if item.get_closest_marker("bytes")}
    for item in items:
        path = item.nodeid.split("::")[0]
        item.add_marker(pytest.mark.xdist_group("bytes" if path in bytes_files else path))


class _XdistGroupsSeen:
    """pytest 9.2 keeps a node's id in ``_id``; pytest-xdist 3.8 writes the ``@group`` suffix
    its ``loadgroup`` scheduler reads into the older ``_nodeid``, where nothing reads it, so the
    groups were ignored (a file's tests spread over the workers, its module fixtures computed
    in each). Running after xdist's hook, this copies the suffixed id to where pytest reads it
    (a no-op on the versions where the two agree)."""

    @pytest.hookimpl(trylast=True)
    def pytest_collection_modifyitems(self, items):
        for item in items:
            written = item.__dict__.get("_nodeid")
            if isinstance(written, str) and "@" in written and written != item.nodeid:
                from _pytest.nodeid import NodeId

                item._id = NodeId.parse(written)


def pytest_configure(config):
    if hasattr(config, "workerinput") and config.getvalue("loadgroup"):
        config.pluginmanager.register(_XdistGroupsSeen(), "metasheet-xdist-groups-seen")


def pytest_addoption(parser):
    parser.addoption(
        "--update-goldens",
        action="store_true",
        default=False,
        help="rewrite golden files under tests/golden/ instead of comparing against them",
    )


@pytest.fixture(scope="session", autouse=True)
def one_blas_thread_per_process():
    """One BLAS / OpenMP thread in each test process, as a pipeline run gives itself
    (:data:`metasheet.runtime.executor.UNIT_THREADS`): xdist already fills the cores with processes, and
    idle OpenBLAS threads spin (a reduce stage measured 18 CPU s at two threads, 5 at one).
    A thread count set in the environment (``OPENBLAS_NUM_THREADS=2 python -m pytest``, as
    ``.ci/run`` reruns the bytes tests) is left as it is; tests that compare thread counts set
    their own. numba's parallel kernels (the voxel solver's) get one thread too: numba sizes its
    pool by the cores, whatever ``OMP_NUM_THREADS`` says."""
    import numba

    from metasheet.runtime.executor import THREAD_VARS, own_threads

    if any(os.environ.get(var) for var in (*THREAD_VARS, "NUMBA_NUM_THREADS")):
        yield
        return
    before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        with own_threads(1):
            yield
    finally:
        numba.set_num_threads(before)


@pytest.fixture(scope="module")
def foam_robot_14():
    """The light foam robot on 14 mm P1 sheets (solver tests)."""
    from metasheet.published import paper
    from metasheet.robot.builder import SheetPair, six_dof_robot
    from metasheet.sheet.geometry import SheetParams

    sheets = SheetPair.spiral(SheetParams(mesh_size=14))
    return six_dof_robot(sheets, paper.PAPER_FOAM, density=paper.FOAM_DENSITY)


@pytest.fixture(scope="module")
def foam_rest_14(foam_robot_14):
    """Its rest equilibrium, to 1e-10 of the force scale."""
    from metasheet.robot.equilibrium import solve_equilibrium

    return solve_equilibrium(foam_robot_14, foam_robot_14.coupling.rest_angles, tol=1e-10)


@pytest.fixture(scope="session")
def quick_outputs(tmp_path_factory):
    """The quick pipeline run once per session through ``printmap`` (cell, homogenize, material,
    orient, printmap): its output root, holding ``quick/<stage>/``. Read it; a test that runs a
    stage again copies it first (``shutil.copytree``), and the copy's stages stay cached."""
    from pathlib import Path

    from metasheet.pipeline.config import load_pipeline
    from metasheet.pipeline.runner import run_pipeline

    pipeline = load_pipeline(Path(__file__).resolve().parents[1] / "pipelines" / "quick.toml")
    if os.environ.get("PYTEST_XDIST_WORKER") is None:
        root = tmp_path_factory.mktemp("quick-outputs")
        run_pipeline(pipeline, out_root=root, only="printmap")
        return root
    # under xdist the workers share one run: the first to take the lock computes it, the
    # others wait and read (the stages' manifests make the second call a cache hit)
    import fcntl

    root = tmp_path_factory.getbasetemp().parent / "quick-outputs"
    root.mkdir(exist_ok=True)
    with open(root.parent / "quick-outputs.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        run_pipeline(pipeline, out_root=root, only="printmap")
    return root
