"""Stage ``report``: one Markdown page collecting constants, pictures and tables of the
studies, each labelled with the paper figure it reproduces, and the differences found.

Reads the summaries (``<stage>.json``, or the manifest's summary) of whichever study stages
ran, copies their pictures next to ``report.md`` so the page is self-contained.
"""

from __future__ import annotations

import json
import shutil

from pydantic import Field

from ...studies.report import build_report
from ..artefacts import read_cell_design, read_cell_info, read_chart, read_constants, read_material, read_summary
from ..manifest import read_manifest
from ..registry import Params, Stage, StageContext, register

STUDIES = ("workspace", "ranges", "anisotropy", "maze")


class ReportParams(Params):
    title: str = Field("metasheet: reproduction of the paper's studies", description="report title")


def run(ctx: StageContext) -> dict:
    summaries, pictures = {}, {}
    for name, d in ctx.inputs.items():
        summaries[name] = read_summary(d, name if name in STUDIES else None)
        png = d / f"{name}.png"
        if png.exists():
            shutil.copyfile(png, ctx.path(png.name))
            pictures[name] = png.name
    if "homogenize" in ctx.inputs:
        h = ctx.inputs["homogenize"]
        summaries["homogenize"] = read_constants(h)
        summaries["homogenize_timings"] = (read_manifest(h) or {}).get("timings_s")
        if (h / "convergence.json").exists():  # the cell-size study
            summaries["size_study"] = json.loads((h / "convergence.json").read_text())
            if (h / "convergence.png").exists():
                shutil.copyfile(h / "convergence.png", ctx.path("homogenize_convergence.png"))
                pictures["size_study"] = "homogenize_convergence.png"
    if "printmap" in ctx.inputs and (ctx.inputs["printmap"] / "print_consistency.json").exists():
        summaries["print_consistency"] = json.loads((ctx.inputs["printmap"] / "print_consistency.json").read_text())
    if "chart" in ctx.inputs:
        from ...homogenize.chart import rows_of

        summaries["chart"] = {"rows": rows_of(read_chart(ctx.inputs["chart"])), "shrink": _cell_shrink(ctx)}
    if "cell" in ctx.inputs:
        info = read_cell_info(ctx.inputs["cell"])
        summaries["cell"] = {k: info[k] for k in ("name", "kind", "size_mm", "mean_void_chord_mm", "seed_count")
                             if k in info}
    if "orient" in ctx.inputs:
        sheet_info = json.loads((ctx.inputs["orient"] / "sheet.json").read_text())
        summaries["sheet_thickness_mm"] = sheet_info.get("geometry", {}).get("thickness")
        summaries["scene"] = sheet_info.get("scene")
    if "material" in ctx.inputs:
        m = read_material(ctx.inputs["material"])
        summaries["material"] = {**m.material.to_dict(), "alpha_percent": m.material.alpha, "source": m.source,
                                 "model": m.model}
    if "robot" in ctx.inputs and (ctx.inputs["robot"] / "convergence.json").exists():
        summaries["convergence"] = json.loads((ctx.inputs["robot"] / "convergence.json").read_text())
        summaries["meshes"] = _robot_meshes(ctx)
    if "reduce" in ctx.inputs and (ctx.inputs["reduce"] / "reduce.json").exists():
        summaries["reduce_json"] = json.loads((ctx.inputs["reduce"] / "reduce.json").read_text())
        summaries["reduce_seconds"] = (read_manifest(ctx.inputs["reduce"]) or {}).get("wall_time_s")
        second = ctx.inputs["reduce"] / "reproduction" / "reduce.json"
        if second.exists():  # the reproduction column's basis (metasheet/studies/columns.py)
            summaries["reduce_reproduction_json"] = json.loads(second.read_text())
    if "sheet" in ctx.inputs and (ctx.inputs["sheet"] / "sheet_dns.json").exists():  # the printed sheet's DNS
        summaries["sheet_dns"] = json.loads((ctx.inputs["sheet"] / "sheet_dns.json").read_text())
        for key in ("printed_sheet", "sheet_dns"):
            if (ctx.inputs["sheet"] / f"{key}.png").exists():
                shutil.copyfile(ctx.inputs["sheet"] / f"{key}.png", ctx.path(f"{key}.png"))
                pictures[key] = f"{key}.png"
    if "design" in ctx.inputs and (ctx.inputs["design"] / "design.json").exists():  # the fibre design (issue 45)
        summaries["design_json"] = json.loads((ctx.inputs["design"] / "design.json").read_text())
        for f in ("field", "pareto"):
            if (ctx.inputs["design"] / f"{f}.png").exists():
                shutil.copyfile(ctx.inputs["design"] / f"{f}.png", ctx.path(f"design_{f}.png"))
                pictures[f"design_{f}"] = f"design_{f}.png"
    summaries["columns"] = {name: _columns(ctx, name, pictures) for name in STUDIES if name in ctx.inputs}
    text = build_report(summaries, pictures, title=ctx.params.title)
    ctx.path("report.md").write_text(text)
    return {"sections": sorted(k for k, v in summaries.items() if v), "pictures": sorted(pictures.values())}


