"""Mesh convergence of the robot: its figures over a sequence of sheet meshes, observed
orders and an extrapolated limit (issue 14).

Per mesh level (element, mesh_size, layers) the robot is built and measured at its rest
equilibrium under gravity:

* ``singular_values`` of diag(1, 1, 1, L, L, L) J [mm/rad] and the Jacobian J itself;
* ``rod_rotation_deg_per_deg``: rotation about the rod when all six motors move together (J);
* ``rod_compliance_mm_per_N``: the effector's compliance along the rod with the motors held,
  ``a^T (S_ee^-1)[:3, :3] a`` (S the Schur complement on the rigid coordinates, a the rod axis);
* ``gravity_sag_mm``: the effector's displacement from the unloaded rest to the gravity
  equilibrium.

Extrapolation: with ``h`` the mesh's effective size (mean tet volume)^(1/3) [mm], each figure
q is fitted as ``q(h) = q_inf + c h^p`` by least squares over all levels of one element
(:func:`fit_power_law`); p is the fitted order, the fit's residual its scatter. The Jacobian
is fitted entry by entry with one order. An error of a mesh is measured against the limit
of the more accurate element's sequence (P2's when it ran).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError
from .kinematics import kinematics
from .equilibrium import solve_equilibrium

#: figures extrapolated per level (scalar, or the vector of singular values)
FIGURES = ("singular_values", "rod_rotation_deg_per_deg", "rod_compliance_mm_per_N", "gravity_sag_mm")


@dataclass(frozen=True)
class Level:
    """One mesh of the sequence: element "p1" | "p2", size [mm], layers through the thickness
    (0: free mesh) and size at the grip borders [mm] (0: uniform), as in
    :class:`~metasheet.sheet.outline.SheetParams`."""

    element: str
    mesh_size: float
    layers: int = 0
    grip_size: float = 0.0

    @property
    def label(self) -> str:
        return (f"{self.element} h={self.mesh_size:g} mm" + (f" x{self.layers}" if self.layers else "")
                + (f" grip {self.grip_size:g} mm" if self.grip_size else ""))


@dataclass(frozen=True)
class LevelResult:
    """A level's figures (see the module docstring); ``h`` the effective size [mm]."""

    level: Level
    tets: int
    dofs: int
    h: float
    J: np.ndarray
    singular_values: np.ndarray
    rod_rotation_deg_per_deg: float
    rod_compliance_mm_per_N: float
    gravity_sag_mm: float
    seconds: float

    def to_dict(self) -> dict:
        return {"element": self.level.element, "mesh_size": self.level.mesh_size, "layers": self.level.layers,
                "grip_size": self.level.grip_size,
                "tets": self.tets, "dofs": self.dofs, "h_effective_mm": self.h,
                "singular_values": self.singular_values.tolist(),
                "rod_rotation_deg_per_deg": self.rod_rotation_deg_per_deg,
                "rod_compliance_mm_per_N": self.rod_compliance_mm_per_N,
                "gravity_sag_mm": self.gravity_sag_mm, "J": self.J.tolist(), "seconds": self.seconds}


def measure(robot, level: Level, *, length_scale: float = 50.0) -> LevelResult:
    """The figures of ``robot`` (built on ``level``'s mesh) at its rest equilibrium under gravity."""
    t0 = time.perf_counter()
    lz = robot.linearizer()
    rest = solve_equilibrium(robot, robot.coupling.rest_angles, linearizer=lz)
    lin = lz.linearize(rest.state)
    kin = kinematics(lin, length_scale=length_scale)
    ax = np.asarray(robot.axis, float) / np.linalg.norm(robot.axis)
    W_held = np.linalg.inv(lin.S[:6, :6])  # effector compliance with the motors held
    body = robot.body
    h = float((body.volumes.sum() / body.n_elements) ** (1.0 / 3.0))
    return LevelResult(level, int(body.n_elements), int(3 * body.n_nodes), h, kin.J, kin.singular_values,
                       float(kin.all_together[3:] @ ax), float(ax @ W_held[:3, :3] @ ax),
                       float(np.linalg.norm(rest.state.p - robot.coupling.origin)),
                       time.perf_counter() - t0)


