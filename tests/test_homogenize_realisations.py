"""The homogenize stage's realisations and cell-size study (issue 43), on the quick Polyfoam.

Checked against independent answers: the means and half-widths in constants.json are those
of the per-realisation rows recomputed here (numpy mean, Student t), realisation 0 is the
cell stage's own voxels (the single-realisation run's constants), the study's sizes are
built with the requested cell counts, a laminate refuses realisations, and two runs give the
same bytes.
"""

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from metasheet.errors import ConfigError, StageError
from metasheet.homogenize.realisations import check_design, realisation_items
from metasheet.mechanics.material import CONSTANT_NAMES
from metasheet.pipeline.config import load_pipeline
from metasheet.pipeline.runner import run_pipeline

ROOT = Path(__file__).resolve().parents[1]


def _run(tmp_path, name: str, homogenize: str, only: str | None = None, executor=None) -> Path:
    (tmp_path / "pipelines").mkdir(exist_ok=True)
    if not (tmp_path / "cells").exists():
        (tmp_path / "cells").symlink_to(ROOT / "cells")
    toml = tmp_path / "pipelines" / f"{name}.toml"
    toml.write_text(f'[pipeline]\nname = "{name}"\nstages = ["cell", "homogenize"]\n'
                    '[cell]\ndesign = "cells/quick_polyfoam.toml"\npicture = false\nsurface = false\n'
                    f'[homogenize]\nfields = false\n{homogenize}\n')
    run_pipeline(load_pipeline(toml), out_root=tmp_path / "out", only=only, force=only is not None,
                 **({"executor": executor} if executor else {}))
    return tmp_path / "out" / name / "homogenize"


SMALL = "realisations = 2\nsizes = [2]\nsize_realisations = 2\npicture = false"


@pytest.fixture(scope="module")
def small_study(tmp_path_factory):
    """The default selection's study: two realisations and two at the size study's 2 cells, no
    picture (the slow ``study`` below: three each, a picture and a second full run)."""
    tmp = tmp_path_factory.mktemp("small")
    one = _run(tmp, "one", "picture = false")
    # the same cell stage: its outputs copied, so "small" finds it cached (the cell key does
    # not hold the pipeline's name) and only its homogenize stage runs
    shutil.copytree(one.parent / "cell", tmp / "out" / "small" / "cell")
    ens = _run(tmp, "small", SMALL)
    assert json.loads((ens / "manifest.json").read_text())["inputs"] == \
        json.loads((one / "manifest.json").read_text())["inputs"]  # the same cell, cached
    return tmp, one, ens


def _check_means_and_intervals(one: Path, ens: Path, k: int) -> None:
    c = json.loads((ens / "constants.json").read_text())
    rows = json.loads((ens / "realisations.json").read_text())["rows"]
    own = [r for r in rows if r["n_cells"] == 4]
    seeds = list(range(1, k + 1))
    assert [r["seed"] for r in own] == seeds and c["ensemble"]["seeds"] == seeds
    single = json.loads((one / "constants.json").read_text())
    t = stats.t.ppf(0.975, k - 1)
    for name in CONSTANT_NAMES:
        v = np.array([r[name] for r in own])
        assert own[0][name] == single[name]  # realisation 0 is the cell stage's voxels
        assert c["ensemble"]["realisation_0"][name] == single[name]
        assert c[name] == pytest.approx(v.mean(), rel=1e-14)
        hw = t * v.std(ddof=1) / math.sqrt(k)
        assert c["ci95"]["halfwidth"][name] == pytest.approx(hw, rel=1e-12)
        assert c["ci95"]["rel_halfwidth"][name] == pytest.approx(hw / abs(v.mean()), rel=1e-12)
        assert c["ensemble"]["meets_target"][name] == (hw / abs(v.mean()) <= 0.05)
        assert c["ensemble"]["k_required"][name] >= 2
    assert len({r[CONSTANT_NAMES[1]] for r in own}) == k  # k different foams
    assert np.allclose(c["C"], np.mean([r["C"] for r in own], axis=0), rtol=1e-14, atol=0)
    assert c["ci95"]["k"] == k and c["ci95"]["n_cells"] == 4


def _check_size_study(ens: Path, k: int) -> None:
    conv = json.loads((ens / "convergence.json").read_text())
    rows = json.loads((ens / "realisations.json").read_text())["rows"]
    assert [s["n_cells"] for s in conv["sizes"]] == [2, 4]
    small = [r for r in rows if r["n_cells"] == 2]
    assert [r["seed"] for r in small] == list(range(1, k + 1))
    assert conv["sizes"][0]["constants"]["E_t"]["mean"] == pytest.approx(np.mean([r["E_t"] for r in small]), rel=1e-14)
    # a 2-cell Polyfoam has fewer unknowns than the 4-cell one at the same voxel edge
    assert max(r["n_dof"] for r in small) < min(r["n_dof"] for r in rows if r["n_cells"] == 4)
    assert set(conv["trend"]) == set(CONSTANT_NAMES) and set(conv["k_required_per_size"]) == {"2", "4"}


