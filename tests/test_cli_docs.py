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


def synopsis(page: str, name: str) -> str:
    """The first code block of section ``## name`` of the CLI page (the command's synopsis)."""
    section = re.split(r"^## ", page, flags=re.M)
    body = next(s for s in section if s.split("\n", 1)[0].strip() == name)
    block = re.search(r"```[a-z]*\n(.*?)```", body, re.S)
    assert block, f"docs/cli.md: section {name!r} has no synopsis block"
    return block.group(1)


def test_every_option_of_every_command_is_in_its_synopsis_and_no_other():
    page = (ROOT / DOCS_PAGE).read_text()
    for name, cmd in commands():
        if hasattr(cmd, "commands"):  # a group: its commands have the options
            continue
        text = synopsis(page, name)
        cli = {o for p in cmd.params for o in getattr(p, "opts", []) if o.startswith("--")} - {"--help"}
        documented = set(re.findall(r"(?<![\w-])(--[a-z][a-z0-9-]*)", text)) - {"--help"}
        assert cli <= documented, f"{name}: options missing from docs/cli.md's synopsis: {sorted(cli - documented)}"
        assert documented <= cli, f"{name}: docs/cli.md names options the command lacks: {sorted(documented - cli)}"
