"""The command line and its documentation page agree: every command's help links to a
section of docs/cli.md that exists; ``--version`` and ``python -m metasheet`` work."""

import re
import subprocess
import sys
from pathlib import Path

import typer.main

from metasheet import __version__
from metasheet.cli import app
from metasheet.cli_output import DOCS_PAGE

ROOT = Path(__file__).resolve().parents[1]


def commands(group=None, prefix=""):
    """(full name, click command) of every command of the CLI, groups included."""
    group = group or typer.main.get_command(app)
    for name, cmd in group.commands.items():
        full = f"{prefix}{name}"
        yield full, cmd
        if hasattr(cmd, "commands"):
            yield from commands(cmd, f"{full} ")


def test_every_command_links_to_its_section_of_the_cli_page():
    page = (ROOT / DOCS_PAGE).read_text()
    anchors = {re.sub(r"\s+", "-", h.strip().lower()) for h in re.findall(r"^## (.+)$", page, re.M)}
    seen = []
    for name, cmd in commands():
        anchor = name.replace(" ", "-")
        assert f"{DOCS_PAGE}#{anchor}" in (cmd.epilog or ""), name
        assert anchor in anchors, f"docs/cli.md has no section for {name!r}"
        seen.append(name)
    assert {"run", "clean", "stages", "validate", "diff", "robot goto", "serve"} <= set(seen)


def test_version_and_module_entry_point():
    out = subprocess.run([sys.executable, "-m", "metasheet", "--version"], capture_output=True, text=True,
                         cwd=ROOT, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == f"metasheet {__version__}"
    assert re.fullmatch(r"\d+\.\d+\.\d+", __version__)
