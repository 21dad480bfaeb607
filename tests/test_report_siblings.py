"""Issue 59 item 3: the paper pipeline carries the paper's figures; the design chart, the
cell-size study and the robot's mesh convergence run as pipelines of their own, and the
report reads them beside its own outputs (or names the command that makes them)."""

import json
from pathlib import Path

import numpy as np

from metasheet.homogenize.chart import to_csv
from metasheet.published.literature import authors_constants, authors_table
from metasheet.pipeline import manifest as mf
from metasheet.pipeline.config import load_pipeline, siblings
from metasheet.pipeline.runner import run_pipeline
from metasheet.robot.convergence import FIT_LEVELS, Level, LevelResult, convergence_summary, family
from metasheet.report.build import build_report

ROOT = Path(__file__).resolve().parents[1]


def test_the_paper_pipeline_reads_its_model_studies_from_their_own_pipelines():
    """paper.toml holds no chart, no size study, no mesh study and no dynamics; the report names the
    four pipelines that do, each shipped under its run name, the convergence one on the paper's robot."""
    paper = load_pipeline(ROOT / "pipelines" / "paper.toml")
    assert "chart" not in paper.order and paper.params["robot"].convergence == []
    assert paper.params["homogenize"].sizes == [] and paper.params["homogenize"].realisations == 4
    beside = {}
    for rel in siblings(paper, "report"):
        run, stage = rel.split("/")
        pl = load_pipeline(ROOT / "pipelines" / f"{run}.toml")
        assert pl.name == run and stage in pl.order
        beside[stage] = pl
    assert set(beside) == {"chart", "homogenize", "robot", "dynamics", "printed"}
    for stage in ("cell", "homogenize", "material", "orient", "printmap"):  # the printed robot: the paper's prints
        assert beside["printed"].params[stage] == paper.params[stage], stage
    assert beside["homogenize"].params["homogenize"].sizes
    conv = beside["robot"]
    for stage in ("cell", "homogenize", "material", "orient"):  # the paper's robot, stage by stage
        assert conv.params[stage] == paper.params[stage], stage
    fams = [family(Level(*lev)) for lev in conv.params["robot"].convergence]
    # P1 graded at the grips as P2 is: a limit of each element, fitted from as many levels
    assert fams.count("p1-graded") >= FIT_LEVELS and fams.count("p2-graded") >= FIT_LEVELS


def _folder(out: Path, rel: str, files: dict, inputs: dict | None = None, timings: dict | None = None) -> None:
    """A finished stage folder of another pipeline: its files and a manifest hashing them."""
    d = out / rel
    d.mkdir(parents=True, exist_ok=True)
    for name, data in files.items():
        (d / name).write_bytes(data if isinstance(data, bytes) else data.encode())
    mf.write_json_atomic(d / mf.MANIFEST, {"stage": rel.split("/")[1], "key": "made by hand", "inputs": inputs or {},
                                           "outputs": mf.output_hashes(d), "timings_s": timings or {}})


def _chart_csv() -> str:
    """A Polyfoam chart whose points are the authors' transverse foam at its densities."""
    rows = []
    for rho in authors_table("transverse")["density"]:
        c = {k: float(v) for k, v in authors_constants(rho).items()}
        for s in (0.2, 1.0):
            rows.append({"infill_percentage": round(100 * float(rho), 3), "kgon_x_shrink": s, "seed": 1,
                         "relative_density": float(rho), **c, "alpha": 0.0, "misfit": 0.0, "n_dof": 1, "solver": "x"})
    return to_csv(rows)


SIZE_STUDY = {"constants": ["E_t"], "trend_model": "mean(n) = a + b * n**(-1/3)",
              "sizes": [{"n_cells": 8, "k": 4, "constants": {"E_t": {"mean": 1.1, "halfwidth": 0.05}}},
                        {"n_cells": 64, "k": 3, "constants": {"E_t": {"mean": 1.0, "halfwidth": 0.04}}}],
              "trend": {}}


