"""Pictures of the studies: workspace (paper Fig. 5), motor ranges (Fig. 6), anisotropy
sweep (Fig. 7) and the maze. Functions take plain arrays and return PNG bytes (matplotlib,
Agg); the stage layer writes them.
"""

from __future__ import annotations


import numpy as np
from . import figure_png, one_at_a_time

CLASS_COLOURS = {3: "#1f5fbf", 2: "#2ca02c", 1: "#ff7f0e", 0: "#d62728", -1: "#c8c8c8"}
CLASS_LABELS = {3: "3 rotations", 2: "2 rotations", 1: "1 rotation", 0: "reachable only", -1: "unreachable"}
#: (title, horizontal axis, vertical axis) of the three views; the rod runs along x
VIEWS = (("front (along the rod)", 1, 2), ("side", 0, 2), ("top", 0, 1))
AXIS = ("x [mm]", "y [mm]", "z [mm]")


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt



def _depth_order(points: np.ndarray, h: int, v: int) -> np.ndarray:
    """Draw far points first so the near ones stay visible (depth = the third axis)."""
    d = 3 - h - v
    return np.argsort(points[:, d], kind="stable")


@one_at_a_time
def workspace_picture(points, cls, strain, sigma_min, valid, *, strain_limit: float, title: str = "",
                      tried=None, rot_untested=None) -> bytes:
    """Three rows (class, max principal strain, smallest singular value) x three views.

    points : (n, 3) [mm]; cls : (n,) int class (-1 unreachable); strain, sigma_min : (n,)
    (NaN where unreachable); valid : (n,) bool, strain within ``strain_limit``; tried : (n,)
    bool or None: the unreachable points never tried (their ray ended before them) are drawn
    apart, as "not tried"; rot_untested : (n,) bool or None: reachable points whose rotations
    were not tried (the workspace's ``rot_stop_after``), drawn apart from "reachable only".
    """
    plt = _plt()
    P = np.asarray(points, float)
    cls = np.asarray(cls, int)
    ok = cls >= 0
    untried = np.zeros(len(cls), bool) if tried is None else (~np.asarray(tried, bool) & ~ok)
    no_rot = np.zeros(len(cls), bool) if rot_untested is None else (np.asarray(rot_untested, bool) & ok)
    fig, axes = plt.subplots(3, 3, figsize=(15, 14.5), squeeze=False)
    for j, (name, h, v) in enumerate(VIEWS):
        order = _depth_order(P, h, v)
        ax = axes[0, j]
        far = order[untried[order]]
        if len(far):
            ax.scatter(P[far, h], P[far, v], s=4, c="#c8c8c8", lw=0, alpha=0.5,
                       label=f"not tried: the ray ended before ({len(far)})")
        bare = order[no_rot[order]]
        if len(bare):
            ax.scatter(P[bare, h], P[bare, v], s=10, facecolors="none", edgecolors=CLASS_COLOURS[0], lw=0.6,
                       label=f"reachable, rotations not tried ({len(bare)})")
        for c in (-1, 0, 1, 2, 3):
            sel = order[(cls[order] == c) & ~untried[order] & ~no_rot[order]]
            if len(sel):
                if c >= 0:
                    ax.scatter(P[sel, h], P[sel, v], s=10, c=CLASS_COLOURS[c], label=f"{CLASS_LABELS[c]} ({len(sel)})",
                               alpha=0.9, lw=0)
                else:
                    ax.scatter(P[sel, h], P[sel, v], s=9, c="#909090", marker="x", lw=0.6, alpha=0.6,
                               label=f"{CLASS_LABELS[c]} ({len(sel)})")
        ax.set_title(f"{name}: class")
        sel = order[ok[order]]
        for row, values, cmap, label in ((1, strain, "viridis", "max principal strain [-]"),
                                         (2, sigma_min, "magma", "smallest Jacobian singular value")):
            ax2 = axes[row, j]
            ax2.scatter(P[~ok, h], P[~ok, v], s=3, c=CLASS_COLOURS[-1], alpha=0.3, lw=0)
            if len(sel):
                sc = ax2.scatter(P[sel, h], P[sel, v], s=10, c=np.asarray(values)[sel], cmap=cmap, lw=0)
                fig.colorbar(sc, ax=ax2, shrink=0.8, label=label)
            if row == 1:
                bad = sel[~np.asarray(valid, bool)[sel]]
                if len(bad):
                    ax2.scatter(P[bad, h], P[bad, v], s=22, facecolors="none", edgecolors="red", lw=0.8,
                                label=f"strain > {strain_limit:g} ({len(bad)})")
                    ax2.legend(loc="upper right", fontsize=8)
            ax2.set_title(f"{name}: {label}")
        for row in range(3):
            axes[row, j].set_xlabel(AXIS[h])
            axes[row, j].set_ylabel(AXIS[v])
            axes[row, j].set_aspect("equal")
            axes[row, j].grid(alpha=0.3)
    axes[0, 0].legend(loc="upper right", fontsize=8, markerscale=1.5)
    fig.suptitle(title or "Workspace (paper Fig. 5)", fontsize=14)
    fig.tight_layout()
    return figure_png(fig)


