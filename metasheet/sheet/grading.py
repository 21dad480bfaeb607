"""Graded designs: relative density and anisotropy varying over the sheet.

A design gives each element a relative density rho [-] and an anisotropy
alpha = 100 - 100 E_l / E_t [%], either uniform, per named region, or as expressions of
the position. Regions (by element centroid):

- ``hub``: within the corner radius arm_width / sqrt(3) of the centre (where arms meet);
- ``tips``: inside an arm's tip box (the servo horn's grip), see ``SheetParams.tip_box``;
- ``arms``: everything else.

Expressions are numpy expressions in x, y, z, r [mm] and t (polar angle [rad]) with the
functions sin, cos, tan, exp, log, sqrt, abs, minimum, maximum, clip, where and the
constant pi, for example ``"0.12 + 0.1 * exp(-r / 20)"``. They are parsed into a tree
of allowed nodes and never passed to ``eval`` unchecked.

Constants per element come from a look-up ``(rho, alpha) -> TransverseIsotropic``: the
design chart's inverse look-up when the homogenize stage made one, otherwise
:func:`scaling_lookup` (the design's material, anisotropy through
``material.interpolate`` and moduli scaled by (rho / rho_ref)^2, Gibson-Ashby's law for
bending-dominated open-cell foams).
"""

from __future__ import annotations

import ast
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, check_range
from ..mechanics.material import CONSTANT_NAMES, TransverseIsotropic, interpolate
from .outline import ARM_ANGLES, SheetParams

REGIONS = ("hub", "arms", "tips")
_FUNCS = {
    "sin": np.sin, "cos": np.cos, "tan": np.tan, "exp": np.exp, "log": np.log,
    "sqrt": np.sqrt, "abs": np.abs, "minimum": np.minimum, "maximum": np.maximum,
    "clip": np.clip, "where": np.where,
}
_VARS = ("x", "y", "z", "r", "t", "pi")
_NODES = (
    ast.Expression, ast.BinOp, ast.UnaryOp, ast.Compare, ast.Call, ast.Name, ast.Load,
    ast.Constant, ast.Add, ast.Sub, ast.Mult, ast.Div, ast.Pow, ast.USub, ast.UAdd,
    ast.Mod, ast.Lt, ast.LtE, ast.Gt, ast.GtE, ast.BitAnd, ast.BitOr,
)


@dataclass(frozen=True)
class Grading:
    """Per-element design.

    density : (m,) relative density [-]; alpha : (m,) anisotropy [%];
    material_id : (m,) int, index into ``names`` (region, or 0 for a uniform design).
    """

    density: np.ndarray
    alpha: np.ndarray
    material_id: np.ndarray
    names: tuple[str, ...]


def regions(centroids: np.ndarray, params: SheetParams) -> np.ndarray:
    """Region index (m,) into :data:`REGIONS` of each centroid (m, 3) [mm]."""
    c = np.asarray(centroids, dtype=float)
    out = np.ones(len(c), dtype=np.int64)  # arms
    out[np.hypot(c[:, 0], c[:, 1]) <= params.arm_width / np.sqrt(3.0)] = 0
    half = 0.5 * np.asarray(params.tip_box)
    for a in ARM_ANGLES:
        s = c[:, 0] * np.cos(a) + c[:, 1] * np.sin(a)
        q = -c[:, 0] * np.sin(a) + c[:, 1] * np.cos(a)
        out[(np.abs(s - params.reach) <= half[0]) & (np.abs(q) <= half[1])] = 2
    return out


def evaluate(expr: str, points: np.ndarray, field: str) -> np.ndarray:
    """Evaluate a position expression (see module doc) at points (m, 3) [mm] -> (m,)."""
    try:
        tree = ast.parse(expr, mode="eval")
    except SyntaxError as exc:
        raise ConfigError(f"{field}: {expr!r}: not an expression ({exc.msg})") from None
    for node in ast.walk(tree):
        if not isinstance(node, _NODES):
            raise ConfigError(f"{field}: {expr!r}: {type(node).__name__} is not allowed")
        if isinstance(node, ast.Name) and node.id not in _FUNCS and node.id not in _VARS:
            raise ConfigError(
                f"{field}: {expr!r}: unknown name {node.id!r}; allowed {sorted(_VARS + tuple(_FUNCS))}"
            )
        if isinstance(node, ast.Call) and not (isinstance(node.func, ast.Name) and node.func.id in _FUNCS):
            raise ConfigError(f"{field}: {expr!r}: only the functions {sorted(_FUNCS)} may be called")
    p = np.asarray(points, dtype=float)
    env = dict(_FUNCS, x=p[:, 0], y=p[:, 1], z=p[:, 2], r=np.hypot(p[:, 0], p[:, 1]),
               t=np.arctan2(p[:, 1], p[:, 0]), pi=np.pi)
    with np.errstate(all="ignore"):
        value = eval(compile(tree, field, "eval"), {"__builtins__": {}}, env)  # noqa: S307 (checked tree)
    value = np.broadcast_to(np.asarray(value, dtype=float), (len(p),)).copy()
    if not np.all(np.isfinite(value)):
        raise ConfigError(f"{field}: {expr!r}: gives non-finite values on the sheet")
    return value


