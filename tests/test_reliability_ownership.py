"""metasheet removes or replaces only what it can prove it wrote (a stage folder whose manifest
lists every file in it). Before: ``clean --all`` deleted a user's folder holding ``thesis.tex``
(no manifest), and ``run`` replaced a ``material/`` holding the user's ``notes.txt``."""

import json
import re
import subprocess
import sys

import pytest
from pipeline_files import material_pipeline

from metasheet.errors import OutputError
from metasheet.pipeline.ownership import foreign_files, name_files
from metasheet.pipeline.runner import clean, run_pipeline


def pipeline(tmp_path, E_t: float = 1.0):
    return material_pipeline(tmp_path, E_t)


def test_a_run_does_not_replace_a_stage_folder_holding_a_users_file(tmp_path):
    out = tmp_path / "outputs"
    run_pipeline(pipeline(tmp_path), out_root=out)
    material = out / "q" / "material"
    (material / "notes.txt").write_text("my notes")
    before = (material / "material.json").read_bytes()
    with pytest.raises(OutputError, match=r"notes\.txt, which metasheet did not write.*--overwrite"):
        run_pipeline(pipeline(tmp_path, E_t=2.0), out_root=out)
    assert (material / "notes.txt").read_text() == "my notes"
    assert (material / "material.json").read_bytes() == before
    assert [p.name for p in (out / "q").iterdir()] == ["material"]  # no temporary folder left
    run_pipeline(pipeline(tmp_path, E_t=2.0), out_root=out, overwrite=True)
    assert not (material / "notes.txt").exists()
    assert json.loads((material / "material.json").read_text())["constants"]["E_t"] == 2.0


def test_a_folder_metasheet_never_wrote_is_neither_replaced_nor_cleaned(tmp_path):
    out = tmp_path / "outputs"
    (out / "q" / "material").mkdir(parents=True)
    (out / "q" / "material" / "data.csv").write_text("1,2")
    (out / "q" / "thesis.tex").write_text("\\documentclass{article}")
    with pytest.raises(OutputError, match="no readable manifest.json"):
        run_pipeline(pipeline(tmp_path), out_root=out)
    said = []
    assert clean(pipeline(tmp_path), out_root=out, everything=True, report=lambda s, m: said.append(m)) == []
    assert (out / "q" / "thesis.tex").exists() and (out / "q" / "material" / "data.csv").exists()
    assert any("kept" in m and "thesis.tex" in m for m in said)


def test_clean_all_removes_its_stage_folders_and_keeps_the_users_files(tmp_path):
    out = tmp_path / "outputs"
    run_pipeline(pipeline(tmp_path), out_root=out)
    (out / "q" / "thesis.tex").write_text("mine")
    removed = clean(pipeline(tmp_path), out_root=out, everything=True)
    assert removed == [out / "q" / "material"]
    assert [p.name for p in (out / "q").iterdir()] == ["thesis.tex"]
    (out / "q" / "thesis.tex").unlink()
    run_pipeline(pipeline(tmp_path), out_root=out)
    assert clean(pipeline(tmp_path), out_root=out, everything=True) == [out / "q" / "material", out / "q"]
    assert not (out / "q").exists()


def test_a_damaged_manifest_proves_nothing(tmp_path):
    out = tmp_path / "outputs"
    run_pipeline(pipeline(tmp_path), out_root=out)
    manifest = out / "q" / "material" / "manifest.json"
    manifest.write_text(manifest.read_text()[:40])  # truncated
    assert foreign_files(out / "q" / "material") is None
    with pytest.raises(OutputError, match="damaged"):
        run_pipeline(pipeline(tmp_path), out_root=out)
    assert clean(pipeline(tmp_path), out_root=out, everything=True) == []
    assert manifest.exists()


def test_name_files_names_five_then_counts():
    assert name_files(["a"]) == "a"
    assert name_files(["a", "b"]) == "a and b"
    assert name_files(list("abcdefg")) == "a, b, c, d, e and 2 more"


def test_the_cli_refuses_with_exit_2_and_a_sentence(tmp_path):
    out = tmp_path / "outputs"
    run_pipeline(pipeline(tmp_path), out_root=out)
    (out / "q" / "material" / "notes.txt").write_text("my notes")
    pipeline(tmp_path, E_t=2.0)
    r = subprocess.run([sys.executable, "-m", "metasheet", "run", str(tmp_path / "pipelines" / "q.toml"),
                        "--out", str(out)], capture_output=True, text=True)
    assert r.returncode == 2, r.stderr
    assert "error:" in r.stderr and "notes.txt" in r.stderr and "--overwrite" in r.stderr
    assert "Traceback" not in r.stderr


def test_a_file_size_limit_and_memory_are_named(tmp_path, monkeypatch):
    """Issue 60: ``ulimit -f`` gave "File too large" without the stage, ``ulimit -v`` an empty
    ``MemoryError:``."""
    import errno
    from dataclasses import replace

    from metasheet.errors import StageError
    from metasheet.pipeline.registry import _REGISTRY, stages

    def efbig(ctx):
        raise OSError(errno.EFBIG, "File too large")

    def no_memory(ctx):
        raise MemoryError()

    for fail, words in ((efbig, "stage 'material': cannot write: file too large for this process's limit "
                         "(ulimit -f)"), (no_memory, "stage 'material' ran out of memory (MemoryError)")):
        monkeypatch.setitem(_REGISTRY, "material", replace(stages()["material"], run=fail))
        with pytest.raises((OutputError, StageError), match=re.escape(words)):
            run_pipeline(pipeline(tmp_path), out_root=tmp_path / "outputs", force=True)
    assert [p.name for p in (tmp_path / "outputs" / "q").iterdir()] == []  # no temporary folder


def test_a_worker_that_dies_is_named(tmp_path, monkeypatch):
    """A worker killed under a unit (the OOM killer, a crash in a native library) gave
    "BrokenProcessPool: A process in the process pool was terminated abruptly ..."."""
    from dataclasses import replace

    from pipeline_files import die

    from metasheet.errors import StageError
    from metasheet.runtime.executor import Executor
    from metasheet.pipeline.registry import _REGISTRY, stages

    def run(ctx):
        ctx.executor.map(die, [0, 1])

    monkeypatch.setitem(_REGISTRY, "material", replace(stages()["material"], run=run))
    with pytest.raises(StageError, match="stage 'material' failed: a worker process died while computing a unit"):
        run_pipeline(pipeline(tmp_path), out_root=tmp_path / "outputs", executor=Executor(workers=2))
    assert [p.name for p in (tmp_path / "outputs" / "q").iterdir()] == []