def _convergence(p1_gap: float) -> dict:
    """convergence.json of P1 and P2 families graded at the grips, P1's limit ``p1_gap`` off."""
    J0 = np.diag([50.0, 40.0, 30.0, 0.5, 0.4, 0.3])

    def level(element, g, limit):
        J = limit * (1 + 0.1 * g)
        return LevelResult(Level(element, 10.0 if element == "p2" else 5.0, 0, g), 100, 300, g, J,
                           np.linalg.svd(J, compute_uv=False), float(J[3, 0]), 8.0 * (1 + 0.1 * g), 0.04, 0.1)

    res = [level("p2", g, J0) for g in (3.0, 2.0, 1.4, 1.0)] + [level("p1", g, J0 * (1 + p1_gap))
                                                                 for g in (2.0, 1.4, 1.0, 0.7)]
    return convergence_summary(res, {"robot": Level("p2", 10.0, 0, 3.0)})


def test_families_agreeing_within_two_percent_make_no_difference():
    near, far = _convergence(0.01), _convergence(0.05)
    text = build_report({"convergence": near}, {})
    assert "Limits against the reference `p2-graded` (largest singular value 50.00): p1-graded 50.50 (+1.0 %" in text
    assert "one element behind it" not in text
    assert "no p1 family's limit of the largest singular value is within 2.00 %" in build_report({"convergence": far},
                                                                                                  {})


def test_the_report_names_the_commands_then_reads_the_pipelines_beside_it(tmp_path):
    (tmp_path / "pipelines").mkdir()
    f = tmp_path / "pipelines" / "p.toml"
    f.write_text('[pipeline]\nname = "paper"\nstages = ["report"]\n'
                 '[report]\nchart = "chart"\ncell_size = "cell-size"\nconvergence = "convergence"\n')
    pl, out = load_pipeline(f), tmp_path / "out"
    report = out / "paper" / "report" / "report.md"
    run_pipeline(pl, out_root=out)
    text = report.read_text()
    for run, what in (("chart", "The design chart"), ("cell-size", "The cell-size study"),
                      ("convergence", "The robot's mesh convergence")):
        assert f"{what} is not in this output root" in text and f"`metasheet run pipelines/{run}.toml`, with" in text
    assert "### Cell-size study\n" in text and "## Mesh convergence of the robot (issue 14)\n" in text

    _folder(out, "chart/chart", {"chart.csv": _chart_csv(), "chart.png": b"png"})
    _folder(out, "cell-size/homogenize", {"convergence.json": json.dumps(SIZE_STUDY), "convergence.png": b"png"},
            timings={"realisation_s.64": 3600.0})
    _folder(out, "convergence/robot", {"convergence.json": json.dumps(_convergence(0.01))})
    (outcome,) = run_pipeline(pl, out_root=out)
    assert outcome.status == "ran"  # the other pipelines' outputs are inputs of the report's key
    text = report.read_text()
    assert "is not in this output root" not in text
    assert "### Cell-size study (cell-size/homogenize/convergence.json)" in text
    assert "From the `cell-size` pipeline beside this one" in text and "| 64 | 3 | 1 +- 0.04 (4 %)" in text
    assert "From the `convergence` pipeline beside this one (`convergence/robot/convergence.json`" in text
    assert "| p1-graded |" in text and "p1-graded 50.50 (+1.0 %" in text
    assert {"chart", "size_study", "convergence"} <= set(outcome.summary["sections"])
    assert {"chart.png", "homogenize_convergence.png"} <= set(outcome.summary["pictures"])
    assert (out / "paper" / "report" / "chart.png").read_bytes() == b"png"
    manifest = json.loads((out / "paper" / "report" / mf.MANIFEST).read_text())
    assert {"chart/chart", "cell-size/homogenize", "convergence/robot"} <= set(manifest["inputs"])

    assert run_pipeline(pl, out_root=out)[0].status == "cached"
    _folder(out, "chart/chart", {"chart.csv": _chart_csv().replace("1.0,", "1.0000001,", 1)})  # a rerun of it
    assert run_pipeline(pl, out_root=out)[0].status == "ran"


def test_the_chart_opens_its_density_sweep_in_the_constants_section():
    """With the homogenised constants, where the chart came from (or the command that makes it)
    stands before its density sweep, inside the constants section."""
    from metasheet.homogenize.chart import parse_csv, rows_of

    note = {"what": "the design chart", "pipeline": "chart", "file": "chart/chart/chart.csv", "found": True}
    h = {"relative_density": 0.15, "E_t": 1.1, "E_l": 0.005, "nu_t": 0.14, "nu_tl": 4.4, "mu_l": 0.03}
    chart = {"rows": rows_of(parse_csv(_chart_csv())), "shrink": 0.2}
    text = build_report({"homogenize": h, "chart": chart, "siblings": {"chart": note}}, {})
    head = text.index("From the `chart` pipeline beside this one (`chart/chart/chart.csv`")
    assert text.index("## Printed foam") < head < text.index("**kgon_x_shrink 0.2** against the authors'")
    text = build_report({"homogenize": h, "siblings": {"chart": {**note, "found": False}}}, {})
    assert text.index("## Printed foam") < text.index("The design chart is not in this output root")


