"""What the design stage writes, as text: the trials and Pareto tables, the chosen design, and
the pipeline file that reproduces it (:func:`chosen_pipeline`). Pure functions of arrays and dicts (the stage writes the
bytes atomically).

Numbers in the CSV tables are written with ``%.9g`` (same results, same bytes; 9 digits keep
the objectives' differences between neighbouring trials).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


def fmt(v) -> str:
    """One CSV cell: integers as such, floats with ``%.9g`` ('nan' when not finite)."""
    if isinstance(v, (bool, np.bool_)):
        return str(int(v))
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return "nan" if not math.isfinite(float(v)) else f"{float(v):.9g}"
    return str(v)


def csv_text(header: Sequence[str], rows: Sequence[Sequence]) -> str:
    """A CSV table (no quoting needed: names and numbers only), '\\n' line ends."""
    return "\n".join([",".join(header)] + [",".join(fmt(v) for v in r) for r in rows]) + "\n"


def trials_table(names: Sequence[str], values: np.ndarray, roll: np.ndarray, objectives: np.ndarray,
                 pareto: np.ndarray, extras: dict[str, np.ndarray] | None = None) -> str:
    """``trials.csv``: trial number, the variables [deg], the signed roll [deg/deg], the two
    objectives, ``extras`` (column name -> (n,) reported values:
    :data:`metasheet.design.search.EXTRAS`) and whether the trial is on the Pareto front (last:
    the one column more trials may change)."""
    extras = extras or {}
    header = ["trial", *names, "roll_deg_per_deg", "abs_roll_deg_per_deg", "other_min_mm_per_rad", *extras,
              "pareto"]
    rows = [[i, *values[i], roll[i], *objectives[i], *(float(v[i]) for v in extras.values()), bool(pareto[i])]
            for i in range(len(values))]
    return csv_text(header, rows)


def pareto_table(names: Sequence[str], values: np.ndarray, roll: np.ndarray, objectives: np.ndarray,
                 pareto: np.ndarray) -> str:
    """``pareto.csv``: the non-dominated trials, by decreasing |roll|."""
    idx = np.flatnonzero(pareto)
    idx = idx[np.lexsort((idx, -objectives[idx, 0]))]  # ties by trial number: a fixed order
    header = ["trial", *names, "roll_deg_per_deg", "abs_roll_deg_per_deg", "other_min_mm_per_rad"]
    return csv_text(header, [[int(i), *values[i], roll[i], *objectives[i]] for i in idx])


@dataclass(frozen=True)
class Candidate:
    """A design the stage may choose.

    Attributes
    ----------
    name : "spiral", "trial <n>" or "gradient".
    roll : signed rod roll per degree [deg/deg]; other_min : [mm/rad];
    singular_values : (6,) [mm/rad]; design : how to rebuild it (JSON-able);
    strain : largest principal strain at the goals [-] (nan: not measured).
    others : the five singular values other than the roll's [mm/rad] (:attr:`.search.Scores.others`).
    """

    name: str
    roll: float
    other_min: float
    singular_values: tuple[float, ...]
    design: dict
    strain: float = float("nan")
    others: tuple[float, ...] = ()

    @classmethod
    def of(cls, name: str, scores, design: dict) -> Candidate:
        """The candidate ``name`` of ``design`` with :class:`.search.Scores` ``scores``."""
        return cls(name, scores.roll, scores.other_min, scores.singular_values, design, scores.strain_max,
                   scores.others)


def choose(candidates: Sequence[Candidate], floor: float, strain_limit: float | None = None,
           others_floor: Sequence[float] | None = None) -> Candidate:
    """The candidate with the largest |roll| among those whose ``other_min`` is at least
    ``floor`` [mm/rad], with ``others_floor`` (5,) [mm/rad] whose other five singular values are
    each at least theirs, and, with ``strain_limit`` [-], whose goal strain is within it (an
    unmeasured, nan, strain is not); ties go to the earlier candidate. The first candidate, the
    spiral, is the reference: it is chosen when it qualifies and nothing rolls more, or when
    no candidate qualifies (then the result breaks the constraints: the caller reports it)."""
    ok = [c for c in candidates if c.other_min >= floor and (strain_limit is None or c.strain <= strain_limit)
          and meets_floors(c.others, others_floor)]
    best = ok[0] if ok else candidates[0]
    for c in ok[1:]:
        if abs(c.roll) > abs(best.roll):
            best = c
    return best


def meets_floors(values: Sequence[float], floors: Sequence[float] | None, rtol: float = 1e-6) -> bool:
    """Whether each of ``values`` is at least its floor (less ``rtol`` relative: SLSQP's
    constraint tolerance); True without ``floors``."""
    if floors is None:
        return True
    return len(values) == len(floors) and all(v >= f * (1 - rtol) for v, f in zip(values, floors))


def scores_record(roll: float, other_min: float, singular_values) -> dict:
    """A design's objectives for ``design.json`` (rounded to 6 significant digits)."""
    return {"roll_deg_per_deg": _r(roll), "abs_roll_deg_per_deg": _r(abs(roll)),
            "other_min_mm_per_rad": _r(other_min),
            "singular_values_mm_per_rad": [_r(s) for s in singular_values]}


