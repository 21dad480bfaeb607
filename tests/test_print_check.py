"""The chosen design printed against its model (issue 63): metasheet.studies.print_check and the
``printcheck`` stage. The design's continuum on the grips is the design stage's own rest problem
(the same rod roll through another code path); a print as stiff as the model, or uniformly
softer, rolls the rod exactly as the model does; the stage end to end (slow) on the coarse robot
of tests/test_design_stage.py printed in a coarse foam."""

import json
import shutil
from dataclasses import replace

import metasheet  # noqa: F401  (pins numpy's code paths before numpy is imported)

# isort: split
import numpy as np
import pytest

from metasheet.studies.print_check import ROLL_TOLERANCE, compare_roll, design_fibres, model_grips, verdict
from metasheet.errors import ConfigError
from metasheet.pipeline.artefacts import read_material, read_orient
from metasheet.pipeline.config import load_pipeline
from metasheet.pipeline.runner import run_pipeline
from metasheet.published import paper
from metasheet.robot.builder import six_dof_robot
from metasheet.sheet.dns import DnsSheet
from metasheet.sheet.fibers import spiral_fibers
from test_design_stage import BASE, DESIGN, first_run
from test_sheet_stage import DESIGN as FOAM  # a small Polyfoam with a 0.8 mm bead

@pytest.fixture(scope="module")
def first(tmp_path_factory):
    tmp = first_run(tmp_path_factory)
    d = tmp / "out" / "d"
    orient, mat = read_orient(d / "orient"), read_material(d / "material")
    design = json.loads((d / "design" / "design.json").read_text())
    pair = replace(orient.sheets(need_constants=False), element="p1")
    return tmp, orient, mat, design, pair


def _robot(pair, orient, mat):
    sc = orient.scene
    return six_dof_robot(pair, mat.material, rod_length=sc.rod_length, geometry=sc.servo_geometry(),
                         density=paper.FOAM_DENSITY, model=mat.model)


def _sheets(Ks, seeds=(1,)):
    return [DnsSheet(np.asarray(K), label, s, "seed", (1, 1, 1), (1.0, 1.0, 1.0), 0.3, 1.0, 1.0, 24, (1,), "none",
                     0.0, 0.0, 0.0) for s, pair in zip(seeds, Ks) for label, K in zip(("normal", "mirrored"), pair)]


def test_design_fibres_are_the_design_stage_fields(first):
    _, orient, _, design, pair = first
    kw = {"law": design["spiral"]["law"], "r_ref": design["spiral"]["r_ref"]}
    q = pair.sheet.centroids()
    spiral = design_fibres({"pitch_deg": 30.0, "basis": None, "coefficients_rad": []}, kw)
    assert np.array_equal(spiral(q, True), spiral_fibers(q, mirrored=True, pitch_deg=30.0, **kw))
    from metasheet.sheet.fibre_field import PolarBSpline

    basis = {"n_radial": 4, "n_angular": 12, "degree": 3, "r_max": 80.0, "symmetric": True}
    zero = design_fibres({"pitch_deg": 30.0, "basis": basis, "coefficients_rad": [0.0] * PolarBSpline(**basis).n_coefficients},
                         kw)
    assert np.allclose(np.abs(np.sum(zero(q, False) * spiral(q, False), axis=1)), 1.0, atol=1e-12)


def test_the_model_on_the_grips_is_the_design_stages_rest_problem(first):
    """The design's continuum condensed on its grips rolls the rod as the design stage's adjoint
    rest problem says (design.json keeps 6 digits)."""
    _, orient, mat, design, pair = first
    kw = {"law": design["spiral"]["law"], "r_ref": design["spiral"]["r_ref"]}
    for key, d in (("chosen", design["chosen"]["design"]),
                   ("spiral", {"pitch_deg": design["spiral"]["pitch_deg"], "basis": None, "coefficients_rad": []})):
        f = design_fibres(d, kw)
        K = model_grips(pair, f, mat.material, mat.model)
        r = compare_roll(K, _sheets([K]), _robot(pair, orient, mat), orient.sheet_params, length_scale=50.0)
        assert r["model"]["rod_rotation_deg_per_deg"] == pytest.approx(design[key]["roll_deg_per_deg"], rel=5e-6)
        assert r["prints"][0]["roll_ratio"] == pytest.approx(1.0, abs=1e-12) and r["meets"]


