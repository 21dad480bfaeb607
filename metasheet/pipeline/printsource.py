"""Print sources: what the printmap prints, as a map between IceSL settings and the five constants.

A :class:`PrintSource` ties one IceSL infill family to the model of its foam:
``settings_for`` turns the constants the robot uses into IceSL settings,
``constants_at`` turns IceSL settings back into constants, so the printmap can check that
what it prints is what was modelled (:mod:`metasheet.sheet.consistency`).

Two sources: the **chart model** (:class:`ChartSource`) when the chart stage ran (the
design chart of the cell's family, calibrated on the homogenised cell:
:mod:`metasheet.homogenize.printmodel`), else the **point model** (:class:`PointModel`): the one
homogenised cell of the pipeline (``cell`` + ``homogenize`` stages), valid near it. Its
moduli follow a local power law in the infill percentage p,

    E_t, E_l, mu_l = (E_t, E_l, mu_l)_cell * (p / p_cell)^n,    nu_t, nu_tl unchanged,

with n = :data:`WALL_EXPONENT`; ``kgon_x_shrink`` is the cell's (one cell gives no chart to
map another shrink). Assumptions, named because no source states them (ICESL.md):
the infill percentage is proportional to the foam's relative density near the cell, and
the moduli scale like rho^1.1 (the authors' homogenised table of IceSL foams: stretch-
dominated walls, E ~ 0.98 rho^1.1 E_s; their fit runs 1.1-1.25).

:func:`print_source` builds the source for the printmap stage from its inputs.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol, runtime_checkable

import numpy as np

from ..errors import ConfigError
from ..mechanics.material import CONSTANT_NAMES, TransverseIsotropic
from ..sheet.icesl import POLYFOAM_DEFAULTS
from .artefacts import read_cell_info, read_constants

#: modulus ~ (infill percentage)^n near the cell: the authors' IceSL foam table (E ~ rho^1.1)
WALL_EXPONENT = 1.1
#: the point model is trusted for p in [p_cell / span, p_cell * span] (and within [0, 100] %)
POINT_MODEL_SPAN = 2.0
MODULI = ("E_t", "E_l", "mu_l")
#: IceSL infill families with a modelled cell family: family -> IceSL's infill_type
FAMILIES = {"polyfoam": "Polyfoam"}
#: IceSL infills without a modelled cell family, and why
UNMODELLED = {"phasor": "no modelled phasor cell family (Phasor is stiff along one axis, the "
                        "opposite symmetry of shrunk Polyfoam; ICESL.md)"}
#: cell kinds that are no IceSL infill
NOT_PRINTABLE = {"foam": "a strut (Voronoi-edge) foam, which no IceSL infill prints",
                 "laminate": "a two-phase laminate, which no IceSL infill prints",
                 "solid": "the bulk material, not an infill"}


@runtime_checkable
class PrintSource(Protocol):
    """What the printmap prints, and the model it came from.

    Attributes
    ----------
    family : IceSL infill family ("polyfoam"); infill_type : IceSL's name ("Polyfoam").
    fixed : IceSL setting (no ``_0`` suffix) -> value, constant over the part.
    field_names : settings that vary per element (``infill_percentage`` at least).
    valid_range : field setting -> (lo, hi) where the model holds, in IceSL units.
    """

    family: str
    infill_type: str

    @property
    def fixed(self) -> dict[str, float]: ...

    @property
    def field_names(self) -> tuple[str, ...]: ...

    @property
    def valid_range(self) -> dict[str, tuple[float, float]]: ...

    def settings_for(self, constants: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """IceSL field settings {name: (n,)} [%, ratio] printing the constants {E_t, ...: (n,)} [MPa]."""
        ...

    def constants_at(self, settings: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The five constants {E_t, E_l, nu_t, nu_tl, mu_l: (n,)} [MPa, -] of field settings {name: (n,)}."""
        ...

    def describe(self) -> dict:
        """JSON-able description for printmap.json."""
        ...


def _arrays(d: Mapping[str, np.ndarray], names, what: str) -> dict[str, np.ndarray]:
    missing = [k for k in names if k not in d]
    if missing:
        raise ConfigError(f"{what}: missing {missing}; expected {list(names)}")
    out = {k: np.atleast_1d(np.asarray(d[k], dtype=float)) for k in names}
    shapes = {v.shape for v in out.values()}
    if len(shapes) != 1 or len(next(iter(shapes))) != 1:
        raise ConfigError(f"{what}: shapes {[v.shape for v in out.values()]} should all be (n,)")
    return out


