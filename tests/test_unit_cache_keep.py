"""Unit results kept across runs (metasheet.studies.resume): the reproduction column's units stay
after success, pruned to the run's, and a rerun whose stage key changed for the prediction only
reuses them; the key covers the code; --force recomputes."""

import os
from pathlib import Path

import pytest

from metasheet.runtime.executor import Executor
from metasheet.pipeline.config import load_pipeline
from metasheet.pipeline.runner import run_pipeline
from metasheet.studies import resume
from metasheet.studies.resume import UnitCache, keep_only_used, unit_key

from test_studies_stages import project, skip_pictures


def _square(x):
    return x * x


def test_keep_only_used_prunes_to_the_units_asked_for(tmp_path):
    d = tmp_path / "u"
    assert UnitCache(d).map(Executor(), _square, [1, 2, 3]) == [1, 4, 9]
    old = UnitCache(d)
    old.store(unit_key(7), 49)  # an earlier run's unit, not asked for in this process since
    (d / f".{unit_key(8)}.123.tmp").write_bytes(b"half")  # a killed writer's
    resume._USED.pop(d.resolve())  # a new run: nothing asked yet
    assert UnitCache(d).map(Executor(), _square, [2, 3]) == [4, 9]
    assert keep_only_used(d) == 2
    assert sorted(f.stem for f in d.iterdir()) == sorted(unit_key(x) for x in (2, 3))


def test_unit_keys_cover_the_code(monkeypatch):
    key = unit_key((1, "a"))
    assert unit_key((1, "a")) == key and unit_key((2, "a")) != key
    monkeypatch.setattr(resume, "code_digest", lambda: "another version of metasheet")
    assert unit_key((1, "a")) != key


TEXT = """[pipeline]
name = "keep"
stages = ["workspace"]
[workspace]
model = "standin"
columns = ["prediction", "reproduction"]
continuity = false
n_azimuth = {az}
n_elevation = {el}
n_steps = {n}
reproduction = {{ n_steps = {n0} }}
"""


def _text(n, small=False):
    """The stage for ``n`` steps a ray in the prediction: 4 x 2 rays of 4 steps in the
    reproduction, or ``small``: 3 x 1 rays of 2 steps (n - 2 in the prediction)."""
    if small:
        return TEXT.format(az=3, el=1, n=n - 2, n0=2)
    return TEXT.format(az=4, el=2, n=n, n0=4)


def _units(out):
    return {f.name: f.stat().st_mtime_ns for f in (out / ".workspace-reproduction.units").glob("*.pkl")}


@pytest.mark.slow
def test_a_rerun_for_the_prediction_reuses_the_reproduction_units(tmp_path):
    """Default-selection sibling: test_a_rerun_on_fewer_rays_reuses_the_reproduction_units."""
    _rerun_reuses(tmp_path, small=False)


def test_a_rerun_on_fewer_rays_reuses_the_reproduction_units(tmp_path, monkeypatch):
    """The slow test's three runs on 3 x 1 rays of 2 steps (the prediction 2, then 3), without
    the workspace pictures (six of them, each 3 x 3 matplotlib panels: nine tenths of this
    test's time; they are not read here, and test_studies_stages.py draws and checks them)."""
    calls = skip_pictures(monkeypatch, "workspace")
    _rerun_reuses(tmp_path, small=True)
    assert calls == ["workspace"] * 6  # both columns ran in each of the three runs


def _rerun_reuses(tmp_path, small):
    out = tmp_path / "outputs" / "keep"
    run_pipeline(load_pipeline(project(tmp_path, _text(4, small), "keep")))
    rep = (out / "workspace" / "reproduction" / "workspace.csv").read_bytes()
    pred = (out / "workspace" / "workspace.csv").read_bytes()
    kept = _units(out)
    assert len(kept) >= (3 if small else 8) and not (out / ".workspace.units").exists()  # the prediction's are removed
    # another prediction (more steps per ray), the reproduction pinned by its own table
    run_pipeline(load_pipeline(project(tmp_path, _text(5, small), "keep")))
    assert (out / "workspace" / "workspace.csv").read_bytes() != pred
    assert (out / "workspace" / "reproduction" / "workspace.csv").read_bytes() == rep
    assert _units(out) == kept  # every unit loaded, none computed or rewritten
    # --force computes them again: the same units, the same bytes
    run_pipeline(load_pipeline(project(tmp_path, _text(5, small), "keep")), force=True)
    again = _units(out)
    assert again.keys() == kept.keys() and all(again[k] != kept[k] for k in kept)
    assert (out / "workspace" / "reproduction" / "workspace.csv").read_bytes() == rep


def test_without_resume_nothing_is_kept(tmp_path, monkeypatch):
    skip_pictures(monkeypatch, "workspace")  # not read here (see above)
    text = _text(4, small=True).replace("continuity = false", "continuity = false\nresume = false")
    run_pipeline(load_pipeline(project(tmp_path, text, "keep")))
    assert not list((tmp_path / "outputs" / "keep").glob(".*.units"))


def test_the_code_digest_reads_the_whole_package():
    """The digest hashes every module of metasheet, not only its own folder (it lived at the
    package's root before runtime/ existed, and then hashed runtime/ alone)."""
    from metasheet.runtime import provenance

    names = {f.relative_to(provenance.PACKAGE).as_posix() for f in provenance.source_files()}
    assert {"__init__.py", "robot/body.py", "pipeline/manifest.py", "runtime/provenance.py",
            "dynamics/robot.py"} <= names
    assert provenance.PACKAGE.name == "metasheet"


def test_a_unit_holding_a_pydantic_model_has_one_key_in_every_process():
    """A pydantic model's own pickle holds a set whose order follows the string hash seed: the key
    must not (a resumed map in a new process finds its units)."""
    import subprocess
    import sys

    code = ("import tomllib; from metasheet.studies.resume import unit_key; "
            "from metasheet.studies.scale_map import foam_design; "
            "d = tomllib.loads(open('cells/paper_polyfoam.toml').read()); "
            "print(unit_key((foam_design(d, 15.0, 0.2, seed=1), 'normal')))")
    root = Path(__file__).resolve().parents[1]
    keys = {subprocess.run([sys.executable, "-c", code], cwd=root, env={**os.environ, "PYTHONHASHSEED": str(s)},
                           capture_output=True, text=True, check=True).stdout.strip() for s in (1, 2, 3)}
    assert len(keys) == 1 and len(keys.pop()) == 32