def run_levels(build: Callable[[Level], object], levels, progress=None) -> list[LevelResult]:
    """Build (``build(level) -> Robot``) and :func:`measure` every level, in order."""
    out = []
    for i, lev in enumerate(levels):
        if progress is not None:
            progress(f"convergence: {lev.label}", i, len(levels))
        out.append(build_and_measure(build, lev))
    return out


def build_and_measure(build: Callable[[Level], object], level: Level) -> LevelResult:
    """:func:`measure` of ``build(level)``, its ``seconds`` the build's and the measure's [s]."""
    t0 = time.perf_counter()
    r = measure(build(level), level)
    return LevelResult(**{**r.__dict__, "seconds": time.perf_counter() - t0})


def cost_order(levels) -> list[int]:
    """Indices of ``levels``, the likely slowest first (most elements: P2 before P1, finer
    sizes and grips first): a pool's last unit is then a short one."""
    def size(lev: Level) -> float:
        h = min(lev.mesh_size, lev.grip_size or lev.mesh_size)
        return (10.0 if lev.element == "p2" else 1.0) / h**2  # a grip refines a 2D band: ~1/h^2
    return sorted(range(len(levels)), key=lambda i: -size(levels[i]))


#: orders the fit may take: at least 1, as the strains at a clamped edge are no more singular
#: than at a crack tip, where energy-like quantities (compliances, the Jacobian, a ratio of
#: them) converge linearly in the local element size; lower "orders" fitted to a few noisy
#: levels would extrapolate far beyond the data
ORDERS = np.linspace(1.0, 4.0, 61)


def fit_power_law(h, q, orders=ORDERS):
    """Least-squares fit ``q_k = q_inf + c h_k^p`` over the levels (h (L,), q (L, ...)).

    For each trial order p the fit is linear in (q_inf, c) entry by entry; the order with the
    smallest total squared residual wins (one p shared by all entries of a vector figure).
    Returns (q_inf, p, rms residual relative to |q_inf|). Unstructured meshes are not
    nested, so the levels scatter about the power law: a fit over all levels is steadier than
    Richardson's three-level formula, and its residual says how much.
    """
    h = np.asarray(h, float)
    q = np.asarray(q, float)
    Q = q.reshape(len(h), -1)
    best = None
    for p in orders:
        A = np.stack([np.ones_like(h), h**p], axis=1)
        coef, *_ = np.linalg.lstsq(A, Q, rcond=None)
        res = float(np.sum((A @ coef - Q) ** 2))
        if best is None or res < best[0]:
            best = (res, p, coef[0])
    res, p, q_inf = best
    scale = max(float(np.linalg.norm(q_inf)), 1e-300)
    return q_inf.reshape(q.shape[1:]), float(p), float(np.sqrt(res / len(h)) / scale)


@dataclass(frozen=True)
class Limit:
    """Extrapolated limits of one family's sequence (:func:`family`): per figure the limit, the fitted order
    and the fit's rms residual (relative), and the Jacobian's limit (one order for all entries)."""

    family: str
    levels: tuple[str, ...]
    values: dict = field(default_factory=dict)
    orders: dict = field(default_factory=dict)
    scatter: dict = field(default_factory=dict)
    J: np.ndarray | None = None

    def to_dict(self) -> dict:
        v = {k: (np.asarray(x).tolist() if np.ndim(x) else float(x)) for k, x in self.values.items()}
        return {"family": self.family, "from_levels": list(self.levels), "limits": v,
                "fitted_orders": dict(self.orders), "fit_rms_relative": dict(self.scatter),
                "J": None if self.J is None else self.J.tolist()}


#: levels of one family the extrapolation fits (its finest): coarser ones are not yet in the
#: asymptotic range (a 14 mm P2 sheet has one element across an arm's grip)
FIT_LEVELS = 4


def family(level: Level) -> str:
    """The sequence a level belongs to: its element, uniform or graded towards the grips."""
    return level.element + ("-graded" if level.grip_size else "")


def refinement(r: LevelResult) -> float:
    """A level's mesh parameter [mm]: the grip size for graded meshes (where the error lives),
    the effective size for uniform ones."""
    return r.level.grip_size if r.level.grip_size else r.h


