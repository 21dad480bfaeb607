"""``metasheet diff``: identical files, numbers within a tolerance, structure changes, missing files."""

import json
import subprocess
import sys

import numpy as np
import pytest

from metasheet.pipeline.outputs_diff import compare_trees


def _tree(root, scale=1.0, extra=None):
    (root / "s").mkdir(parents=True)
    data = {"E_t": 1.39 * scale, "C": [[1.0 * scale, 2.0], [3.0, 4.0]], "name": "foam", "timings_s": {"x": scale}}
    (root / "s" / "a.json").write_text(json.dumps(data))
    np.savez(root / "s" / "v.npz", u=np.arange(4.0) * scale)
    (root / "s" / "t.csv").write_text(f"x,y\n1,{2 * scale!r}\n3,4\n")
    (root / "s" / "pic.png").write_bytes(b"\x89PNG" + bytes([int(scale)]))
    (root / "s" / "manifest.json").write_text(json.dumps({"wall": scale}))
    if extra:
        (root / "s" / extra).write_text("1")
    return root


def test_identical_trees_and_relative_differences(tmp_path):
    a = _tree(tmp_path / "a")
    same = {d.path: d for d in compare_trees(a, _tree(tmp_path / "b"))}
    assert {d.status for d in same.values()} == {"identical"}
    assert "s/manifest.json" not in same  # manifests carry timings: skipped
    near = {d.path: d for d in compare_trees(a, _tree(tmp_path / "c", scale=1.0 + 1e-13))}
    # E_t moved by 1e-13 relative; C[0][0] by 1e-13 of the largest |C| = 4 -> 2.5e-14
    assert near["s/a.json"].status == "numbers" and np.isclose(near["s/a.json"].max_rel, 1e-13, rtol=1e-2)
    assert np.isclose(near["s/v.npz"].max_rel, 1e-13, rtol=1e-2)
    assert near["s/t.csv"].status == "numbers" and near["s/t.csv"].max_rel > 0
    assert near["s/pic.png"].status == "identical"  # int(1 + 1e-13) == 1


def test_structure_changes_and_missing_files(tmp_path):
    a = _tree(tmp_path / "a")
    b = _tree(tmp_path / "b", scale=2.0, extra="new.txt")
    (b / "s" / "a.json").write_text(json.dumps({"E_t": 1.39, "other": 1.0}))
    out = {d.path: d for d in compare_trees(a, b)}
    assert out["s/a.json"].status == "different" and "structure" in out["s/a.json"].note
    assert out["s/pic.png"].status == "different"
    assert out["s/new.txt"].status == "missing in a"
    assert out["s/v.npz"].max_rel == 0.5  # max |u - 2u| / max |2u| = 3 / 6


def test_cli_exit_status(tmp_path):
    a, b = _tree(tmp_path / "a"), _tree(tmp_path / "b", scale=1.0 + 1e-6)
    run = [sys.executable, "-m", "metasheet.cli", "diff", str(a), str(b)]
    assert subprocess.run(run, capture_output=True, text=True).returncode == 1
    ok = subprocess.run(run + ["--rtol", "1e-5"], capture_output=True, text=True)
    assert ok.returncode == 0, ok.stdout + ok.stderr
    bad = subprocess.run([sys.executable, "-m", "metasheet.cli", "diff", str(a), str(tmp_path / "nope")],
                         capture_output=True, text=True)
    assert bad.returncode == 2 and "not a directory" in bad.stderr


def test_equal_infinities_are_equal_and_nan_against_a_number_is_not():
    """Before: ``inf - inf`` is NaN, so two files holding the same ``inf`` (a JSON ``Infinity``)
    differed by an infinite amount, with a RuntimeWarning printed."""
    import warnings

    import numpy as np

    from metasheet.pipeline.outputs_diff import _gap

    inf, nan = np.inf, np.nan
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert _gap(np.array([1.0, inf, -inf, nan]), np.array([1.0, inf, -inf, nan])).diff == 0.0
        assert _gap(np.array([1.0, inf]), np.array([1.0, -inf])).diff == inf
        assert _gap(np.array([1.0, nan]), np.array([1.0, 2.0])).diff == inf
        assert _gap(np.array([1.0, 2.0]), np.array([1.5, 2.0])).diff == 0.5
        gap = _gap(np.array([2.0, inf]), np.array([3.0, inf]))
        assert gap.scale == 3.0 and gap.rel == pytest.approx(1 / 3) and not gap.within(0.1, 0.0)