def _r(v: float) -> float:
    return float(f"{float(v):.6g}")


def pictures(orient, record, pareto, cands: Sequence[Candidate], chosen: Candidate, grad: dict | None,
             spiral_kw: dict) -> dict[str, bytes]:
    """``pareto.png`` (the search's objectives, the spiral, the gradient's and the chosen design
    marked) and ``field.png`` (sheet A's fibre streaks: spiral | gradient design | chosen design)
    as PNG bytes. ``orient``: the orient stage's :class:`~metasheet.pipeline.artefacts.OrientFile`;
    ``record``, ``pareto``: the search's trials and front; ``cands[0]``: the spiral."""
    from ..sheet import geometry as geo
    from ..viz.design import field_picture, pareto_picture
    from ..sheet.fibre_field import fibres_at
    from .search import design_angles

    marks = [("spiral (start)", abs(cands[0].roll), cands[0].other_min, "s")]
    if grad is not None:
        marks.append(("gradient (free-form)", abs(grad["scores"].roll), grad["scores"].other_min, "D"))
    marks.append((f"chosen: {chosen.name}", abs(chosen.roll), chosen.other_min, "*"))

    def fn(design):
        return lambda q: fibres_at(design_angles(q, design, spiral_kw))

    sp = orient.sheet_params
    grips = orient.normal.mesh.points[orient.normal.mesh.attach > 0]
    panels = [(f"spiral, pitch {cands[0].design['pitch_deg']:g} deg: roll {cands[0].roll:.3f}", fn(cands[0].design),
               grips)]
    if grad is not None and chosen.name != "gradient":
        panels.append((f"gradient design: roll {grad['scores'].roll:.3f}", fn(grad["design"]), grips))
    panels.append((f"chosen ({chosen.name}): roll {chosen.roll:.3f}", fn(chosen.design), grips))
    return {"pareto.png": pareto_picture(record.objectives, pareto, marks, feasible=record.feasible),
            "field.png": field_picture(geo.outline_polygon(sp), sp.hole_radius, panels)}


# ------------------------------------------------------------------------- chosen.toml

def toml_value(v) -> str:
    """A TOML value: bool, int, float (repr: round-trips), string, list, inline table."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items() if x is not None) + "}"
    raise TypeError(f"no TOML form for {type(v).__name__}")


def toml_text(comment: str, tables: dict[str, dict]) -> str:
    """A pipeline file: ``comment`` lines (each prefixed '# '), then one ``[table]`` per entry;
    None values are left out (the parameter's default), empty tables too."""
    out = [f"# {line}".rstrip() for line in comment.splitlines()]
    for name, table in tables.items():
        items = [(k, v) for k, v in table.items() if v is not None and v != {}]
        out += ["", f"[{name}]"] + [f"{k} = {toml_value(v)}" for k, v in items]
    return "\n".join(out) + "\n"


def chosen_pipeline(name: str, material: dict, orient: dict, chosen: Candidate) -> str:
    """``chosen.toml``: a pipeline ``name`` (material, orient, robot) that builds ``chosen``'s
    robot. ``material``: the material table (the constants as the design used them);
    ``orient``: the design's orient table, its ``pitch_deg`` replaced by the design's and, for a
    design with coefficients, ``fibre_field`` set to its basis and coefficients [rad] (floats
    written with ``repr``: they read back bit for bit, so the orient stage rebuilds the field the
    design was evaluated with)."""
    from ..sheet.fibre_field import PolarBSpline, basis_record

    d = chosen.design
    o = {k: v for k, v in orient.items() if k != "fibre_field"}
    o["pitch_deg"] = float(d["pitch_deg"])
    if d.get("basis"):
        o["fibre_field"] = {**basis_record(PolarBSpline(**d["basis"])),
                            "coefficients": [float(c) for c in d["coefficients_rad"]]}
        how = ("a spiral of this pitch plus the\nfree-form correction [orient] fibre_field (design.json's "
               "chosen.design: coefficients [rad]\non a polar B-spline).")
    else:
        how = "a spiral of this pitch."
    comment = (f"The design stage's chosen design ({chosen.name}: rod roll per degree {chosen.roll:.6g} on the\n"
               f"linear rest problem). This pipeline reproduces it exactly: {how}\n"
               "metasheet run design/chosen.toml builds its robot (the robot stage: jacobian.json).")
    return toml_text(comment, {"pipeline": {"name": name, "stages": ["material", "orient", "robot"]},
                               "material": material, "orient": o})
