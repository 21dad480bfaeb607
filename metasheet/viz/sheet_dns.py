"""The printed sheet against the homogenised sheet: ``sheet_dns.png`` (issue 44)."""

from __future__ import annotations

import numpy as np

from . import figure_png


def sheet_dns_picture(study: dict) -> bytes:
    """PNG bytes: left, each mode's stiffness ratio printed / homogenised (the 18 generalised
    eigenvalues of the arms' block, both sheets, every realisation; log scale); right, the
    printed robot's rest singular values and rod roll per degree over the homogenised robot's.

    ``study``: :func:`metasheet.studies.sheet_dns.dns_study`'s dict.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(12.5, 4.6))
    rows = study["realisations"]
    for i, row in enumerate(rows):
        for label, marker in (("normal", "o"), ("mirrored", "s")):
            lam = np.asarray(row["sheets"][label]["eigen_ratios"])
            a.plot(np.arange(1, len(lam) + 1), lam, marker=marker, ls="-" if label == "normal" else ":",
                   color=f"C{i}", ms=4, label=f"seed {row['seed']}, {label}")
    a.axhline(1.0, color="k", lw=0.8)
    a.set_yscale("log")
    a.set_xlabel("mode (ascending)")
    a.set_ylabel("stiffness printed / homogenised")
    a.set_title("Sheet on its grips: generalised eigenvalues (centre held)", fontsize=10)
    a.legend(fontsize=7, ncol=2)
    hom = study["homogenised_robot"]
    sv0 = np.asarray(hom["singular_values"])
    x = np.arange(len(sv0) + 1)
    names = [f"sigma {k + 1}" for k in range(len(sv0))] + ["rod roll"]
    w = 0.8 / max(len(rows), 1)
    for i, row in enumerate(rows):
        r = row["robot"]
        vals = list(np.asarray(r["singular_values"]) / sv0) + [r["rod_roll_ratio"]]
        b.bar(x + (i - (len(rows) - 1) / 2) * w, vals, width=w, color=f"C{i}", label=f"seed {row['seed']}")
    b.axhline(1.0, color="k", lw=0.8)
    b.set_xticks(x, names, fontsize=8)
    b.set_ylabel("printed robot / homogenised robot")
    b.set_title(f"Robot at rest (linear, no gravity): homogenised rod roll {hom['rod_rotation_deg_per_deg']:+.3f} "
                "deg/deg", fontsize=10)
    b.legend(fontsize=7)
    fig.suptitle(study.get("verdict", ""), fontsize=9, wrap=True)
    fig.tight_layout()
    return figure_png(fig, dpi=110)
