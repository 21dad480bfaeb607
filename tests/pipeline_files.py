"""Helpers of the tests that load small pipeline files: the refusal of a bad one (by the
loader and by ``metasheet validate``) and a one-stage material pipeline (milliseconds)."""

import sys
from pathlib import Path

import pytest

from metasheet.cli import main
from metasheet.errors import ConfigError
from metasheet.pipeline.config import load_pipeline


def refused_at(path: Path, capsys=None) -> str:
    """The ConfigError loading the pipeline file ``path`` raises, after checking that
    ``metasheet validate`` exits 2 (and, given ``capsys``, prints exactly that message)."""
    with pytest.raises(ConfigError) as err:
        load_pipeline(path)
    saved, sys.argv = sys.argv, ["metasheet", "validate", str(path)]
    try:
        with pytest.raises(SystemExit) as exc:
            main()
    finally:
        sys.argv = saved
    assert exc.value.code == 2
    if capsys is not None:
        assert capsys.readouterr().err == f"error: {err.value}\n"
    assert str(err.value).startswith(f"{path}: ")
    return str(err.value)


def material_pipeline(project: Path, E_t: float = 1.0):
    """``project/pipelines/q.toml``: the material stage alone, on its config constants, loaded."""
    (project / "cells").mkdir(exist_ok=True)
    (project / "pipelines").mkdir(exist_ok=True)
    toml = project / "pipelines" / "q.toml"
    toml.write_text(f'[pipeline]\nname = "q"\nstages = ["material"]\n[material]\nsource = "config"\nE_t = {E_t}\n')
    return load_pipeline(toml)


def die(_) -> None:
    """A work unit whose worker process dies under it (as one killed by the OOM killer)."""
    import os

    os._exit(3)


def run_cli(*argv: str) -> int:
    """The exit status of ``metasheet ARGV`` run in this process."""
    saved, sys.argv = sys.argv, ["metasheet", *argv]
    try:
        with pytest.raises(SystemExit) as exc:
            main()
    finally:
        sys.argv = saved
    return exc.value.code or 0
