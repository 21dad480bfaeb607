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
from ..registry import Params, Stage, StageContext, register

STUDIES = ("workspace", "ranges", "anisotropy", "maze")


class ReportParams(Params):
    title: str = Field("metasheet: reproduction of the paper's studies", description="report title")


def _summary(directory, name):
    f = directory / f"{name}.json"
    if f.exists():
        return json.loads(f.read_text())
    man = directory / "manifest.json"
    return json.loads(man.read_text()).get("summary") if man.exists() else None


def run(ctx: StageContext) -> dict:
    summaries, pictures = {}, {}
    for name, d in ctx.inputs.items():
        summaries[name] = _summary(d, name) if name in STUDIES else _summary(d, "__none__")
        png = d / f"{name}.png"
        if png.exists():
            shutil.copyfile(png, ctx.path(png.name))
            pictures[name] = png.name
    if "homogenize" in ctx.inputs:
        summaries["homogenize"] = json.loads((ctx.inputs["homogenize"] / "constants.json").read_text())
    if "material" in ctx.inputs:
        m = json.loads((ctx.inputs["material"] / "material.json").read_text())
        summaries["material"] = {**m["constants"], "alpha_percent": m["alpha_percent"], "source": m["source"]}
    text = build_report(summaries, pictures, title=ctx.params.title)
    ctx.path("report.md").write_text(text)
    return {"sections": sorted(k for k, v in summaries.items() if v), "pictures": sorted(pictures.values())}


register(Stage(
    name="report", params=ReportParams, run=run,
    optional=("homogenize", "material", "robot", "workspace", "ranges", "anisotropy", "maze"),
    outputs=("report.md",), doc="Markdown report of the studies, labelled with the paper's figures",
))
