"""Design chart: the five constants over (relative density, stretch), and its inverse.

:func:`chart_points` lists the sweep's work items; :func:`evaluate_point` (module
level, picklable) builds one foam with :mod:`metasheet.cells.design` and homogenises
it, so the sweep runs through :class:`~metasheet.executor.Executor` in parallel.
:func:`lookup` inverts the chart: target (E_t, E_l) or (relative density, alpha)
-> the cell parameters (relative density, stretch), by interpolating the log-moduli
bilinearly on the grid and solving a small least-squares problem.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence

import numpy as np
from scipy.interpolate import RegularGridInterpolator
from scipy.optimize import least_squares

from ..errors import ConfigError, InfeasibleError
from ..material import CONSTANT_NAMES

#: Columns of a chart table (one row per grid point and seed).
COLUMNS = ("target_density", "stretch", "seed", "relative_density", *CONSTANT_NAMES, "alpha", "misfit", "n_dof",
           "solver")


def chart_points(design: Mapping, densities: Sequence[float], stretches: Sequence[float],
                 seeds: Sequence[int], resolution: int) -> list[dict]:
    """Work items of the sweep: every (density, stretch, seed), on the base ``design`` mapping."""
    return [
        {"design": dict(design), "target_density": float(d), "stretch": float(s), "seed": int(k),
         "resolution": int(resolution)}
        for d, s, k in itertools.product(densities, stretches, seeds)
    ]


def evaluate_point(item: dict) -> dict:
    """Build and homogenise one foam of the chart (picklable, for the executor).

    ``item``: ``design`` (a parsed ``cells/*.toml`` foam mapping), ``target_density`` [-],
    ``stretch`` [-] (the design metric's stretch), ``seed``, ``resolution``.
    Returns one chart row (see :data:`COLUMNS`); moduli in MPa.
    """
    from ..cells.design import design_cell, parse_design
    from .voxels import homogenize_voxels

    data = dict(item["design"])
    data["metric"] = {**dict(data.get("metric", {"kind": "stretched"})), "stretch": item["stretch"]}
    design = parse_design(data, overrides={"relative_density": item["target_density"], "seed": item["seed"],
                                           "resolution": item["resolution"]}, source="chart.design")
    cell = design_cell(design)
    r = homogenize_voxels(cell.phases, cell.size, cell.materials, axis=cell.axis_vector, localise=False)
    m = r.fit.material
    return {"target_density": item["target_density"], "stretch": item["stretch"], "seed": item["seed"],
            "relative_density": r.relative_density, **m.to_dict(), "alpha": m.alpha,
            "misfit": r.fit.misfit, "n_dof": r.n_dof, "solver": r.solver}


def _grid(table) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """Seed-averaged values on the (target density, stretch) grid."""
    rows = _rows(table)
    dens = np.unique([float(r["target_density"]) for r in rows])
    st = np.unique([float(r["stretch"]) for r in rows])
    if len(dens) < 2 or len(st) < 2:
        raise ConfigError(f"chart_table: needs >= 2 densities and >= 2 stretches (has {len(dens)} x {len(st)})")
    keys = ("relative_density", *CONSTANT_NAMES)
    acc = {k: np.zeros((len(dens), len(st))) for k in keys}
    cnt = np.zeros((len(dens), len(st)))
    for r in rows:
        i = np.searchsorted(dens, float(r["target_density"]))
        j = np.searchsorted(st, float(r["stretch"]))
        cnt[i, j] += 1
        for k in keys:
            acc[k][i, j] += float(r[k])
    if np.any(cnt == 0):
        raise ConfigError("chart_table: the (density, stretch) grid has missing points")
    return dens, st, {k: v / cnt for k, v in acc.items()}


def _rows(table) -> list[Mapping]:
    if isinstance(table, Mapping):  # columns -> arrays
        n = len(next(iter(table.values())))
        return [{k: table[k][i] for k in table} for i in range(n)]
    return list(table)


def lookup(chart_table, *, E_t: float | None = None, E_l: float | None = None,
           relative_density: float | None = None, alpha: float | None = None) -> dict:
    """Cell parameters that give target constants, from a design chart.

    Parameters
    ----------
    chart_table : rows (dicts with :data:`COLUMNS`) or a mapping column -> values
        (e.g. ``chart.csv`` parsed by :func:`parse_csv`).
    E_t, E_l : target moduli [MPa] (give both), or
    relative_density [-], alpha [%] : target density and anisotropy 100 - 100 E_l / E_t.

    Returns
    -------
    dict with ``target_density`` and ``stretch`` (the cell parameters to use), the
    interpolated ``relative_density, E_t, E_l, nu_t, nu_tl, mu_l, alpha`` there and the
    relative ``residual`` of the match.

    Raises
    ------
    ConfigError : bad targets. InfeasibleError : the target is outside the chart.
    """
    by_moduli = E_t is not None or E_l is not None
    by_density = relative_density is not None or alpha is not None
    if by_moduli == by_density or (by_moduli and (E_t is None or E_l is None)) or (
            by_density and (relative_density is None or alpha is None)):
        raise ConfigError("lookup: give either (E_t, E_l) [MPa] or (relative_density [-], alpha [%])")
    dens, st, g = _grid(chart_table)
    interp = {k: RegularGridInterpolator((dens, st), np.log(v) if k in ("E_t", "E_l", "mu_l") else v)
              for k, v in g.items()}

    def value(k, x):
        v = float(interp[k](np.clip(x, [dens[0], st[0]], [dens[-1], st[-1]]))[0])
        return np.exp(v) if k in ("E_t", "E_l", "mu_l") else v

    if by_moduli:
        for name, v in (("E_t", E_t), ("E_l", E_l)):
            if not np.isfinite(v) or v <= 0:
                raise ConfigError(f"{name}: {v!r}: must be a finite modulus > 0 [MPa]")

        def res(x):
            return [np.log(value("E_t", x) / E_t), np.log(value("E_l", x) / E_l)]
    else:
        if not 0 < relative_density < 1:
            raise ConfigError(f"relative_density: {relative_density!r}: allowed range is (0, 1)")
        if not -100 <= alpha < 100:
            raise ConfigError(f"alpha: {alpha!r}: allowed range is [-100, 100) %")

        def res(x):
            a = 100.0 - 100.0 * value("E_l", x) / value("E_t", x)
            return [(value("relative_density", x) - relative_density) / relative_density, (a - alpha) / 100.0]

    best = None
    for x0 in itertools.product(np.linspace(dens[0], dens[-1], 4), np.linspace(st[0], st[-1], 4)):
        sol = least_squares(res, x0, bounds=([dens[0], st[0]], [dens[-1], st[-1]]))
        if best is None or sol.cost < best.cost:
            best = sol
    resid = float(np.sqrt(2 * best.cost))
    if resid > 0.02:
        raise InfeasibleError(
            f"lookup: target outside the chart (best match misses by {resid:.1%}); the chart spans "
            f"densities {dens[0]:g}..{dens[-1]:g}, stretches {st[0]:g}..{st[-1]:g}, "
            f"E_t {g['E_t'].min():.3g}..{g['E_t'].max():.3g} MPa, E_l {g['E_l'].min():.3g}..{g['E_l'].max():.3g} MPa"
        )
    x = best.x
    out = {"target_density": float(x[0]), "stretch": float(x[1])}
    out.update({k: value(k, x) for k in g})
    out["alpha"] = 100.0 - 100.0 * out["E_l"] / out["E_t"]
    out["residual"] = resid
    return out


def parse_csv(text: str) -> dict[str, np.ndarray]:
    """``chart.csv`` text -> column name -> array (numbers as float, ``solver`` as str)."""
    lines = [ln for ln in text.strip().splitlines() if ln]
    head = lines[0].split(",")
    cols = list(zip(*(ln.split(",") for ln in lines[1:])))
    return {h: (np.array(c) if h == "solver" else np.array(c, float)) for h, c in zip(head, cols)}


def to_csv(rows: Sequence[Mapping]) -> str:
    """Chart rows -> CSV text with :data:`COLUMNS` (repr-exact floats, so bytes are reproducible)."""
    out = [",".join(COLUMNS)]
    for r in rows:
        out.append(",".join(str(r[c]) if isinstance(r[c], str) else repr(float(r[c])) if c not in (
            "seed", "n_dof") else str(int(r[c])) for c in COLUMNS))
    return "\n".join(out) + "\n"
