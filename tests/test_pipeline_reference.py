"""The pipeline-file reference page lists every key of every table, with what the models say.

It is generated from the parameter models (:mod:`metasheet.pipeline.reference`); these tests
read the page back against the models, so a key added without a description, or a page that
drops a table, fails here and not in a user's editor.
"""

import re
from pathlib import Path

import pytest
import yaml

from metasheet.pipeline.config import PipelineSection
from metasheet.pipeline.reference import describe, pipeline_reference
from metasheet.pipeline.registry import stages

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def page() -> str:
    return pipeline_reference()


def sections(page: str) -> dict[str, list[str]]:
    """Each ``## `` section's table rows, by heading."""
    found, heading = {}, None
    for line in page.splitlines():
        if line.startswith("## "):
            heading = line[3:].split(" {#")[0]
            found[heading] = []
        elif heading and line.startswith("| `"):
            found[heading].append(line)
    return found


def row_of(rows: list[str], key: str) -> list[str]:
    match = [r for r in rows if r.startswith(f"| `{key}` |")]
    assert len(match) == 1, key
    return [c.strip() for c in re.split(r"(?<!\\)\|", match[0])[1:-1]]


def test_every_key_of_every_table_has_a_described_row(page):
    tables = {"pipeline": PipelineSection, **{n: s.params for n, s in stages().items()}}
    got = sections(page)
    for table, model in tables.items():
        rows = got[f"[{table}]"]
        assert len(rows) == len(model.model_fields), table
        for key, field in model.model_fields.items():
            cells = row_of(rows, key)
            assert field.description and cells[4], f"[{table}] {key}: no description"
    for name in [h for h in got if not h.startswith("[")]:  # the nested tables are listed too
        assert got[name], name


def test_rows_say_the_type_default_and_range_of_the_model(page):
    got = sections(page)
    assert row_of(got["[pipeline]"], "workers")[1:4] == ["integer", "`1`", "[1, 256]"]
    assert row_of(got["[pipeline]"], "name")[2] == "required"
    assert row_of(got["[material]"], "E_t")[1:4] == ["number", "`1.39`", "[1e-06, 2e+06]"]
    kind = row_of(got["[material]"], "kind")
    assert kind[3] == 'one of `"transverse"`, `"isotropic"`'
    seed = row_of(got["[cell]"], "seed")
    assert seed[1:4] == ["integer or none", "none", ">= 0"]


@pytest.mark.parametrize(("node", "expected"), [
    ({"type": "number", "exclusiveMinimum": 0, "maximum": 1000}, ("number", "(0, 1000]")),
    ({"type": "number", "exclusiveMaximum": 1}, ("number", "< 1")),
    ({"type": "array", "items": {"type": "number"}, "minItems": 2, "maxItems": 2}, ("list of number", "2 items")),
    ({"type": "array", "items": {"type": "integer", "minimum": 1}}, ("list of integer", "each >= 1")),
    ({"anyOf": [{"type": "integer", "minimum": 16, "maximum": 128}, {"type": "null"}]},
     ("integer or none", "[16, 128]")),
    ({"type": "string", "const": "p1"}, ("text", '`"p1"` only')),
    ({"$ref": "#/$defs/ColumnParams"}, ("table ([ColumnParams](#columnparams))", "")),
])
def test_a_schema_node_in_words(node, expected):
    assert describe(node) == expected


def test_the_docs_build_writes_the_page_and_lists_it():
    conf = (ROOT / "mkdocs.yml").read_text()
    assert "docs/_scripts/gen_pipeline_reference.py" in conf
    nav = yaml.safe_load(conf.split("\nnav:", 1)[1].join(["nav:", ""]))["nav"]
    reference = next(item["Reference"] for item in nav if isinstance(item, dict) and "Reference" in item)
    assert {"Pipeline file keys": "pipeline-keys.md"} in reference
