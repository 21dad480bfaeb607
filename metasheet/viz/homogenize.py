"""Pictures and field meshes of a homogenisation result.

:func:`summary_picture` returns PNG bytes (matplotlib, Agg): the effective stiffness
matrix, the fitted constants, and the strain localisation per load case.
:func:`voxel_field_mesh` / :func:`tet_field_mesh` return a ``meshio.Mesh`` of the
solid with per-element strains, for ParaView; the stage layer writes both.
"""

from __future__ import annotations


import numpy as np

from ..homogenize.result import LOAD_CASES, HomogenizationResult
from . import figure_png, one_at_a_time

#: VTK hexahedron order of our local nodes a = ax + 2 ay + 4 az.
_VTK_HEX = [0, 1, 3, 2, 4, 5, 7, 6]


def _cell_data(result: HomogenizationResult) -> dict:
    data = {}
    loc = result.localisation
    if loc is None:
        return data
    for j, name in enumerate(LOAD_CASES):
        data[f"strain_E{name}"] = [loc.strain[:, j, :]]
        data[f"max_principal_E{name}"] = [loc.max_principal[:, j]]
    return data


def voxel_field_mesh(result: HomogenizationResult, shape, size):
    """Hexahedral mesh of the solid voxels the result used, with per-element fields.

    Parameters
    ----------
    result : from :func:`~metasheet.homogenize.homogenize_voxels`.
    shape : (3,) grid shape; size : (3,) box [mm].

    Returns
    -------
    meshio.Mesh with cell data ``strain_E<IJ>`` (m, 6) Voigt strain (engineering shear)
    under the unit macro strain E_IJ, ``max_principal_E<IJ>`` (m,), and ``voxel`` (m,).
    """
    import meshio

    shape = np.asarray(shape, int)
    h = np.asarray(size, float) / shape
    ijk = np.stack(np.unravel_index(result.element_ids, tuple(shape)), axis=1)
    corners = np.array([[a & 1, (a >> 1) & 1, (a >> 2) & 1] for a in range(8)])
    nodes = ijk[:, None, :] + corners[None]
    flat = (nodes[..., 0] * (shape[1] + 1) + nodes[..., 1]) * (shape[2] + 1) + nodes[..., 2]
    grid, inv = np.unique(flat, return_inverse=True)
    points = np.stack(np.unravel_index(grid, tuple(shape + 1)), axis=1) * h
    cells = inv.reshape(-1, 8)[:, _VTK_HEX]
    data = _cell_data(result)
    data["voxel"] = [np.asarray(result.element_ids, np.int64)]
    return meshio.Mesh(points, [("hexahedron", cells)], cell_data=data)


def tet_field_mesh(result: HomogenizationResult, points, tets):
    """Tet mesh of the tets the result used (from :func:`~metasheet.homogenize.homogenize_mesh`)."""
    import meshio

    data = _cell_data(result)
    data["tet"] = [np.asarray(result.element_ids, np.int64)]
    return meshio.Mesh(np.asarray(points, float), [("tetra", np.asarray(tets)[result.element_ids])], cell_data=data)


