"""Pipeline files: TOML, validated with pydantic, errors as ``file: field: value: what is allowed``.

A pipeline file has one ``[pipeline]`` table and one table per stage::

    [pipeline]
    name = "quick"                       # outputs go to outputs/<name>/
    stages = ["material", "orient"]      # which stages run (order is resolved from their inputs)

    [material]
    E_t = 1.39                           # [MPa]

A stage listed without a table runs with its defaults. A parameter naming a project file
(its description says "relative to the project root": ``cell.design``, ``chart.design``)
must name an existing file: loading the pipeline (``metasheet validate`` too) checks it.
Loading also refuses nan and inf in any number, the checks across a table's fields (the five
constants' stability, a sheet's geometry) and across tables (a sheet too large to mesh, or to
build its robot on: :data:`metasheet.pipeline.stages.orient.MAX_SHEET_TETS`).
"""

from __future__ import annotations

import json
import re
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import UnionType
from typing import Annotated, Any, Union, get_args, get_origin, get_type_hints

from pydantic import BaseModel, Field, ValidationError, field_validator

from ..errors import TYPE_WORDS, ConfigError
from .overrides import apply_overrides
from .registry import Params, Stage, stages


#: A run name is one folder under outputs/ that ``metasheet clean --all`` deletes: no separator, no
#: "." or ".." (the outputs root or its parent), no hidden name, no trailing dot (Windows drops it).
NAME_MAX = 64
_NAME = re.compile(rf"[A-Za-z0-9_-]([A-Za-z0-9_.-]{{0,{NAME_MAX - 2}}}[A-Za-z0-9_-])?")
#: Device names Windows reserves, with any extension (``nul.txt`` too): such a folder cannot be made there.
_WINDOWS_RESERVED = re.compile(r"(con|prn|aux|nul|com[1-9]|lpt[1-9])(\..*)?", re.IGNORECASE)


#: Most local worker processes a run takes (the file's ``workers`` and ``--workers``).
MAX_WORKERS = 256


class PipelineSection(Params):
    """The ``[pipeline]`` table: the run's name, its stages, and the processes they run on."""

    name: str = Field(description="run name: outputs/<name>/, one folder name (letters, digits, _ - .; not "
                      f"starting or ending with '.'; at most {NAME_MAX} characters)")
    stages: list[str] = Field(min_length=1, description="stages to run")
    description: str = Field("", description="free text about the run (not used by any stage)")
    workers: int = Field(1, ge=1, le=MAX_WORKERS, description="local worker processes for sweeps")
    scheduler: str | None = Field(None, description="dask.distributed scheduler address")
    stages_at_once: int = Field(1, ge=1, le=16, description="stages whose inputs are ready that run at once "
                                "(each in a thread of the run, its work units on the workers); 1: one after another")

    @field_validator("name")
    @classmethod
    def _one_folder(cls, name: str) -> str:
        return check_run_name(name)


def check_run_name(name: str) -> str:
    """``name`` when it is a run name (one folder under the output root), else ValueError saying why."""
    if not _NAME.fullmatch(name):
        raise ValueError(f"expected one folder name: letters, digits, '_', '-' and '.', not starting or ending "
                         f"with '.', 1 to {NAME_MAX} characters")
    if _WINDOWS_RESERVED.fullmatch(name):
        raise ValueError("a device name reserved on Windows (CON, PRN, AUX, NUL, COM1-9, LPT1-9)")
    return name


@dataclass(frozen=True)
class Pipeline:
    """A validated pipeline: its file, name, stages (dependency order) and their parameters."""

    path: Path
    root: Path
    section: PipelineSection
    order: tuple[str, ...]
    params: dict[str, Params]

    @property
    def name(self) -> str:
        return self.section.name


def find_root(path: Path) -> Path:
    """The project directory of a pipeline file: the nearest ancestor holding ``cells/``."""
    for parent in path.resolve().parents:
        if (parent / "cells").is_dir():
            return parent
    return path.resolve().parent


def format_validation(source: str, table: str, err: ValidationError, data: dict,
                      model: type[BaseModel] | None = None) -> str:
    """One ``file: field: value: what is allowed`` line per pydantic error.

    A range or finiteness error adds the field's whole ``allowed range`` (from ``model``); a
    model validator's :class:`ConfigError` ``"field: value: what"`` is prefixed with the file,
    the table and the path of the model that raised it.
    """
    lines = []
    for e in err.errors():
        loc, bounds = locate(model, e["loc"]) if model else (".".join(str(p) for p in e["loc"]), [])
        field = f"{table}.{loc}" if loc else table
        value = e.get("input", data)
        cause = (e.get("ctx") or {}).get("error")
        if isinstance(cause, ConfigError):
            lines.append(f"{source}: {field}.{cause}")
            continue
        if e["type"] == "extra_forbidden":
            msg = "unknown key"
        elif e["type"] == "missing":
            msg, value = "required key is missing", "<missing>"
        elif e["type"] == "value_error" and cause is not None:
            msg = str(cause)  # the validator's own words, without pydantic's "Value error, "
        else:
            msg = TYPE_WORDS.get(e["type"], e["msg"])
            if (e["type"] in _RANGE_ERRORS or e["type"] in TYPE_WORDS) and range_text(bounds):
                msg += f"; allowed range is {range_text(bounds)}"
        lines.append(f"{source}: {field}: {value!r}: {msg}")
    return "\n".join(lines)


