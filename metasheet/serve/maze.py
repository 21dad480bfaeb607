"""The maze stage's motor series, for playing it back on the page.

The maze stage (:mod:`metasheet.pipeline.stages.maze`) solves a maze path open loop into a
motor series and writes it, per material, to ``maze/maze.csv`` (foam) and
``maze/maze_silicone.csv``: time [s], the six motor angles [deg], the segment and the
commanded tilt (a rotation vector [deg]), among other columns. Playing it back replays the
motor angles through the forward model, as the stage's own replay does, while the goal
shows the commanded tilt.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ConfigError

#: the maze file of each material
FILES = {"foam": "maze.csv", "silicone": "maze_silicone.csv"}
MOTORS = tuple(f"motor{k}_deg" for k in range(6))
COMMAND = ("cmd_rx_deg", "cmd_ry_deg", "cmd_rz_deg")


@dataclass(frozen=True)
class MazePlayback:
    """A motor series to play: ``time`` (T,) [s] increasing, ``motors_deg`` (T, 6) [deg],
    ``command_deg`` (T, 3) the commanded tilt (rotation vector) [deg], ``segment`` (T,) int,
    and the ``source`` file."""

    time: np.ndarray
    motors_deg: np.ndarray
    command_deg: np.ndarray
    segment: np.ndarray
    source: Path

    def __len__(self) -> int:
        return len(self.time)


def maze_file(out_dir: Path, material: str) -> Path:
    """The maze file of ``material`` ("foam" / "silicone") in the output folder ``out_dir``."""
    if material not in FILES:
        raise ConfigError(f"material: {material!r}: allowed values are {', '.join(FILES)}")
    return Path(out_dir) / "maze" / FILES[material]


def read_maze(path: Path) -> MazePlayback:
    """The motor series of a maze CSV; a :class:`ConfigError` naming the file and the
    column or row when it is missing, malformed or not a series in time."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{path}: missing: add the maze stage to the pipeline and run it")
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if not rows:
        raise ConfigError(f"{path}: empty")
    header, body = rows[0], rows[1:]
    need = ("time_s", *MOTORS, "segment", *COMMAND)
    missing = [c for c in need if c not in header]
    if missing:
        raise ConfigError(f"{path}: no column {missing[0]!r} (the maze stage writes {', '.join(need)})")
    if not body:
        raise ConfigError(f"{path}: no rows")
    col = {c: header.index(c) for c in need}
    try:
        data = np.array([[float(r[col[c]]) for c in need] for r in body])
    except (ValueError, IndexError) as exc:
        raise ConfigError(f"{path}: a row is not a number in every column {need}: {exc}") from None
    t = data[:, 0]
    if not np.all(np.isfinite(data[:, :7])):
        raise ConfigError(f"{path}: time and motor angles must be finite numbers")
    if np.any(np.diff(t) <= 0):
        i = int(np.flatnonzero(np.diff(t) <= 0)[0]) + 2  # the file's row number (header = 1)
        raise ConfigError(f"{path}: time_s must increase: row {i + 1} is not after row {i}")
    return MazePlayback(t, data[:, 1:7], np.nan_to_num(data[:, 8:11]), data[:, 7].astype(int), path)
