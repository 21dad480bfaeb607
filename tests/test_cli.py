"""The metasheet command: clean errors, stage listing, a real run."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def cli(*args, cwd=ROOT):
    return subprocess.run(
        [sys.executable, "-m", "metasheet.cli", *args], cwd=cwd, capture_output=True, text=True, timeout=600
    )


def test_bad_config_is_one_clean_message(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[pipeline]\nname = "x"\nstages = ["material"]\n[material]\nE_t = -1\n')
    r = cli("run", str(bad))
    assert r.returncode == 2
    assert "material.E_t: -1" in r.stderr and "greater than 0" in r.stderr
    assert "Traceback" not in r.stderr + r.stdout


def test_stages_lists_material():
    r = cli("stages")
    assert r.returncode == 0 and "material" in r.stdout


def test_run_writes_manifest(tmp_path):
    r = cli("run", "pipelines/quick.toml", "--stage", "material", "--out", str(tmp_path))
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "quick/material/material.json").is_file()
    assert (tmp_path / "quick/material/manifest.json").is_file()
