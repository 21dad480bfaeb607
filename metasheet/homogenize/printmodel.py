"""The print model: a cell family's print settings <-> the five constants, both ways.

``M(S)`` maps settings ``S`` (for Polyfoam: ``infill_percentage`` [%], ``kgon_x_shrink``
[-]) to the transverse-isotropic constants (E_t, E_l, nu_t, nu_tl, mu_l) [MPa, -]; its
inverse gives the settings a slicer must print for target moduli (E_t, E_l).

The design chart (:mod:`metasheet.homogenize.chart`) is swept on cheaper cells (coarser
voxels, fewer seeds) than the pipeline's own homogenised cell, so it is exact in *shape*
(how the constants move with the settings) but not in *level*. :meth:`PrintModel.calibrated`
anchors it on the fine cell: moduli are scaled by ``C_cell / chart(S_cell)`` and Poisson
ratios shifted by ``C_cell - chart(S_cell)``, so ``M(S_cell) = C_cell`` exactly and the
robot, the print map and the round-trip check all speak of one material. The calibration
factors are recorded: they measure how far the chart's discretisation is from the cell's.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError, InfeasibleError
from ..mechanics.material import CONSTANT_NAMES
from .chart import ChartInterpolant, lookup

_MODULI = ("E_t", "E_l", "mu_l")
#: Settings this far outside the swept range (fraction of the span) are clipped, not refused:
#: an 8-bit texture's quantisation step is 1/255 of the scale.
CLIP_SLACK = 0.01


@dataclass(frozen=True, eq=False)
class PrintModel:
    """Settings <-> constants of one cell family, from a chart, optionally calibrated.

    Attributes
    ----------
    chart : the seed-averaged, interpolated design chart.
    calibration : constant -> factor (moduli, multiplicative) or shift (Poisson ratios,
        additive); empty = the chart as it is.
    anchor : the settings the calibration was made at (empty if none).
    """

    chart: ChartInterpolant
    calibration: dict = field(default_factory=dict)
    anchor: dict = field(default_factory=dict)

    @property
    def family(self) -> str:
        return self.chart.family

    @property
    def axes(self) -> tuple[str, str]:
        return self.chart.axes

    def _points(self, settings: Mapping[str, np.ndarray]) -> np.ndarray:
        missing = [a for a in self.axes if a not in settings]
        if missing:
            raise ConfigError(f"settings: missing {', '.join(missing)} (the {self.family} model needs "
                              f"{', '.join(self.axes)})")
        cols = np.broadcast_arrays(*(np.asarray(settings[a], float) for a in self.axes))
        pts = np.stack([c.ravel() for c in cols], axis=1)
        lo, hi = self.chart.bounds
        slack = CLIP_SLACK * (hi - lo)
        bad = np.any((pts < lo - slack) | (pts > hi + slack) | ~np.isfinite(pts), axis=1)
        if np.any(bad):
            i = int(np.flatnonzero(bad)[0])
            j = int(np.argmax((pts[i] < lo - slack) | (pts[i] > hi + slack) | ~np.isfinite(pts[i])))
            raise InfeasibleError(
                f"{self.axes[j]}: {float(pts[i, j]):g} (point {i}): outside the chart's range "
                f"[{lo[j]:g}, {hi[j]:g}]; widen chart.sweep.{self.axes[j]}")
        return pts

    def constants_at(self, settings: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Settings (name -> (n,) array, IceSL units) -> the five constants, each (n,) [MPa, -]."""
        pts = self._points(settings)
        out = {}
        for k in CONSTANT_NAMES:
            v = self.chart(k, pts)
            c = self.calibration.get(k)
            if c is not None:
                v = v * c if k in _MODULI else v + c
            out[k] = v
        return out

    def settings_for(self, constants: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Target moduli ``E_t``, ``E_l`` ((n,) arrays [MPa]) -> the settings to print, each (n,).

        Solved once per distinct (E_t, E_l) pair with :func:`~metasheet.homogenize.chart.lookup`
        on the uncalibrated chart (targets divided by the calibration factors).

        Raises
        ------
        InfeasibleError : a target outside the chart, naming it.
        """
        e_t, e_l = np.broadcast_arrays(np.asarray(constants["E_t"], float), np.asarray(constants["E_l"], float))
        pairs = np.stack([e_t.ravel(), e_l.ravel()], axis=1)
        uniq, inverse = np.unique(pairs, axis=0, return_inverse=True)
        ft, fl = self.calibration.get("E_t", 1.0), self.calibration.get("E_l", 1.0)
        solved = np.empty((len(uniq), 2))
        for i, (a, b) in enumerate(uniq):
            try:
                r = lookup(self.chart, E_t=a / ft, E_l=b / fl)
            except InfeasibleError as err:
                raise InfeasibleError(f"E_t {a:.4g}, E_l {b:.4g} MPa: no {self.family} setting prints them: {err}") \
                    from None
            solved[i] = r[self.axes[0]], r[self.axes[1]]
        flat = solved[np.ravel(inverse)]
        return {name: flat[:, j].reshape(e_t.shape) for j, name in enumerate(self.axes)}

    def settings_at_density(self, relative_density: float, alpha: float) -> dict[str, float]:
        """The settings whose cell has relative density ``relative_density`` [-] and anisotropy
        ``alpha`` = 100 - 100 E_l / E_t [%] of the calibrated model (graded designs)."""
        from scipy.optimize import least_squares

        if not 0 < relative_density < 1:
            raise ConfigError(f"relative_density: {relative_density!r}: allowed range is (0, 1)")
        if not -100 <= alpha < 100:
            raise ConfigError(f"alpha: {alpha!r}: allowed range is [-100, 100) %")
        lo, hi = self.chart.bounds
        ratio = self.calibration.get("E_l", 1.0) / self.calibration.get("E_t", 1.0)

        def res(x):
            rho = float(self.chart("relative_density", x)[0])
            a = 100.0 - 100.0 * ratio * float(self.chart("E_l", x)[0]) / float(self.chart("E_t", x)[0])
            return [(rho - relative_density) / relative_density, (a - alpha) / 100.0]

        best = min((least_squares(res, x0, bounds=(lo, hi)) for x0 in
                    np.stack(np.meshgrid(np.linspace(lo[0], hi[0], 3), np.linspace(lo[1], hi[1], 3)), -1).reshape(-1, 2)),
                   key=lambda r: r.cost)
        resid = float(np.sqrt(2 * best.cost))
        if resid > 0.02:
            raise InfeasibleError(
                f"relative_density {relative_density:g}, alpha {alpha:g} %: no {self.family} setting in the chart "
                f"gives them (best match misses by {resid:.1%}); the chart spans {self.axes[0]} {lo[0]:g}..{hi[0]:g}, "
                f"{self.axes[1]} {lo[1]:g}..{hi[1]:g}")
        return {self.axes[0]: float(best.x[0]), self.axes[1]: float(best.x[1])}

    def calibrated(self, settings: Mapping[str, float], constants: Mapping[str, float]) -> PrintModel:
        """This chart anchored on a homogenised cell: ``M(settings) = constants`` exactly."""
        raw = PrintModel(self.chart).constants_at({k: np.array([float(settings[k])]) for k in self.axes})
        cal = {}
        for k in CONSTANT_NAMES:
            target, base = float(constants[k]), float(raw[k][0])
            cal[k] = target / base if k in _MODULI else target - base
        return PrintModel(self.chart, cal, {k: float(settings[k]) for k in self.axes})

    def describe(self) -> dict:
        """JSON-able summary: the chart's family, axes and grid, and the calibration."""
        return {**self.chart.describe(), "calibration": {k: float(v) for k, v in self.calibration.items()},
                "calibration_kind": {k: ("factor" if k in _MODULI else "shift") for k in self.calibration},
                "anchor": dict(self.anchor)}


def model_from_chart(table) -> PrintModel:
    """The uncalibrated print model of a chart table (rows, columns or ``chart.csv`` parsed)."""
    return PrintModel(ChartInterpolant.from_table(table))