def test_a_study_of_another_robot_is_named(tmp_path):
    """The report compares the upstream outputs the convergence pipeline's robot read with its own
    robot's (their manifests' hashes): the same, or which differ."""
    from metasheet.pipeline.registry import StageContext
    from metasheet.pipeline.stages import report as report_stage

    hashes = {"orient": {"sheet.vtu": "a"}, "material": {"material.json": "b"}}
    _folder(tmp_path, "paper/robot", {"jacobian.json": "{}"}, inputs=hashes)
    params = report_stage.ReportParams(convergence="convergence")

    def report(orient_hash):
        _folder(tmp_path, "convergence/robot", {"convergence.json": json.dumps(_convergence(0.01))},
                inputs={**hashes, "orient": {"sheet.vtu": orient_hash}})
        work = tmp_path / f"work-{orient_hash}"
        report_stage.run(StageContext("report", params, work, {"robot": tmp_path / "paper/robot"}, tmp_path,
                                      siblings={"convergence/robot": tmp_path / "convergence/robot"}))
        return (work / "report.md").read_text()

    assert "on the same robot as this pipeline's (the same upstream outputs)" in report("a")
    text = report("c")
    assert "on another robot: its orient outputs are not this pipeline's" in text
    diffs = text.split("## Differences from the paper")[1]
    assert "The robot's mesh convergence (`convergence/robot/convergence.json`) was computed on another robot" in diffs


def test_the_printed_robot_beside_is_the_tables_third_column(tmp_path):
    """Issue 62 item 5: the paper's report reads the printed-robot pipeline's printed.json beside it
    (the same output root) as its side-by-side table's third column, says where it came from and
    whether on this pipeline's robot; without it the table names the command that makes it."""
    from metasheet.pipeline.registry import StageContext
    from metasheet.pipeline.stages import report as report_stage

    maze = {"foam_impossible_segments": [], "segments": 8, "silicone_impossible_segments": None, "tilt_deg": 1.5}
    (tmp_path / "paper/maze/reproduction").mkdir(parents=True)
    (tmp_path / "paper/maze/reproduction/maze.json").write_text(json.dumps({**maze, "column": "reproduction"}))
    _folder(tmp_path, "paper/maze", {})  # the reproduction column only: no maze section of its own
    hashes = {"orient": {"sheet.vtu": "a"}, "material": {"material.json": "b"}}
    _folder(tmp_path, "paper/robot", {"jacobian.json": "{}"}, inputs=hashes)
    printed = {"claims": {"maze": "predicted"}, "realisations": [
        {"seed": s, "studies": {"maze": {"verdict": {"text": f"{s} solved", "status": "predicted"}}}} for s in (1, 2)]}
    params = report_stage.ReportParams(printed="printed-robot")
    inputs = {"maze": tmp_path / "paper/maze", "robot": tmp_path / "paper/robot"}

    def report(name, siblings):
        work = tmp_path / name
        report_stage.run(StageContext("report", params, work, inputs, tmp_path, siblings=siblings))
        return (work / "report.md").read_text()

    text = report("alone", {})
    assert "| figure | the paper | reproduction | prediction | verdict |" in text
    assert ("The printed robot is not in this output root (`printed-robot/printed/printed.json`): `metasheet run "
            "pipelines/printed-robot.toml`") in text
    _folder(tmp_path, "printed-robot/printed", {"printed.json": json.dumps(printed)}, inputs=hashes)
    text = report("beside", {"printed-robot/printed": tmp_path / "printed-robot/printed"})
    assert "| figure | the paper | reproduction | prediction | printed robot | verdict |" in text
    assert "| **predicted** (seed 1: 1 solved; seed 2: 2 solved) | reproduced |" in text
    assert "From the `printed-robot` pipeline beside this one" in text and "on the same robot" in text
    assert "## The printed robot against" not in text  # its own section is in its pipeline's report