def extrapolate(results: list[LevelResult], fam: str) -> Limit:
    """:class:`Limit` of the :data:`FIT_LEVELS` finest levels of family ``fam`` in ``results``
    (at least 3), by :func:`fit_power_law` per figure and for the Jacobian."""
    seq = sorted((r for r in results if family(r.level) == fam), key=lambda r: -refinement(r))[-FIT_LEVELS:]
    if len(seq) < 3:
        raise ConfigError(f"convergence: {len(seq)} levels of {fam!r}; at least 3 are needed to extrapolate")
    h = [refinement(r) for r in seq]
    values, orders, scatter = {}, {}, {}
    for name in FIGURES:
        values[name], orders[name], scatter[name] = fit_power_law(h, [getattr(r, name) for r in seq])
    J, orders["J"], scatter["J"] = fit_power_law(h, [r.J for r in seq])
    return Limit(fam, tuple(r.level.label for r in seq), values, orders, scatter, J)


def errors_against(r: LevelResult, limit: Limit) -> dict:
    """Relative errors of a level against a limit: the Jacobian (Frobenius), its singular
    values (largest entry-wise), rod rotation, rod compliance and gravity sag."""
    def rel(a, b):
        return float(np.linalg.norm(np.asarray(a) - np.asarray(b)) / max(np.linalg.norm(b), 1e-300))

    v = limit.values
    return {"jacobian": rel(r.J, limit.J),
            "singular_values": float(np.max(np.abs(r.singular_values - v["singular_values"])
                                            / np.abs(v["singular_values"]))),
            "rod_rotation": rel(r.rod_rotation_deg_per_deg, v["rod_rotation_deg_per_deg"]),
            "rod_compliance": rel(r.rod_compliance_mm_per_N, v["rod_compliance_mm_per_N"]),
            "gravity_sag": rel(r.gravity_sag_mm, v["gravity_sag_mm"])}


#: the issue's acceptance: the default meshes within these of the extrapolated limit
TOLERANCES = {"jacobian": 0.02, "rod_compliance": 0.05}


def within_tolerance(errors: dict) -> bool:
    return all(errors[k] <= tol for k, tol in TOLERANCES.items())


#: the most accurate family first: P2 graded towards the grips' clamped edges resolves the
#: strain singularity there, which uniform meshes of either order converge to slowly
REFERENCE_ORDER = ("p2-graded", "p2", "p1-graded", "p1")


def convergence_summary(results: list[LevelResult], checks: dict[str, Level] | None = None) -> dict:
    """JSON-able summary: every level's figures and errors against the reference limit (of the
    first of :data:`REFERENCE_ORDER` with 3 levels), each family's limit, and ``checks``: named meshes
    (e.g. the robot stage's and each study's), each of which must be one of the levels,
    with their errors and whether they meet :data:`TOLERANCES`. No wall time (the levels'
    ``seconds`` go to the stage manifest): the same config gives the same bytes."""
    fams = sorted({family(r.level) for r in results})
    limits = {f: extrapolate(results, f) for f in fams if sum(family(r.level) == f for r in results) >= 3}
    if not limits:
        raise ConfigError("convergence: no mesh family has the 3 levels an extrapolation needs")
    ref = limits[next(f for f in REFERENCE_ORDER + tuple(limits) if f in limits)]
    by_level = {r.level: r for r in results}
    rows = []
    for r in results:
        d = r.to_dict()
        d.pop("seconds")
        rows.append({**d, "errors": errors_against(r, ref)})
    out_checks = {}
    for name, lev in (checks or {}).items():
        if lev not in by_level:
            raise ConfigError(f"convergence: the {name} mesh ({lev.label}) is not among the levels; add it")
        e = errors_against(by_level[lev], ref)
        out_checks[name] = {"mesh": lev.label, "errors": e, "tolerances": dict(TOLERANCES),
                            "within": within_tolerance(e)}
    return {"reference": ref.family, "reference_levels": list(ref.levels),
            "figures": {"singular_values": "of diag(1,1,1,50 mm) J [mm/rad]",
                        "rod_rotation_deg_per_deg": "all six motors +1 deg, rotation about the rod (J)",
                        "rod_compliance_mm_per_N": "effector along the rod, motors held",
                        "gravity_sag_mm": "effector, unloaded rest -> gravity equilibrium",
                        "h_effective_mm": "(mean tet volume)^(1/3)",
                        "fit": "q = q_inf + c h^p over a family's finest levels; h = grip_size (graded) "
                               "or h_effective (uniform)"},
            "levels": rows, "limits": {el: lim.to_dict() for el, lim in limits.items()}, "checks": out_checks}
