"""The command line's commands about pipeline files: ``init`` (write one), ``status`` (which of
its stages are up to date, and why not) and ``schema`` (its JSON schema). :mod:`.cli` registers
them (:data:`FILE_COMMANDS`); ``run``, ``clean`` and ``validate`` stay there."""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Annotated, Optional

import typer
from rich.text import Text

from .cli_output import say, stdout, table
from .errors import ConfigError


def init(
    path: Annotated[Path, typer.Argument(help="pipeline file to write, e.g. pipelines/mine.toml")],
    stage_list: Annotated[str, typer.Option("--stages", help="comma-separated stages")] =
        "cell,homogenize,material,orient,printmap,robot",
    force: Annotated[bool, typer.Option("--force", help="replace an existing file")] = False,
) -> None:
    """Write PATH: a pipeline of the stages named, each key at its default under its
    description, commented out. It validates as written (checked before it is written)."""
    from .pipeline.config import load_pipeline
    from .pipeline.manifest import write_bytes_atomic
    from .pipeline.template import pipeline_template

    if path.exists() and not force:
        raise ConfigError(f"{path}: exists; choose another name, or pass --force to replace it")
    names = [s.strip() for s in stage_list.split(",") if s.strip()]
    text = pipeline_template(path.stem, names)
    staging = path.with_name(f".{path.name}.init-{os.getpid()}")
    write_bytes_atomic(staging, text.encode())
    try:
        load_pipeline(staging)  # a combination of stages the defaults do not serve: nothing is written
    except BaseException as err:
        staging.unlink(missing_ok=True)
        if isinstance(err, ConfigError):
            raise ConfigError(str(err).replace(str(staging), str(path))) from None
        raise
    os.replace(staging, path)
    say(f"wrote {path}: stages {' -> '.join(load_pipeline(path).order)}; "
        f"`metasheet validate {path}` after editing", err=False)


def status(
    pipeline: Annotated[Path, typer.Argument(help="pipeline TOML file, e.g. pipelines/quick.toml")],
    out: Annotated[Optional[Path], typer.Option("--out", help="output root (default: outputs/ of the project)")] = None,
) -> None:
    """Each stage of PIPELINE: up to date, stale (and what changed since it ran: parameters,
    files, an upstream stage's outputs, the code), not run, or waiting for an upstream stage.
    Exit status 0 when every stage is up to date, 1 otherwise."""
    from .pipeline.config import load_pipeline
    from .pipeline.debris import output_folder
    from .pipeline.status import pipeline_status

    p = load_pipeline(pipeline)
    rows = pipeline_status(p, output_folder(Path(out) if out else p.root / "outputs", p.name))
    stdout.print(table(f"pipeline {p.name}", ("stage", "state", "why"),
                        [(r.name, Text(r.state, style="" if r.state == "up to date" else "yellow"), "; ".join(r.why))
                         for r in rows]))
    if any(r.state != "up to date" for r in rows):
        raise typer.Exit(1)


def schema(
    out: Annotated[Optional[Path], typer.Option("--out", help="file to write (default: print it)")] = None,
) -> None:
    """The JSON schema of a pipeline file (every table and key, with its type, default and
    allowed range), for an editor that completes and checks TOML against a schema."""
    import json

    from .pipeline.manifest import write_bytes_atomic
    from .pipeline.schema import pipeline_schema

    text = json.dumps(pipeline_schema(), indent=2) + "\n"
    if out is None:
        sys.stdout.write(text)
    else:
        write_bytes_atomic(Path(out), text.encode())
        say(f"wrote {out}", err=False)


#: (name, function, one-line help) of each command, in the order ``metasheet --help`` lists them.
FILE_COMMANDS = (
    ("init", init, "Write a pipeline file to start from, every key documented."),
    ("status", status, "Which stages are up to date, and why the others are not."),
    ("schema", schema, "Write the JSON schema of a pipeline file, for editors."),
)
