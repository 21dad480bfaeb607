"""Stage ``anisotropy``: rod rotation and lateral translation against alpha (paper Fig. 7).

Writes ``anisotropy.csv`` (alpha, for pull and push: applied motor change, rod rotation,
lateral and axial translation, full pose change), ``anisotropy.png`` and ``anisotropy.json``.
When the sheets' material is not the paper's published foam, ``anisotropy.json`` also holds
the sweep's end point computed with the published constants (``published_end_point``), so
the two materials' Fig. 7 end points can be compared. With ``compare_models`` the end point
(only it: the sweep is expensive) is also computed under the other material model
(:mod:`metasheet.mechanics.material_model`), for the pipeline's constants (``model_end_points[<other>]``)
and the published ones (``model_end_points["published_<other>"]``).

``model = "reduced"`` runs the sweep on the FULL model: every alpha is another sheet
material, and the reduce stage's basis was trained for the design material only
(``model_info`` says so).
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from dataclasses import replace

from ...published import paper
from ...errors import ConfigError
from ...mechanics.material import TransverseIsotropic
from ...mechanics.material_model import model_stiffness, other_model
from ...studies.anisotropy import anisotropy_sweeps
from ..manifest import write_json_atomic
from ..registry import Stage, StageContext, register
from ._studies import (run_columns, StudyRobotParams, build_spec, drop_cache, model_record, progress, study_reads, unit_cache,
                       write_csv)


class AnisotropyParams(StudyRobotParams):
    n_alpha: int = Field(6, ge=2, le=1000, description="alpha values from 0 to the design value [-]")
    pull_deg: float = Field(15.0, ge=0, le=90, description="all motors pull by [deg]")
    push_deg: float = Field(35.0, ge=0, le=90, description="all motors push by [deg]")
    ramp_deg: float = Field(5.0, gt=0, le=90, description="largest motor increment per forward solve [deg]")
    compare_published: bool = Field(True, description="also compute the end point with the paper's published "
                                    "constants when the material differs from them")
    compare_models: bool = Field(True, description="also compute the end point under the other material model "
                                 "('ours' / 'authors') for the report's mu_l table")


def run(ctx: StageContext) -> dict:
    return run_columns(ctx, _run_one)


def _run_one(ctx: StageContext) -> dict:
    p: AnisotropyParams = ctx.params
    spec = build_spec(ctx)
    info = model_record(spec)
    if info["model"] == "reduced":  # a material sweep: the basis is the design material's
        info = {"model": "robot", "requested": "reduced", "reason": "the sweep changes the sheet material at "
                "every alpha; the reduced basis was trained for the design material only"}
        spec = spec.full
    alphas = np.linspace(0.0, spec.design_alpha, p.n_alpha)
    published = _published_spec(ctx, spec) if p.compare_published else None
    ends, skipped = _end_point_specs(spec, published) if p.compare_models and hasattr(spec, "model") else ({}, {})
    if published is not None:
        ends = {"published": published, **ends}
    # the sweep and every end point in one map: their long units overlap
    res, *end_res = anisotropy_sweeps([(spec, alphas)] + [(sp, [sp.design_alpha]) for sp in ends.values()],
                                      pull_deg=p.pull_deg, push_deg=p.push_deg, ramp_deg=p.ramp_deg,
                                      executor=ctx.executor, progress=progress(ctx), cache=unit_cache(ctx))
    end_points = {name: _end_point(r) for name, r in zip(ends, end_res)}
    header = ["alpha_percent"]
    for case in ("pull", "push"):
        header += [f"{case}_applied_deg", f"{case}_rod_rotation_deg", f"{case}_lateral_mm", f"{case}_axial_mm",
                   f"{case}_dx_mm", f"{case}_dy_mm", f"{case}_dz_mm", f"{case}_drx_deg", f"{case}_dry_deg",
                   f"{case}_drz_deg"]
    rows = []
    for i, a in enumerate(res.alpha):
        row = [a]
        for j in range(2):
            d = res.delta[i, j]
            row += [res.applied_deg[i, j], res.rod_rotation_deg[i, j], res.lateral_mm[i, j], res.axial_mm[i, j],
                    *d[:3], *np.degrees(d[3:])]
        rows.append(row)
    write_csv(ctx.path("anisotropy.csv"), header, rows)
    from ...viz.studies import anisotropy_picture

    applied = res.applied_deg.mean(axis=0)
    ctx.path("anisotropy.png").write_bytes(anisotropy_picture(
        res.alpha, res.rod_rotation_deg, res.lateral_mm, pull_deg=abs(applied[0]), push_deg=abs(applied[1]),
        title=f"Anisotropy sweep, all motors together (paper Fig. 7) [{ctx.column}, {p.model}]"))
    failed = np.isnan(res.rod_rotation_deg)
    summary = {
        "column": ctx.column,
        "alpha_percent": res.alpha.round(4).tolist(),
        "rod_rotation_deg": {"pull": _listed(res.rod_rotation_deg[:, 0]), "push": _listed(res.rod_rotation_deg[:, 1])},
        "lateral_mm": {"pull": _listed(res.lateral_mm[:, 0]), "push": _listed(res.lateral_mm[:, 1])},
        "not_converged": [{"alpha_percent": round(float(res.alpha[i]), 4), "case": ("pull", "push")[j],
                           "reached_deg": round(float(res.applied_deg[i, j]), 4)} for i, j in zip(*np.nonzero(failed))],
        "applied_deg": {"pull": float(applied[0]), "push": float(applied[1])},
        "requested_deg": {"pull": p.pull_deg, "push": p.push_deg}, "model": p.model, "model_info": info,
    }
    if "published" in end_points:
        summary["published_end_point"] = end_points.pop("published")
    if p.compare_models and hasattr(spec, "model"):  # the FEM robot: the other material model's end points
        summary["material_model"], summary["model_end_points"] = spec.model, {**end_points, **skipped}
    write_json_atomic(ctx.path("anisotropy.json"), summary)
    drop_cache(ctx)
    return summary


def _end_point_specs(spec, published) -> tuple[dict, dict]:
    """The other material model's specs ({name: spec}) for the pipeline's constants (``<other>``)
    and the published ones (``published_<other>``), and the ones skipped ({name: {"skipped": why}}):
    the authors' tensor may be indefinite for some constants."""
    other = other_model(spec.model)
    specs, skipped = {}, {}
    for name, sp in ((other, spec), (f"published_{other}", published)):
        if sp is None:
            continue
        try:
            model_stiffness(TransverseIsotropic(*sp.design), other)
        except ConfigError as exc:
            skipped[name] = {"skipped": str(exc)}
            continue
        specs[name] = replace(sp, model=other)
    return specs, skipped


