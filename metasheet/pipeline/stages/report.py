"""Stage ``report``: one Markdown page collecting constants, pictures and tables of the
studies, each labelled with the paper figure it reproduces, and the differences found.

Reads the summaries (``<stage>.json``, or the manifest's summary) of whichever study stages
ran, copies their pictures next to ``report.md`` so the page is self-contained.

The studies of our own model that are not the paper's figures run as pipelines of their
own (issue 59): the design chart, the cell-size study and the robot's mesh convergence; so
does the robot in time (issue 64, the maze played), and the printed robot (issue 62: the
side-by-side table's third column). ``[report] chart``, ``cell_size``, ``convergence``,
``dynamics`` and ``printed`` name those pipelines' runs; the report
reads their outputs beside its own (``<out root>/<run>/<stage>/``) when this pipeline does
not hold them itself, and otherwise names the command that makes them. Their outputs are
inputs of the report's cache key (:attr:`~metasheet.pipeline.registry.Stage.siblings`).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from pydantic import Field, field_validator

from ...report.build import build_report
from ..artefacts import read_cell_design, read_cell_info, read_chart, read_constants, read_material, read_summary
from ..config import check_run_name
from ..manifest import read_manifest
from ..registry import Params, Stage, StageContext, register

STUDIES = ("workspace", "ranges", "anisotropy", "maze")

#: [report] key -> (the stage of that pipeline the report reads, the file it needs, what it holds)
SIBLINGS = {"chart": ("chart", "chart.csv", "the design chart"),
            "cell_size": ("homogenize", "convergence.json", "the cell-size study"),
            "convergence": ("robot", "convergence.json", "the robot's mesh convergence"),
            "dynamics": ("dynamics", "dynamics.json", "the maze played in time"),
            "printed": ("printed", "printed.json", "the printed robot")}
_BESIDE = ("run name of the pipeline beside this one (the same output root) whose {} the report shows when "
           "this pipeline has none; '': none")


class ReportParams(Params):
    title: str = Field("metasheet: reproduction of the paper's studies", description="report title")
    chart: str = Field("", description=_BESIDE.format("chart stage (chart.csv)"))
    cell_size: str = Field("", description=_BESIDE.format("cell-size study (homogenize/convergence.json)"))
    convergence: str = Field("", description=_BESIDE.format("mesh convergence (robot/convergence.json)"))
    dynamics: str = Field("", description=_BESIDE.format("maze played in time (dynamics/dynamics.json)"))
    printed: str = Field("", description=_BESIDE.format("printed robot (printed/printed.json: the side-by-side "
                                                         "table's third column)"))

    @field_validator("chart", "cell_size", "convergence", "dynamics", "printed")
    @classmethod
    def _run_name(cls, name: str) -> str:
        return check_run_name(name) if name else name


def sibling_folders(p: ReportParams) -> tuple[str, ...]:
    """The other pipelines' stage folders the report reads when they have outputs."""
    return tuple(f"{getattr(p, key)}/{stage}" for key, (stage, _, _) in SIBLINGS.items() if getattr(p, key))


