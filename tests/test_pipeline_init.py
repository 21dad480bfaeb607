"""``metasheet init``: a pipeline file written from the parameter models, every key documented
at its default; it validates as written, and with every default uncommented it loads the same
parameters (the TOML writer is faithful)."""

import re
import shutil
from pathlib import Path

import pytest
from pipeline_files import run_cli

from metasheet.pipeline.config import load_pipeline
from metasheet.pipeline.registry import stages
from metasheet.pipeline.template import pipeline_template

ROOT = Path(__file__).resolve().parents[1]
ALL = ",".join(stages())


@pytest.fixture
def project(tmp_path):
    shutil.copytree(ROOT / "cells", tmp_path / "cells")
    (tmp_path / "pipelines").mkdir()
    return tmp_path


def uncommented(text: str) -> str:
    """``text`` with every ``# key = value`` line of a stage's table uncommented."""
    out, fields = [], {}
    for line in text.splitlines():
        if m := re.fullmatch(r"\[(\w+)\]", line):
            fields = stages()[m[1]].params.model_fields if m[1] in stages() else {}
        if (m := re.fullmatch(r"# (\w+) = (.*)", line)) and m[1] in fields and m[2] != "(none)":
            line = f"{m[1]} = {m[2]}"
        out.append(line)
    return "\n".join(out) + "\n"


def test_init_writes_a_file_that_validates_with_every_key(project, capsys):
    path = project / "pipelines" / "mine.toml"
    assert run_cli("init", str(path)) == 0
    p = load_pipeline(path)
    assert p.order == ("cell", "homogenize", "material", "orient", "printmap", "robot")
    text = path.read_text()
    for name in p.order:
        for key in stages()[name].params.model_fields:
            assert re.search(rf"^(# )?{key} = ", text, re.M), (name, key)
    assert run_cli("init", str(path)) == 2 and "exists" in capsys.readouterr().err


def test_every_default_uncommented_loads_the_defaults(project):
    path = project / "pipelines" / "all.toml"
    path.write_text(uncommented(pipeline_template("all", list(stages()))))
    p = load_pipeline(path)
    for name, params in p.params.items():
        defaults = stages()[name].params.model_fields
        for key, field in defaults.items():
            if (name, key) in (("cell", "design"), ("orient", "element")):
                continue  # set by the template for this combination of stages
            assert getattr(params, key) == field.get_default(call_default_factory=True), (name, key)


def test_a_combination_the_defaults_do_not_serve_is_named_and_nothing_written(project, capsys):
    assert run_cli("init", str(project / "pipelines" / "r.toml"), "--stages", "robot") == 2
    assert "stage 'robot' needs stage 'orient'" in capsys.readouterr().err
    assert run_cli("init", str(project / "pipelines" / "b.toml"), "--stages", "banana") == 2
    assert list((project / "pipelines").iterdir()) == []


def test_all_stages_at_once_validate(project):
    assert run_cli("init", str(project / "pipelines" / "all.toml"), "--stages", ALL) == 0
