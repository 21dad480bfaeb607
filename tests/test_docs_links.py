"""The site's link checker (docs/_scripts/check_links.py, run by .ci/run on the built site)
finds what ``mkdocs build --strict`` does not: a broken link inside the notebook page."""

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("check_links", ROOT / "docs" / "_scripts" / "check_links.py")
check_links = importlib.util.module_from_spec(spec)
spec.loader.exec_module(check_links)


def page(path: Path, body: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f"<html><body>{body}</body></html>")


def test_broken_and_sound_links(tmp_path):
    page(tmp_path / "index.html", '<a href="concepts/guarantees/">g</a> <a href="https://x.org/y">ext</a>')
    page(tmp_path / "concepts" / "guarantees" / "index.html", '<h2 id="kill-means-stop">k</h2><a href="#top">t</a>')
    page(tmp_path / "tutorials" / "python_api" / "index.html",
         '<a href="../concepts/guarantees.md">bad</a> <a href="../../concepts/guarantees/#kill-means-stop">ok</a>'
         ' <a href="../../concepts/guarantees/#no-such">frag</a> <img src="../../img/x.png">')
    assert check_links.broken_links(tmp_path) == [
        "tutorials/python_api/index.html: ../concepts/guarantees.md (no such file)",
        "tutorials/python_api/index.html: ../../concepts/guarantees/#no-such (no #no-such on that page)",
        "tutorials/python_api/index.html: ../../img/x.png (no such file)",
    ]
    (tmp_path / "img").mkdir()
    (tmp_path / "img" / "x.png").write_bytes(b"png")
    assert len(check_links.broken_links(tmp_path)) == 2


def test_the_notebook_links_to_pages_by_their_url():
    """The tutorial notebook is rendered at tutorials/python_api/: a link is a URL from there."""
    text = (ROOT / "docs" / "tutorials" / "python_api.py").read_text()
    assert "](../concepts/" not in text
