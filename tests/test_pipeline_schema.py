"""``metasheet schema``: the JSON schema of a pipeline file, from the parameter models."""

import json
import tomllib
from pathlib import Path

import pytest
from pipeline_files import run_cli

from metasheet.pipeline.registry import stages
from metasheet.pipeline.schema import pipeline_schema

ROOT = Path(__file__).resolve().parents[1]
PIPELINES = sorted((ROOT / "pipelines").glob("*.toml"))


def resolve(schema: dict, node: dict) -> dict:
    return schema["$defs"][node["$ref"].rsplit("/", 1)[1]] if "$ref" in node else node


def test_every_table_and_every_key_of_the_shipped_pipelines_is_in_the_schema():
    schema = pipeline_schema()
    assert set(schema["properties"]) == {"pipeline", *stages()}
    assert schema["additionalProperties"] is False
    for f in PIPELINES:
        for table, keys in tomllib.loads(f.read_text()).items():
            props = resolve(schema, schema["properties"][table])["properties"]
            assert set(keys) <= set(props), (f.name, table, set(keys) - set(props))


def test_a_range_and_a_description_reach_the_schema():
    schema = pipeline_schema()
    mesh = resolve(schema, schema["properties"]["orient"])["properties"]["mesh_size"]
    assert mesh["type"] == "number" and mesh["minimum"] == 0.3 and mesh["maximum"] == 50 and mesh["description"]


@pytest.mark.parametrize("path", PIPELINES, ids=[p.stem for p in PIPELINES])
def test_the_shipped_pipelines_validate_against_it(path):
    jsonschema = pytest.importorskip("jsonschema")
    jsonschema.validate(tomllib.loads(path.read_text()), pipeline_schema())


def test_the_cli_writes_it(tmp_path, capsys):
    assert run_cli("schema", "--out", str(tmp_path / "s.json")) == 0
    assert json.loads((tmp_path / "s.json").read_text()) == json.loads(json.dumps(pipeline_schema()))
