"""``--set TABLE.KEY=VALUE`` on ``run`` and ``validate``: values of the file, with its checks."""

import json

import pytest
from pipeline_files import material_pipeline, run_cli

from metasheet.errors import ConfigError
from metasheet.pipeline.config import load_pipeline
from metasheet.pipeline.overrides import apply_overrides, parse_value


def test_values_are_toml_and_bare_words_are_strings():
    assert parse_value("8") == 8 and parse_value("2.5") == 2.5 and parse_value("true") is True
    assert parse_value('"8"') == "8" and parse_value("p1") == "p1" and parse_value("[1, 2]") == [1, 2]
    assert parse_value("{ E_t = 1.0 }") == {"E_t": 1.0}
    with pytest.raises(ConfigError, match="not a TOML value"):
        parse_value("[1")


def test_overrides_set_nested_keys_without_changing_the_file_data():
    data = {"pipeline": {"name": "p"}, "orient": {"mesh_size": 10.0}}
    out = apply_overrides(data, ["orient.mesh_size=8", "orient.constants.E_t=2.0", "material.source=config"])
    assert out["orient"] == {"mesh_size": 8, "constants": {"E_t": 2.0}} and out["material"] == {"source": "config"}
    assert data["orient"] == {"mesh_size": 10.0}
    for bad, why in (("orient=3", "expected TABLE.KEY=VALUE"), ("orient.mesh_size.x=1", "is a value, not a table")):
        with pytest.raises(ConfigError, match=why):
            apply_overrides(data, [bad])


def test_an_override_is_checked_as_the_file_is(tmp_path):
    material_pipeline(tmp_path)
    f = tmp_path / "pipelines" / "q.toml"
    assert load_pipeline(f, ["material.E_t=2.5"]).params["material"].E_t == 2.5
    with pytest.raises(ConfigError, match=r"q\.toml: material\.E_t: '2\.5': expected a number"):
        load_pipeline(f, ['material.E_t="2.5"'])


def test_run_with_set_writes_the_overridden_value(tmp_path):
    material_pipeline(tmp_path)
    assert run_cli("run", str(tmp_path / "pipelines" / "q.toml"), "--set", "material.E_t=3.5",
                   "--out", str(tmp_path / "out")) == 0
    assert json.loads((tmp_path / "out" / "q" / "material" / "material.json").read_text())["constants"]["E_t"] == 3.5