def test_a_uniformly_softer_print_rolls_alike_and_a_changed_one_misses(first):
    _, orient, mat, design, pair = first
    f = design_fibres(design["chosen"]["design"], {"law": design["spiral"]["law"], "r_ref": design["spiral"]["r_ref"]})
    Ka, Kb = model_grips(pair, f, mat.material, mat.model)
    robot = _robot(pair, orient, mat)
    soft = compare_roll((Ka, Kb), _sheets([(0.2 * Ka, 0.2 * Kb)]), robot, orient.sheet_params, length_scale=50.0)
    assert soft["prints"][0]["roll_ratio"] == pytest.approx(1.0, rel=1e-9)  # no load but the horns: scale-free
    # a print whose foam lost its anisotropy (the same sheets, isotropic): the rod rolls far less;
    # two prints, the worse one named
    from metasheet.mechanics.material import TransverseIsotropic

    m = mat.material
    iso = TransverseIsotropic(m.E_t, m.E_t, m.nu_t, m.nu_t, m.E_t / (2 * (1 + m.nu_t)))
    Ki = model_grips(pair, f, iso, mat.model)
    odd = compare_roll((Ka, Kb), _sheets([(Ka, Kb), Ki], seeds=(1, 2)), robot, orient.sheet_params,
                       length_scale=50.0)
    r = odd["roll_ratio"]
    assert r["min"] <= 1.0 <= r["max"] and abs(r["max"] - r["min"]) > ROLL_TOLERANCE
    assert not odd["meets"] and odd["misses_by"] == pytest.approx(max(abs(r["min"] - 1), abs(r["max"] - 1)))
    assert "misses the model by" in verdict(odd) and "meets the model" in verdict(soft, odd)


def test_bad_print_design_is_named(tmp_path):
    (tmp_path / "foam.toml").write_text('kind = "foam"\nname = "f"\n')
    f = tmp_path / "p.toml"
    f.write_text(BASE.format(design="n_trials = 4").replace('"design"]', '"design", "printcheck"]')
                 + f'\n[printcheck]\nprint_design = "{tmp_path / "foam.toml"}"\n')
    with pytest.raises(ConfigError, match="printcheck.print_design"):
        load_pipeline(f)
    (tmp_path / "foam.toml").write_text(FOAM)
    f.write_text(f.read_text() + "voxel_mm = 1.0\n")
    with pytest.raises(ConfigError, match="printcheck.voxel_mm: 1: allowed range"):
        load_pipeline(f)


@pytest.mark.slow
def test_stage_prints_the_chosen_design(first, tmp_path):
    """The stage after the first run's design (its stages reused): both designs printed once at
    the coarse foam's bead, against their models; the report carries the section (~40 s)."""
    tmp = first[0]
    shutil.copytree(tmp / "out", tmp_path / "out")
    (tmp_path / "foam.toml").write_text(FOAM)
    table = "\n".join(f"{k} = {v}" for k, v in DESIGN.items())
    f = tmp_path / "p.toml"
    f.write_text(BASE.format(design=table).replace('"design"]', '"design", "printcheck", "report"]')
                 + f'\n[printcheck]\nprint_design = "{tmp_path / "foam.toml"}"\nvoxel_mm = 0.8\n')
    run_pipeline(load_pipeline(f), out_root=tmp_path / "out")
    d = json.loads((tmp_path / "out" / "d" / "printcheck" / "print_check.json").read_text())
    design = json.loads((tmp_path / "out" / "d" / "design" / "design.json").read_text())
    assert d["chosen"]["model"]["rod_rotation_deg_per_deg"] == pytest.approx(design["chosen"]["roll_deg_per_deg"],
                                                                             rel=5e-6)
    for k in ("chosen", "spiral"):
        p = d[k]["prints"][0]
        assert np.sign(p["rod_rotation_deg_per_deg"]) == np.sign(d[k]["model"]["rod_rotation_deg_per_deg"])
        assert p["roll_ratio"] == pytest.approx(p["rod_rotation_deg_per_deg"] / d[k]["model"]["rod_rotation_deg_per_deg"])
    report = (tmp_path / "out" / "d" / "report" / "report.md").read_text()
    assert "The chosen design printed" in report and d["verdict"] in report