def run(ctx: StageContext) -> dict:
    summaries, pictures = {}, {}
    for name, d in ctx.inputs.items():
        summaries[name] = read_summary(d, name if name in STUDIES else None)
        png = d / f"{name}.png"
        if png.exists():
            shutil.copyfile(png, ctx.path(png.name))
            pictures[name] = png.name
    if "workspace" in ctx.inputs:  # its clocks: the manifest's, never the result's
        summaries["workspace_timings"] = (read_manifest(ctx.inputs["workspace"]) or {}).get("timings_s")
    if "homogenize" in ctx.inputs:
        h = ctx.inputs["homogenize"]
        summaries["homogenize"] = read_constants(h)
        summaries["homogenize_timings"] = (read_manifest(h) or {}).get("timings_s")
    notes = {}
    h, notes["cell_size"] = _source(ctx, "cell_size")
    if h is not None:  # the cell-size study: this pipeline's homogenize, or the cell-size pipeline's
        summaries["size_study"] = json.loads((h / "convergence.json").read_text())
        summaries["size_study_timings"] = (read_manifest(h) or {}).get("timings_s")
        if (h / "convergence.png").exists():
            shutil.copyfile(h / "convergence.png", ctx.path("homogenize_convergence.png"))
            pictures["size_study"] = "homogenize_convergence.png"
        if notes["cell_size"]:
            notes["cell_size"]["differs"] = _differs(h, ctx.inputs.get("homogenize"), ("cell",))
    if "printmap" in ctx.inputs and (ctx.inputs["printmap"] / "print_consistency.json").exists():
        summaries["print_consistency"] = json.loads((ctx.inputs["printmap"] / "print_consistency.json").read_text())
    chart, notes["chart"] = _source(ctx, "chart")
    if chart is not None:
        from ...homogenize.chart import rows_of

        summaries["chart"] = {"rows": rows_of(read_chart(chart)), "shrink": _cell_shrink(ctx)}
        if notes["chart"] and (chart / "chart.png").exists():  # the chart pipeline's picture, as its own was
            shutil.copyfile(chart / "chart.png", ctx.path("chart.png"))
            pictures["chart"] = "chart.png"
    if "cell" in ctx.inputs:
        info = read_cell_info(ctx.inputs["cell"])
        summaries["cell"] = {k: info[k] for k in ("name", "kind", "size_mm", "mean_void_chord_mm", "seed_count")
                             if k in info}
    if "orient" in ctx.inputs:
        sheet_info = json.loads((ctx.inputs["orient"] / "sheet.json").read_text())
        summaries["sheet_thickness_mm"] = sheet_info.get("geometry", {}).get("thickness")
        summaries["continuum"] = sheet_info.get("continuum")  # the scale map's verdict on the cell's foam
        summaries["scene"] = sheet_info.get("scene")
    if "material" in ctx.inputs:
        m = read_material(ctx.inputs["material"])
        summaries["material"] = {**m.material.to_dict(), "alpha_percent": m.material.alpha, "source": m.source,
                                 "model": m.model}
        choice = json.loads((ctx.inputs["material"] / "material.json").read_text()).get("choice")
        if choice:  # source = "auto": which continuum, and why
            summaries["material"]["why"] = choice["why"]
    conv, notes["convergence"] = _source(ctx, "convergence")
    if conv is not None:  # the robot's mesh study: this pipeline's robot, or the convergence pipeline's
        summaries["convergence"] = json.loads((conv / "convergence.json").read_text())
        summaries["meshes"] = _robot_meshes(ctx)
        if notes["convergence"]:
            notes["convergence"]["differs"] = _differs(conv, ctx.inputs.get("robot"), ("orient", "material"))
    dyn, notes["dynamics"] = _source(ctx, "dynamics")
    if dyn is not None:  # the robot in time: this pipeline's dynamics stage, or the maze-dynamics pipeline's
        summaries["dynamics"] = _dynamics(dyn, pictures, ctx)
        if notes["dynamics"]:
            notes["dynamics"]["differs"] = _differs(dyn, ctx.inputs.get("robot"), ("orient", "material"))
    pr, notes["printed"] = _source(ctx, "printed")
    if pr is not None:  # the printed robot (issue 62): this pipeline's printed stage, or the printed-robot pipeline's
        summaries["printed_column"] = json.loads((pr / "printed.json").read_text())
        if notes["printed"]:
            notes["printed"]["differs"] = _differs(pr, ctx.inputs.get("robot"), ("orient", "material"))
        else:  # its own: the whole section, with its picture
            summaries["printed"] = summaries["printed_column"]
            if (pr / "printed_robot.png").exists():
                shutil.copyfile(pr / "printed_robot.png", ctx.path("printed_robot.png"))
                pictures["printed_robot"] = "printed_robot.png"
    summaries["siblings"] = {k: v for k, v in notes.items() if v}
    if "reduce" in ctx.inputs and (ctx.inputs["reduce"] / "reduce.json").exists():
        summaries["reduce_json"] = json.loads((ctx.inputs["reduce"] / "reduce.json").read_text())
        summaries["reduce_seconds"] = (read_manifest(ctx.inputs["reduce"]) or {}).get("wall_time_s")
        second = ctx.inputs["reduce"] / "reproduction" / "reduce.json"
        if second.exists():  # the reproduction column's basis (metasheet/pipeline/column.py)
            summaries["reduce_reproduction_json"] = json.loads(second.read_text())
    if "sheet" in ctx.inputs and (ctx.inputs["sheet"] / "sheet_dns.json").exists():  # the printed sheet's DNS
        summaries["sheet_dns"] = json.loads((ctx.inputs["sheet"] / "sheet_dns.json").read_text())
        for key in ("printed_sheet", "sheet_dns"):
            if (ctx.inputs["sheet"] / f"{key}.png").exists():
                shutil.copyfile(ctx.inputs["sheet"] / f"{key}.png", ctx.path(f"{key}.png"))
                pictures[key] = f"{key}.png"
    if "scalemap" in ctx.inputs and (ctx.inputs["scalemap"] / "scale_map.json").exists():  # issue 63's map
        summaries["scale_map"] = json.loads((ctx.inputs["scalemap"] / "scale_map.json").read_text())
        if (ctx.inputs["scalemap"] / "scale_map.png").exists():
            shutil.copyfile(ctx.inputs["scalemap"] / "scale_map.png", ctx.path("scale_map.png"))
            pictures["scale_map"] = "scale_map.png"
    if "printcheck" in ctx.inputs and (ctx.inputs["printcheck"] / "print_check.json").exists():  # issue 63
        summaries["print_check"] = json.loads((ctx.inputs["printcheck"] / "print_check.json").read_text())
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


