"""Issue 14 item 2: the convergence study's fit, its errors, and the robot stage's
convergence.json with the report's section (a coarse case)."""

import json

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.robot.convergence import (
    TOLERANCES,
    Level,
    LevelResult,
    convergence_summary,
    errors_against,
    extrapolate,
    fit_power_law,
)
from metasheet.pipeline.runner import run_pipeline
from metasheet.pipeline.config import load_pipeline


def test_fit_recovers_an_exact_power_law():
    h = np.array([4.0, 3.0, 2.0, 1.5, 1.0])
    q_inf, p, rms = fit_power_law(h, 3.0 + 2.0 * h**1.5)
    assert abs(p - 1.5) < 1e-9 and abs(q_inf - 3.0) < 1e-9 and rms < 1e-12
    # a vector figure shares one order; each entry gets its own limit
    Q = np.stack([1.0 + 0.5 * h**2, -2.0 + 0.1 * h**2], axis=1)
    lim, p, _ = fit_power_law(h, Q)
    assert abs(p - 2.0) < 1e-9 and np.allclose(lim, [1.0, -2.0], rtol=0, atol=1e-9)


def test_fit_does_not_extrapolate_below_order_one():
    """Levels that creep (order 0.3) are fitted with order 1: the limit stays near the data."""
    h = np.array([2.0, 1.4, 1.0, 0.7])
    q = 10.0 + np.sqrt(np.sqrt(h))
    _, p, _ = fit_power_law(h, q)
    assert p == 1.0


def _fake(level, h, J, w):
    return LevelResult(level, 100, 300, h, np.asarray(J, float), np.linalg.svd(J, compute_uv=False),
                       float(J[3, 0]), float(w), 0.04, 0.1)


def test_errors_and_checks_against_the_reference_limit():
    rng = np.random.default_rng(0)
    J0 = rng.normal(size=(6, 6))
    sizes = (3.0, 2.0, 1.4, 1.0)
    res = [_fake(Level("p2", 10.0, 0, g), g, J0 * (1 + 0.1 * g**2), 25.0 * (1 + 0.2 * g**2)) for g in sizes]
    res.append(_fake(Level("p1", 14.0), 5.0, J0 * 1.2, 10.0))
    lim = extrapolate(res, "p2-graded")
    assert np.allclose(lim.J, J0, rtol=1e-8, atol=1e-8) and abs(lim.orders["J"] - 2.0) < 1e-9
    e = errors_against(res[-2], lim)  # g = 1: J off by 10 %, W by 20 %
    assert abs(e["jacobian"] - 0.1) < 1e-8 and abs(e["rod_compliance"] - 0.2) < 1e-8
    s = convergence_summary(res, {"robot": Level("p2", 10.0, 0, 1.0), "workspace": Level("p1", 14.0)})
    assert s["reference"] == "p2-graded" and set(s["limits"]) == {"p2-graded"}  # p1: one level only
    assert not s["checks"]["robot"]["within"] and not s["checks"]["workspace"]["within"]
    assert s["checks"]["robot"]["tolerances"] == TOLERANCES
    assert all("seconds" not in row for row in s["levels"])  # artefacts hold no wall time
    with pytest.raises(ConfigError, match="not among the levels"):
        convergence_summary(res, {"maze": Level("p1", 9.0)})


@pytest.fixture(scope="module")
def coarse_run(tmp_path_factory):
    """material (published) -> orient (P1, 16 mm) -> robot with a 5-level study (and the orient
    mesh: 3 levels of each element) -> report. The robot's own sheets are P1 and it draws no
    picture (tests/test_robot_stage.py draws it): the stage's own cases cost 0.6 CPU s, not 5.6
    on P2 with the picture; the P2 levels are the study's, the same as before."""
    root = tmp_path_factory.mktemp("conv")
    (root / "pipelines").mkdir()
    f = root / "pipelines" / "c.toml"
    f.write_text('[pipeline]\nname = "c"\nstages = ["material", "orient", "robot", "report"]\n'
                 '[material]\nsource = "config"\n[orient]\nscene = "metasheet"\nelement = "p1"\nmesh_size = 16.0\npicture = false\n'
                 '[robot]\ncompare_models = false\npicture = false\n'
                 'convergence = [["p1", 12.0, 0, 0.0], ["p1", 9.0, 0, 0.0], '
                 '["p2", 16.0, 0, 0.0], ["p2", 13.0, 0, 0.0], ["p2", 11.0, 0, 0.0]]\n')
    run_pipeline(load_pipeline(f), out_root=root / "out")
    return root / "out" / "c"


