"""MkDocs hooks of the site (``hooks:`` in mkdocs.yml).

- Benchmark results: a page line ``<!-- results: NAME | COMMAND -->`` becomes the content of
  ``benchmarks/results/NAME.md`` (the table a benchmark wrote with ``--save``: its own output,
  never retyped), or, when that file does not exist yet, a note naming the command that
  writes it. A missing results file never fails the build.
- Docstring roles: the library's docstrings cross-reference in Sphinx's style
  (``:func:`solve_spd```); mkdocstrings renders the role's name as text before the code
  span. The role's name is dropped from the HTML, the code span stays.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "benchmarks" / "results"
MARKER = re.compile(r"^<!--\s*results:\s*(?P<name>[\w.-]+)\s*\|\s*(?P<command>.+?)\s*-->\s*$", re.M)
ROLE = re.compile(r":(?:mod|func|class|meth|data|attr|exc|obj|const|ref|term|py:\w+):(?=<code>)")


def _results(match: re.Match) -> str:
    name, command = match["name"], match["command"]
    path = RESULTS / f"{name}.md"
    if path.is_file():
        return path.read_text(encoding="utf-8").strip() + "\n"
    return (f'!!! note "Not measured in this build"\n\n'
            f"    `{command}` writes `benchmarks/results/{name}.md`; this section shows it once it exists.\n")


def on_page_markdown(markdown: str, page, config, files) -> str:
    return MARKER.sub(_results, markdown)


def on_page_content(html: str, page, config, files) -> str:
    if page.file.src_uri.startswith("reference/"):
        return ROLE.sub("", html)
    return html
