"""A journal of expensive evaluations, so a long search killed part way resumes where it stopped.

Each evaluation (a pose of the finite-strain robot: minutes of solves on a print) is appended to
a JSON-lines file as soon as it is done, under the key of the inputs it was computed from. A
rerun with the same key replays the journalled results for the arguments it meets again and
computes only the rest; a search that chooses its next argument from the previous results (a
bracketing root search) then retraces its steps exactly, because the floats are stored exactly
(JSON's shortest repr round-trips). A line cut short by a kill is ignored (the next entry starts
on a line of its own); a journal written for other inputs is refused, not mixed in.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from ..errors import ConfigError


class Journal:
    """The evaluations at ``path`` (a ``.jsonl`` file) made under ``key`` (a JSON-able dict: the
    inputs every entry depends on). ``get(x)`` the entry recorded at the float ``x`` or None;
    ``add(x, entry)`` records one (flushed to disk before it returns)."""

    def __init__(self, path, key: dict):
        self.path, self.key = Path(path), json.loads(json.dumps(key))
        self._entries = {}
        if not self.path.exists():
            return
        lines = self.path.read_text().splitlines()
        for n, line in enumerate(lines):
            try:
                item = json.loads(line)
            except json.JSONDecodeError:
                if n > 0:
                    continue  # a line cut short by a kill
                raise ConfigError(f"{self.path}: its first line is not JSON: not a journal; remove it") from None
            if n == 0:
                got = item.get("key") if isinstance(item, dict) else item
                if got != self.key:
                    raise ConfigError(f"{self.path}: journal written for other inputs ({got}, asked "
                                      f"{self.key}): remove it or choose another path")
                continue
            self._entries[float(item["x"])] = item["entry"]

    def __len__(self) -> int:
        return len(self._entries)

    def get(self, x: float):
        return self._entries.get(float(x))

    def add(self, x: float, entry: dict) -> None:
        self._entries[float(x)] = entry
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fresh = not self.path.exists() or self.path.stat().st_size == 0
        with open(self.path, "a") as f:
            if fresh:
                f.write(json.dumps({"key": self.key}) + "\n")
            elif not self._ends_with_newline():
                f.write("\n")  # a line cut short before: its remnant stays alone on its line
            f.write(json.dumps({"x": float(x), "entry": entry}) + "\n")
            f.flush()
            os.fsync(f.fileno())

    def _ends_with_newline(self) -> bool:
        with open(self.path, "rb") as f:
            f.seek(-1, os.SEEK_END)
            return f.read(1) == b"\n"