_RANGE_ERRORS = {"finite_number", "greater_than", "greater_than_equal", "less_than", "less_than_equal"}



def _unwrap(tp) -> tuple[Any, list]:
    """``tp`` without ``Optional`` and ``Annotated``, and the constraints ``Annotated`` carried."""
    meta: list = []
    while True:
        if get_origin(tp) is Annotated:
            tp, *extra = get_args(tp)
            meta += [m for x in extra for m in getattr(x, "metadata", [x])]
        elif get_origin(tp) in (Union, UnionType) and len(args := [a for a in get_args(tp) if a is not type(None)]) == 1:
            tp = args[0]
        else:
            return tp, meta


def locate(model: type[BaseModel], loc: tuple) -> tuple[str, list]:
    """The field at pydantic's ``loc`` in ``model``: its name as a reader writes it (indices as
    ``[i]``, a NamedTuple's items by name: ``convergence[0].mesh_size``) and its constraints."""
    path, tp, meta = "", model, []
    for part in loc:
        tp, _ = _unwrap(tp)
        fields = getattr(tp, "_fields", None) if isinstance(tp, type) and issubclass(tp, tuple) else None
        if isinstance(tp, type) and issubclass(tp, BaseModel) and part in tp.model_fields:
            info = tp.model_fields[part]
            path, tp, meta = f"{path}.{part}", info.annotation, list(info.metadata)
        elif isinstance(part, int) and fields:
            path, tp, meta = f"{path}.{fields[part]}", get_type_hints(tp, include_extras=True)[fields[part]], []
        elif isinstance(part, int):
            args = [a for a in get_args(tp) if a is not Ellipsis]  # list[T], tuple[T, ...], tuple[A, B]
            path, meta, tp = f"{path}[{part}]", [], args[min(part, len(args) - 1)] if args else None
        else:
            path, meta = f"{path}.{part}", []
            tp = get_args(tp)[1] if get_origin(tp) is dict else None
    return path.lstrip("."), meta + _unwrap(tp)[1]


def range_text(constraints: list) -> str:
    """``[lo, hi]`` of annotated-types constraints (``(`` / ``)`` for strict bounds, -inf / inf
    where none), or "" when there is no bound."""
    b = {k: getattr(c, k) for c in constraints for k in ("gt", "ge", "lt", "le") if getattr(c, k, None) is not None}
    if not b:
        return ""
    left, lo = ("(", b["gt"]) if "gt" in b else ("[", b["ge"]) if "ge" in b else ("(", float("-inf"))
    right, hi = (")", b["lt"]) if "lt" in b else ("]", b["le"]) if "le" in b else (")", float("inf"))
    return f"{left}{lo:g}, {hi:g}{right}"


def validate_table(source: str, table: str, model: type[Params], data: Any) -> Params:
    """Validate one table with ``model`` or raise :class:`ConfigError` naming the fields."""
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: {table}: {data!r}: expected a table")
    try:
        text = json.dumps(data, allow_nan=True)
    except (TypeError, ValueError) as err:  # a TOML date or time: no parameter takes one
        raise ConfigError(f"{source}: {table}: {err}: dates and times are not parameters") from None
    try:
        # strict: no string, bool or float read as a number ("8", true -> 1.0, 2.5 -> 2);
        # JSON mode still takes TOML's arrays for tuples and strings for paths
        return model.model_validate_json(text, strict=True)
    except ValidationError as err:
        raise ConfigError(format_validation(source, table, err, data, model)) from None


