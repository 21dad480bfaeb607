"""The paper page shows the paper's figures from a run of ``pipelines/paper.toml``, both columns,
and says which run: ``docs/img/paper/source.json`` (written by ``docs/_scripts/paper_figures.py``)
names the commit and each picture's sha256, checked here against the files and the page."""

import hashlib
import json
import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FIGURES = ROOT / "docs" / "img" / "paper"


@pytest.fixture(scope="module")
def source() -> dict:
    return json.loads((FIGURES / "source.json").read_text())


def test_every_picture_is_the_one_the_source_names(source):
    on_disk = sorted(p.name for p in FIGURES.glob("*.png"))
    assert on_disk == sorted(source["pictures"])
    for name, entry in source["pictures"].items():
        assert hashlib.sha256((FIGURES / name).read_bytes()).hexdigest() == entry["sha256"], name


def test_the_page_shows_every_figure_in_both_columns(source):
    page = (ROOT / "docs" / "paper.md").read_text()
    shown = set(re.findall(r"\]\(img/paper/([\w.]+\.png)\)", page))
    assert shown == set(source["pictures"])
    for study in ("workspace", "ranges", "anisotropy", "maze"):
        assert {f"{study}.png", f"{study}_reproduction.png"} <= shown, study
    assert source["commit"][:12] in page  # the page names the run's commit


def test_the_source_commit_is_in_the_history(source):
    assert re.fullmatch(r"[0-9a-f]{40}", source["commit"] or ""), "the pictures' run has no commit"
    if not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    r = subprocess.run(["git", "cat-file", "-e", f"{source['commit']}^{{commit}}"], cwd=ROOT, capture_output=True)
    assert r.returncode == 0, f"commit {source['commit']} is not in this clone's history"
