"""What the design stage writes, as text: the trials and Pareto tables, the chosen design, and
the pipeline file that reproduces it. Pure functions of arrays and dicts (the stage writes the
bytes atomically).

Numbers in the CSV tables are written with ``%.9g`` (same results, same bytes; 9 digits keep
the objectives' differences between neighbouring trials).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


def fmt(v) -> str:
    """One CSV cell: integers as such, floats with ``%.9g`` ('nan' when not finite)."""
    if isinstance(v, (bool, np.bool_)):
        return str(int(v))
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return "nan" if not math.isfinite(float(v)) else f"{float(v):.9g}"
    return str(v)


def csv_text(header: Sequence[str], rows: Sequence[Sequence]) -> str:
    """A CSV table (no quoting needed: names and numbers only), '\\n' line ends."""
    return "\n".join([",".join(header)] + [",".join(fmt(v) for v in r) for r in rows]) + "\n"


def trials_table(names: Sequence[str], values: np.ndarray, roll: np.ndarray, objectives: np.ndarray,
                 pareto: np.ndarray) -> str:
    """``trials.csv``: trial number, the variables [deg], the signed roll [deg/deg], the two
    objectives and whether the trial is on the Pareto front."""
    header = ["trial", *names, "roll_deg_per_deg", "abs_roll_deg_per_deg", "other_min_mm_per_rad", "pareto"]
    rows = [[i, *values[i], roll[i], *objectives[i], bool(pareto[i])] for i in range(len(values))]
    return csv_text(header, rows)


def pareto_table(names: Sequence[str], values: np.ndarray, roll: np.ndarray, objectives: np.ndarray,
                 pareto: np.ndarray) -> str:
    """``pareto.csv``: the non-dominated trials, by decreasing |roll|."""
    idx = np.flatnonzero(pareto)
    idx = idx[np.lexsort((idx, -objectives[idx, 0]))]  # ties by trial number: a fixed order
    header = ["trial", *names, "roll_deg_per_deg", "abs_roll_deg_per_deg", "other_min_mm_per_rad"]
    return csv_text(header, [[int(i), *values[i], roll[i], *objectives[i]] for i in idx])


@dataclass(frozen=True)
class Candidate:
    """A design the stage may choose.

    Attributes
    ----------
    name : "spiral", "trial <n>" or "gradient".
    roll : signed rod roll per degree [deg/deg]; other_min : [mm/rad];
    singular_values : (6,) [mm/rad]; design : how to rebuild it (JSON-able).
    """

    name: str
    roll: float
    other_min: float
    singular_values: tuple[float, ...]
    design: dict


def choose(candidates: Sequence[Candidate], floor: float) -> Candidate:
    """The candidate with the largest |roll| whose ``other_min`` is at least ``floor`` [mm/rad]
    (the first candidate, the spiral, when none is); ties go to the earlier candidate."""
    best = candidates[0]
    for c in candidates[1:]:
        if c.other_min >= floor and abs(c.roll) > abs(best.roll):
            best = c
    return best


def scores_record(roll: float, other_min: float, singular_values) -> dict:
    """A design's objectives for ``design.json`` (rounded to 6 significant digits)."""
    return {"roll_deg_per_deg": _r(roll), "abs_roll_deg_per_deg": _r(abs(roll)),
            "other_min_mm_per_rad": _r(other_min),
            "singular_values_mm_per_rad": [_r(s) for s in singular_values]}


def _r(v: float) -> float:
    return float(f"{float(v):.6g}")


# ------------------------------------------------------------------------- chosen.toml

def toml_value(v) -> str:
    """A TOML value: bool, int, float (repr: round-trips), string, list, inline table."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items() if x is not None) + "}"
    raise TypeError(f"no TOML form for {type(v).__name__}")


def toml_text(comment: str, tables: dict[str, dict]) -> str:
    """A pipeline file: ``comment`` lines (each prefixed '# '), then one ``[table]`` per entry;
    None values are left out (the parameter's default), empty tables too."""
    out = [f"# {line}".rstrip() for line in comment.splitlines()]
    for name, table in tables.items():
        items = [(k, v) for k, v in table.items() if v is not None and v != {}]
        out += ["", f"[{name}]"] + [f"{k} = {toml_value(v)}" for k, v in items]
    return "\n".join(out) + "\n"
