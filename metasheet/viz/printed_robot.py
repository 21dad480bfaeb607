"""The printed robot's picture (stage ``printed``): the rod's roll against the motors' travel,
print by print, and where the walls first touch."""

from __future__ import annotations

import numpy as np

from . import figure_png


def printed_robot_picture(study: dict) -> bytes:
    """PNG bytes: left, the rod's rotation with all six motors pulled (travel > 0) and pushed
    (travel < 0) per print, dotted past the walls' first contact (a cross marks it); middle, the
    validity map around the plane of the sheets' common modes (each print's first-contact travel
    against the direction's angle); right, on the rays of Fig. 5, the rod's travel before the walls
    touch (the smallest over the prints) by the ray's azimuth and elevation.

    ``study``: the ``printed`` stage's ``printed.json`` dict."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(16.5, 4.8))
    a = fig.add_subplot(1, 3, 1)
    plane_ax = fig.add_subplot(1, 3, 2, projection="polar")
    ray_ax = fig.add_subplot(1, 3, 3)
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
    maps = [r for r in rows if r.get("map")]
    if maps:
        _plane_panel(fig, plane_ax, maps, study["params"]["search_deg"])
        _ray_panel(fig, ray_ax, maps)
    else:
        for ax in (plane_ax, ray_ax):
            ax.text(0.5, 0.5, "walls not searched (contact = false)", ha="center", va="center", transform=ax.transAxes)
            ax.set_axis_off()
    names = {"roll": "rod rolled both ways (Fig. 7)", "rotations": "10 deg about each axis at rest",
             "workspace": "Fig. 5", "ranges": "Fig. 6", "maze": "maze"}
    said = "; ".join(f"{names[k]}: {v}" for k, v in study["claims"].items() if k in names)
    fig.suptitle(f"Printed robot, {len(rows)} print(s). {said}", fontsize=9, wrap=True)
    fig.tight_layout()
    return figure_png(fig, dpi=110)


def _plane_panel(fig, ax, rows, search_deg: float) -> None:
    """Each print's first-contact travel [deg] around the plane of the common modes (none within
    the search: drawn at the search's end, hollow)."""
    for i, row in enumerate(rows):
        pts = sorted(row["map"]["plane"], key=lambda x: x["phi_deg"])
        if not pts:
            continue
        phi = np.radians([x["phi_deg"] for x in pts] + [pts[0]["phi_deg"]])
        r = np.array([np.nan if x["contact_deg"] is None else x["contact_deg"] for x in pts + pts[:1]])
        ax.plot(phi, r, "o-", color=f"C{i}", ms=3, label=f"seed {row['seed']}")
        none = np.isnan(r)
        ax.plot(phi[none], np.full(int(none.sum()), search_deg), "o", mfc="none", color=f"C{i}", ms=4)
    ticks = {0: "A up", 45: "roll up", 90: "B up", 180: "A down", 225: "roll down", 270: "B down"}
    ax.set_xticks(np.radians(list(ticks)), list(ticks.values()), fontsize=7)
    ax.tick_params(axis="y", labelsize=7)
    ax.set_title("Walls' first contact [deg of the largest motor]\naround sheet A's and B's common modes", fontsize=9)
    ax.legend(fontsize=7, loc="lower left", bbox_to_anchor=(-0.15, -0.15))


def _ray_panel(fig, ax, rows) -> None:
    """The rod's travel along each ring ray of Fig. 5 before the walls touch [mm], the smallest
    over the prints, as an azimuth by elevation map; the two rod rays in the title."""
    rays = [r["map"]["rays"] for r in rows if r["map"]["rays"]]
    if not rays:
        ax.text(0.5, 0.5, "rays not searched (map_rays = false)", ha="center", va="center", transform=ax.transAxes)
        ax.set_axis_off()
        return
    worst = [min((x[k]["contact_mm"] for x in rays if x[k]["contact_mm"] is not None), default=np.nan)
             for k in range(len(rays[0]))]
    ring = [(x["azimuth"], x["elevation"], w) for x, w in zip(rays[0], worst) if x["azimuth"] >= 0]
    n_az = max(a for a, _, _ in ring) + 1
    n_el = max(e for _, e, _ in ring) + 1
    grid = np.full((n_el, n_az), np.nan)
    for a, e, w in ring:
        grid[e, a] = w
    im = ax.imshow(grid, origin="lower", aspect="auto", cmap="viridis",
                   extent=(-0.5 * 360 / n_az, 360 - 0.5 * 360 / n_az, -0.5, n_el - 0.5))
    for e in range(n_el):
        for a in range(n_az):
            ok = np.isfinite(grid[e, a])  # no contact within the search on any print: blank, "none"
            ax.text(a * 360 / n_az, e, f"{grid[e, a]:.2g}" if ok else "none", ha="center", va="center", fontsize=6,
                    color="w" if ok else "k")
    fig.colorbar(im, ax=ax, label="rod travel before the walls touch [mm]")
    ax.set_xlabel("ray azimuth about the rod [deg]")
    # the grid's rod axis is x (metasheet.studies.grid.star_grid's default, the stage's)
    el = {x["elevation"]: np.degrees(np.arcsin(np.clip(x["direction"][0], -1, 1)))
          for x in rays[0] if x["azimuth"] >= 0}
    ax.set_yticks(range(n_el), [f"{el[e]:.0f}" for e in range(n_el)])
    ax.set_ylabel("ray elevation towards the rod axis [deg]")
    rod = [f"{w:.2g} mm" if np.isfinite(w) else "no contact" for x, w in zip(rays[0], worst) if x["azimuth"] < 0]
    ax.set_title(f"On the rays of Fig. 5, orientation held (smallest over the prints);\nalong the rod: "
                 f"{' and '.join(rod)}", fontsize=9)