@dataclass(frozen=True)
class PointModel:
    """The point model of a polyfoam cell (module doc).

    percent : the cell's ``infill_percentage`` p_cell [%]; shrink : its ``kgon_x_shrink`` [-];
    constants : its homogenised constants {E_t, E_l, nu_t, nu_tl, mu_l} [MPa, -] about l;
    kgon : the cell's other kgon settings that differ from IceSL's defaults;
    exponent : n of the power law; span : validity factor around p_cell; cell : its name.
    """

    percent: float
    shrink: float
    constants: Mapping[str, float]
    kgon: Mapping[str, float] = field(default_factory=dict)
    exponent: float = WALL_EXPONENT
    span: float = POINT_MODEL_SPAN
    cell: str = ""
    family: str = "polyfoam"
    infill_type: str = "Polyfoam"

    def __post_init__(self):
        if not 0.0 < self.percent <= 100.0:
            raise ConfigError(f"infill_percentage: {self.percent!r} %: allowed range is (0, 100]")
        if not 0.0 < self.shrink <= 1.0:
            raise ConfigError(f"kgon_x_shrink: {self.shrink!r}: allowed range is (0, 1]")
        if not self.exponent > 0 or not self.span >= 1:
            raise ConfigError(f"exponent {self.exponent!r} must be > 0 and span {self.span!r} >= 1")
        TransverseIsotropic.from_mapping(dict(self.constants), where="point model constants")

    @property
    def fixed(self) -> dict[str, float]:
        return {"kgon_x_shrink": float(self.shrink), **{k: float(v) for k, v in self.kgon.items()}}

    @property
    def field_names(self) -> tuple[str, ...]:
        return ("infill_percentage",)

    @property
    def valid_range(self) -> dict[str, tuple[float, float]]:
        return {"infill_percentage": (self.percent / self.span, min(100.0, self.percent * self.span))}

    def settings_for(self, constants: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """p = p_cell (s)^(1/n), s the geometric mean of the three moduli's ratios to the cell's."""
        c = _arrays(constants, MODULI, "constants")
        if any(np.any(v <= 0) for v in c.values()):
            raise ConfigError("constants: moduli must be > 0")
        log_s = np.mean([np.log(c[k] / float(self.constants[k])) for k in MODULI], axis=0)
        return {"infill_percentage": self.percent * np.exp(log_s / self.exponent)}

    def constants_at(self, settings: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        p = _arrays(settings, ("infill_percentage",), "settings")["infill_percentage"]
        if "kgon_x_shrink" in settings:
            s = np.asarray(settings["kgon_x_shrink"], dtype=float)
            bad = np.abs(s - self.shrink) > 1e-9
            if np.any(bad):
                raise ConfigError(
                    f"kgon_x_shrink: {float(s[np.argmax(bad)]):g}: the point model knows only the cell's "
                    f"shrink {self.shrink:g} (no chart to map a different shrink)")
        if np.any(p <= 0):
            raise ConfigError(f"infill_percentage: {float(p.min()):g} %: must be > 0")
        scale = (p / self.percent) ** self.exponent
        out = {k: float(self.constants[k]) * (scale if k in MODULI else np.ones_like(p)) for k in CONSTANT_NAMES}
        return out

    def describe(self) -> dict:
        return {
            "model": "point",
            "cell": self.cell,
            "cell_infill_percentage": self.percent,
            "cell_kgon_x_shrink": self.shrink,
            "cell_constants": {k: float(self.constants[k]) for k in CONSTANT_NAMES},
            "law": "E_t, E_l, mu_l = cell * (p / p_cell)^n; nu_t, nu_tl = cell's",
            "exponent": self.exponent,
            "valid_range": {k: list(v) for k, v in self.valid_range.items()},
        }


@dataclass(frozen=True, eq=False)
class ChartSource:
    """The chart model of a polyfoam cell family: both settings are fields.

    ``model`` : a :class:`~metasheet.homogenize.printmodel.PrintModel` of a Polyfoam chart,
    normally calibrated on the pipeline's homogenised cell (so a uniform sheet prints the
    cell's own settings and reads back the cell's constants); ``kgon`` : the cell's other
    kgon settings that differ from IceSL's defaults; ``cell`` : its name.
    """

    model: object
    kgon: Mapping[str, float] = field(default_factory=dict)
    cell: str = ""
    family: str = "polyfoam"
    infill_type: str = "Polyfoam"

    @property
    def fixed(self) -> dict[str, float]:
        return {k: float(v) for k, v in self.kgon.items()}

    @property
    def field_names(self) -> tuple[str, ...]:
        return tuple(self.model.axes)

    @property
    def valid_range(self) -> dict[str, tuple[float, float]]:
        lo, hi = self.model.chart.bounds
        return {name: (float(lo[i]), float(hi[i])) for i, name in enumerate(self.model.axes)}

    def settings_for(self, constants: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        c = _arrays(constants, ("E_t", "E_l"), "constants")
        return self.model.settings_for(c)

    def constants_at(self, settings: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        return self.model.constants_at(_arrays(settings, self.model.axes, "settings"))

    def describe(self) -> dict:
        return {"model": "chart", "cell": self.cell, **self.model.describe(),
                "valid_range": {k: list(v) for k, v in self.valid_range.items()}}


# -------------------------------------------------------------------------- builder

def cell_settings(info: dict, where: str = "cell.json") -> dict:
    """The IceSL settings of a polyfoam cell design, from ``cell.json``.

    Looked for in ``design.icesl``, ``design.settings`` and ``design`` itself (the first
    that holds ``infill_percentage``); IceSL's defaults fill the rest.
    """
    design = info.get("design", {}) or {}
    for key in ("icesl", "settings", None):
        d = design if key is None else design.get(key)
        if isinstance(d, Mapping) and "infill_percentage" in d:
            out = dict(POLYFOAM_DEFAULTS)
            out.update({k: float(d[k]) for k in POLYFOAM_DEFAULTS if k in d})
            return out
    raise ConfigError(f"{where}: the design has no IceSL setting 'infill_percentage' "
                      "(looked in design.icesl, design.settings and design)")


def print_source(ctx, infill: str = "auto") -> PrintSource:
    """The print source of a printmap stage: its ``infill`` ("auto" = the cell's family).

    Reads ``ctx.inputs["cell"]`` (cell.json: the design and its IceSL settings) and
    ``ctx.inputs["homogenize"]`` (constants.json), and ``ctx.inputs["chart"]`` when the chart
    stage ran: then the source is the :class:`ChartSource` (the chart calibrated on the cell),
    else the :class:`PointModel`. Raises :class:`ConfigError` for an
    infill without a modelled cell family, a cell family IceSL cannot print, or a pipeline
    without the cell and homogenize stages.
    """
    if infill in UNMODELLED:
        raise ConfigError(f"printmap.infill: {infill!r}: {UNMODELLED[infill]}; set printmap.infill = "
                          f"\"auto\" (or one of {sorted(FAMILIES)}) with a cell of that family")
    if infill != "auto" and infill not in FAMILIES:
        raise ConfigError(f"printmap.infill: {infill!r}: allowed values are auto, {', '.join(FAMILIES)}")
    missing = [s for s in ("cell", "homogenize") if s not in ctx.inputs]
    if missing:
        raise ConfigError(
            f"printmap.infill: {infill!r}: the printmap prints the modelled foam and needs the "
            f"{' and '.join(missing)} stage{'s' if len(missing) > 1 else ''}: add "
            f"{', '.join(repr(s) for s in missing)} to [pipeline] stages, with a polyfoam cell "
            "design ([cell] design = a cells/*.toml with kind = \"polyfoam\")")
    info = read_cell_info(ctx.inputs["cell"])
    design = info.get("design", {}) or {}
    kind = str(info.get("kind", design.get("kind", "foam")))
    name = str(info.get("name", design.get("name", "")))
    if infill == "auto" and kind not in FAMILIES:
        why = NOT_PRINTABLE.get(kind, "not an IceSL infill family")
        raise ConfigError(f"printmap.infill: 'auto': the cell {name!r} is of family {kind!r}, {why}; "
                          f"use a cell of family {' or '.join(repr(f) for f in FAMILIES)}")
    if infill != "auto" and kind != infill:
        why = NOT_PRINTABLE.get(kind, "a different family")
        raise ConfigError(f"printmap.infill: {infill!r}: the cell {name!r} is of family {kind!r}, {why}: "
                          f"the print would not be the modelled foam; use a {infill} cell or infill = \"auto\"")
    settings = cell_settings(info, str(Path(ctx.inputs["cell"]) / "cell.json"))
    const_path = Path(ctx.inputs["homogenize"]) / "constants.json"
    consts = read_constants(ctx.inputs["homogenize"])
    mat = TransverseIsotropic.from_mapping(consts, where=str(const_path))
    kgon = {k: settings[k] for k in ("kgon_min_angle", "kgon_norm_alpha")
            if abs(settings[k] - POLYFOAM_DEFAULTS[k]) > 1e-12}
    if "chart" in ctx.inputs:  # the chart of the cell's family, anchored on the homogenised cell
        from .artefacts import read_print_model

        return ChartSource(read_print_model(ctx.inputs["chart"], ctx.inputs["cell"], ctx.inputs["homogenize"]),
                           kgon=kgon, cell=name)
    return PointModel(percent=settings["infill_percentage"], shrink=settings["kgon_x_shrink"],
                      constants={k: float(getattr(mat, k)) for k in CONSTANT_NAMES}, kgon=kgon, cell=name)
