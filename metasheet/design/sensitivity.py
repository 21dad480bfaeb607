"""Sensitivities of the design objectives to the search's variables (issue 45, item 2):
one-at-a-time curves about a base design, and Sobol indices over the whole box.

* One-at-a-time: each variable swept over its bounds at ``n`` evenly spaced values, the
  others held at the base design's (the paper's spiral: its pitch, no radial correction).
* Sobol (SALib): first-order S1 and total ST indices of each objective, from Saltelli's
  scheme on a scrambled Sobol sequence (``N (k + 2)`` designs for k variables, no
  second-order terms), with bootstrap 95 % half-widths; seeded, so the same seed gives the
  same samples and the same intervals.

Pure functions: the caller evaluates the designs (the stage, through its executor). SALib is
given ``seed + 1``: its ``analyze`` ignores a seed of 0 (``if seed:``) and then draws its
bootstrap from numpy's global state, so the intervals would change from run to run.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from .search import SearchSpace


def oat_designs(space: SearchSpace, base: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(k n, k) one-at-a-time designs [deg] and (k n,) the index of the variable each one
    moves: variable i over ``linspace(lo_i, hi_i, n)``, the others at ``base`` (k,) [deg]."""
    if n < 2:
        raise ConfigError(f"oat_points: {n!r}: allowed range is [2, inf) (or 0: none)")
    base = np.asarray(base, float)
    rows, which = [], []
    for i, (lo, hi) in enumerate(space.bounds()):
        for v in np.linspace(lo, hi, n):
            x = base.copy()
            x[i] = v
            rows.append(x)
            which.append(i)
    return np.array(rows), np.array(which)


def _salib_problem(space: SearchSpace) -> dict:
    return {"num_vars": len(space.names), "names": list(space.names), "bounds": [list(b) for b in space.bounds()]}


def sobol_designs(space: SearchSpace, n: int, seed: int) -> np.ndarray:
    """(n (k + 2), k) Saltelli designs [deg] for first-order and total Sobol indices; ``n`` a
    power of two (the Sobol sequence's balance)."""
    if n < 2 or n & (n - 1):
        raise ConfigError(f"sobol_n: {n!r}: expected a power of two >= 2 (or 0: none)")
    from SALib.sample import sobol as sample

    return np.asarray(sample.sample(_salib_problem(space), n, calc_second_order=False, seed=int(seed) + 1), float)


@dataclass(frozen=True)
class SobolIndices:
    """Sobol indices of one objective over the search's variables.

    Attributes
    ----------
    names : the variables; S1, ST : (k,) first-order and total indices [-];
    S1_conf, ST_conf : (k,) their bootstrap 95 % half-widths [-].
    """

    names: tuple[str, ...]
    S1: np.ndarray
    ST: np.ndarray
    S1_conf: np.ndarray
    ST_conf: np.ndarray

    def to_dict(self) -> dict:
        return {n: {"S1": _r(self.S1[i]), "S1_conf95": _r(self.S1_conf[i]), "ST": _r(self.ST[i]),
                    "ST_conf95": _r(self.ST_conf[i])} for i, n in enumerate(self.names)}


def sobol_indices(space: SearchSpace, y: np.ndarray, seed: int) -> SobolIndices:
    """The indices of the objective values ``y`` (n (k + 2),) at :func:`sobol_designs`' rows."""
    from SALib.analyze import sobol as analyze

    y = np.asarray(y, float)
    if not np.all(np.isfinite(y)):
        raise ConfigError("sobol: an objective is not finite at some design")
    si = analyze.analyze(_salib_problem(space), y, calc_second_order=False, seed=int(seed) + 1,
                           print_to_console=False)
    return SobolIndices(tuple(space.names), *(np.asarray(si[k], float) for k in ("S1", "ST", "S1_conf", "ST_conf")))


def _r(v: float) -> float:
    return float(f"{float(v):.6g}")
