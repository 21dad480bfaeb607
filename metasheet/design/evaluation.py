"""Every objective of issue 45's item 1 for one design, and the chosen design against the spiral.

:func:`evaluate` scores a design (the design stage's dict: ``pitch_deg``, ``basis``,
``coefficients_rad``) on the linear rest problem of one material:

* ``roll_deg_per_deg`` [deg/deg] (:func:`.objectives.rod_roll_per_degree`);
* ``singular_values_mm_per_rad`` (6,) [mm/rad] of ``diag(1, 1, 1, L, L, L) J``, largest first,
  and ``other_min_mm_per_rad`` (:func:`.search.other_five_min`);
* ``decoupling`` (:func:`.objectives.decoupling`): parasitic translation [mm/deg] and tilt
  [deg/deg] of the all-together move, and per degree of roll;
* ``strain`` (:func:`.strain.goal_strain`): largest principal small strain [-] at the goals.

:func:`printability` (material-free: the print depends on the fibres only) checks the IceSL
settings' ranges and the angle's round trip (:mod:`.printability`). :func:`comparison` puts
the spiral and the chosen design side by side on the pipeline's material and the published
constants; :func:`comparison_markdown` writes it as ``comparison.md``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

from ..mechanics.material_model import model_stiffness
from . import objectives as obj
from . import printability as pr
from . import strain as st
from .adjoint import solve_rest
from ..sheet.fibre_field import fibres_at
from .search import design_angles, design_problem, other_five_min

#: relative size below which a parasitic motion is round-off: with sheet B the mirror of sheet A
#: (every design here) the all-together move has no tilt, and its computed tilt is ~1e-15 |roll|
ROUND_OFF = 1e-10


def _r(v: float) -> float:
    return float(f"{float(v):.6g}")


def _parasitic(v: float, scale: float) -> float:
    """``v`` to 6 digits, 0 where it is below :data:`ROUND_OFF` x ``scale`` (round-off)."""
    return 0.0 if abs(v) < ROUND_OFF * abs(scale) else _r(v)


def evaluate(sheets, material, design: dict, spiral: dict, r_max: float, *, goal_deg: float = st.GOAL_DEG,
             **kw) -> dict:
    """The objectives of ``design`` on ``sheets`` of ``material`` (``kw``:
    :func:`.adjoint.rest_problem`'s keywords) as a JSON-able dict (module docstring), 6 digits."""
    return evaluate_problem(*design_problem(sheets, material, design, spiral, r_max, **kw), goal_deg=goal_deg)


def evaluate_problem(problem, c, *, goal_deg: float = st.GOAL_DEG) -> dict:
    """:func:`evaluate` on a built rest ``problem`` at coefficients ``c`` (n,) [rad]."""
    sol = solve_rest(problem, c)
    d = obj.decoupling(sol.J, problem.robot.axis)
    g = st.goal_strain(problem, sol, goal_deg)
    return {
        "roll_deg_per_deg": _r(sol.roll), "abs_roll_deg_per_deg": _r(abs(sol.roll)),
        "singular_values_mm_per_rad": [_r(s) for s in sol.singular_values],
        "other_min_mm_per_rad": _r(other_five_min(sol.J, problem.robot.axis, problem.length_scale)),
        "decoupling": {"translation_mm_per_deg": _r(d.translation_mm_per_deg),
                       "tilt_deg_per_deg": _parasitic(d.tilt_deg_per_deg, d.roll_deg_per_deg),
                       "translation_mm_per_roll_deg": _r(d.translation_per_roll),
                       "tilt_per_roll": _parasitic(d.tilt_per_roll, 1.0)},
        "strain": {"measure": "largest principal linearised small strain, elements beyond the grip band",
                   "goal_deg": g.goal_deg, "limit": g.limit, "elements": g.elements,
                   "goals": {q.name: _r(s) for q, s in zip(g.goals, g.strain)}, "max": _r(g.worst),
                   "within_limit": bool(g.within_limit)},
    }


def printability(mesh, params, design: dict, spiral: dict, settings: Mapping[str, float] | None = None, *,
                 round_trip: bool = True) -> dict:
    """IceSL ranges of ``settings`` (the foam's, IceSL units) and, with ``round_trip``, the angle
    round trip of ``design``'s fibres on sheet A's ``mesh`` (points, tets) of geometry ``params``."""
    rec = {"settings": {k: list(v) for k, v in pr.check_settings(dict(settings or {})).items()}}
    if round_trip:
        rt = pr.angle_round_trip(mesh.points, mesh.tets, params,
                                 lambda q: fibres_at(design_angles(q, design, spiral)))
        rec["settings"]["infill_angle"] = list(rt.infill_angle_range_deg)
        rec["angle_round_trip"] = {"max_deg": _r(rt.max_deg), "p99_deg": _r(rt.p99_deg),
                                   "tolerance_deg": rt.tolerance_deg, "compared": rt.compared, "seam": rt.seam,
                                   "ok": bool(rt.ok)}
    rec["in_range"] = True  # check_settings raised otherwise
    what = "IceSL ranges of the settings" + ("; the angle's 8-bit round trip on sheet A" if round_trip else "")
    rec["checked"] = what + "; not the constants' (no print source)"
    return rec


# ------------------------------------------------------------------------ comparison

#: (label, unit, path of keys into an :func:`evaluate` dict)
ROWS = (
    (("rod roll per motor degree", "deg/deg", ("roll_deg_per_deg",)),)
    + tuple((f"singular value {i + 1} of 6", "mm/rad", ("singular_values_mm_per_rad", i)) for i in range(6))
    + (("smallest of the five other DOF", "mm/rad", ("other_min_mm_per_rad",)),
       ("parasitic translation, all together", "mm/deg", ("decoupling", "translation_mm_per_deg")),
       ("parasitic tilt, all together", "deg/deg", ("decoupling", "tilt_deg_per_deg")),
       ("parasitic translation per roll", "mm/deg of roll", ("decoupling", "translation_mm_per_roll_deg")),
       ("parasitic tilt per roll", "-", ("decoupling", "tilt_per_roll")))
)


def _get(e: dict, path: tuple):
    for k in path:
        e = e[k]
    return e


def comparison(spiral: Mapping[str, dict], chosen: Mapping[str, dict], printing: Mapping[str, dict]) -> dict:
    """The table of the chosen design against the spiral: ``spiral`` and ``chosen`` map a
    material label ("pipeline", "published") to an :func:`evaluate` dict; ``printing`` maps
    "spiral" and "chosen" to a :func:`printability` dict. Ratios chosen / spiral (None where the
    spiral's value is 0)."""
    labels = list(spiral)
    goals = list(next(iter(spiral.values()))["strain"]["goals"])
    rows = list(ROWS) + [(f"largest principal strain, {g}", "-", ("strain", "goals", g)) for g in goals]
    out = []
    for name, unit, path in rows:
        r = {"objective": name, "unit": unit}
        for m in labels:
            a, b = _get(spiral[m], path), _get(chosen[m], path)
            r[m] = {"spiral": a, "chosen": b, "ratio": _r(b / a) if a != 0 else None}
        out.append(r)
    limit = next(iter(spiral.values()))["strain"]["limit"]
    return {"materials": labels, "rows": out, "strain_limit": limit,
            "printability": {k: {"in_range": v["in_range"], **({"angle_round_trip_max_deg":
                                 v["angle_round_trip"]["max_deg"], "angle_tolerance_deg":
                                 v["angle_round_trip"]["tolerance_deg"]} if "angle_round_trip" in v else {})}
                             for k, v in printing.items()}}


#: the comparison's column titles of its materials
TITLES = {"pipeline": "pipeline's material", "published": "published constants"}


def _cell(v) -> str:
    return "-" if v is None else f"{v:.4g}"


def comparison_markdown(table: dict, titles: Mapping[str, str] | None = None) -> str:
    """``comparison.md``: one markdown table of :func:`comparison`'s rows (spiral, chosen and
    chosen / spiral per material), then the printability lines."""
    titles = dict(titles or {})
    ms = table["materials"]
    head = ["objective", "unit"]
    for m in ms:
        t = titles.get(m, m)
        head += [f"spiral ({t})", f"chosen ({t})", "chosen / spiral"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in table["rows"]:
        cells = [r["objective"], r["unit"]]
        for m in ms:
            cells += [_cell(r[m]["spiral"]), _cell(r[m]["chosen"]), _cell(r[m]["ratio"])]
        lines.append("| " + " | ".join(cells) + " |")
    lines += ["", (f"Strain: the linear rest problem's largest principal small strain beyond the grip band; "
                   f"validity limit {table['strain_limit']:g}.")]
    for k, v in table["printability"].items():
        rt = (f"; fibre axis round trip {v['angle_round_trip_max_deg']:.3g} deg (tolerance "
              f"{v['angle_tolerance_deg']:g} deg)") if "angle_round_trip_max_deg" in v else ""
        lines.append(f"Printability, {k}: IceSL settings {'within' if v['in_range'] else 'outside'} range{rt}.")
    return "\n".join(lines) + "\n"


def compare_designs(sheets, materials: Mapping[str, object], designs: Mapping[str, dict], spiral: dict, r_max: float,
                    *, params, settings: Mapping[str, float] | None = None, round_trip: bool = True,
                    goal_deg: float = st.GOAL_DEG, **kw) -> dict:
    """Every objective of each of ``designs`` ("spiral", "chosen" -> design dict) on each of
    ``materials`` (label -> material) and their printability on sheet A (geometry ``params``):
    ``{"evaluations": {design: {material: evaluate dict}}, "printability": {design: dict},
    "table": comparison(...)}``."""
    ev = {}
    for name, des in designs.items():
        # one robot per design: a material changes only the rest problem's tensor C_local
        problem, c = design_problem(sheets, next(iter(materials.values())), des, spiral, r_max, **kw)
        ev[name] = {m: evaluate_problem(replace(problem, C_local=model_stiffness(mat, kw.get("model", "ours"))), c,
                                        goal_deg=goal_deg) for m, mat in materials.items()}
    printing = {d: printability(sheets.sheet, params, des, spiral, settings, round_trip=round_trip)
                for d, des in designs.items()}
    return {"evaluations": ev, "printability": printing,
            "table": comparison(ev["spiral"], ev["chosen"], printing)}
