"""``--set TABLE.KEY=VALUE``: a pipeline file's values overridden from the command line.

The value is read as TOML (``--set orient.mesh_size=8``, ``--set 'workspace.columns=["prediction"]'``,
``--set material.source='"config"'``); a word that is not TOML is taken as a string
(``--set orient.element=p1``). The result is validated as the file is: an override is a
value of the file, with the same checks and messages.
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Iterable

from ..errors import ConfigError

_ASSIGNMENT = re.compile(r"^(?P<path>[A-Za-z_][\w-]*(\.[A-Za-z_][\w-]*)+)=(?P<value>.*)$", re.S)


def parse_value(text: str):
    """The TOML value ``text``, or ``text`` itself when it is a bare word that TOML does not read."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        if re.fullmatch(r"[\w./+-]+", text):
            return text
        raise ConfigError(f"--set: {text!r}: not a TOML value (a number, true / false, \"a string\", "
                          "[an, array] or { a = table })") from None


def apply_overrides(data: dict, assignments: Iterable[str]) -> dict:
    """``data`` (a parsed pipeline file, not changed) with each ``TABLE.KEY=VALUE`` set."""
    out = {k: dict(v) if isinstance(v, dict) else v for k, v in data.items()}
    for text in assignments:
        m = _ASSIGNMENT.match(text)
        if m is None:
            raise ConfigError(f"--set: {text!r}: expected TABLE.KEY=VALUE, e.g. orient.mesh_size=8")
        *tables, key = m["path"].split(".")
        node = out
        for i, t in enumerate(tables):
            child = node.get(t, {})
            if not isinstance(child, dict):
                raise ConfigError(f"--set: {text!r}: {'.'.join(tables[:i + 1])} is a value, not a table")
            node[t] = child = dict(child)
            node = child
        node[key] = parse_value(m["value"])
    return out
