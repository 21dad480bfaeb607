"""Picture of a sheet cut from a foam against the bulk continuum (``plate.json``).

:func:`plate_picture` returns PNG bytes (matplotlib, Agg) drawn from the homogenize stage's
``plate.json`` alone (:meth:`metasheet.homogenize.plate_slabs.SlabStudy.to_dict`): each
diagonal stiffness of the sheet over the bulk plate's, one dot per slab, the mean with its 95 %
interval, and the line at 1 where the bulk continuum would be the sheet.
"""

from __future__ import annotations

import numpy as np

from . import figure_png, one_at_a_time


@one_at_a_time
def plate_picture(doc: dict, title: str = "") -> bytes:
    """PNG: ratio to the bulk plate (log axis) of A_11, A_22, A_66 (stretching, shear) and
    D_11, D_22, D_66 (bending, twist) for every slab of ``doc`` (a ``plate.json`` dict)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [n for n in doc["ratio_to_bulk"] if n != "geometric_mean"]
    fig, ax = plt.subplots(figsize=(7.5, 4.2))
    for i, name in enumerate(names):
        pts = np.array([s["ratio_to_bulk"][name] for s in doc["slabs"]])
        ax.scatter(np.full(len(pts), i) + np.linspace(-0.15, 0.15, len(pts)), pts, s=14, color="0.55", zorder=2)
        st = doc["ratio_to_bulk"][name]
        lo = max(st["mean"] - st["halfwidth"], 1e-3)
        ax.errorbar(i + 0.3, st["mean"], yerr=[[st["mean"] - lo], [st["halfwidth"]]], fmt="o",
                    color="C0" if name.startswith("A") else "C3", capsize=4, zorder=3)
    ax.axhline(1.0, color="k", lw=1, ls="--")
    ax.text(-0.45, 1.02, "bulk continuum", va="bottom", ha="left", fontsize=8)
    ax.set_yscale("log")
    ax.set_xticks(range(len(names)), [f"{n}\n({'stretch' if n.startswith('A') else 'bend'})" for n in names])
    ax.set_ylabel("sheet / bulk plate [-]")
    gm = doc["ratio_to_bulk"]["geometric_mean"]
    ax.set_title(title or (f"a {doc['thickness_mm']:.2f} mm sheet cut from the foam: {len(doc['slabs'])} slabs; "
                           f"geometric mean {gm['mean']:.2f} +- {gm['halfwidth']:.2f}"), fontsize=9)
    ax.grid(True, axis="y", which="both", alpha=0.3)
    return figure_png(fig)
