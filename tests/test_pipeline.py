"""Pipeline layer: caching, partial reruns, atomic outputs, config errors, executor."""

import json
from pathlib import Path

import pytest
from pydantic import Field

from metasheet.errors import ConfigError, StageError
from metasheet.runtime.executor import Executor
from metasheet.pipeline import registry
from metasheet.pipeline.config import load_pipeline
from metasheet.pipeline.registry import Params, Stage, register
from metasheet.pipeline.runner import run_pipeline

CALLS: list[str] = []


class AParams(Params):
    value: float = Field(1.0, ge=0, le=10, description="a number [-]")
    explode: bool = False


class BParams(Params):
    scale: float = 2.0


def run_a(ctx):
    CALLS.append("t_a")
    ctx.path("a.txt").write_text(f"{ctx.params.value}\n")
    if ctx.params.explode:
        ctx.path("half.txt").write_text("half-written")
        raise RuntimeError("boom")
    return {"value": ctx.params.value}


def run_b(ctx):
    CALLS.append("t_b")
    a = float((ctx.inputs["t_a"] / "a.txt").read_text())
    ctx.path("b.txt").write_text(f"{a * ctx.params.scale}\n")
    return {}


@pytest.fixture
def project(tmp_path, monkeypatch):
    registry.stages()  # import the real stages first
    register(Stage("t_a", AParams, run_a, outputs=("a.txt",)))
    register(Stage("t_b", BParams, run_b, requires=("t_a",), outputs=("b.txt",)))
    (tmp_path / "cells").mkdir()
    (tmp_path / "pipelines").mkdir()
    CALLS.clear()
    yield tmp_path
    registry._REGISTRY.pop("t_a")
    registry._REGISTRY.pop("t_b")


def write(project: Path, text: str) -> Path:
    p = project / "pipelines" / "p.toml"
    p.write_text(text)
    return p


BASE = '[pipeline]\nname = "p"\nstages = ["t_b", "t_a"]\n[t_a]\nvalue = {v}\n[t_b]\nscale = {s}\n'


def test_runs_in_dependency_order_and_caches(project):
    pl = load_pipeline(write(project, BASE.format(v=1.5, s=2.0)))
    assert pl.order == ("t_a", "t_b")
    out = run_pipeline(pl)
    assert [o.status for o in out] == ["ran", "ran"]
    assert (project / "outputs/p/t_b/b.txt").read_text() == "3.0\n"
    manifest = json.loads((project / "outputs/p/t_b/manifest.json").read_text())
    assert "a.txt" in manifest["inputs"]["t_a"]
    assert manifest["outputs"]["b.txt"]["bytes"] == 4
    assert "numpy" in manifest["versions"]
    CALLS.clear()
    out = run_pipeline(load_pipeline(write(project, BASE.format(v=1.5, s=2.0))))
    assert [o.status for o in out] == ["cached", "cached"] and CALLS == []


def test_parameter_change_reruns_only_that_stage_and_downstream(project):
    run_pipeline(load_pipeline(write(project, BASE.format(v=1.5, s=2.0))))
    CALLS.clear()
    run_pipeline(load_pipeline(write(project, BASE.format(v=1.5, s=4.0))))
    assert CALLS == ["t_b"]
    CALLS.clear()
    run_pipeline(load_pipeline(write(project, BASE.format(v=2.5, s=4.0))))
    assert CALLS == ["t_a", "t_b"]
    assert (project / "outputs/p/t_b/b.txt").read_text() == "10.0\n"


def test_edited_code_reruns_every_stage_without_force(project, monkeypatch):
    from metasheet.pipeline import manifest

    pl = load_pipeline(write(project, BASE.format(v=1.5, s=2.0)))
    run_pipeline(pl)
    first = json.loads((project / "outputs/p/t_a/manifest.json").read_text())
    assert first["versions"]["metasheet_code"] == manifest.code_digest()
    CALLS.clear()
    monkeypatch.setattr(manifest, "code_digest", lambda: "an edited metasheet")
    out = run_pipeline(pl)
    assert [o.status for o in out] == ["ran", "ran"] and CALLS == ["t_a", "t_b"]
    CALLS.clear()
    assert [o.status for o in run_pipeline(pl)] == ["cached", "cached"] and CALLS == []


def test_tampered_output_is_recomputed(project):
    pl = load_pipeline(write(project, BASE.format(v=1.5, s=2.0)))
    run_pipeline(pl)
    (project / "outputs/p/t_b/b.txt").write_text("garbage\n")
    CALLS.clear()
    run_pipeline(pl)
    assert CALLS == ["t_b"]


def test_only_and_force(project):
    pl = load_pipeline(write(project, BASE.format(v=1.5, s=2.0)))
    run_pipeline(pl, only="t_a")
    assert CALLS == ["t_a"] and not (project / "outputs/p/t_b").exists()
    CALLS.clear()
    run_pipeline(pl, only="t_b", force=True)
    assert CALLS == ["t_b"]  # upstream fresh: reused, not forced
    with pytest.raises(ConfigError, match="--stage"):
        run_pipeline(pl, only="nope")