def _source(ctx: StageContext, key: str) -> tuple[Path | None, dict | None]:
    """Where the report reads the study ``key`` of :data:`SIBLINGS` from, and the note on it.

    This pipeline's own stage when it wrote the study's file (no note); else the sibling
    pipeline's stage folder named by ``[report] <key>`` when it did (a note ``found``); else
    None and a note that is not ``found`` (the report names the command), or no note when
    ``[report] <key>`` is empty.
    """
    stage, filename, what = SIBLINGS[key]
    own = ctx.inputs.get(stage)
    if own is not None and (own / filename).exists():
        return own, None
    run = getattr(ctx.params, key)
    if not run:
        return None, None
    rel = f"{run}/{stage}"
    folder = ctx.siblings.get(rel)
    found = folder is not None and (folder / filename).exists()
    note = {"what": what, "pipeline": run, "file": f"{rel}/{filename}", "found": found}
    return (folder if found else None), note


def _differs(theirs: Path, ours: Path | None, stages: tuple[str, ...]) -> list[str] | None:
    """The upstream ``stages`` whose outputs the sibling's stage (folder ``theirs``) read and this
    pipeline's same stage (``ours``) did not, by the content hashes their manifests record; None
    when there is nothing to compare (this pipeline has no such stage, or its manifest names
    none of ``stages``)."""
    mine = (read_manifest(ours) or {}).get("inputs", {}) if ours is not None else {}
    other = (read_manifest(theirs) or {}).get("inputs", {})
    common = [s for s in stages if s in mine]
    return [s for s in common if other.get(s) != mine[s]] if common else None


def _columns(ctx: StageContext, name: str, pictures: dict) -> dict:
    """Column -> summary of the study ``name``: its own folder's and its ``<column>/``
    folders'; each column's picture copied as ``<name>_<column>.png`` (the first's is
    ``<name>.png``) and listed in ``pictures`` under "<name>/<column>"."""
    from ..column import COLUMNS

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


def _dynamics(d: Path, pictures: dict, ctx: StageContext) -> dict:
    """Column -> the dynamics stage's summary (its folder and ``<column>/``), its pictures copied
    as ``dynamics_<column>_<name>`` and listed under "dynamics/<column>/<name>"."""
    from ...report.dynamics import COPIED
    from ..column import COLUMNS

    out = {}
    for folder in (d, *(d / c for c in COLUMNS)):
        if not (folder / "dynamics.json").exists():
            continue
        z = json.loads((folder / "dynamics.json").read_text())
        col = z.get("column", "prediction")
        out[col] = z
        for name in COPIED:
            if (folder / name).exists():
                target = f"dynamics_{col}_{name}"
                shutil.copyfile(folder / name, ctx.path(target))
                pictures[f"dynamics/{col}/{name}"] = target
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
              "ranges", "anisotropy", "maze", "sheet", "printed", "scalemap", "design", "printcheck", "dynamics"),
    siblings=sibling_folders, outputs=("report.md",),
    doc="Markdown report of the studies, labelled with the paper's figures",
))
