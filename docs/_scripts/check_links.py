"""Check the links between the pages of a built documentation site.

    python docs/_scripts/check_links.py SITE_DIR

Every relative ``href`` and ``src`` in every HTML page must name a file of the site (a folder's
``index.html`` for a directory URL), and a ``#fragment`` to another page an ``id`` on it.
``mkdocs build --strict`` checks the Markdown pages' links, but not those inside a notebook
page (mkdocs-jupyter's tutorial): there ``../concepts/guarantees.md`` resolved to
``tutorials/concepts/...``, a page that does not exist. External links (``http:``,
``mailto:``) are not followed. Exit status 1 and one line per broken link.
"""

from __future__ import annotations

import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit


class _Links(HTMLParser):
    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.links: list[str] = []
        self.ids: set[str] = set()

    def handle_starttag(self, tag, attrs):
        for name, value in attrs:
            if name in ("href", "src") and value:
                self.links.append(value)
            elif name in ("id", "name") and value:
                self.ids.add(value)


def parse(page: Path) -> _Links:
    p = _Links()
    p.feed(page.read_text(encoding="utf-8", errors="replace"))
    return p


def target(site: Path, page: Path, link: str) -> tuple[Path, str] | None:
    """The file a relative ``link`` of ``page`` names, and its fragment; None for an external
    link, a page-local fragment or a scheme the site does not serve."""
    parts = urlsplit(link)
    if parts.scheme or parts.netloc or link.startswith(("#", "//")):
        return None
    path = unquote(parts.path)
    f = (site / path.lstrip("/")) if path.startswith("/") else (page.parent / path)
    if path.endswith("/") or f.is_dir():
        f = f / "index.html"
    return f, parts.fragment


def broken_links(site: Path) -> list[str]:
    """``page: link (why)`` for each link of the site that does not resolve."""
    site = Path(site).resolve()
    parsed = {p: parse(p) for p in sorted(site.rglob("*.html"))}
    out = []
    for page, links in parsed.items():
        for link in links.links:
            found = target(site, page, link)
            if found is None:
                continue
            f, fragment = found
            f = f.resolve()
            rel = page.relative_to(site).as_posix()
            if not f.is_file():
                out.append(f"{rel}: {link} (no such file)")
            elif fragment and f.suffix == ".html" and f != page and f in parsed and fragment not in parsed[f].ids:
                out.append(f"{rel}: {link} (no #{fragment} on that page)")
    return out


def main(argv: list[str]) -> int:
    if len(argv) != 1 or not Path(argv[0]).is_dir():
        print("usage: check_links.py SITE_DIR (a built site)", file=sys.stderr)
        return 2
    bad = broken_links(Path(argv[0]))
    for line in bad:
        print(f"broken link: {line}", file=sys.stderr)
    pages = sum(1 for _ in Path(argv[0]).rglob("*.html"))
    print(f"links: {len(bad)} broken in {pages} pages")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
