"""The Python API at the top level (:mod:`metasheet.api`): a pipeline from a mapping validated
as a file is, ``metasheet.run`` with overrides and caching, and the typed readers against the
JSON files they read."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import metasheet
from metasheet.errors import ConfigError, OutputError

ROOT = Path(__file__).resolve().parents[1]

MATERIAL = {"pipeline": {"name": "q", "stages": ["material"]}, "material": {"source": "config", "E_t": 1.0}}


def test_import_metasheet_stays_light():
    code = "import sys, metasheet; print('metasheet.api' in sys.modules, 'metasheet.pipeline' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert out.stdout.split() == ["False", "False"], out.stderr
    assert metasheet.run.__module__ == "metasheet.api" and "read_constants" in dir(metasheet)
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        metasheet.nope  # noqa: B018


def test_a_mapping_is_validated_as_a_file_is(tmp_path):
    (tmp_path / "pipelines").mkdir()
    toml = tmp_path / "pipelines" / "q.toml"
    toml.write_text('[pipeline]\nname = "q"\nstages = ["material"]\n[material]\nsource = "config"\nE_t = 1.0\n')
    from_file, from_dict = metasheet.load_pipeline(toml), metasheet.load_pipeline(MATERIAL, root=tmp_path)
    assert from_dict.params == from_file.params and from_dict.order == from_file.order
    assert from_dict.root == tmp_path.resolve()
    with pytest.raises(ConfigError, match=r"^<dict>: material\.E_t: '1': "):
        metasheet.load_pipeline({**MATERIAL, "material": {"E_t": "1"}})  # strict: no string to number
    with pytest.raises(ConfigError, match=r"^<dict>: material: 3: must be a table"):
        metasheet.load_pipeline({**MATERIAL, "material": 3})
    overridden = metasheet.load_pipeline(MATERIAL, ["material.E_t=2.5"])
    assert overridden.params["material"].E_t == 2.5


def test_run_caches_reruns_on_an_override_and_names_its_stages(tmp_path):
    (tmp_path / "cells").mkdir()
    seen = []
    first = metasheet.run(metasheet.load_pipeline(MATERIAL, root=tmp_path), out=tmp_path / "out",
                          progress=lambda stage, text: seen.append((stage, text)))
    assert first.folder == tmp_path / "out" / "q" and [s.status for s in first.stages] == ["ran"]
    assert ("material", "running") in seen
    data = json.loads((first.stage("material") / "material.json").read_text())
    assert data["constants"]["E_t"] == 1.0
    again = metasheet.run(MATERIAL, out=tmp_path / "out")
    assert [s.status for s in again.stages] == ["cached"]
    changed = metasheet.run(MATERIAL, out=tmp_path / "out", overrides=["material.E_t=2.0"], workers=1)
    assert [s.status for s in changed.stages] == ["ran"]
    assert json.loads((changed.stage("material") / "material.json").read_text())["constants"]["E_t"] == 2.0
    with pytest.raises(ConfigError, match="stage 'robot': not in pipeline 'q'"):
        changed.stage("robot")
    with pytest.raises(ConfigError, match="workers: 0: allowed 1 to 256"):
        metasheet.run(MATERIAL, out=tmp_path / "out", workers=0)


def test_read_constants_reads_what_homogenize_wrote(quick_outputs):
    run = quick_outputs / "quick"
    raw = json.loads((run / "homogenize" / "constants.json").read_text())
    for folder in (run, run / "homogenize"):  # the run's folder or the stage's
        c = metasheet.read_constants(folder)
        assert c.to_dict() == {k: raw[k] for k in ("E_t", "E_l", "nu_t", "nu_tl", "mu_l")}
        assert c.C.shape == (6, 6) and np.array_equal(c.C, np.asarray(raw["C"]))
        assert np.allclose(c.C, c.C.T, rtol=0, atol=1e-9 * np.abs(c.C).max())
        assert c.relative_density == raw["relative_density"] and np.linalg.norm(c.axis) == pytest.approx(1.0)


def jacobian_file(folder: Path) -> Path:
    """A ``robot/jacobian.json`` of two cases, written as the robot stage writes it."""
    J = np.arange(36.0).reshape(6, 6) / 7.0
    case = {"J_mm_per_rad_and_rad_per_rad": J.tolist(), "singular_values": [6.0, 5, 4, 3, 2, 1],
            "singular_values_length_scale_mm": 50.0, "rod_rotation_deg_per_deg": -2.5}
    path = folder / "robot" / "jacobian.json"
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({"materials": {"foam": case, "published": {**case, "rod_rotation_deg_per_deg": -1.5}}}))
    return path


def test_read_jacobian_picks_a_case_and_names_the_others(tmp_path):
    jacobian_file(tmp_path)
    j = metasheet.read_jacobian(tmp_path)
    assert j.material == "foam" and j.J.shape == (6, 6) and j.J[1, 0] == 6.0 / 7.0
    assert j.singular_values.tolist() == [6.0, 5, 4, 3, 2, 1] and j.length_scale_mm == 50.0
    assert metasheet.read_jacobian(tmp_path / "robot", "published").rod_rotation_deg_per_deg == -1.5
    with pytest.raises(ConfigError, match=r"material: 'silicone': not a case of .*\(its cases: foam, published\)"):
        metasheet.read_jacobian(tmp_path, "silicone")


def test_read_study_gives_a_columns_summary(tmp_path):
    columns = {"prediction": {"column": "prediction", "reachable": 3}, "reproduction": {"column": "reproduction",
                                                                                         "reachable": 9}}
    (tmp_path / "workspace").mkdir()
    (tmp_path / "workspace" / "manifest.json").write_text(json.dumps(
        {"summary": {**columns["prediction"], "columns": columns}}))
    assert metasheet.read_study(tmp_path, "workspace", "reproduction")["reachable"] == 9
    assert metasheet.read_study(tmp_path / "workspace", "workspace")["reachable"] == 3
    with pytest.raises(ConfigError, match=r"column: 'other': not a column of stage workspace \(its columns: "
                                          r"prediction, reproduction\)"):
        metasheet.read_study(tmp_path, "workspace", "other")


def test_missing_or_damaged_outputs_are_named(tmp_path):
    with pytest.raises(OutputError, match=r"no robot outputs \(robot/jacobian.json\): run the pipeline's robot stage"):
        metasheet.read_jacobian(tmp_path)
    (tmp_path / "homogenize").mkdir()
    (tmp_path / "homogenize" / "constants.json").write_text("{trunc")
    with pytest.raises(OutputError, match="constants.json: not a readable JSON file"):
        metasheet.read_constants(tmp_path)


def test_write_file_is_atomic_and_makes_its_folder(tmp_path):
    path = metasheet.write_file(tmp_path / "a" / "b.png", b"\x89PNG")
    assert path.read_bytes() == b"\x89PNG" and sorted(p.name for p in path.parent.iterdir()) == ["b.png"]
