"""A damaged manifest is never trusted. Before: with ``robot/manifest.json`` truncated,
``metasheet diff`` said the trees were the same, and ``robot goto`` after an edit of the
pipeline answered from the stale outputs (an unreadable manifest skipped the staleness check)."""

import shutil

import pytest
from pipeline_files import material_pipeline

from metasheet.errors import ConfigError
from metasheet.pipeline import manifest as mf
from metasheet.pipeline.outputs_diff import compare_trees
from metasheet.pipeline.runner import run_pipeline
from metasheet.pipeline.staleness import stale_stages
from metasheet.serve.loading import check_fresh


def pipeline(tmp_path, E_t: float = 1.0):
    return material_pipeline(tmp_path, E_t)


@pytest.fixture
def run(tmp_path):
    out = tmp_path / "outputs"
    run_pipeline(pipeline(tmp_path), out_root=out)
    return out / "q"


@pytest.mark.parametrize("damaged", ["truncated", "not an object", "no key", "binary"])
def test_a_damaged_manifest_is_stale_and_named(tmp_path, run, damaged):
    path = run / "material" / mf.MANIFEST
    text = path.read_text()
    path.write_bytes({"truncated": text[: len(text) // 2].encode(), "not an object": b"[1, 2]",
                      "no key": b'{"outputs": {}}', "binary": b"\xff\xfe\x00garbage"}[damaged])
    if damaged == "no key":  # readable: stale by its key, as an edited pipeline's
        assert mf.damage(run / "material") is None
    else:
        assert mf.damage(run / "material").startswith(str(path))
    assert stale_stages(pipeline(tmp_path), run) == ("material",)
    with pytest.raises(ConfigError, match="manifest damaged"):
        check_fresh(pipeline(tmp_path), run, "metasheet run q.toml")


def test_sound_and_absent_manifests_are_not_damaged(tmp_path, run):
    assert mf.damage(run / "material") is None
    assert mf.damage(tmp_path) is None  # no manifest: outputs written by hand are not judged
    assert stale_stages(pipeline(tmp_path), run) == ()


def test_diff_reports_a_damaged_manifest(tmp_path, run):
    copy = tmp_path / "copy"
    shutil.copytree(run, copy)
    assert all(d.within for d in compare_trees(run, copy))
    path = copy / "material" / mf.MANIFEST
    path.write_text(path.read_text()[:50])
    rows = compare_trees(run, copy)
    bad = [d for d in rows if not d.within]
    assert [d.path for d in bad] == ["material/manifest.json"]
    assert "damaged manifest in b" in bad[0].note


def test_a_run_recomputes_a_stage_whose_manifest_is_damaged(tmp_path, run):
    path = run / "material" / mf.MANIFEST
    good = path.read_bytes()
    path.write_text("{")
    said = []
    run_pipeline(pipeline(tmp_path), out_root=run.parent, overwrite=True, report=lambda s, m: said.append(m))
    assert "running" in said
    assert mf.damage(run / "material") is None
    assert path.read_bytes() != b"{" and len(path.read_bytes()) > 0.5 * len(good)