@one_at_a_time
def ranges_picture(points, reached, ranges, *, found=None, title: str = "") -> bytes:
    """Nested reachable sets for each motor range (Fig. 6): points (n, 3), reached (r, n), ranges (r, 2);
    found (r, n): the points each range's own search reached (the legend counts the others)."""
    plt = _plt()
    P = np.asarray(points, float)
    R = np.asarray(reached, bool)
    F = R if found is None else np.asarray(found, bool)
    widths = np.asarray(ranges, float)[:, 1] - np.asarray(ranges, float)[:, 0]
    order_r = np.argsort(-widths, kind="stable")  # widest first, narrower drawn on top
    colours = plt.get_cmap("plasma")(np.linspace(0.1, 0.85, len(order_r)))
    fig, axes = plt.subplots(1, 3, figsize=(15, 5), squeeze=False)
    for j, (name, h, v) in enumerate(VIEWS):
        ax = axes[0, j]
        ax.scatter(P[:, h], P[:, v], s=3, c=CLASS_COLOURS[-1], alpha=0.3, lw=0)
        for k, r in enumerate(order_r):
            sel = np.flatnonzero(R[r])
            sel = sel[_depth_order(P[sel], h, v)] if len(sel) else sel
            lo, hi = ranges[r]
            extra = int((R[r] & ~F[r]).sum())
            ax.scatter(P[sel, h], P[sel, v], s=12 - 3 * k, color=colours[k], lw=0,
                       label=f"{lo:g}-{hi:g} deg ({len(sel)} points"
                             + (f", {extra} by a narrower range's path)" if extra else ")"))
        ax.set_title(name)
        ax.set_xlabel(AXIS[h])
        ax.set_ylabel(AXIS[v])
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="upper right", fontsize=8)
    fig.suptitle(title or "Reachable workspace for several motor ranges (paper Fig. 6)")
    fig.tight_layout(rect=(0, 0, 1, 0.95))  # the equal-aspect panels otherwise meet the title
    return figure_png(fig)


@one_at_a_time
def anisotropy_picture(alpha, rod_rotation_deg, lateral_mm, *, pull_deg: float, push_deg: float,
                       title: str = "") -> bytes:
    """Rod rotation and lateral translation against alpha (Fig. 7); (a,) and (a, 2) arrays."""
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5), squeeze=False)
    for j, lab in enumerate((f"pull {pull_deg:.3g} deg", f"push {push_deg:.3g} deg")):
        axes[0, 0].plot(alpha, np.asarray(rod_rotation_deg)[:, j], "o-", label=lab)
        axes[0, 1].plot(alpha, np.asarray(lateral_mm)[:, j], "s-", label=lab)
    axes[0, 0].set_ylabel("rotation about the rod [deg]")
    axes[0, 1].set_ylabel("lateral translation of the effector [mm]")
    for ax in axes[0]:
        ax.set_xlabel("alpha = 100 - 100 E_l / E_t [%]")
        ax.axhline(0.0, color="k", lw=0.6)
        ax.grid(alpha=0.3)
        ax.legend()
    fig.suptitle(title or "Anisotropy sweep: all motors together (paper Fig. 7)")
    fig.tight_layout()
    return figure_png(fig)