@one_at_a_time
def summary_picture(result: HomogenizationResult, title: str = "") -> bytes:
    """PNG: C (6 x 6) heat map, fitted constants, localisation curves per load case."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import SymLogNorm

    fig, axes = plt.subplots(1, 2, figsize=(12, 6.2), gridspec_kw={"width_ratios": [1, 1.2]})
    ax = axes[0]
    C = np.asarray(result.C)
    vmax = np.abs(C).max()
    im = ax.imshow(C, cmap="RdBu_r", norm=SymLogNorm(linthresh=1e-3 * vmax, vmin=-vmax, vmax=vmax))
    for i in range(6):
        for j in range(6):
            ax.text(j, i, f"{C[i, j]:.3g}", ha="center", va="center", fontsize=7.5,
                    color="white" if abs(C[i, j]) > 0.3 * vmax else "black")
    ax.set_xticks(range(6), LOAD_CASES)
    ax.set_yticks(range(6), LOAD_CASES)
    ax.set_title("effective stiffness C* [MPa] (Voigt, engineering shear)", fontsize=10)
    fig.colorbar(im, ax=ax, fraction=0.046)
    m = result.fit.material
    axis = np.asarray(result.fit.axis)
    text = (f"E_t = {m.E_t:.4g} MPa   E_l = {m.E_l:.4g} MPa\n"
            f"nu_t = {m.nu_t:.3f}   nu_tl = {m.nu_tl:.3f}   mu_l = {m.mu_l:.4g} MPa\n"
            f"axis l = ({axis[0]:.2f}, {axis[1]:.2f}, {axis[2]:.2f}), alpha = {m.alpha:.1f} %, "
            f"TI misfit {result.fit.misfit:.2%}\n"
            f"density {result.relative_density:.3f}, {result.n_dof} dofs, {result.solver}")
    ax.text(0.0, -0.16, text, transform=ax.transAxes, fontsize=8.5, va="top", family="monospace")
    ax = axes[1]
    loc = result.localisation
    if loc is not None:
        scale = np.array([1.0, 1.0, 1.0, 0.5, 0.5, 0.5])
        for j, name in enumerate(LOAD_CASES):
            r = np.sort(loc.max_principal[:, j] / scale[j])
            frac = 1.0 - np.arange(len(r)) / len(r)
            ax.semilogy(r, frac, label=f"E{name}: max {loc.ratio_max[j]:.1f}, p99 {loc.ratio_p99[j]:.1f}")
        ax.set_xlabel("local max |principal strain| / macro principal strain [-]")
        ax.set_ylabel("fraction of solid elements above [-]")
        ax.set_title("strain localisation per unit macro strain", fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    else:
        ax.axis("off")
    if title:
        fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    fig.subplots_adjust(bottom=0.26)
    return figure_png(fig, dpi=110, tight=False)


#: each panel's note on its bars (:attr:`~metasheet.homogenize.chart_bars.ChartBars.pooled`)
BARS_TITLE = {"chart": "bars: relative scatter pooled over the chart",
              "lines": "bars: pooled along each line where homogeneous, else per point",
              "points": "bars: per point"}


@one_at_a_time
def chart_picture(rows, title: str = "") -> bytes:
    """PNG with one panel per constant (E_t, E_l, nu_t, nu_tl, mu_l, alpha) against the
    achieved relative density, one line per value of the family's second setting (stretch,
    or Polyfoam's kgon_x_shrink), seed-averaged; with >= 2 seeds per point the error bars are the
    95 % interval of the mean, the seeds' relative scatter pooled over the points or along each
    line where it is homogeneous (:mod:`metasheet.homogenize.chart_bars`), none with one seed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..homogenize.chart import FAMILY_AXES, table_family
    from ..homogenize.chart_bars import chart_bars

    first, second = FAMILY_AXES[table_family(rows)]
    keys = [("E_t", "E_t [MPa]", True), ("E_l", "E_l [MPa]", True), ("mu_l", "mu_l [MPa]", True),
            ("nu_t", "nu_t [-]", False), ("nu_tl", "nu_tl [-]", False), ("alpha", "alpha = 100 - 100 E_l/E_t [%]", False)]
    stretches = sorted({float(r[second]) for r in rows})
    fig, axes = plt.subplots(2, 3, figsize=(13, 7.5))
    cmap = plt.get_cmap("viridis")
    rho = chart_bars(rows, "relative_density", first, second)
    for ax, (k, label, log) in zip(axes.ravel(), keys):
        bars = chart_bars(rows, k, first, second)
        for i, s in enumerate(stretches):
            at = bars.points[:, 1] == s  # this line's points, ascending in the first setting
            y, e = bars.means[at], bars.halfwidths[at]
            if log:  # a bar reaching below zero is drawn down to a tenth of the mean
                e = np.vstack([np.minimum(e, 0.9 * y), e])
            ax.errorbar(rho.means[at], y, yerr=e, marker="o", ms=4, capsize=2,
                        color=cmap(i / max(1, len(stretches) - 1)), label=f"{second} {s:g}")
        if bars.k.max() > 1:
            ax.set_title(BARS_TITLE[bars.pooled], fontsize=8)
        if log:
            ax.set_yscale("log")
        ax.set_xlabel("relative density [-]")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    if title:
        fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    return figure_png(fig, dpi=100, tight=False)
