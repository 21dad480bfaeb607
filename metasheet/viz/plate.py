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
    """PNG: ratio to the bulk plate (log axis) of A_11, A_22, A_66 (stretching, shear), D_11,
    D_22, D_66 (bending, twist) and, when computed, H_xz, H_yz (transverse shear, against 5/6 G t)
    for every slab of ``doc`` (a ``plate.json`` dict)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [n for n in doc["ratio_to_bulk"] if n != "geometric_mean"]
    columns = [(n, [s["ratio_to_bulk"][n] for s in doc["slabs"]], doc["ratio_to_bulk"][n]) for n in names]
    if "shear" in doc:
        sh = doc["shear"]
        columns += [(n, [row[i] for row in sh["slab_ratios"]], sh["ratio_to_bulk"][n])
                    for i, n in enumerate(sh["ratio_to_bulk"])]
    kinds = {"A": ("C0", "stretch"), "D": ("C3", "bend"), "H": ("C2", "shear")}
    fig, ax = plt.subplots(figsize=(7.5 + 0.8 * (len(columns) - 6), 4.2))
    for i, (name, pts, st) in enumerate(columns):
        pts = np.asarray(pts, float)
        ax.scatter(np.full(len(pts), i) + np.linspace(-0.15, 0.15, len(pts)), pts, s=14, color="0.55", zorder=2)
        lo = max(st["mean"] - st["halfwidth"], 1e-3)
        ax.errorbar(i + 0.3, st["mean"], yerr=[[st["mean"] - lo], [st["halfwidth"]]], fmt="o",
                    color=kinds[name[0]][0], capsize=4, zorder=3)
    ax.axhline(1.0, color="k", lw=1, ls="--")
    ax.text(-0.45, 1.02, "bulk continuum", va="bottom", ha="left", fontsize=8)
    ax.set_yscale("log")
    ax.set_xticks(range(len(columns)), [f"{n}\n({kinds[n[0]][1]})" for n, _, _ in columns])
    ax.set_ylabel("sheet / bulk plate [-]")
    gm = doc["ratio_to_bulk"]["geometric_mean"]
    ax.set_title(title or (f"a {doc['thickness_mm']:.2f} mm sheet cut from the foam: {len(doc['slabs'])} slabs; "
                           f"geometric mean {gm['mean']:.2f} +- {gm['halfwidth']:.2f}"), fontsize=9)
    ax.grid(True, axis="y", which="both", alpha=0.3)
    return figure_png(fig)
