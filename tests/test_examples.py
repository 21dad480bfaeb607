"""The gallery in ``examples/``: each script's small case, its numbers and its picture.

Each script is imported by path and its ``main(small=True, out=...)`` run; the numbers it
returns are checked against values measured on the small case (``python examples/NAME.py``
runs the full one), with a physical reason where there is one, and its picture must exist
and not be blank. The tolerances are regression tolerances: loose enough for another BLAS or
CPU code path, tight enough that a change in the model shows.
"""

from __future__ import annotations

import ast
import importlib.util
import inspect
import re
from pathlib import Path

import numpy as np
import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
NAMES = ("cell_constants", "chart_lookup", "sheet_printmap", "jacobian_silicone_vs_foam", "goto", "small_workspace",
         "motor_program", "printed_robot")


def load(name: str):
    """The example script ``examples/<name>.py`` as a module (not run: its main is guarded)."""
    spec = importlib.util.spec_from_file_location(f"examples_{name}", EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def run(name: str, tmp_path: Path) -> dict:
    out = tmp_path / f"{name}.png"
    numbers = load(name).main(small=True, out=out)
    non_blank_png(out)
    assert not list(tmp_path.glob(".*.tmp-*")), "the temporary picture was left behind"
    return numbers


def non_blank_png(path: Path) -> None:
    import matplotlib.image as mpimg

    img = mpimg.imread(path)
    assert img.shape[0] > 200 and img.shape[1] > 200
    assert img[..., :3].std() > 0.05  # not a flat picture


def test_every_example_is_listed_documented_and_has_main():
    assert sorted(p.stem for p in EXAMPLES.glob("*.py")) == sorted(NAMES)  # a new script gets a test here
    for name in NAMES:
        source = (EXAMPLES / f"{name}.py").read_text()
        doc = ast.get_docstring(ast.parse(source))
        title, blank, paragraph = (doc.splitlines() + ["", ""])[:3]
        assert title and not blank and paragraph, f"{name}: docstring is a title line, a blank line, a paragraph"
        assert re.search(r'^if __name__ == "__main__":.*\n    main\(out=Path\(sys.argv\[1\]\) if len\(sys.argv\) > 1 else None\)$',
                         source, re.M)
        assert len(source.splitlines()) <= 130, f"{name}: keep an example short"
        params = inspect.signature(load(name).main).parameters
        assert list(params) == ["small", "out"] and params["small"].default is False and params["out"].default is None


def test_cell_constants(tmp_path):
    n = run("cell_constants", tmp_path)
    # measured: quick_foam on 24^3 voxels, 14,268 dofs
    expected = {"E_t": 0.35975, "E_l": 0.13273, "nu_t": 0.36222, "nu_tl": 0.49482, "mu_l": 0.086547,
                "alpha": 63.1036, "misfit": 0.069958}
    for key, value in expected.items():
        assert n[key] == pytest.approx(value, rel=1e-4), key
    assert n["n_dof"] == 14268
    # physics: a stable material, soft along l (the cells are flattened along it)
    assert all(n[k] > 0 for k in ("E_t", "E_l", "mu_l", "nu_t", "nu_tl"))
    assert n["E_l"] < 0.5 * n["E_t"]
    assert n["relative_density"] == pytest.approx(0.15, abs=0.005)  # the design's density tolerance
    assert n["E_t"] < 0.15 * 12.0  # below the Voigt bound rho E_s (TPU, 12 MPa)
    assert n["misfit"] < 0.1  # the TI fit holds 93 % of the stiffness (Frobenius, Mandel)


@pytest.mark.slow
def test_chart_lookup(tmp_path):
    """Nine cells homogenised (about 12 s on 2 quiet cores). Default siblings: the chart's own
    tests (test_homogenize_chart.py) and this file's listing check of the script."""
    n = run("chart_lookup", tmp_path)
    assert n["points"] == 9
    # measured: 3 x 3 Polyfoam chart, 0.4 mm voxels, target E_t 2, E_l 0.3 MPa
    assert n["infill_percentage"] == pytest.approx(28.650, abs=0.01)
    assert n["kgon_x_shrink"] == pytest.approx(0.5331, abs=0.001)
    # the target lies inside the chart: the interpolant matches it exactly
    assert n["residual"] < 1e-8
    assert n["E_t_chart"] == pytest.approx(2.0, rel=1e-6) and n["E_l_chart"] == pytest.approx(0.3, rel=1e-6)
    # the cell printed at the answer, homogenised: interpolation and seed scatter only (E_l, from the
    # walls' bending, is the more sensitive); measured +1.3 % and +9.7 %
    assert n["E_t_error"] == pytest.approx(0.0126, abs=0.002)
    assert n["E_l_error"] == pytest.approx(0.0971, abs=0.005)
    assert abs(n["E_t_error"]) < 0.05 and abs(n["E_l_error"]) < 0.15


def test_sheet_printmap(tmp_path):
    n = run("sheet_printmap", tmp_path)
    # measured: 8 mm sheet, 1,915 tets, 625 of them in the solid ring and tabs
    assert n["tets"] == pytest.approx(1915, abs=20)
    assert n["foam_elements"] + n["solid_elements"] == n["tets"]
    assert n["infill_min"] == pytest.approx(13.843, abs=0.01) and n["infill_max"] == pytest.approx(16.211, abs=0.01)
    # the print model's exponent is the design's: printed infill = 100 x designed density
    assert 100 * n["density_min"] - 1e-9 <= n["infill_min"] < n["infill_max"] <= 100 * n["density_max"] + 1e-9
    # the round trip of the 8-bit fields is within the printmap stage's tolerances (2 %, 2 deg)
    assert n["ok"]
    assert n["max_rel_difference"] == pytest.approx(0.01639, abs=0.001) and n["max_rel_difference"] < 0.02
    assert n["max_axis_difference_deg"] == pytest.approx(0.751, abs=0.02)


def test_jacobian_silicone_vs_foam(tmp_path):
    n = run("jacobian_silicone_vs_foam", tmp_path)
    s_sil, s_foam = np.array(n["silicone_singular_values"]), np.array(n["foam_singular_values"])
    # measured: P1 14 mm, 1,297 tets a sheet
    np.testing.assert_allclose(s_foam, [18.4412, 12.6614, 12.5665, 12.3836, 10.1406, 9.9327], rtol=1e-4)
    np.testing.assert_allclose(s_sil[:5], [16.9230, 13.5530, 13.4906, 10.8550, 10.7709], rtol=1e-4)
    assert n["foam_roll_per_degree"] == pytest.approx(-0.6153, rel=1e-3)
    # silicone's sixth singular value (0.02) is the mesh's asymmetry only: it loses the rod roll
    assert s_sil[5] == pytest.approx(0.0205, rel=0.05)
    assert s_sil[5] < 0.01 * s_foam[5]
    assert abs(n["silicone_roll_per_degree"]) < 0.01 * abs(n["foam_roll_per_degree"])
    assert abs(n["silicone_roll_finite"]) < 0.01 * abs(n["foam_roll_finite"])
    # the other five directions are much alike in both materials
    assert np.all((s_foam[:5] / s_sil[:5] > 0.8) & (s_foam[:5] / s_sil[:5] < 1.25))
    # J's prediction agrees with the finite -10 deg move in sign and roughly in size (the foam stiffens)
    assert n["foam_roll_finite"] / n["foam_roll_per_degree"] == pytest.approx(0.88, abs=0.05)


def test_goto(tmp_path):
    n = run("goto", tmp_path)
    foam, sil = n["foam"], n["silicone"]
    # the foam reaches the pose, roll about the rod included, within the inverse model's tolerances
    assert foam["status"] == "reached"
    assert foam["pos_error_mm"] <= n["tolerance_mm"] and foam["rot_error_deg"] <= n["tolerance_deg"]
    # measured: 5 control steps
    np.testing.assert_allclose(foam["angles_deg"], [54.15, 54.36, 43.55, 49.32, 36.90, 48.99], atol=0.05)
    assert np.all((np.array(foam["angles_deg"]) >= 0.0) & (np.array(foam["angles_deg"]) <= 90.0))  # the stroke
    # silicone cannot roll the rod: it stalls with (nearly) the whole 6 deg roll missing
    assert sil["status"] in ("stalled", "max_steps")
    assert sil["rot_error_deg"] == pytest.approx(6.0, abs=0.1)


def test_motor_program(tmp_path):
    n = run("motor_program", tmp_path)
    a, p = np.array(n["angles_deg"]), np.array(n["pulses_us"])
    # a 9.4 mm circle at 6 mm/s, sampled at 5 Hz: 9 samples to 1.6 s, each reached (0.1 mm), within the servos
    assert n["samples"] == 9 and n["duration_s"] == pytest.approx(1.6) and n["reached"] == 9 and n["ok"]
    assert n["max_error_mm"] <= 0.1 and n["max_speed_deg_s"] < 600.0
    # the bottom of the circle lies in the robot's mirror plane (y = 0): sheet B's motors mirror A's
    # (0 <-> 3, 1 <-> 5, 2 <-> 4); measured 68.53, 57.41, 52.63 deg on the 14 mm sheets
    np.testing.assert_allclose(a[4, [3, 5, 4]], a[4, :3], atol=1e-6)
    np.testing.assert_allclose(a[4, :3], [68.53, 57.41, 52.63], atol=0.05)
    # back where it started, within the tolerance's worth of motor angle; the pulses are the stated map
    np.testing.assert_allclose(a[-1], a[0], atol=0.2)
    np.testing.assert_allclose(p, 500.0 + a / 180.0 * 2000.0, rtol=1e-12)


@pytest.mark.slow
def test_small_workspace(tmp_path):
    """Default siblings: the workspace study on coarse robots (test_studies_core.py,
    test_studies_robot.py) and this file's listing check of the script."""
    n = run("small_workspace", tmp_path)
    # measured: 3 + 2 rays of 2 steps on the P1 14 mm robot; all reached, one connected piece
    assert n["goals"] == 10 and n["reached"] == 10 and n["unreachable"] == 0
    assert (n["3 rotations"], n["2 rotations"], n["1 rotation"], n["reachable only"]) == (2, 0, 4, 4)
    assert n["components"] == 1 and n["paths_passed"] == n["paths_tested"] == 18
    assert n["max_strain"] == pytest.approx(0.3710, abs=0.002)
    assert n["min_sigma"] == pytest.approx(3.193, abs=0.01)
    # the two points beyond the foam's strain limit are far ends of lateral rays (the outer step, 8 mm)
    assert n["valid"] == 8
    assert sum(n[k] for k in ("3 rotations", "2 rotations", "1 rotation", "reachable only", "unreachable")) == 10


@pytest.mark.parametrize("name", NAMES)
def test_an_example_run_as_is_writes_under_outputs(name):
    """Issue 61: each example wrote its picture into docs/examples/ (tracked files) by default."""
    source = (EXAMPLES / f"{name}.py").read_text()
    assert 'ROOT / "outputs" / "examples" /' in source and '"docs" / "examples"' not in source


@pytest.mark.slow
def test_printed_robot(tmp_path):
    """Default-selection sibling: tests/test_sheet_stage.py's printed stage on a small printed
    sheet (the same functions through the pipeline)."""
    n = run("printed_robot", tmp_path)
    # measured: the small tripod's two prints at 0.5 mm, seed 1 (CG to 1e-6)
    assert n["binding"] == "roll down" and n["valid_deg"] == pytest.approx(1.9019, rel=1e-3)
    assert n["rod_pull_deg"] == pytest.approx(-33.869, rel=1e-3)
    assert n["rod_pull_within_deg"] == pytest.approx(-15.967, rel=1e-3)
    # physics: pulled and pushed, the rod turns opposite ways before the walls touch
    assert n["rod_pull_within_deg"] * n["rod_push_within_deg"] < 0
    assert n["status"] == "predicted up to the walls' limit"
