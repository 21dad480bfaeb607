"""Design chart: the five constants over a cell family's two print settings, and its inverse.

A chart sweeps two settings of a cell family (:data:`FAMILY_AXES`):

- ``foam`` (strut foams): ``target_density`` [-] x ``stretch`` [-];
- ``polyfoam`` (IceSL's Polyfoam): ``infill_percentage`` [%] x ``kgon_x_shrink`` [-], the
  slicer's own settings, so the inverse look-up returns values IceSL can print.

:func:`chart_points` lists the sweep's work items; :func:`evaluate_point` (module level,
picklable) builds one cell with :mod:`metasheet.cells.catalogue` and homogenises it, so the
sweep runs through :class:`~metasheet.runtime.executor.Executor` in parallel.
:class:`ChartInterpolant` interpolates the seed-averaged constants bilinearly (log of the
moduli, the Poisson ratios as they are) and :func:`lookup` inverts it: target (E_t, E_l) or
(relative density, alpha) -> the two settings, by a small bounded least-squares solve.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, InfeasibleError
from ..mechanics.material import CONSTANT_NAMES

#: The two swept settings of each cell family, in chart order.
FAMILY_AXES = {"foam": ("target_density", "stretch"), "polyfoam": ("infill_percentage", "kgon_x_shrink")}
_RESULTS = ("seed", "relative_density", *CONSTANT_NAMES, "alpha", "misfit", "n_dof", "solver")
_LOG = ("E_t", "E_l", "mu_l")  # interpolated as logarithms (power laws in density)


def columns(family: str = "foam") -> tuple[str, ...]:
    """Columns of a chart table of ``family`` (one row per grid point and seed)."""
    if family not in FAMILY_AXES:
        raise ConfigError(f"chart family: {family!r}: expected one of {', '.join(FAMILY_AXES)}")
    return (*FAMILY_AXES[family], *_RESULTS)


COLUMNS = columns("foam")


def chart_points(design: Mapping, first: Sequence[float], second: Sequence[float], seeds: Sequence[int], *,
                 resolution: int | None = None, voxel_mm: float | None = None, rtol: float = 1e-8) -> list[dict]:
    """Work items of the sweep: every (first, second, seed) setting pair on the base ``design``.

    ``first``, ``second``: values of the family's two axes (:data:`FAMILY_AXES`);
    ``resolution`` (foam, voxels per side) or ``voxel_mm`` (polyfoam, voxel edge [mm]);
    ``rtol``: the corrector solves' relative residual (:func:`~.voxels.homogenize_voxels`).
    """
    family = str(design.get("kind", "foam"))
    a, b = FAMILY_AXES.get(family, (None, None))
    if a is None:
        raise ConfigError(f"chart.design: kind {family!r}: a chart needs one of {', '.join(FAMILY_AXES)}")
    return [
        {"design": dict(design), "family": family, a: float(x), b: float(y), "seed": int(k),
         "resolution": resolution, "voxel_mm": voxel_mm, "rtol": float(rtol)}
        for x, y, k in itertools.product(first, second, seeds)
    ]


def item_design(item: dict) -> tuple[dict, dict]:
    """(design data, parse_design overrides) of one work item."""
    data = dict(item["design"])
    if item["family"] == "foam":
        data["metric"] = {**dict(data.get("metric", {"kind": "stretched"})), "stretch": item["stretch"]}
        return data, {"relative_density": item["target_density"], "seed": item["seed"],
                      "resolution": item["resolution"]}
    return data, {"infill_percentage": item["infill_percentage"], "kgon_x_shrink": item["kgon_x_shrink"],
                  "seed": item["seed"], "voxel_mm": item["voxel_mm"]}


def evaluate_point(item: dict) -> dict:
    """Build and homogenise one cell of the chart (picklable, for the executor).

    ``item``: one entry of :func:`chart_points`. Returns one chart row
    (:func:`columns` of the family); moduli in MPa.
    """
    from ..cells.catalogue import design_cell, parse_design
    from .voxels import homogenize_voxels

    data, overrides = item_design(item)
    design = parse_design(data, overrides=overrides, source="chart.design")
    cell = design_cell(design)
    r = homogenize_voxels(cell.phases, cell.size, cell.materials, axis=cell.axis_vector, localise=False,
                          rtol=item.get("rtol", 1e-8))
    m = r.fit.material
    a, b = FAMILY_AXES[item["family"]]
    return {a: item[a], b: item[b], "seed": item["seed"], "relative_density": r.relative_density,
            **m.to_dict(), "alpha": m.alpha, "misfit": r.fit.misfit, "n_dof": r.n_dof, "solver": r.solver}


def rows_of(table) -> list[Mapping]:
    if isinstance(table, Mapping):  # columns -> arrays
        n = len(next(iter(table.values())))
        return [{k: table[k][i] for k in table} for i in range(n)]
    return list(table)


def table_family(table) -> str:
    """The cell family whose axes a chart table carries."""
    keys = set(table) if isinstance(table, Mapping) else set(rows_of(table)[0]) if rows_of(table) else set()
    for family, axes in FAMILY_AXES.items():
        if set(axes) <= keys:
            return family
    raise ConfigError(f"chart_table: columns {sorted(keys)} name no family's axes ({FAMILY_AXES})")


@dataclass(frozen=True, eq=False)
class ChartInterpolant:
    """Seed-averaged chart values on the (first, second) settings grid, interpolated bilinearly.

    Attributes
    ----------
    family : the cell family; ``axes`` its two setting names.
    grid : ((na,), (nb,)) the swept setting values.
    values : name -> (na, nb) seed means of ``relative_density`` and the five constants.
    spread : name -> (na, nb) seed standard deviations (0 with one seed).
    """

    family: str
    axes: tuple[str, str]
    grid: tuple[np.ndarray, np.ndarray]
    values: dict
    spread: dict

    @classmethod
    def from_table(cls, table) -> ChartInterpolant:
        family = table_family(table)
        a, b = FAMILY_AXES[family]
        rows = rows_of(table)
        ga = np.unique([float(r[a]) for r in rows])
        gb = np.unique([float(r[b]) for r in rows])
        if len(ga) < 2 or len(gb) < 2:
            raise ConfigError(f"chart_table: needs >= 2 values of {a} and of {b} (has {len(ga)} x {len(gb)})")
        keys = ("relative_density", *CONSTANT_NAMES)
        samples = {k: [[[] for _ in gb] for _ in ga] for k in keys}
        for r in rows:
            i, j = np.searchsorted(ga, float(r[a])), np.searchsorted(gb, float(r[b]))
            for k in keys:
                samples[k][i][j].append(float(r[k]))
        if any(not samples["E_t"][i][j] for i in range(len(ga)) for j in range(len(gb))):
            raise ConfigError(f"chart_table: the ({a}, {b}) grid has missing points")
        mean = {k: np.array([[np.mean(c) for c in row] for row in v]) for k, v in samples.items()}
        std = {k: np.array([[np.std(c) for c in row] for row in v]) for k, v in samples.items()}
        return cls(family, (a, b), (ga, gb), mean, std)

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(lower (2,), upper (2,)) of the swept settings."""
        return (np.array([self.grid[0][0], self.grid[1][0]]), np.array([self.grid[0][-1], self.grid[1][-1]]))

    def __call__(self, name: str, points) -> np.ndarray:
        """``name`` at setting pairs ``points`` (m, 2) -> (m,), clipped into the swept box."""
        interp = _interpolators(self)[name]
        lo, hi = self.bounds
        pts = np.clip(np.atleast_2d(np.asarray(points, float)), lo, hi)
        v = interp(pts)
        return np.exp(v) if name in _LOG else v

    def describe(self) -> dict:
        return {"family": self.family, "axes": list(self.axes), "grid": [g.tolist() for g in self.grid]}


