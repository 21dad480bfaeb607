"""The pipeline-file reference: every key of ``[pipeline]`` and of every stage's table.

One row per key (type, default, allowed values, description with its unit), written from the
same parameter models ``metasheet validate`` checks with, through their JSON schema
(:func:`.schema.pipeline_schema`), so the page cannot fall behind the code. The docs build
writes it to ``pipeline-keys.md`` (*Reference > Pipeline file keys*,
``docs/_scripts/gen_pipeline_reference.py``).
"""

from __future__ import annotations

from .registry import stages
from .schema import pipeline_schema
from .template import toml_value

TYPE_WORDS = {"number": "number", "integer": "integer", "string": "text", "boolean": "true / false",
              "array": "list", "object": "table", "null": "none"}


def _num(v) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def _bounds(p: dict) -> str:
    """``[0.3, 50]``, ``> 0``, ``<= 180``... from a schema node's numeric bounds ('' when none)."""
    lo = ("[", p["minimum"]) if "minimum" in p else ("(", p["exclusiveMinimum"]) if "exclusiveMinimum" in p else None
    hi = ("]", p["maximum"]) if "maximum" in p else (")", p["exclusiveMaximum"]) if "exclusiveMaximum" in p else None
    if lo and hi:
        return f"{lo[0]}{_num(lo[1])}, {_num(hi[1])}{hi[0]}"
    if lo:
        return f"{'>=' if lo[0] == '[' else '>'} {_num(lo[1])}"
    if hi:
        return f"{'<=' if hi[0] == ']' else '<'} {_num(hi[1])}"
    return ""


def _ref_name(p: dict) -> str:
    return p["$ref"].rsplit("/", 1)[1]


def describe(p: dict, defs: dict | None = None) -> tuple[str, str]:
    """(type, allowed values) of one schema node, in words; nested tables (``$ref`` to a model
    with properties) by their model name, other ``$ref`` (a named pair) as what they hold."""
    if "$ref" in p:
        name = _ref_name(p)
        target = (defs or {}).get(name, {"properties": {}})
        if "properties" not in target:
            return describe(target, defs)
        return f"table ([{name}](#{name.lower()}))", ""
    if "anyOf" in p:
        parts = [describe(q, defs) for q in p["anyOf"]]
        types = " or ".join(dict.fromkeys(t for t, _ in parts))
        allowed = "; ".join(a for _, a in parts if a)
        return types, allowed
    if "const" in p:
        return TYPE_WORDS.get(p.get("type", ""), "value"), f"`{toml_value(p['const'])}` only"
    if "enum" in p:
        return TYPE_WORDS.get(p.get("type", "string"), "text"), "one of " + ", ".join(
            f"`{toml_value(v)}`" for v in p["enum"])
    kind = p.get("type", "")
    if kind == "array":
        items = p.get("items") or (p.get("prefixItems") or [None])[0]
        item, allowed = describe(items, defs) if items else ("value", "")
        n = (p.get("minItems"), p.get("maxItems"))
        length = (f"{n[0]} items" if n[0] == n[1] and n[0] is not None else
                  f"{n[0] or 0} to {n[1]} items" if n[1] is not None else
                  f"at least {n[0]} item{'s' * (n[0] != 1)}" if n[0] else "")
        return f"list of {item}", "; ".join(x for x in (length, f"each {allowed}" if allowed else "") if x)
    if kind == "object":
        value = p.get("additionalProperties")
        inner = describe(value, defs)[0] if isinstance(value, dict) else "values"
        return f"table of {inner}", ""
    return TYPE_WORDS.get(kind, kind or "value"), _bounds(p)


def _cell(text: str) -> str:
    return str(text).replace("``", "`").replace("|", "\\|").replace("\n", " ")


def _table(model: dict, defs: dict) -> list[str]:
    """The rows of one table: key, type, default, allowed, description."""
    rows = ["| key | type | default | allowed | description |", "|---|---|---|---|---|"]
    required = set(model.get("required", ()))
    for key, p in model.get("properties", {}).items():
        kind, allowed = describe(p, defs)
        if key in required:
            default = "required"
        elif "default" in p:
            default = "none" if p["default"] is None else f"`{toml_value(p['default'])}`"
        else:
            default = ""
        rows.append(f"| `{key}` | {_cell(kind)} | {_cell(default)} | {_cell(allowed)} | "
                    f"{_cell(p.get('description', ''))} |")
    return rows


def _nested(model: dict, defs: dict) -> list[str]:
    """The names of the tables (models with properties) ``model``'s keys hold."""
    return [name for p in model.get("properties", {}).values() for q in [p, *p.get("anyOf", ())]
            if "$ref" in q and "properties" in defs.get(name := _ref_name(q), {})]


def pipeline_reference() -> str:
    """The reference page (Markdown): an intro, then ``[pipeline]``, each stage's table in the
    registry's order, and the tables nested in them."""
    schema = pipeline_schema()
    defs = schema["$defs"]
    registry = stages()
    tables = list(schema["properties"])
    lines = ["# Pipeline file keys", "",
             "Every key a pipeline file can set, table by table, generated from the parameter models that "
             "`metasheet validate` checks with. A key left out takes its default; *none* means the stage "
             "chooses (the description says how). Units are in square brackets. `metasheet init` writes a "
             "file with every key of the stages you name, and `metasheet schema` the JSON schema editors "
             "complete and check against ([Command line](cli.md)); "
             "[The pipeline file](concepts/pipeline-file.md) explains the layout.", "",
             "Tables: " + ", ".join(f"[`[{t}]`](#{t})" for t in tables), ""]
    nested: list[str] = []
    for table in tables:
        model = defs[_ref_name(schema["properties"][table])]
        lines += [f"## [{table}] {{#{table}}}", ""]
        if table in registry:
            s = registry[table]
            needs = ", ".join(f"`{r}`" for r in s.requires) or "no other stage"
            also = f" (and reads {', '.join(f'`{r}`' for r in s.optional)} when in the pipeline)" if s.optional else ""
            lines += [f"{s.doc.rstrip('.')}. Needs {needs}{also}; writes "
                      + ", ".join(f"`{o}`" for o in s.outputs) + ".", ""]
        if model.get("description"):
            lines += [_cell(model["description"].strip().split("\n\n")[0]), ""]
        lines += _table(model, defs) + [""]
        nested += _nested(model, defs)
    seen: set[str] = set()
    while nested:
        name = nested.pop(0)
        if name in seen:
            continue
        seen.add(name)
        model = defs[name]
        lines += [f"## {name} {{#{name.lower()}}}", "", "A table inside a stage's table (TOML: an inline "
                  "table `{ key = value }` or a `[stage.key]` section)."]
        if model.get("description"):
            lines += ["", _cell(model["description"].strip().split("\n\n")[0])]
        lines += [""] + _table(model, defs) + [""]
        nested += _nested(model, defs)
    return "\n".join(lines)