def test_failing_stage_keeps_old_outputs_and_leaves_no_partial_file(project):
    run_pipeline(load_pipeline(write(project, BASE.format(v=1.5, s=2.0))))
    before = (project / "outputs/p/t_a/manifest.json").read_text()
    bad = write(project, BASE.format(v=3.0, s=2.0).replace("value = 3.0", "value = 3.0\nexplode = true"))
    with pytest.raises(StageError, match="stage 't_a' failed: RuntimeError: boom"):
        run_pipeline(load_pipeline(bad))
    out = project / "outputs/p"
    assert (out / "t_a/a.txt").read_text() == "1.5\n"
    assert (out / "t_a/manifest.json").read_text() == before
    assert not (out / "t_a/half.txt").exists()
    assert sorted(p.name for p in out.iterdir()) == ["t_a", "t_b"]  # no temporary leftovers


@pytest.mark.parametrize(
    "text, expected",
    [
        (BASE.format(v=11, s=2.0), r"p.toml: t_a.value: 11: Input should be less than or equal to 10"),
        (BASE.format(v='"x"', s=2.0), r"p.toml: t_a.value: 'x': expected a number, without quotes"),
        (BASE.format(v=1, s=2.0) + "bogus = 1\n", r"p.toml: t_b.bogus: 1: unknown key"),
        ('[pipeline]\nname = "p"\nstages = ["t_b"]\n', r"stage 't_b' needs stage 't_a'"),
        ('[pipeline]\nname = "p"\nstages = ["nope"]\n', r"pipeline.stages\[0\]: 'nope': unknown stage"),
        ('[pipeline]\nname = "p"\nstages = ["t_a"]\n[zzz]\n', r"zzz: unknown table"),
        ("[pipeline\n", r"invalid TOML"),
    ],
)
def test_config_errors_name_the_field(project, text, expected):
    with pytest.raises(ConfigError, match=expected):
        load_pipeline(write(project, text))


def square(x):
    return x * x


@pytest.mark.parametrize("workers", [1, 2])
def test_executor_keeps_order(workers):
    seen = []
    out = Executor(workers=workers).map(square, range(7), progress=lambda d, n: seen.append((d, n)))
    assert out == [x * x for x in range(7)]
    assert seen[0] == (0, 7) and seen[-1] == (7, 7)  # told at the start, so a line's clock starts there
    assert sorted(d for d, _ in seen) == list(range(8))


def test_executor_rejects_bad_settings():
    with pytest.raises(ConfigError, match="workers"):
        Executor(workers=0)
    with pytest.raises(ConfigError, match="scheduler"):
        Executor(scheduler="localhost:8786")


def test_quick_pipeline_material_stage(quick_outputs):
    data = json.loads((quick_outputs / "quick/material/material.json").read_text())
    assert data["constants"]["E_t"] > data["constants"]["E_l"] > 0
    assert data["nu_lt"] == pytest.approx(data["constants"]["nu_tl"] * data["constants"]["E_l"] / data["constants"]["E_t"])
    import numpy as np

    assert np.allclose(np.array(data["stiffness"]) @ np.array(data["compliance"]), np.eye(6), atol=1e-9)
    assert (quick_outputs / "quick/material/manifest.json").is_file()


@pytest.mark.parametrize("as_value", [True, False])
def test_quick_pipeline_prints_what_it_models(tmp_path, quick_outputs, as_value):
    """Issue 13 round trip on the quick pipeline: the printed Polyfoam map read back through the
    model gives the robot's constants and axes within the tolerance, with every setting bound.
    A uniform infill is written as an exact value by default; as an 8-bit field (as_value False)
    its quantisation shows in the round trip (30 % prints as 76/255 = 29.8 %). The session's
    quick outputs are copied: only the printmap stage runs again where its setting changed."""
    import shutil
    from dataclasses import replace

    root = Path(__file__).resolve().parents[1]
    shutil.copytree(quick_outputs / "quick", tmp_path / "quick")
    pl = load_pipeline(root / "pipelines" / "quick.toml")
    # as_value True is the quick pipeline's own setting: a cache hit, so its picture setting stays too
    update = {"uniform_as_value": True} if as_value else {"uniform_as_value": False, "picture": False}
    pl = replace(pl, params={**pl.params, "printmap": pl.params["printmap"].model_copy(update=update)})
    ran = {o.name: o.status for o in run_pipeline(pl, out_root=tmp_path, only="printmap")}
    assert ran["cell"] == ran["homogenize"] == ran["orient"] == "cached"
    out = tmp_path / "quick/printmap"
    rt = json.loads((out / "print_consistency.json").read_text())
    assert rt["ok"]
    for sheet in ("normal", "mirrored"):
        r = rt[sheet]
        assert r["elements_compared"] > 500
        for k, d in r["constants_relative_difference"].items():
            assert d["max"] <= r["tolerance"], (sheet, k)
        e_t = r["constants_relative_difference"]["E_t"]["max"]
        if as_value:
            assert e_t < 1e-6
        else:  # E_t ~ p^n: the quantised percentage moves it by about n x 0.39 %
            assert 1e-3 < e_t < 0.02
        assert r["axis_angle_difference_deg"]["max"] <= r["angle_tolerance_deg"]
        lua = (out / sheet / "print.lua").read_text()
        percent = "'infill_percentage_0', 30.0" if as_value else "'infill_percentage_0', read_field"
        for bound in ("'infill_type_0', 'Polyfoam'", "'print_perimeter_0', false", "'num_shells_0', 0",
                      "'kgon_x_shrink_0', 0.5", percent, "'infill_angle_0', read_field"):
            assert bound in lua, (sheet, bound)
    # the homogenised cell is the material: the robot's constants are the cell's
    mat = json.loads((tmp_path / "quick/material/material.json").read_text())
    cons = json.loads((tmp_path / "quick/homogenize/constants.json").read_text())
    assert mat["constants"]["E_l"] == pytest.approx(cons["E_l"], rel=1e-12)


