"""``metasheet status``: each stage up to date, stale (and what changed), not run, or waiting."""

import shutil

import pytest
from pipeline_files import run_cli

from metasheet.pipeline import manifest as mf
from metasheet.pipeline.config import load_pipeline
from metasheet.pipeline.runner import run_pipeline
from metasheet.pipeline.status import changed_keys, pipeline_status


def pipeline(project, E_t: float = 1.0, mesh: float = 20.0):
    (project / "cells").mkdir(exist_ok=True)
    (project / "pipelines").mkdir(exist_ok=True)
    f = project / "pipelines" / "s.toml"
    f.write_text(f'[pipeline]\nname = "s"\nstages = ["material", "orient"]\n[material]\nsource = "config"\n'
                 f'E_t = {E_t}\n[orient]\nelement = "p1"\nmesh_size = {mesh}\npicture = false\n')
    return load_pipeline(f)


def states(project, **kw):
    return {s.name: (s.state, s.why) for s in pipeline_status(pipeline(project, **kw), project / "outputs" / "s")}


@pytest.fixture(scope="module")
def ran(tmp_path_factory):
    project = tmp_path_factory.mktemp("status")
    run_pipeline(pipeline(project), out_root=project / "outputs")
    return project


def test_status_says_what_changed(ran, tmp_path):
    project = tmp_path / "p"
    shutil.copytree(ran, project)
    assert states(project) == {"material": ("up to date", ()), "orient": ("up to date", ())}
    s = states(project, E_t=2.0, mesh=25.0)
    assert s["material"] == ("stale", ("parameters changed: E_t",))
    assert s["orient"] == ("stale", ("parameters changed: mesh_size",))  # material's outputs unchanged yet
    (project / "outputs" / "s" / "material" / "material.json").write_text("{}")
    assert states(project)["material"] == ("stale", ("outputs changed since they were written (their hashes "
                                                     "differ)",))
    (project / "outputs" / "s" / "material" / mf.MANIFEST).write_text("{")
    assert states(project)["material"][1][0].startswith("manifest damaged:")
    shutil.rmtree(project / "outputs" / "s" / "material")
    s = states(project)
    assert s["material"][0] == "not run" and s["orient"][0] == "waits" and "'material'" in s["orient"][1][0]


def test_the_cli_exits_0_when_everything_is_up_to_date(ran, capsys):
    assert run_cli("status", str(ran / "pipelines" / "s.toml"), "--out", str(ran / "outputs")) == 0
    assert "up to date" in capsys.readouterr().out


def test_changed_keys_walks_nested_tables():
    assert changed_keys({"a": 1, "t": {"x": 1, "y": 2}}, {"a": 1, "t": {"x": 3, "y": 2}, "b": 0}) == ["b", "t.x"]