def load_pipeline(source: str | Path | Mapping, overrides: Sequence[str] = (), *,
                  root: str | Path | None = None) -> Pipeline:
    """Read and validate a pipeline: a TOML file's path, or its tables as a mapping
    (``{"pipeline": {"name": ..., "stages": [...]}, "cell": {...}}``), with ``overrides``
    ``TABLE.KEY=VALUE`` set (:mod:`.overrides`: ``--set`` on the command line).

    ``root``: the project directory that relative file names (the cell's design) are read
    from; by default the file's (:func:`find_root`), or the working directory for a mapping.
    Messages about a mapping name it ``<dict>``.

    Raises :class:`ConfigError` for a missing file, a TOML syntax error, an unknown
    stage or table, a wrong type or a value out of range.
    """
    if isinstance(source, Mapping):
        path = Path("<dict>")
        data = _plain(source)
        root = Path(root).resolve() if root is not None else Path.cwd()
    else:
        path = Path(source)
        data = _read_toml(path)
        root = Path(root).resolve() if root is not None else find_root(path)
    if overrides:
        data = apply_overrides(data, overrides)
    registry = stages()
    if "pipeline" not in data:
        raise ConfigError(f"{path}: pipeline: <missing>: a [pipeline] table with name and stages is required")
    section = validate_table(str(path), "pipeline", PipelineSection, data["pipeline"])
    for i, name in enumerate(section.stages):
        if name not in registry:
            raise ConfigError(
                f"{path}: pipeline.stages[{i}]: {name!r}: unknown stage; known: {', '.join(registry)}"
            )
    for table in data:
        if table != "pipeline" and table not in registry:
            raise ConfigError(
                f"{path}: {table}: unknown table; allowed: pipeline, {', '.join(registry)}"
            )
    params = {
        name: validate_table(str(path), name, registry[name].params, data.get(name, {}))
        for name in section.stages
    }
    order = resolve_order(section.stages, registry, str(path))
    for name in section.stages:
        check_project_files(str(path), name, params[name], root)
        try:
            params[name].check_pipeline(name, params)
            params[name].check_files(name, params, root)
        except ConfigError as err:  # "table.field: value: what"
            raise ConfigError(f"{path}: {err}") from None
    return Pipeline(path, root, section, order, params)


def _read_toml(path: Path) -> dict:
    if not path.is_file():
        raise ConfigError(f"{path}: pipeline file not found")
    try:
        return tomllib.loads(path.read_text(encoding="utf-8").removeprefix("\ufeff"))  # an editor's BOM
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(f"{path}: invalid TOML: {err}") from None
    except (OSError, UnicodeDecodeError) as err:
        raise ConfigError(f"{path}: cannot read: {getattr(err, 'strerror', None) or err}") from None


def _plain(source: Mapping) -> dict:
    """A mapping of tables as the TOML reader gives them (dicts all the way down), so that the
    same strict checks apply: a table that is not a mapping is refused by name."""
    data = {}
    for table, value in source.items():
        if not isinstance(value, Mapping):
            raise ConfigError(f"<dict>: {table}: {value!r}: must be a table (a mapping of keys to values)")
        data[str(table)] = {str(k): v for k, v in value.items()}
    return data


#: Words in a parameter's description that mark it as a project file (see :class:`.registry.Params`).
PROJECT_FILE_MARK = "relative to the project root"


def check_project_files(source: str, table: str, params: Params, root: Path) -> None:
    """Raise :class:`ConfigError` ``file: table.field: value: no such file under ROOT`` for a
    project-file parameter (see :data:`PROJECT_FILE_MARK`) naming no existing file."""
    for fname, info in type(params).model_fields.items():
        extra = info.json_schema_extra if isinstance(info.json_schema_extra, dict) else {}
        if not (extra.get("project_file") or PROJECT_FILE_MARK in (info.description or "")):
            continue
        value = getattr(params, fname)
        if isinstance(value, str) and value and not (root / value).is_file():
            what = "is a directory, not a file" if (root / value).is_dir() else "no such file"
            raise ConfigError(f"{source}: {table}.{fname}: {value!r}: {what} under {root}")


def resolve_order(names: list[str], registry: dict[str, Stage], source: str) -> tuple[str, ...]:
    """Topological order of ``names``; a missing required upstream stage is an error."""
    chosen = set(names)
    for name in names:
        for up in registry[name].requires:
            if up not in chosen:
                raise ConfigError(
                    f"{source}: pipeline.stages: {names!r}: stage {name!r} needs stage {up!r}; add it"
                )
    order: list[str] = []
    visiting: set[str] = set()

    def visit(n: str) -> None:
        if n in order:
            return
        if n in visiting:
            raise ConfigError(f"{source}: pipeline.stages: dependency cycle through {n!r}")
        visiting.add(n)
        st = registry[n]
        for up in (*st.requires, *st.optional):
            if up in chosen:
                visit(up)
        visiting.discard(n)
        order.append(n)

    for n in registry:  # registry order breaks ties: stable, readable
        if n in chosen:
            visit(n)
    return tuple(order)


def upstream(pipeline: Pipeline, name: str) -> tuple[str, ...]:
    """The stages of ``pipeline`` that stage ``name`` reads (required and optional)."""
    st = stages()[name]
    optional = st.optional if st.reads is None else tuple(u for u in st.optional if u in st.reads(pipeline.params[name]))
    return tuple(u for u in (*st.requires, *optional) if u in pipeline.params)


def siblings(pipeline: Pipeline, name: str) -> tuple[str, ...]:
    """The other pipelines' stage folders stage ``name`` reads when they have outputs,
    ``"<pipeline name>/<stage>"`` under the same output root (:attr:`.registry.Stage.siblings`)."""
    st = stages()[name]
    return () if st.siblings is None else tuple(st.siblings(pipeline.params[name]))