def _end_point(end) -> dict:
    """A one-alpha sweep's end point: alpha [%], rod rotation [deg] and lateral translation [mm]
    for pull and push (None: not converged)."""
    return {"alpha_percent": round(float(end.alpha[0]), 4),
            "rod_rotation_deg": {"pull": _listed(end.rod_rotation_deg[:, 0])[0],
                                 "push": _listed(end.rod_rotation_deg[:, 1])[0]},
            "lateral_mm": {"pull": _listed(end.lateral_mm[:, 0])[0], "push": _listed(end.lateral_mm[:, 1])[0]}}


def _listed(values) -> list:
    """Values rounded to 4 decimals, None where the equilibrium did not converge (NaN)."""
    return [None if not np.isfinite(v) else round(float(v), 4) for v in np.asarray(values, float)]


def _published_spec(ctx: StageContext, spec):
    """The same robot with the paper's published constants, or None (stand-in model, uniform
    published material already, or a graded design whose per-element constants it would erase)."""
    from ..column import column

    if column(ctx.column).fixes_material or ctx.params.model not in ("robot", "reduced") or "material" not in ctx.inputs:
        return None
    from ..artefacts import read_material, read_orient

    mat = read_material(ctx.inputs["material"])
    if paper.is_published(mat.material):
        return None
    if "orient" in ctx.inputs and read_orient(ctx.inputs["orient"]).graded:
        return None
    # the sweep interpolates from the spec's design material: the published set is both
    # same density as the spec's (the material's, or the scene's sheet mass over the sheet volume)
    return replace(spec.with_material(paper.PAPER_FOAM), design=paper.PAPER_FOAM.as_tuple())


register(Stage(
    name="anisotropy", params=AnisotropyParams, run=run, optional=("orient", "material", "robot", "reduce"),
    reads=study_reads,
    outputs=("anisotropy.csv", "anisotropy.png", "anisotropy.json"),
    doc="rod rotation and lateral translation vs anisotropy alpha (Fig. 7)",
))
