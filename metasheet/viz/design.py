"""Pictures of the design stage: the search's Pareto front, and the designed fibre field beside
the starting spiral (like the paper's Fig. 3).

Functions return PNG bytes (matplotlib, Agg); the stage layer writes them.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from . import figure_png, one_at_a_time
from .sheet import _figure, sheet_picture


@one_at_a_time
def pareto_picture(objectives: np.ndarray, pareto: np.ndarray, marks: Sequence[tuple[str, float, float, str]],
                   *, title: str = "", feasible: np.ndarray | None = None) -> bytes:
    """Every trial's objectives, the Pareto front joined, and named points.

    Parameters
    ----------
    objectives : (n, 2) per trial (|rod roll per degree| [deg/deg], smallest other singular value [mm/rad]).
    pareto : (n,) bool, the non-dominated trials.
    marks : (label, roll, other_min, matplotlib marker) per named design (the spiral, the
        gradient's design, the chosen one).
    feasible : (n,) bool, the trials within the search's strain limit (None: all; else the others
        are drawn hollow).
    """
    fig, axes = _figure(1, size=5.5)
    ax = axes[0, 0]
    F = np.asarray(objectives, float).reshape(-1, 2)
    ok = np.ones(len(F), bool) if feasible is None else np.asarray(feasible, bool)
    if ok.all():
        ax.plot(F[:, 0], F[:, 1], ".", color="0.6", ms=6, label=f"trials ({len(F)})")
    else:
        ax.plot(F[ok, 0], F[ok, 1], ".", color="0.35", ms=7, label=f"trials within the strain limit ({ok.sum()})")
        ax.plot(F[~ok, 0], F[~ok, 1], "o", mfc="none", color="0.6", ms=4,
                label=f"trials beyond it ({(~ok).sum()})")
    front = F[np.asarray(pareto, bool)]
    front = front[np.argsort(front[:, 0])]
    ax.plot(front[:, 0], front[:, 1], "o-", color="C0", ms=6, lw=1.2, mec="w", zorder=6,  # over the marks
            label=f"Pareto front ({len(front)})")
    for i, (label, x, y, marker) in enumerate(marks):
        ax.plot([x], [y], marker, color=f"C{i + 1}", ms=11, mec="k", label=label)
    ax.set_xlabel("|rod roll per motor degree| [deg/deg]  (maximise)")
    ax.set_ylabel("smallest singular value of the other five DOF [mm/rad]  (maximise)")
    ax.set_title(title or "Design search: roll against the other five DOF")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    return figure_png(fig, dpi=110)


def field_picture(outline: np.ndarray, hole_radius: float,
                  panels: Sequence[tuple[str, Callable[[np.ndarray], np.ndarray], np.ndarray]]) -> bytes:
    """Fibre streaks of sheet A for each design, side by side (:func:`.sheet.sheet_picture`):
    ``panels`` (title, points (q, 3) [mm] -> unit fibres (q, 3), attached points (a, 3) [mm])."""
    return sheet_picture(outline, hole_radius, panels)


@one_at_a_time
def sensitivity_picture(oat: Sequence[tuple[str, np.ndarray, np.ndarray, np.ndarray]], sobol: dict | None) -> bytes:
    """One-at-a-time curves and Sobol total indices.

    Parameters
    ----------
    oat : (variable, values [deg], |roll| [deg/deg], other_min [mm/rad]) per variable (may be empty).
    sobol : objective -> variable -> {"ST", "ST_conf95", "S1", ...} (None: no Sobol panel).
    """
    n = (2 if oat else 0) + (1 if sobol else 0)
    fig, axes = _figure(max(n, 1), size=4.6)
    k = 0
    if oat:
        for j, (ylabel, col) in enumerate((("|rod roll per degree| [deg/deg]", 2), ("other_min [mm/rad]", 3))):
            ax = axes[0, k + j]
            for name, x, *ys in oat:
                x = np.asarray(x, float)
                ax.plot((x - x[0]) / (x[-1] - x[0]), ys[col - 2], "o-", ms=3, label=name)
            ax.set_xlabel("variable across its bounds (0: lower, 1: upper)")
            ax.set_ylabel(ylabel)
            ax.set_title("one at a time, about the spiral")
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7)
        k = 2
    if sobol:
        ax = axes[0, k]
        objs = list(sobol)
        names = list(sobol[objs[0]])
        w = 0.8 / len(objs)
        for j, o in enumerate(objs):
            st = [sobol[o][v]["ST"] for v in names]
            err = [sobol[o][v]["ST_conf95"] for v in names]
            ax.bar(np.arange(len(names)) + (j - (len(objs) - 1) / 2) * w, st, w, yerr=err, capsize=3, label=o)
        ax.set_xticks(np.arange(len(names)), names, rotation=30, fontsize=8)
        ax.set_ylabel("total Sobol index ST [-] (95 % bootstrap)")
        ax.set_title("Sobol: share of each objective's variance")
        ax.grid(alpha=0.3, axis="y")
        ax.legend(fontsize=8)
    return figure_png(fig, dpi=110)
