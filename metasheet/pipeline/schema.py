"""The JSON schema of a pipeline file (``metasheet schema``), from the parameter models.

Editors that read JSON schemas (VS Code's Even Better TOML, taplo, PyCharm) complete the keys
of a pipeline file and flag a wrong type or an out-of-range value as it is typed: the same
models ``metasheet validate`` checks with (the checks across fields and files are the
validator's alone).
"""

from __future__ import annotations

from pydantic.json_schema import models_json_schema

from .config import PipelineSection
from .registry import stages

SCHEMA_DIALECT = "https://json-schema.org/draft/2020-12/schema"


def pipeline_schema() -> dict:
    """The schema: ``[pipeline]`` and one table per registered stage, no other table."""
    tables = {"pipeline": PipelineSection, **{name: s.params for name, s in stages().items()}}
    refs, defs = models_json_schema([(m, "validation") for m in dict.fromkeys(tables.values())],
                                    ref_template="#/$defs/{model}")
    return {
        "$schema": SCHEMA_DIALECT,
        "title": "metasheet pipeline file",
        "description": "A [pipeline] table (name, stages) and one table per stage it lists; docs/cli.md#schema.",
        "type": "object",
        "properties": {name: refs[(model, "validation")] for name, model in tables.items()},
        "required": ["pipeline"],
        "additionalProperties": False,
        "$defs": defs["$defs"],
    }