def grade(
    centroids: np.ndarray,
    params: SheetParams,
    *,
    density: float,
    alpha: float,
    table: dict[str, dict[str, float]] | None = None,
    density_expr: str | None = None,
    alpha_expr: str | None = None,
) -> Grading:
    """Per-element density and anisotropy of a design.

    ``density`` [-] and ``alpha`` [%] are the uniform values; ``table`` maps region names
    (:data:`REGIONS`) to ``{"density": .., "alpha": ..}`` overrides; the expressions,
    when given, replace both. Densities must lie in (0, 1], alphas in [0, 100).
    """
    c = np.asarray(centroids, dtype=float)
    m = len(c)
    rho = np.full(m, float(density))
    alp = np.full(m, float(alpha))
    ids = np.zeros(m, dtype=np.int64)
    names: tuple[str, ...] = ("uniform",)
    if table:
        ids = regions(c, params)
        names = REGIONS
        for name, row in table.items():
            if name not in REGIONS:
                raise ConfigError(f"grading.table: region {name!r}: allowed regions are {list(REGIONS)}")
            bad = set(row) - {"density", "alpha"}
            if bad:
                raise ConfigError(f"grading.table.{name}: keys {sorted(bad)}: allowed keys are density, alpha")
            sel = ids == REGIONS.index(name)
            if "density" in row:
                rho[sel] = row["density"]
            if "alpha" in row:
                alp[sel] = row["alpha"]
    if density_expr:
        rho = evaluate(density_expr, c, "grading.density_expr")
    if alpha_expr:
        alp = evaluate(alpha_expr, c, "grading.alpha_expr")
    # the uniform material's own alpha is allowed below 0 (E_l > E_t: apparent constants, say);
    # graded values come from the chart, whose alphas lie in [0, 100)
    for field, v, lo, hi in (("density", rho, 0.0, 1.0), ("alpha", alp, min(0.0, float(alpha)), 100.0)):
        worst = v[np.argmax(np.maximum(lo - v, v - hi))]
        check_range(f"grading.{field}", worst, lo, hi, lo_open=(field == "density"), hi_open=(field == "alpha"))
    return Grading(rho, alp, ids, names)


def scaling_lookup(material: TransverseIsotropic, rho_ref: float, exponent: float = 2.0):
    """A look-up (rho, alpha) -> TransverseIsotropic without a design chart.

    Anisotropy from ``interpolate(material, alpha)`` (alpha in [0, material.alpha], else
    ConfigError),
    moduli scaled by (rho / rho_ref)^exponent, Poisson ratios kept. Graded designs should
    prefer the homogenize stage's chart; this is the documented fallback.
    """
    check_range("rho_ref", rho_ref, 0.0, 1.0, lo_open=True)

    def lookup(rho: float, alpha: float) -> TransverseIsotropic:
        if abs(float(alpha) - material.alpha) < 1e-9:
            base = material  # exact for the design point itself
        elif material.alpha <= 0:
            raise ConfigError(f"alpha: {alpha:g} %: the material is isotropic; allowed range is [0, 0]")
        else:
            base = interpolate(material, float(alpha))  # raises past the design's alpha
        s = (float(rho) / rho_ref) ** exponent
        return TransverseIsotropic(base.E_t * s, base.E_l * s, base.nu_t, base.nu_tl, base.mu_l * s)

    return lookup


def element_constants(
    grading: Grading, lookup: Callable[[float, float], TransverseIsotropic]
) -> dict[str, np.ndarray]:
    """Per-element constants {name: (m,)} [MPa] from a grading and a look-up.

    The look-up runs once per distinct (density, alpha) pair.
    """
    pairs = np.stack([grading.density, grading.alpha], axis=1)
    uniq, inv = np.unique(pairs, axis=0, return_inverse=True)
    mats = [lookup(float(r), float(a)) for r, a in uniq]
    return {k: np.array([getattr(mt, k) for mt in mats], dtype=float)[inv.ravel()] for k in CONSTANT_NAMES}