@one_at_a_time
def maze_picture(path, time, motors_deg, track_mm, track_deg, segment_ok, segment_ok_silicone,
                 motor_range, *, title: str = "", strain=None, strain_limit: float | None = None) -> bytes:
    """Maze path with feasible / impossible segments (foam vs silicone; ``segment_ok_silicone``
    None: foam only), the motor series and
    the replay's tracking error (and the strain along the path, against its limit, when given).
    path (m, 2) [mm]; time (T,); motors_deg (T, 6); strain (T,) [-]."""
    plt = _plt()
    P = np.asarray(path, float)
    fig, axes = plt.subplots(1, 3, figsize=(17, 5), squeeze=False)
    ax = axes[0, 0]
    for i in range(len(P) - 1):
        d = P[i + 1] - P[i]
        normal = np.array([-d[1], d[0]]) / max(np.hypot(*d), 1e-12)  # silicone beside the foam, whatever the heading
        for ok_arr, off, name in ((segment_ok, 0.0, "foam"), (segment_ok_silicone, 1.2, "silicone")):
            if ok_arr is None:  # the silicone sheets were not run (the stage's ``silicone``)
                continue
            ok = bool(ok_arr[i])
            seg = P[i:i + 2] + off * normal
            ax.plot(seg[:, 0], seg[:, 1], "-" if ok else ":", lw=3 if name == "foam" else 1.5,
                    color=("#1f77b4" if name == "foam" else "#9467bd") if ok else "#d62728")
        mid = P[i:i + 2].mean(axis=0)
        ax.annotate(str(i), mid, fontsize=8, xytext=(3, 3), textcoords="offset points")
    ax.plot(*P[0], "ko")
    ax.plot([], [], "-", color="#1f77b4", lw=3, label="foam: feasible")
    if segment_ok_silicone is not None:
        ax.plot([], [], "-", color="#9467bd", lw=1.5, label="silicone: feasible (offset)")
    ax.plot([], [], ":", color="#d62728", lw=2, label="impossible")
    ax.set_aspect("equal")
    ax.set_xlabel("maze u = rod axis [mm]")
    ax.set_ylabel("maze v [mm]")
    ax.legend(fontsize=8, loc="center", bbox_to_anchor=(0.5, 0.62))  # inside the loop, off the path
    ax.set_title("path and segment feasibility")
    ax.grid(alpha=0.3)
    ax = axes[0, 1]
    for k in range(np.asarray(motors_deg).shape[1]):
        ax.plot(time, np.asarray(motors_deg)[:, k], label=f"motor {k}")
    for lim in motor_range:
        ax.axhline(lim, color="k", ls="--", lw=0.8)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("motor angle [deg]")
    ax.set_title("open-loop motor series (foam)")
    ax.legend(fontsize=7, ncol=2)
    ax.grid(alpha=0.3)
    ax = axes[0, 2]
    ax.plot(time, track_mm, label="position [mm]")
    ax.plot(time, track_deg, label="orientation [deg]")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("replay tracking error")
    ax.set_title("forward replay vs command (foam)")
    ax.grid(alpha=0.3)
    handles = ax.get_legend_handles_labels()
    if strain is not None:
        ax2 = ax.twinx()
        ax2.plot(time, strain, color="#2ca02c", lw=1.2, label="largest principal strain [-]")
        if strain_limit is not None:
            ax2.axhline(strain_limit, color="#2ca02c", ls="--", lw=0.8, label=f"strain limit {strain_limit:g}")
        # headroom on both axes: the one legend sits above the curves
        ax2.set_ylim(0, 1.45 * max(np.nanmax(np.append(strain, 0)), strain_limit or 0))
        ax2.set_ylabel("strain [-]")
        ax.set_ylim(0, 1.45 * max(np.nanmax(np.append(track_mm, 0)), np.nanmax(np.append(track_deg, 0)), 1e-9))
        h2 = ax2.get_legend_handles_labels()
        handles = (handles[0] + h2[0], handles[1] + h2[1])
    ax.legend(*handles, loc="upper center", fontsize=8, ncol=2)
    fig.suptitle(title or "Maze: tilt commands solved open loop")
    fig.tight_layout()
    return figure_png(fig)
