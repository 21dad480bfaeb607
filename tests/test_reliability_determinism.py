"""Issue 15, item 1: the same config gives the same bytes.

- the quick pipeline run twice from scratch (a cold numba cache for the first run, as on a
  fresh clone) writes byte-identical outputs; manifests agree on every field but the
  wall-clock and CPU ones (``started``, ``wall_time_s``, ``cpu_s``, ``timings_s``);
- no artefact holds a wall-clock time (``constants.json`` had ``timings_s``);
- pyamg's random spectral-radius estimate is seeded: AMG-CG gives the same bits whatever
  numpy's global generator holds, and leaves that generator as it found it;
- the cache key hashes a JSON artefact's canonical content: a last-bit change upstream does
  not rerun the stages downstream.
"""

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from metasheet.runtime import cpu
from metasheet.pipeline import registry
from metasheet.pipeline.config import load_pipeline
from metasheet.pipeline.registry import Params, Stage, register
from metasheet.pipeline.runner import run_pipeline

ROOT = Path(__file__).resolve().parents[1]
#: Manifest fields that hold wall-clock times: the only ones two runs may differ in.
TIME_FIELDS = ("started", "wall_time_s", "cpu_s", "timings_s")


def _tree(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


#: Thread settings a user may have: the run's bytes must not depend on them.
BLAS_THREADS = {"a": "2", "b": "1"}


@pytest.mark.slow
def test_quick_pipeline_twice_from_scratch_gives_the_same_bytes(tmp_path):
    """The whole quick pipeline, robot included (about 70 s on 2 quiet cores); its default
    sibling is :func:`test_quick_pipeline_to_material_twice_from_scratch_gives_the_same_bytes`.
    Not marked ``bytes``: it sets the BLAS threads of each run itself (2, then 1), so .ci/run's
    reruns under 1 and 2 threads would repeat it unchanged.
    The first runs serially with two BLAS threads asked for, the second with one, on a pool of
    two workers, its independent stages at once (``stages_at_once = 2``: printmap beside
    robot, both drawing pictures): the same bytes. Before: 10 of 26 files differed between
    the default threads and one (the Jacobian by 9e-9). Every picture's bytes are compared here
    (cell.png and homogenize.png too, which the default sibling does not draw)."""
    _twice_from_scratch(tmp_path, [])


def test_quick_pipeline_to_material_twice_from_scratch_gives_the_same_bytes(tmp_path):
    """The same two runs up to the material stage (cell, homogenize, material: the voxels, the
    corrector solves and their BLAS sums, where threads split work), without the cell's and
    homogenize's pictures (``picture = false``: a VTK render and a matplotlib figure, a third
    of each run's CPU time; no BLAS sum in them). The first run's cold numba cache stays."""
    _twice_from_scratch(tmp_path, ["--stage", "material"], pictures=False)


def _twice_from_scratch(tmp_path: Path, only: list[str], pictures: bool = True) -> None:
    """Run the quick pipeline (``only``: extra ``metasheet run`` arguments) twice from scratch
    in copies of the project, serially with two BLAS threads, then on two workers with one;
    assert the same bytes in every output and the same manifests but for the clocks.
    ``pictures`` False: the cell and homogenize stages draw none (and none is compared)."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba-cache")}  # cold, as on a fresh clone
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    env.pop(cpu.DECISION, None)  # each run decides its code paths as a user's would (metasheet.runtime.cpu)
    trees, seconds = [], []
    for run in ("a", "b"):
        project = tmp_path / f"project_{run}"
        for d in ("cells", "pipelines"):
            shutil.copytree(ROOT / d, project / d)
        extra = list(only)
        toml = project / "pipelines" / "quick.toml"
        if not pictures:
            text = toml.read_text()
            for table in ("cell", "homogenize"):
                assert text.count(f"\n[{table}]\n") == 1, table
                text = text.replace(f"\n[{table}]\n", f"\n[{table}]\npicture = false\n")
            toml.write_text(text)
        if run == "b":
            toml.write_text(toml.read_text().replace("[pipeline]\n", "[pipeline]\nstages_at_once = 2\n", 1))
            extra += ["--workers", "2"]
        threads = {v: BLAS_THREADS[run] for v in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OMP_NUM_THREADS")}
        t0 = time.perf_counter()
        r = subprocess.run([sys.executable, "-m", "metasheet.cli", "run", "pipelines/quick.toml",
                            "--out", str(tmp_path / run), *extra], cwd=project, env={**env, **threads},
                           capture_output=True, text=True, timeout=900)
        seconds.append(time.perf_counter() - t0)
        assert r.returncode == 0, r.stdout + r.stderr
        trees.append(_tree(tmp_path / run / "quick"))
    a, b = trees
    assert a.keys() == b.keys()
    assert not any(".tmp-" in k or ".old-" in k for k in a)
    assert any(k.endswith(".png") for k in a) == pictures
    manifests = [k for k in a if k.endswith("manifest.json")]
    order = load_pipeline(project / "pipelines/quick.toml").order
    assert len(manifests) == (order.index(only[1]) + 1 if only else len(order))
    differ = [k for k in a if k not in manifests and a[k] != b[k]]
    assert differ == [], f"files differ between two runs from scratch: {differ}"
    for k in manifests:
        ma, mb = json.loads(a[k]), json.loads(b[k])
        assert ma.keys() == mb.keys()
        assert {f for f in ma if ma[f] != mb[f]} <= {*TIME_FIELDS, "executor"}, k
        assert ma["code_paths"]["decision"] == ("pinned" if cpu.has_avx2_fma() else "native"), k
    for k, data in a.items():  # wall-clock times live in manifests only
        if k.endswith(".json") and k not in manifests:
            assert "timings_s" not in json.loads(data), k
    print(f"two quick runs from scratch: {seconds[0]:.1f} s and {seconds[1]:.1f} s")


def test_homogenize_writes_no_wall_time_into_constants(tmp_path):
    from metasheet.pipeline.stages import homogenize as stage

    cell = tmp_path / "cell"
    cell.mkdir()
    phases = np.ones((4, 4, 4), np.uint8)
    phases[:, :, 2:] = 2
    np.savez(cell / "voxels.npz", phases=phases, size=np.ones(3), axis=np.array([0.0, 0.0, 1.0]))
    (cell / "cell.json").write_text(json.dumps({"name": "lam", "materials": {
        "1": {"E": 12.0, "nu": 0.3}, "2": {"E": 1.5, "nu": 0.45}}}))
    work = tmp_path / "work"
    work.mkdir()
    ctx = registry.StageContext("homogenize", stage.HomogenizeParams(fields=False, picture=False), work,
                                {"cell": cell}, tmp_path)
    stage.run(ctx)
    constants = json.loads((work / "constants.json").read_text())
    assert "timings_s" not in constants
    assert set(ctx.timings) == {"assembly", "setup", "solve", "post"}  # for the manifest


@pytest.mark.bytes
def test_amg_cg_is_the_same_bits_whatever_the_global_generator():
    """pyamg estimates spectral radii from ``np.random.rand`` vectors: seeded now."""
    from metasheet.fem.amg import amg_cg

    A, B, coords = _elastic_system()
    np.random.seed(1)
    before = np.random.get_state()[1].copy()
    x1, it1, _ = amg_cg(A, B, 1e-10, coords, 500)
    assert np.array_equal(np.random.get_state()[1], before)  # the caller's stream is untouched
    np.random.seed(2)
    x2, it2, _ = amg_cg(A, B, 1e-10, coords, 500)
    assert it1 == it2
    assert x1.tobytes() == x2.tobytes()


def _elastic_system():
    """A small SPD P1 elasticity system, anchored (enough dofs for a multi-level hierarchy)."""
    import scipy.sparse as sp

    from metasheet.fem.meshes import box_mesh
    from metasheet.fem.tet4 import tet4_matrices
    from metasheet.mechanics.material import Isotropic

    points, tets = box_mesh((1.0, 1.0, 1.0), (8, 8, 8), jitter=0.2, seed=3)
    K, _, _, _ = tet4_matrices(points, tets, Isotropic(1.0, 0.3).stiffness())
    dofs = (3 * tets[:, :, None] + np.arange(3)).reshape(len(tets), 12)
    rows = np.repeat(dofs, 12, axis=1).ravel()
    cols = np.tile(dofs, (1, 12)).ravel()
    n = 3 * len(points)
    A = sp.csr_matrix((K.ravel(), (rows, cols)), shape=(n, n)) + 1e-3 * sp.eye(n, format="csr")
    B = np.random.default_rng(0).standard_normal((n, 2))
    return A.tocsr(), B, points


# ------------------------------------------------------------------------ canonical cache key

COUNT = {"a": 0}


class JParams(Params):
    scale: float = 1.0


def run_jitter(ctx):
    """Writes 0.1 with a different last bit every time it runs."""
    COUNT["a"] += 1
    v = 0.1 + COUNT["a"] * 2.0 ** -56
    ctx.path("c.json").write_text(json.dumps({"E": v}))
    return {}


def run_reader(ctx):
    COUNT["b"] = COUNT.get("b", 0) + 1
    e = json.loads((ctx.inputs["t_jit"] / "c.json").read_text())["E"]
    ctx.path("r.txt").write_text(f"{e:.6f}\n")
    return {}


@pytest.fixture
def jitter_project(tmp_path):
    registry.stages()
    register(Stage("t_jit", JParams, run_jitter, outputs=("c.json",)))
    register(Stage("t_read", JParams, run_reader, requires=("t_jit",), outputs=("r.txt",)))
    (tmp_path / "cells").mkdir()
    (tmp_path / "pipelines").mkdir()
    p = tmp_path / "pipelines" / "j.toml"
    p.write_text('[pipeline]\nname = "j"\nstages = ["t_jit", "t_read"]\n')
    COUNT.clear()
    COUNT["a"] = 0
    yield p
    registry._REGISTRY.pop("t_jit")
    registry._REGISTRY.pop("t_read")


def test_last_bit_change_upstream_does_not_rerun_downstream(jitter_project):
    pl = load_pipeline(jitter_project)
    run_pipeline(pl)
    first = (jitter_project.parents[1] / "outputs/j/t_jit/c.json").read_bytes()
    out = run_pipeline(pl, only="t_jit", force=True)
    assert (jitter_project.parents[1] / "outputs/j/t_jit/c.json").read_bytes() != first  # the bit moved
    out = run_pipeline(pl)
    assert [o.status for o in out] == ["cached", "cached"] and COUNT["b"] == 1


def test_canonical_hash_rounds_to_the_documented_digits(tmp_path):
    from metasheet.pipeline.manifest import SIGNIFICANT_DIGITS, canonical_sha256

    a, b, c = tmp_path / "a.json", tmp_path / "b.json", tmp_path / "c.json"
    a.write_text(json.dumps({"x": [0.1, -0.0], "y": 1}))
    b.write_text(json.dumps({"y": 1, "x": [0.1 + 2.0 ** -56, 0.0]}, indent=2))
    c.write_text(json.dumps({"x": [0.1 * (1 + 10.0 ** -(SIGNIFICANT_DIGITS - 2)), 0.0], "y": 1}))
    assert canonical_sha256(a) == canonical_sha256(b)
    assert canonical_sha256(a) != canonical_sha256(c)