@pytest.mark.slow
@pytest.mark.bytes
def test_the_levels_on_two_workers_give_the_same_study(coarse_run):
    """The levels run as work units, the slowest first: on a pool the study is the serial one's,
    byte for byte, its levels in the configured order (default sibling:
    :func:`test_two_levels_on_two_workers_give_the_serial_study`). The pooled run starts from copies of the
    serial run's material and orient outputs, which its runner finds up to date (the orient
    stage's sheet.png alone cost 4 CPU s): only the robot stage runs again."""
    import shutil

    from metasheet.runtime.executor import Executor

    root = coarse_run.parent.parent
    for stage in ("material", "orient"):
        shutil.copytree(coarse_run / stage, root / "pooled" / "c" / stage)
    run_pipeline(load_pipeline(root / "pipelines" / "c.toml"), out_root=root / "pooled", only="robot",
                 executor=Executor(workers=2))
    name = "convergence.json"
    assert (root / "pooled" / "c" / "robot" / name).read_bytes() == (coarse_run / "robot" / name).read_bytes()
    cpu = json.loads((root / "pooled" / "c" / "robot" / "manifest.json").read_text())["cpu_s"]
    assert cpu["by_unit"]["_level_unit"][1] == 6  # the five levels and the orient mesh


@pytest.mark.bytes
def test_two_levels_on_two_workers_give_the_serial_study(coarse_run):
    """The same check on a study of two coarse P1 levels, run serially then on a pool of two,
    each from copies of the module run's material and orient outputs (cached: the robot stage
    alone runs)."""
    import shutil

    from metasheet.runtime.executor import Executor

    root = coarse_run.parent.parent
    text = (root / "pipelines" / "c.toml").read_text()
    two = root / "pipelines" / "c2.toml"
    two.write_text(text[:text.index("convergence = ")] + 'convergence = [["p1", 14.0, 0, 0.0], ["p1", 12.0, 0, 0.0]]\n'
                   'uncertainty = false\n')
    for run in ("serial2", "pooled2"):
        for stage in ("material", "orient"):
            shutil.copytree(coarse_run / stage, root / run / "c" / stage)
        ran = run_pipeline(load_pipeline(two), out_root=root / run, only="robot",
                           executor=Executor(workers=2 if run == "pooled2" else 1))
        assert [o.status for o in ran] == ["cached", "cached", "ran"]
    name = "robot/convergence.json"
    assert (root / "pooled2" / "c" / name).read_bytes() == (root / "serial2" / "c" / name).read_bytes()
    cpu = json.loads((root / "pooled2" / "c" / "robot" / "manifest.json").read_text())["cpu_s"]
    assert cpu["by_unit"]["_level_unit"][1] == 3  # the two levels and the orient mesh


def test_robot_stage_writes_convergence_json(coarse_run):
    conv = json.loads((coarse_run / "robot" / "convergence.json").read_text())
    labels = [(r["element"], r["mesh_size"]) for r in conv["levels"]]
    assert labels == [("p1", 12.0), ("p1", 9.0), ("p2", 16.0), ("p2", 13.0), ("p2", 11.0), ("p1", 16.0)]
    # the more accurate element's limit is the reference, whatever the robot's own element
    assert conv["reference"] == "p2" and conv["checks"]["robot"]["mesh"] == "p1 h=16 mm"
    for r in conv["levels"]:
        assert r["dofs"] == 3 * (r["dofs"] // 3) and len(r["singular_values"]) == 6
        assert r["rod_compliance_mm_per_N"] > 0 and r["gravity_sag_mm"] > 0
    p1 = {r["mesh_size"]: r for r in conv["levels"] if r["element"] == "p1"}
    p2 = {r["mesh_size"]: r for r in conv["levels"] if r["element"] == "p2"}
    # linear sheets lock in bending: at comparable dofs they are far stiffer along the rod
    assert p1[9.0]["rod_compliance_mm_per_N"] < 0.5 * p2[16.0]["rod_compliance_mm_per_N"]
    man = json.loads((coarse_run / "robot" / "manifest.json").read_text())
    assert any(k.startswith("convergence p2 h=11") for k in man["timings_s"])


def test_report_states_each_mesh_error(coarse_run):
    text = (coarse_run / "report" / "report.md").read_text()
    assert "## Mesh convergence of the robot" in text
    assert "| robot | p1 h=16 mm |" in text
