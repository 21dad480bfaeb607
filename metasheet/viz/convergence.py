"""Picture of a cell-size study: homogenised constants against the number of cells.

:func:`convergence_picture` returns PNG bytes (matplotlib, Agg) drawn from the
``convergence.json`` summary (:func:`metasheet.homogenize.ensemble.convergence_summary`),
so the picture can be redrawn from the artefact alone; the stage layer writes it.
"""

from __future__ import annotations

import numpy as np

from . import figure_png, one_at_a_time

#: axis label per known constant; others are labelled with their name
_LABELS = {"E_t": "E_t [MPa]", "E_l": "E_l [MPa]", "mu_l": "mu_l [MPa]", "nu_t": "nu_t [-]", "nu_tl": "nu_tl [-]"}


@one_at_a_time
def convergence_picture(summary: dict, title: str = "") -> bytes:
    """PNG with one panel per scalar constant: mean +- 95 % half-width against n_cells.

    A constant whose means span more than a factor 3 gets a log axis (its bars clipped at a
    tenth of the mean). Where the size trend is significant the extrapolated value (n -> inf) is a dashed line,
    with the fitted ``a + b * n**(-1/3)`` dotted; otherwise the panel says "no size trend
    detected". ``summary`` is the ``convergence.json`` dict (schema in
    :mod:`metasheet.homogenize.ensemble`).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(summary["constants"])
    sizes = summary["sizes"]
    n = np.array([s["n_cells"] for s in sizes], float)
    ncol = min(3, max(1, len(names)))
    nrow = -(-len(names) // ncol) if names else 1
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.3 * ncol, 3.4 * nrow), squeeze=False)
    conf = summary.get("confidence", 0.95)
    for ax, name in zip(axes.ravel(), names):
        y = np.array([_f(s["constants"][name]["mean"]) for s in sizes])
        e = np.array([_f(s["constants"][name]["halfwidth"]) for s in sizes])
        log = bool(np.all(y > 0) and np.nanmax(y) > 3 * np.nanmin(y))  # means a decade apart: log axis
        ax.errorbar(n, y, yerr=np.vstack([np.minimum(e, 0.9 * y), e]) if log else e, marker="o", ms=4, capsize=3,
                    color="C0", label=f"mean, {conf:.0%} CI" + (" (clipped at 0.1 x mean)" if log else ""))
        if log:
            ax.set_yscale("log")
        for ni, yi, s in zip(n, y, sizes):
            ax.annotate(f"k={s['k']}", (ni, yi), textcoords="offset points", xytext=(4, 4), fontsize=7)
        trend = summary.get("trend", {}).get(name)
        if trend and trend.get("significant") and trend.get("extrapolated") is not None:
            a, b, ha = trend["a"], trend["b"], _f(trend["halfwidth_a"])
            ax.axhline(a, ls="--", color="C3", lw=1.2, label=f"n -> inf: {a:.4g} +- {ha:.2g}")
            fitted = summary.get("trend_sizes") or n.tolist()  # the fit's sizes (older files: all)
            grid = np.geomspace(min(fitted), n.max() * 4, 60)
            ax.plot(grid, a + b * grid ** (-1.0 / 3.0), ":", color="C3", lw=1,
                    label=f"fit over {', '.join(f'{v:g}' for v in fitted)} cells")
        elif trend:
            ax.text(0.02, 0.03, "no size trend detected", transform=ax.transAxes, fontsize=8, color="0.3")
        ax.set_xscale("log")
        ax.set_xticks(n, [f"{v:g}" for v in n])
        ax.minorticks_off()
        ax.set_xlabel("cells in the periodic volume [-]")
        ax.set_ylabel(_LABELS.get(name, name))
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    for ax in axes.ravel()[len(names):]:
        ax.axis("off")
    if title:
        fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    return figure_png(fig, dpi=100, tight=False)


def _f(v) -> float:
    """JSON null (a non-finite number) as NaN, for matplotlib."""
    return float("nan") if v is None else float(v)
