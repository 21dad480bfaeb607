"""The metasheet command: clean errors, stage listing, a real run.

The error paths, message by message, are in ``test_reliability_errors.py``; the lock,
debris and clean in ``test_reliability_lock.py``.

One test runs the command as a user does, in its own process (its exit status, the results
table, the lock's holder file); the others call ``metasheet.cli.main`` in this process, as
test_reliability_errors.py does: the same code from the argument list on, without the four CPU
seconds a fresh interpreter spends importing the stages.
"""

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def cli(*args, cwd=ROOT):
    return subprocess.run(
        [sys.executable, "-m", "metasheet.cli", *args], cwd=cwd, capture_output=True, text=True, timeout=600
    )


@pytest.fixture
def cli_here(capsys, monkeypatch):
    """``metasheet ARGS`` in this process, from the repository root: (returncode, stdout, stderr)
    like :func:`cli`'s result (a SystemExit's code; 0 when main returns)."""
    from metasheet.cli import main

    monkeypatch.chdir(ROOT)

    def run(*args):
        capsys.readouterr()
        try:
            main(list(args))
            code = 0
        except SystemExit as exc:
            code = 0 if exc.code is None else exc.code
        out, err = capsys.readouterr()
        return subprocess.CompletedProcess(["metasheet", *args], code, out, err)

    return run


def test_bad_config_is_one_clean_message(tmp_path, cli_here):
    bad = tmp_path / "bad.toml"
    bad.write_text('[pipeline]\nname = "x"\nstages = ["material"]\n[material]\nE_t = -1\n')
    r = cli_here("run", str(bad))
    assert r.returncode == 2
    assert "material.E_t: -1" in r.stderr and "allowed range is [1e-06, 2e+06]" in r.stderr
    assert "Traceback" not in r.stderr + r.stdout


def test_stages_lists_material(cli_here):
    r = cli_here("stages")
    assert r.returncode == 0 and "material" in r.stdout


def test_run_writes_manifest(tmp_path, quick_outputs):
    """A real run of the command: the session's quick outputs copied without their material
    stage, which runs again (its upstream stages cached)."""
    shutil.copytree(quick_outputs / "quick", tmp_path / "quick", ignore=shutil.ignore_patterns("material"))
    r = cli("run", "pipelines/quick.toml", "--stage", "material", "--out", str(tmp_path))
    assert r.returncode == 0, r.stderr
    assert re.search(r"material\s+│ ran", r.stdout), r.stdout
    assert (tmp_path / "quick/material/material.json").is_file()
    manifest = json.loads((tmp_path / "quick/material/manifest.json").read_text())
    assert {"started", "wall_time_s", "cpu_s", "timings_s"} <= manifest.keys()
    assert "time [s]" in r.stdout  # the results table keeps its unit
    assert not (tmp_path / ".quick.lock.json").exists()  # the lock's holder file leaves with the run
    constants = json.loads((tmp_path / "quick/homogenize/constants.json").read_text())
    assert "timings_s" not in constants  # wall-clock times: manifests only
    h = json.loads((tmp_path / "quick/homogenize/manifest.json").read_text())
    assert set(h["timings_s"]) == {"assembly", "setup", "solve", "post"}


def test_validate_checks_the_files_a_pipeline_names(tmp_path, cli_here):
    r = cli_here("validate", "pipelines/quick.toml")
    assert r.returncode == 0 and "ok; stages in order: cell -> homogenize" in r.stdout
    (tmp_path / "cells").mkdir()
    bad = tmp_path / "bad.toml"
    bad.write_text('[pipeline]\nname = "x"\nstages = ["cell"]\n[cell]\ndesign = "cells/missing.toml"\n')
    r = cli_here("validate", str(bad))
    assert r.returncode == 2
    assert r.stderr == f"error: {bad}: cell.design: 'cells/missing.toml': no such file under {tmp_path}\n"


def test_clean_on_a_folder_never_written(tmp_path, cli_here):
    r = cli_here("clean", "pipelines/quick.toml", "--out", str(tmp_path))
    assert r.returncode == 0 and "nothing to remove" in r.stdout