def test_small_study_means_intervals_and_sizes(small_study):
    """Default-selection sibling of the slow study tests below, on two realisations per size."""
    _, one, ens = small_study
    _check_means_and_intervals(one, ens, 2)
    _check_size_study(ens, 2)
    assert not (ens / "convergence.png").exists()  # picture = false


def test_small_study_same_bytes_when_homogenize_runs_again(small_study):
    """Default-selection sibling of test_same_bytes_on_a_second_run: the homogenize stage run
    again (forced) on the same cell, now on a pool of two workers (the cell's own solve one
    of the units, beside the realisations), writes the serial run's bytes."""
    from metasheet.runtime.executor import Executor

    tmp, _, ens = small_study
    names = ("constants.json", "realisations.json", "convergence.json")
    before = {name: (ens / name).read_bytes() for name in names}
    again = _run(tmp, "small", SMALL, only="homogenize", executor=Executor(workers=2))
    for name in names:
        assert (again / name).read_bytes() == before[name], name


def test_size_max_voxels_refused_on_an_existing_cell(small_study):
    """Default-selection sibling of test_size_max_voxels_reaches_the_study_only: the study's
    cells get the override and are refused by name (the cell stage's own cell already built).
    One realisation at the cell's own size (none to build again before the study's), two in the
    study."""
    tmp, one, _ = small_study
    with pytest.raises(StageError, match="homogenize.*max_voxels: 1000: the cell needs"):
        _run(tmp, "one", "realisations = 1\nsizes = [2]\nsize_realisations = 2\nsize_max_voxels = 1000\n"
             "picture = false", only="homogenize")
    assert (one.parent / "cell" / "voxels.npz").exists()


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("ens")
    one = _run(tmp, "one", "picture = false")
    ens = _run(tmp, "ens", "realisations = 3\nsizes = [2]\nsize_realisations = 3\npicture = true")
    again = _run(tmp, "again", "realisations = 3\nsizes = [2]\nsize_realisations = 3\npicture = true")
    return one, ens, again


@pytest.mark.slow
def test_means_and_intervals_are_those_of_the_realisations(study):
    """Default-selection sibling: test_small_study_means_intervals_and_sizes."""
    one, ens, _ = study
    _check_means_and_intervals(one, ens, 3)


@pytest.mark.slow
def test_size_study_writes_convergence_and_picture(study):
    """Default-selection sibling: test_small_study_means_intervals_and_sizes."""
    _, ens, _ = study
    _check_size_study(ens, 3)
    assert (ens / "convergence.png").stat().st_size > 10_000


@pytest.mark.slow
def test_same_bytes_on_a_second_run(study):
    """Default-selection sibling: test_small_study_same_bytes_when_homogenize_runs_again."""
    _, ens, again = study
    for name in ("constants.json", "realisations.json", "convergence.json"):
        assert (ens / name).read_bytes() == (again / name).read_bytes(), name


def test_refusals_name_the_field():
    with pytest.raises(ConfigError, match="homogenize.realisations.*deterministic"):
        check_design({"kind": "laminate"}, realisations=2, sizes=[])
    with pytest.raises(ConfigError, match="homogenize.sizes.*polyfoam"):
        check_design({"kind": "foam", "seeds": {}}, realisations=2, sizes=[8])
    from metasheet.pipeline.stages.homogenize import HomogenizeParams

    with pytest.raises(ValueError, match="sizes"):
        HomogenizeParams(sizes=[2, 2], realisations=3)
    with pytest.raises(ValueError, match="realisations >= 2"):
        HomogenizeParams(sizes=[2])
    with pytest.raises(ValueError, match="voxel route only"):
        HomogenizeParams(realisations=2, mesh_route=True)


def test_items_override_count_and_seed_only():
    design = {"kind": "polyfoam", "name": "x", "seeds": {"sampler": "poisson", "count": 8, "seed": 1}}
    items = realisation_items(design, 27, [5, 6], solver="auto", rtol=1e-8)
    assert [it["design"]["seeds"] for it in items] == [{"sampler": "poisson", "count": 27, "seed": 5},
                                                      {"sampler": "poisson", "count": 27, "seed": 6}]
    assert design["seeds"]["count"] == 8  # the caller's design is untouched


@pytest.mark.slow
def test_size_max_voxels_reaches_the_study_only(tmp_path):
    """Default-selection sibling: test_size_max_voxels_refused_on_an_existing_cell."""
    # the study's cells get the override (here a limit below their grids: refused by name);
    # the cell stage's own cell keeps the design's limit and is built
    with pytest.raises(StageError, match="homogenize.*max_voxels: 1000: the cell needs"):
        _run(tmp_path, "small", "realisations = 2\nsizes = [2]\nsize_max_voxels = 1000\npicture = false")
    assert (tmp_path / "out" / "small" / "cell" / "voxels.npz").exists()