def _columns(ctx: StageContext, name: str, pictures: dict) -> dict:
    """Column -> summary of the study ``name``: its own folder's and its ``<column>/``
    folders'; each column's picture copied as ``<name>_<column>.png`` (the first's is
    ``<name>.png``) and listed in ``pictures`` under "<name>/<column>"."""
    from ...studies.columns import COLUMNS

    d, out = ctx.inputs[name], {}
    for folder in (d, *(d / c for c in COLUMNS)):
        summary = read_summary(folder, name) if (folder / f"{name}.json").exists() else None
        if summary is None:
            continue
        col = summary.get("column", "prediction")
        out[col] = summary
        png = folder / f"{name}.png"
        if png.exists():
            target = f"{name}.png" if folder == d else f"{name}_{col}.png"
            if folder != d:
                shutil.copyfile(png, ctx.path(target))
            pictures[f"{name}/{col}"] = target
    return out


def _robot_meshes(ctx: StageContext) -> dict:
    """Stage -> the robot mesh it ran on (element, mesh_size, layers, grip_size): the orient
    stage's for the robot stage, with each study's own overrides (its manifest's params)."""
    if "orient" not in ctx.inputs:
        return {}
    info = json.loads((ctx.inputs["orient"] / "sheet.json").read_text())
    g = info.get("geometry", {})
    base = {"element": info.get("element", "p1"), "mesh_size": g.get("mesh_size"), "layers": g.get("layers", 0),
            "grip_size": g.get("grip_size", 0.0)}
    out = {"robot": base}
    for name in ("workspace", "ranges", "anisotropy", "maze"):
        if name not in ctx.inputs:
            continue
        params = (read_manifest(ctx.inputs[name]) or {}).get("params", {})
        if params.get("model", "robot") not in ("robot", "reduced"):
            continue
        out[name] = {k: (base[k] if params.get(k) is None else params[k]) for k in base}
    return out


def _cell_shrink(ctx: StageContext) -> float | None:
    """The printed cell's ``kgon_x_shrink`` (Polyfoam cells), else None."""
    if "cell" not in ctx.inputs:
        return None
    design = read_cell_design(ctx.inputs["cell"])
    shrink = design.get("kgon_x_shrink")
    return None if shrink is None else float(shrink)


register(Stage(
    name="report", params=ReportParams, run=run,
    optional=("cell", "homogenize", "chart", "material", "orient", "printmap", "robot", "reduce", "workspace",
              "ranges", "anisotropy", "maze", "sheet", "design"),
    outputs=("report.md",), doc="Markdown report of the studies, labelled with the paper's figures",
))
