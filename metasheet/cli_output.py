"""What the command line prints: its two consoles, one-line messages, plain-text tables and the
``--help`` epilog that points at each command's documentation (shared by :mod:`.cli` and
:mod:`.cli_files`)."""

from __future__ import annotations

from rich.console import Console
from rich.table import Table
from rich.text import Text

#: Where each command is documented: the site's CLI page (``mkdocs serve`` shows it), one
#: section per command.
DOCS_PAGE = "docs/cli.md"

# markup=False, highlight=False, emoji=False: a string prints as given
console = Console(stderr=True, markup=False, highlight=False, emoji=False)
stdout = Console(markup=False, highlight=False, emoji=False)


def docs(command: str) -> str:
    """The ``--help`` epilog pointing at ``command``'s section of the documentation."""
    return f"Documentation: {DOCS_PAGE}#{command.replace(' ', '-')} (browse the site: mkdocs serve)"


def say(message: str, *, err: bool = True, prefix: str = "", style: str = "") -> None:
    """Print ``message`` verbatim (no markup, no highlighting, no wrapping), after an
    optional styled ``prefix``."""
    text = Text()
    if prefix:
        text.append(prefix, style=style)
    text.append(str(message))
    (console if err else stdout).print(text, soft_wrap=True)


def table(title: str, columns, rows) -> Table:
    """A rich table whose title, headers and cells are plain text (``time [s]`` stays)."""
    t = Table(title=Text(title) if title else None)
    for col in columns:
        t.add_column(Text(col), overflow="fold")
    for row in rows:
        t.add_row(*(c if isinstance(c, Text) else Text(str(c)) for c in row))
    return t
