"""The material models: ours (all five constants) and the authors' SOFA force field's tensor."""

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.mechanics.material import Isotropic, TransverseIsotropic
from metasheet.mechanics.material_model import (
    MATERIAL_MODELS,
    authors_effective,
    authors_entries,
    authors_stiffness,
    check_model,
    model_stiffness,
    other_model,
)
from metasheet.published.paper import FOAM_DENSITY, PAPER_FOAM
from metasheet.robot.builder import (
    SheetPair,
    element_stiffness,
    material_stiffness,
    six_dof_robot,
)
from metasheet.sheet.geometry import SheetParams
from metasheet.mechanics.voigt import MANDEL

CASES = [PAPER_FOAM, TransverseIsotropic(1.0, 0.5, 0.3, 0.3, 0.2), TransverseIsotropic(2.0, 0.2, 0.2, 0.6, 0.05)]


def _kelvin(m: TransverseIsotropic) -> np.ndarray:
    """The authors' tensor rebuilt as their code does (TetrahedronAnisotropicForceField.inl
    lines 457-578): the c entries, then the Kelvin modes and eigenvalues, summed, n = e3."""
    E_t, E_l, nu_t, nu_tl = m.E_t, m.E_l, m.nu_t, m.nu_tl
    nu_lt = nu_tl * E_l / E_t
    g = 1 / (1 - nu_t**2 - 2 * nu_lt * nu_tl - 2 * nu_t * nu_lt * nu_tl)
    c11, c33 = E_t * g * (1 - nu_lt * nu_tl), E_l * g * (1 - nu_t * nu_t)
    c44, c12 = E_t / (2 * (1 + nu_t)), E_t * g * (nu_t + nu_lt * nu_tl)
    c13 = E_t * g * (nu_lt + nu_t * nu_tl)
    ta = np.sqrt(2) * (c11 + c12 - c33) / (4 * c13)
    al = np.arctan(ta)
    sa, ca, sec = np.sin(al), np.cos(al), 1 / np.cos(al)
    eig = [c33 + np.sqrt(2) * c13 * (ta + sec), c11 - c12, c11 - c12, c33 + np.sqrt(2) * c13 * (ta - sec), 2 * c44,
           2 * c44]
    v1, v2, n = np.eye(3)
    d = np.outer
    a1, b1 = 0.5 * (1 + sa) + np.sqrt(2) * ca / 4, 0.5 * (1 - sa) + np.sqrt(2) * ca / 2
    a2, b2 = 0.5 * (1 - sa) - np.sqrt(2) * ca / 4, 0.5 * (1 + sa) - np.sqrt(2) * ca / 2
    Nh1 = (a1 * (d(v1, v1) + d(v2, v2)) + b1 * d(n, n)) / np.sqrt(2 * a1 * a1 + b1 * b1)
    Nh2 = (a2 * (d(v1, v1) + d(v2, v2)) + b2 * d(n, n)) / np.sqrt(2 * a2 * a2 + b2 * b2)
    r = 1 / np.sqrt(2)
    modes = [Nh1, (d(v1, v1) - d(v2, v2)) * r, (d(v1, v2) + d(v2, v1)) * r, Nh2, (d(v2, n) + d(n, v2)) * r,
             (d(v1, n) + d(n, v1)) * r]
    pairs = ((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1))
    mandel = [np.array([N[i, j] * (1 if i == j else np.sqrt(2)) for i, j in pairs]) for N in modes]
    return sum(lam * np.outer(v, v) for lam, v in zip(eig, mandel)) / MANDEL


@pytest.mark.parametrize("m", CASES)
def test_authors_tensor_equals_their_kelvin_sum_and_the_closed_form(m):
    C = authors_stiffness(m)
    np.testing.assert_allclose(C, _kelvin(m), rtol=1e-12, atol=1e-14)
    ours = m.stiffness()
    # same c11, c12, c33, c66 as ours; shear E_t / (2 (1 + nu_t)) whatever mu_l
    for i, j in ((0, 0), (1, 1), (0, 1), (2, 2), (5, 5)):
        assert C[i, j] == pytest.approx(ours[i, j], rel=1e-12)
    assert C[3, 3] == C[4, 4] == pytest.approx(m.E_t / (2 * (1 + m.nu_t)), rel=1e-15)
    c = authors_entries(m)
    assert C[0, 2] == C[1, 2] == pytest.approx(c["c13"])
    # c13: theirs E_t g (nu_lt + nu_t nu_tl) against the consistent E_t g nu_lt (1 + nu_t)
    g = 1 / (1 - m.nu_t**2 - 2 * m.nu_lt * m.nu_tl - 2 * m.nu_t * m.nu_lt * m.nu_tl)
    assert ours[0, 2] == pytest.approx(m.E_t * g * m.nu_lt * (1 + m.nu_t), rel=1e-10)
    assert c["c13"] == pytest.approx(m.E_t * g * (m.nu_lt + m.nu_t * m.nu_tl), rel=1e-14)


def test_authors_tensor_is_ours_with_mu_t_when_isotropic_in_stiffness():
    m = TransverseIsotropic(1.0, 1.0, 0.3, 0.3, 0.05)  # E_l = E_t, nu_tl = nu_t: only mu_l differs
    np.testing.assert_allclose(authors_stiffness(m), Isotropic(1.0, 0.3).stiffness(), rtol=1e-12, atol=1e-15)
    eff = authors_effective(PAPER_FOAM)
    assert eff.mu_l == pytest.approx(PAPER_FOAM.E_t / (2 * (1 + PAPER_FOAM.nu_t)))
    assert eff.mu_l / PAPER_FOAM.mu_l == pytest.approx(33.8, abs=0.1)  # the "~34x" of the issue


