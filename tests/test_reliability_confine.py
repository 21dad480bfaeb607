"""Deletions stay inside the pipeline's own output folder, and ``clean`` tidies what an
interrupted run leaves. Before: ``[pipeline] name = ".."`` made ``clean --all`` delete the
output root's parent, and ``"."`` the whole output root; an empty ``.anisotropy.units/`` stayed
after a SIGTERM and ``clean`` said "nothing to remove"."""

import os
from dataclasses import replace

import pytest

from metasheet.errors import ConfigError, OutputError
from metasheet.pipeline.config import load_pipeline
from metasheet.pipeline.debris import output_folder, remove_own_debris
from metasheet.pipeline.runner import clean


@pytest.fixture
def pipe(tmp_path):
    (tmp_path / "cells").mkdir()
    (tmp_path / "pipelines").mkdir()
    toml = tmp_path / "pipelines" / "p.toml"
    toml.write_text('[pipeline]\nname = "p"\nstages = ["material"]\n')
    return load_pipeline(toml)


def forged(pipeline, name: str):
    """``pipeline`` renamed past the file's validation (the library API takes any object)."""
    return replace(pipeline, section=pipeline.section.model_construct(**{**dict(pipeline.section), "name": name}))


@pytest.mark.parametrize("name", ["..", ".", "", "a/b", "../x", ".hidden"])
def test_clean_all_refuses_a_name_that_leaves_the_output_root(tmp_path, pipe, name):
    out = tmp_path / "root" / "outs"
    out.mkdir(parents=True)
    (tmp_path / "root" / "keep.txt").write_text("a user's file")
    (out / "other").mkdir()
    with pytest.raises(ConfigError, match="pipeline.name"):
        clean(forged(pipe, name), out_root=out, everything=True)
    assert (tmp_path / "root" / "keep.txt").read_text() == "a user's file"
    assert (out / "other").is_dir()


def test_a_link_in_place_of_the_output_folder_is_not_followed(tmp_path):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "precious.txt").write_text("x")
    (tmp_path / "outs").mkdir()
    (tmp_path / "outs" / "p").symlink_to(elsewhere)
    with pytest.raises(OutputError, match="not touching it"):
        output_folder(tmp_path / "outs", "p")
    assert (elsewhere / "precious.txt").exists()


def test_clean_removes_an_empty_resume_cache_and_keeps_one_with_units(tmp_path, pipe):
    base = tmp_path / "outputs" / "p"
    (base / ".workspace.units").mkdir(parents=True)
    (base / ".anisotropy.units").mkdir()
    (base / ".anisotropy.units" / "abc.pkl").write_bytes(b"unit")
    said = []
    removed = clean(pipe, report=lambda stage, msg: said.append(msg))
    assert removed == [base / ".workspace.units"]
    assert (base / ".anisotropy.units" / "abc.pkl").exists()
    assert any("kept" in m and "1 finished unit" in m for m in said)
    assert clean(pipe, everything=True) == [base / ".anisotropy.units", base]


def test_an_interrupted_run_removes_its_own_debris_and_puts_back_a_half_swapped_stage(tmp_path):
    base = tmp_path / "p"
    me = os.getpid()
    (base / f".cell.tmp-{me}").mkdir(parents=True)  # being written
    (base / f".robot.old-{me}").mkdir()  # a swap cut between its renames: robot/ is gone
    (base / f".robot.old-{me}" / "jacobian.json").write_text("{}")
    (base / ".orient.tmp-1").mkdir()  # another process's: not ours to judge here
    (base / ".maze.units").mkdir()
    remove_own_debris(base)
    assert sorted(p.name for p in base.iterdir()) == [".orient.tmp-1", "robot"]
    assert (base / "robot" / "jacobian.json").exists()