_INTERP_CACHE: dict[int, tuple[ChartInterpolant, dict]] = {}


def _interpolators(chart: ChartInterpolant) -> dict:
    hit = _INTERP_CACHE.get(id(chart))
    if hit is None or hit[0] is not chart:
        from scipy.interpolate import RegularGridInterpolator  # here: 0.2 s of every command's start

        f = {k: RegularGridInterpolator(chart.grid, np.log(v) if k in _LOG else v) for k, v in chart.values.items()}
        hit = _INTERP_CACHE[id(chart)] = (chart, f)
    return hit[1]


def lookup(chart_table, *, E_t: float | None = None, E_l: float | None = None,
           relative_density: float | None = None, alpha: float | None = None) -> dict:
    """Cell settings that give target constants, from a design chart.

    Parameters
    ----------
    chart_table : rows (dicts with :func:`columns`), a mapping column -> values (e.g.
        ``chart.csv`` parsed by :func:`parse_csv`), or a :class:`ChartInterpolant`.
    E_t, E_l : target moduli [MPa] (give both), or
    relative_density [-], alpha [%] : target density and anisotropy 100 - 100 E_l / E_t.

    Returns
    -------
    dict with the family's two settings (``target_density`` and ``stretch`` for foams,
    ``infill_percentage`` and ``kgon_x_shrink`` for Polyfoam: the values to print), the
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
    chart = chart_table if isinstance(chart_table, ChartInterpolant) else ChartInterpolant.from_table(chart_table)
    lo, hi = chart.bounds

    def value(k, x):
        return float(chart(k, x)[0])

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

    from scipy.optimize import least_squares

    best = None
    for x0 in itertools.product(np.linspace(lo[0], hi[0], 4), np.linspace(lo[1], hi[1], 4)):
        sol = least_squares(res, x0, bounds=(lo, hi))
        if best is None or sol.cost < best.cost:
            best = sol
    resid = float(np.sqrt(2 * best.cost))
    if resid > 0.02:
        (a, b), g = chart.axes, chart.values
        raise InfeasibleError(
            f"lookup: target outside the chart (best match misses by {resid:.1%}); the chart spans "
            f"{a} {lo[0]:g}..{hi[0]:g}, {b} {lo[1]:g}..{hi[1]:g}, "
            f"E_t {g['E_t'].min():.3g}..{g['E_t'].max():.3g} MPa, E_l {g['E_l'].min():.3g}..{g['E_l'].max():.3g} MPa"
        )
    x = best.x
    out = {chart.axes[0]: float(x[0]), chart.axes[1]: float(x[1])}
    out.update({k: value(k, x) for k in chart.values})
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
    """Chart rows -> CSV text with the family's :func:`columns` (repr-exact floats: reproducible bytes)."""
    cols = columns(table_family(rows))
    out = [",".join(cols)]
    for r in rows:
        out.append(",".join(str(r[c]) if isinstance(r[c], str) else repr(float(r[c])) if c not in (
            "seed", "n_dof") else str(int(r[c])) for c in cols))
    return "\n".join(out) + "\n"