def test_ours_is_unchanged_and_isotropic_is_the_same_under_both():
    for m in CASES:
        np.testing.assert_array_equal(model_stiffness(m), m.stiffness())
        np.testing.assert_array_equal(model_stiffness(m, "ours"), m.stiffness())
    iso = Isotropic(2.0, 0.45)
    np.testing.assert_array_equal(model_stiffness(iso, "authors"), iso.stiffness())


def test_bad_model_names_the_key_and_the_allowed_values():
    with pytest.raises(ConfigError, match=r"material.model: 'sofa': allowed values are 'ours', 'authors'"):
        check_model("sofa")
    with pytest.raises(ConfigError, match=r"model: 'Authors': allowed values are 'ours', 'authors'"):
        model_stiffness(PAPER_FOAM, "Authors")
    assert MATERIAL_MODELS == ("ours", "authors") and other_model("ours") == "authors"


def test_indefinite_authors_tensor_is_refused_with_the_condition():
    soft = TransverseIsotropic(2.0, 0.05, 0.2, 0.9, 0.05)  # valid for us, not for their c13
    soft.stiffness()
    with pytest.raises(ConfigError, match=r"material.model: 'authors'.*\(c11 \+ c12\) c33 > 2 c13\^2"):
        authors_stiffness(soft)


@pytest.fixture(scope="module")
def sheets():
    return SheetPair.spiral(SheetParams(mesh_size=15.0))


def test_mu_l_has_no_effect_on_the_robot_under_the_authors_model(sheets):
    stiff = replace(PAPER_FOAM, mu_l=0.3)
    for model, same in (("authors", True), ("ours", False)):
        a = material_stiffness(PAPER_FOAM, sheets.fibers, model)
        b = material_stiffness(stiff, sheets.fibers, model)
        assert np.allclose(a, b, rtol=1e-13, atol=0) == same
        ea = element_stiffness(sheets.fibers, np.tile(PAPER_FOAM.as_tuple(), (len(sheets.fibers), 1)), model)
        np.testing.assert_allclose(ea, a, rtol=1e-12, atol=1e-15)
    ra = six_dof_robot(sheets, PAPER_FOAM, density=FOAM_DENSITY, model="authors")
    rb = six_dof_robot(sheets, stiff, density=FOAM_DENSITY, model="authors")
    np.testing.assert_array_equal(ra.body.stiffness, rb.body.stiffness)
    default = six_dof_robot(sheets, PAPER_FOAM, density=FOAM_DENSITY)
    ours = six_dof_robot(sheets, PAPER_FOAM, density=FOAM_DENSITY, model="ours")
    np.testing.assert_array_equal(default.body.stiffness, ours.body.stiffness)
    assert not np.allclose(default.body.stiffness, ra.body.stiffness)
    with pytest.raises(ConfigError, match="model: 'x': allowed values"):
        six_dof_robot(sheets, PAPER_FOAM, density=FOAM_DENSITY, model="x")


def test_material_stage_records_the_model_and_config_names_the_key(tmp_path):
    from metasheet.pipeline.artefacts import read_material
    from metasheet.pipeline.config import load_pipeline
    from metasheet.pipeline.runner import run_pipeline

    (tmp_path / "pipelines").mkdir()
    p = tmp_path / "pipelines" / "m.toml"
    p.write_text('[pipeline]\nname = "m"\nstages = ["material"]\n[material]\nsource = "config"\nmodel = "authors"\n')
    run_pipeline(load_pipeline(p), out_root=tmp_path / "out")
    d = tmp_path / "out" / "m" / "material"
    data = json.loads((d / "material.json").read_text())
    assert data["model"] == "authors" and read_material(d).model == "authors"
    np.testing.assert_allclose(data["model_stiffness"], authors_stiffness(PAPER_FOAM), rtol=1e-12)
    assert data["authors_effective_constants"]["mu_l"] == pytest.approx(authors_effective(PAPER_FOAM).mu_l)
    man = json.loads((d / "manifest.json").read_text())
    assert man["params"]["model"] == "authors" and man["summary"]["model"] == "authors"
    p.write_text('[pipeline]\nname = "m"\nstages = ["material"]\n[material]\nmodel = "sofa"\n')
    with pytest.raises(ConfigError, match=r"material.model: 'sofa': Input should be 'ours' or 'authors'"):
        load_pipeline(p)


def test_goto_takes_the_material_stage_model(tmp_path):
    from metasheet.goto import goto_model
    from metasheet.pipeline.artefacts import write_material

    (tmp_path / "orient").mkdir()
    (tmp_path / "material").mkdir()
    assert goto_model(tmp_path / "orient", None) == "ours"  # no material.json yet
    write_material(tmp_path / "material" / "material.json", PAPER_FOAM, density=FOAM_DENSITY, source="config",
                   model="authors")
    assert goto_model(Path(tmp_path / "orient"), None) == "authors"
    assert goto_model(tmp_path / "orient", "ours") == "ours"
    with pytest.raises(ConfigError, match="--material-model: 'x': allowed values"):
        goto_model(None, "x")
