"""``metasheet init``: a pipeline file to start from, written from the parameter models.

Every key of every stage it lists is there, commented out at its default, under its one-line
description (unit and allowed range included): uncomment a line to change it. The few values
a stage cannot default (the cell's design file) are set to the shipped quick ones, so the file
validates as written.
"""

from __future__ import annotations

from collections.abc import Sequence

from pydantic_core import PydanticUndefined

from ..design.outputs import toml_value as design_toml_value
from ..errors import ConfigError
from .config import resolve_order
from .registry import stages

#: Values written uncommented: those without a default, and those a combination of stages needs.
REQUIRED = {("cell", "design"): "cells/quick_foam.toml"}
#: The design stage's rest problem takes P1 sheets only (orient's default is P2).
WITH_DESIGN = {("orient", "element"): "p1"}
#: The printed sheet is modelled for Polyfoam cells (the print map's foam).
WITH_SHEET = {("cell", "design"): "cells/quick_polyfoam.toml"}


def toml_value(v) -> str:
    """``v`` (a parameter default: number, bool, string, list, table or a parameter model) as TOML."""
    return design_toml_value(v.model_dump(mode="json") if hasattr(v, "model_dump") else v)


def pipeline_template(name: str, stage_names: Sequence[str]) -> str:
    """The text of a pipeline file ``name`` with ``stage_names``, every key documented."""
    registry = stages()
    unknown = [s for s in stage_names if s not in registry]
    if unknown:
        raise ConfigError(f"--stages: {', '.join(unknown)}: unknown stage(s); known: {', '.join(registry)}")
    order = resolve_order([s for s in registry if s in stage_names], registry, "--stages")
    fixed = {**REQUIRED, **(WITH_DESIGN if "design" in order else {}), **(WITH_SHEET if "sheet" in order else {})}
    lines = [f"# A metasheet pipeline ({', '.join(order)}), written by `metasheet init`.",
             "# Every key is below at its default (# key = value), under its description (#: ...):",
             "# uncomment a key's line to change it. docs/cli.md has the commands.",
             "[pipeline]", f"name = {toml_value(name)}", "stages = [" + ", ".join(toml_value(s) for s in order) + "]",
             "workers = 2"]
    for stage in order:
        lines += ["", f"[{stage}]"]
        for key, field in registry[stage].params.model_fields.items():
            if field.description:
                lines.append(f"#: {field.description}")
            if (stage, key) in fixed:
                lines.append(f"{key} = {toml_value(fixed[stage, key])}")
                continue
            default = field.get_default(call_default_factory=True)
            lines.append(f"# {key} = (none)" if default is None or default is PydanticUndefined
                         else f"# {key} = {toml_value(default)}")
    return "\n".join(lines) + "\n"
