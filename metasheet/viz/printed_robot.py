"""The printed robot's picture (stage ``printed``): the rod's roll against the motors' travel,
print by print, and where the walls first touch."""

from __future__ import annotations

import numpy as np

from . import figure_png


def printed_robot_picture(study: dict) -> bytes:
    """PNG bytes: left, the rod's rotation with all six motors pulled (travel > 0) and pushed
    (travel < 0) per print, dotted past the walls' first contact (a cross marks it); right, each
    print's first-contact travel per searched direction (the walls' limits; hatched to the
    search's end: none found).

    ``study``: the ``printed`` stage's ``printed.json`` dict."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(12.5, 4.6))
    rows = study["realisations"]
    for i, row in enumerate(rows):
        for name, sign in (("pull", 1.0), ("push", -1.0)):
            r = row["roll"][name]
            path = np.asarray(r["path"], float)
            t, rot = sign * path[:, 0], path[:, 1]
            c = r.get("contact_deg")
            inside = path[:, 0] <= (np.inf if c is None else c)
            label = f"seed {row['seed']}" if name == "pull" else None
            a.plot(t, rot, ":", color=f"C{i}")
            a.plot(t[inside], rot[inside], "-", color=f"C{i}", label=label)
            if "rod_rotation_at_contact_deg" in r:
                a.plot(sign * c, r["rod_rotation_at_contact_deg"], "x", color=f"C{i}", ms=8, mew=2)
    a.axhline(0.0, color="k", lw=0.6)
    a.axvline(0.0, color="k", lw=0.6)
    a.set_xlabel("all six motors from rest [deg] (pulled > 0, pushed < 0)")
    a.set_ylabel("rod rotation [deg]")
    a.set_title("The rod's roll (x: the walls first touch; dotted: past it)", fontsize=10)
    a.legend(fontsize=8)
    names = list((rows[0]["limits"] or {}).get("directions", {}))
    if names:
        x = np.arange(len(names))
        w = 0.8 / max(len(rows), 1)
        for i, row in enumerate(rows):
            vals = [row["limits"]["directions"][n]["contact_deg"] for n in names]
            none = [v is None for v in vals]
            at = x + (i - (len(rows) - 1) / 2) * w
            b.bar(at, [np.nan if v is None else v for v in vals], width=w, color=f"C{i}", label=f"seed {row['seed']}")
            # no contact within the search: a hatched bar to the search's end
            b.bar(at[none], [study["params"]["search_deg"]] * int(sum(none)), width=w, color="none",
                  edgecolor=f"C{i}", hatch="//", lw=0.5)
        b.set_xticks(x, names, fontsize=8, rotation=30)
        b.set_ylabel("motor travel at the first contact [deg]")
        b.set_title(f"The walls' first self-contact (first order; searched to {study['params']['search_deg']:g} deg)",
                    fontsize=10)
        b.legend(fontsize=8)
    else:
        b.text(0.5, 0.5, "walls not searched (contact = false)", ha="center", va="center", transform=b.transAxes)
        b.set_axis_off()
    names = {"roll": "rod rolled both ways (Fig. 7)", "rotations": "10 deg about each axis at rest",
             "workspace": "Fig. 5", "ranges": "Fig. 6", "maze": "maze"}
    said = "; ".join(f"{names[k]}: {v}" for k, v in study["claims"].items() if k in names)
    fig.suptitle(f"Printed robot, {len(rows)} print(s). {said}", fontsize=9, wrap=True)
    fig.tight_layout()
    return figure_png(fig, dpi=110)