def test_a_stage_waits_only_for_the_optional_stages_it_reads(tmp_path):
    """The paper pipeline's anisotropy sweep runs the full model: it does not wait for the
    reduce stage (it runs beside it); its reduced studies do. With a design chart in the
    pipeline (the paper's has none: pipelines/chart.toml), a uniform orient does not wait for
    it, a graded one reads it."""
    from metasheet.pipeline.config import upstream

    root = Path(__file__).resolve().parents[1]
    paper = load_pipeline(root / "pipelines" / "paper.toml")
    assert "reduce" not in upstream(paper, "anisotropy") and "robot" in upstream(paper, "anisotropy")
    assert all("reduce" in upstream(paper, s) for s in ("workspace", "ranges", "maze"))
    text = (root / "pipelines" / "paper.toml").read_text()
    charted = text.replace('stages = ["cell", "homogenize", ', 'stages = ["cell", "homogenize", "chart", ', 1)
    graded = charted.replace('scene = "authors"\n', 'scene = "authors"\ngrading = { density_expr = "0.15" }\n', 1)
    assert text != charted != graded
    (tmp_path / "pipelines").mkdir()
    (tmp_path / "cells").symlink_to(root / "cells")
    for variant, reads in ((charted, False), (graded, True)):
        (tmp_path / "pipelines" / "paper.toml").write_text(variant)
        pl = load_pipeline(tmp_path / "pipelines" / "paper.toml")
        assert ("chart" in upstream(pl, "orient")) == reads and "chart" in upstream(pl, "printmap")


def spin(seconds):
    """Spin for ``seconds`` of CPU time [s]."""
    import time

    t0 = time.process_time()
    while time.process_time() - t0 < seconds:
        pass
    return seconds


def run_spinning(ctx):
    ctx.executor.map(spin, [0.2, 0.2, 0.2])
    spin(0.15)  # the stage's own thread
    ctx.path("c.txt").write_text("spun\n")
    return {}


def test_a_manifest_states_the_stage_cpu_time_in_its_thread_and_its_workers(project):
    register(Stage("t_c", AParams, run_spinning, outputs=("c.txt",)))
    try:
        pl = load_pipeline(write(project, '[pipeline]\nname = "p"\nstages = ["t_c"]\n'))
        (out,) = run_pipeline(pl, executor=Executor(workers=2))
        cpu = json.loads((project / "outputs/p/t_c/manifest.json").read_text())["cpu_s"]
        assert cpu["worker_units"] == 3 and 0.6 <= cpu["workers"] <= 0.7
        assert list(cpu["by_unit"]) == ["spin"] and cpu["by_unit"]["spin"] == [cpu["workers"], 3]
        assert 0.15 <= cpu["stage_thread"] <= 0.5  # its spin and the map's bookkeeping
        assert cpu["total"] == pytest.approx(cpu["stage_thread"] + cpu["workers"], abs=2e-3)
        assert out.cpu_time == cpu["total"]
        assert run_pipeline(pl)[0].cpu_time is None  # cached: nothing ran
    finally:
        registry._REGISTRY.pop("t_c")


@pytest.mark.parametrize("name", sorted(p.name for p in (Path(__file__).resolve().parents[1] / "pipelines")
                                        .glob("*.toml")))
def test_every_shipped_pipeline_validates(name):
    """Each pipeline under pipelines/ loads: its tables, its stages' parameters and the checks
    across stages (what ``metasheet validate`` runs), so a shipped file cannot rot unseen."""
    pl = load_pipeline(Path(__file__).resolve().parents[1] / "pipelines" / name)
    assert pl.order and set(pl.order) <= set(pl.params) and pl.name == name.removesuffix(".toml")
