"""The homogenize stage on hand-made cell artefacts (exact laminate) and end to end."""

import json

import meshio
import numpy as np
import pytest

from metasheet.mechanics.material import Isotropic
from metasheet.pipeline.registry import StageContext
from metasheet.pipeline.stages import homogenize as stage

from homogenize_bounds import backus_laminate
from homogenize_samples import laminate


def _cell_dir(tmp_path, phases, size, materials):
    d = tmp_path / "cell"
    d.mkdir()
    np.savez(d / "voxels.npz", phases=phases.astype(np.uint8), size=np.asarray(size, float),
             axis=np.array([0.0, 0.0, 1.0]))
    (d / "cell.json").write_text(json.dumps({"name": "test_laminate", "materials": materials}))
    return d


def _png_is_not_blank(path):
    import matplotlib.image as mpimg

    img = mpimg.imread(path)
    return img.shape[0] > 100 and float(img[..., :3].std()) > 0.05


def test_stage_writes_exact_laminate_constants_fields_and_picture(tmp_path):
    ph = laminate(6, 0.5, axis=2)
    mats = {"1": {"E": 12.0, "nu": 0.3}, "2": {"E": 1.5, "nu": 0.45}}
    cell = _cell_dir(tmp_path, ph, (2.0, 2.0, 2.0), mats)
    work = tmp_path / "work"
    work.mkdir()
    ctx = StageContext("homogenize", stage.HomogenizeParams(tolerance=1e-10), work, {"cell": cell}, tmp_path)
    summary = stage.run(ctx)
    out = json.loads((work / "constants.json").read_text())
    C_ex = backus_laminate([Isotropic(12.0, 0.3).stiffness(), Isotropic(1.5, 0.45).stiffness()], [0.5, 0.5])
    assert np.abs(np.array(out["C"]) - C_ex).max() < 1e-6 * np.abs(C_ex).max()
    for k in ("E_t", "E_l", "nu_t", "nu_tl", "mu_l", "misfit", "relative_density", "solver", "resolution",
              "localisation", "axis", "symmetry_error"):
        assert k in out
    assert out["misfit"] < 1e-8 and summary["E_t"] == pytest.approx(out["E_t"], rel=1e-5)
    m = meshio.read(work / "fields.vtu")
    assert len(m.cells_dict["hexahedron"]) == ph.size
    strain = m.cell_data_dict["strain_E33"]["hexahedron"]
    # volume average of the local strain is the macro strain E33 (uniform voxels)
    np.testing.assert_allclose(strain.mean(axis=0), [0, 0, 1, 0, 0, 0], atol=1e-8)
    assert _png_is_not_blank(work / "homogenize.png")


def test_stage_refuses_bad_params_and_missing_mesh(tmp_path):
    from pydantic import ValidationError

    from metasheet.errors import ConfigError

    with pytest.raises(ValidationError):
        stage.HomogenizeParams(solver="lu")
    with pytest.raises(ValidationError):
        stage.HomogenizeParams(tolerance=0.5)
    cell = _cell_dir(tmp_path, np.ones((4, 4, 4), int), (1.0, 1.0, 1.0), {"1": {"E": 12.0, "nu": 0.3}})
    (tmp_path / "w").mkdir()
    ctx = StageContext("homogenize", stage.HomogenizeParams(mesh_route=True), tmp_path / "w", {"cell": cell}, tmp_path)
    with pytest.raises(ConfigError, match="cell.vtu"):
        stage.run(ctx)
    with pytest.raises(ConfigError, match="materials"):
        stage.materials_from_json({"1": {"E": 12.0}})


def test_cell_to_homogenize_end_to_end(tmp_path):
    """Runs the colleague's cell stage on the catalogue's quick foam, then this stage."""
    from pathlib import Path

    from metasheet.pipeline.config import load_pipeline
    from metasheet.pipeline.runner import run_pipeline

    root = Path(__file__).resolve().parents[1]
    (tmp_path / "pipelines").mkdir()
    (tmp_path / "cells").symlink_to(root / "cells")
    toml = tmp_path / "pipelines" / "h.toml"
    toml.write_text('[pipeline]\nname = "h"\nstages = ["cell", "homogenize"]\n'
                    '[cell]\ndesign = "cells/quick_foam.toml"\npicture = false\nsurface = false\n')
    run_pipeline(load_pipeline(toml), out_root=tmp_path / "out")
    out = json.loads((tmp_path / "out" / "h" / "homogenize" / "constants.json").read_text())
    rho = out["relative_density"]
    assert 0.1 < rho < 0.3
    # an open-cell foam: far below Voigt, of Gibson-Ashby order
    assert 0.1 * rho**2 < out["E_t"] / 12.0 < rho
    assert out["axis"] == [0.0, 0.0, 1.0]


def test_stage_plate_slabs_of_a_laminate_are_classical_laminate_theory(tmp_path):
    # layers normal to z, nu = 0: each slab is a laminate whose ABD classical laminate theory
    # gives exactly; a slab one period thick has the bulk's membrane stiffness (ratio 1)
    from metasheet.homogenize.plate import laminate_abd

    ph = laminate(6, 0.5, axis=2)  # phase 1 in z voxels 0-2, phase 2 in 3-5 (1/3 mm each)
    mats = {"1": {"E": 12.0, "nu": 0.0}, "2": {"E": 1.5, "nu": 0.0}}
    cell = _cell_dir(tmp_path, ph, (2.0, 2.0, 2.0), mats)
    work = tmp_path / "work"
    work.mkdir()
    params = stage.HomogenizeParams(tolerance=1e-10, plate_thickness=2.0, plate_slabs=3, fields=False, picture=True)
    summary = stage.run(StageContext("homogenize", params, work, {"cell": cell}, tmp_path))
    out = json.loads((work / "plate.json").read_text())
    assert out["thickness_mm"] == pytest.approx(2.0) and out["offsets_mm"] == pytest.approx([0.0, 2 / 3, 4 / 3])
    C1, C2 = Isotropic(12.0, 0.0).stiffness(), Isotropic(1.5, 0.0).stiffness()
    # the slab at 2/3 mm: phase 1 in 2/3..1, phase 2 in 1..2, phase 1 again in 2..2 + 2/3
    exact = laminate_abd([(C1, -1.0, -2 / 3), (C2, -2 / 3, 1 / 3), (C1, 1 / 3, 1.0)])
    got = np.array(out["slabs"][1]["A_N_per_mm"])
    assert np.abs(got - exact[:3, :3]).max() < 1e-9 * np.abs(exact).max()
    D = np.array(out["slabs"][1]["D_N_mm"])
    assert np.abs(D - exact[3:, 3:]).max() < 1e-9 * np.abs(exact[3:, 3:]).max()
    ratios = out["ratio_to_bulk"]
    for name in ("A_11", "A_22", "A_66"):
        assert ratios[name]["mean"] == pytest.approx(1.0, rel=1e-9) and ratios[name]["halfwidth"] < 1e-9
    assert ratios["D_11"]["halfwidth"] > 0.01  # where the stiff layer sits matters in bending
    assert summary["plate_ratio_to_bulk"] == pytest.approx(ratios["geometric_mean"]["mean"], abs=1e-4)
    assert np.array(out["ABD"]["mean"]).shape == (6, 6)
    # the transverse shear of each slab, against the bulk's 5/6 G t (tests/test_homogenize_plate_shear.py)
    shear = out["shear"]
    assert summary["plate_shear_ratio_to_bulk"] == pytest.approx(
        [shear["ratio_to_bulk"][n]["mean"] for n in ("H_xz", "H_yz")], abs=1e-4)
    assert all(np.all(np.linalg.eigvalsh(np.array(sl["shear"]["H_N_per_mm"])) > 0) for sl in out["slabs"])
    from metasheet.report.build import build_report
    assert "transverse shear H_xz" in build_report({"homogenize": summary}, {})
    assert _png_is_not_blank(work / "plate.png")


def test_stage_plate_thickness_below_two_voxels_is_refused(tmp_path):
    from metasheet.errors import ConfigError

    cell = _cell_dir(tmp_path, laminate(6, 0.5, axis=2), (2.0, 2.0, 2.0), {"1": {"E": 1.0, "nu": 0.3},
                                                                        "2": {"E": 2.0, "nu": 0.3}})
    work = tmp_path / "work"
    work.mkdir()
    params = stage.HomogenizeParams(plate_thickness=0.4, fields=False, picture=False)
    with pytest.raises(ConfigError, match="plate_thickness"):
        stage.run(StageContext("homogenize", params, work, {"cell": cell}, tmp_path))
    from pydantic import ValidationError

    with pytest.raises(ValidationError, match="plate_thickness"):
        stage.HomogenizeParams(plate_thickness=5.0, mesh_route=True)


def test_material_source_plate_takes_the_sheets_equivalent_constants(tmp_path):
    from metasheet.homogenize.plate import abd_moduli, equivalent_constants
    from metasheet.pipeline.stages import material as material_stage

    ph = laminate(6, 0.5, axis=2)
    cell = _cell_dir(tmp_path, ph, (2.0, 2.0, 2.0), {"1": {"E": 12.0, "nu": 0.3}, "2": {"E": 1.5, "nu": 0.45}})
    hom = tmp_path / "homogenize"
    hom.mkdir()
    params = stage.HomogenizeParams(tolerance=1e-10, plate_thickness=1.0, plate_slabs=2, fields=False, picture=False)
    stage.run(StageContext("homogenize", params, hom, {"cell": cell}, tmp_path))
    plate = json.loads((hom / "plate.json").read_text())
    bulk = json.loads((hom / "constants.json").read_text())
    for variant in ("membrane", "bending"):
        work = tmp_path / f"material_{variant}"
        work.mkdir()
        mp = material_stage.MaterialParams(source="plate", plate_variant=variant)
        summary = material_stage.run(StageContext("material", mp, work, {"homogenize": hom}, tmp_path))
        from metasheet.mechanics.material import TransverseIsotropic

        expect = equivalent_constants(abd_moduli(plate["ABD"]["mean"], plate["thickness_mm"])[variant],
                                      TransverseIsotropic.from_mapping(bulk))
        assert summary["source"] == f"plate ({variant})"
        for k, v in expect.to_dict().items():
            assert summary[k] == pytest.approx(v, rel=1e-12)
    # without plate.json the error says what to set
    bare = tmp_path / "bare"
    bare.mkdir()
    (bare / "constants.json").write_text((hom / "constants.json").read_text())
    out = tmp_path / "m"
    out.mkdir()
    from metasheet.errors import ConfigError

    with pytest.raises(ConfigError, match="plate_thickness"):
        material_stage.run(StageContext("material", material_stage.MaterialParams(source="plate"), out,
                                        {"homogenize": bare}, tmp_path))


def _ratios(**r):
    names = ("A_11", "A_22", "A_66", "D_11", "D_22", "D_66")
    return {"thickness_mm": 5.0, "ratio_to_bulk": {**{n: {"mean": r.get(n, 1.0)} for n in names},
                                                   "geometric_mean": {"mean": 1.0}}}


def test_auto_choice_keeps_the_bulk_within_ten_percent_and_says_why():
    from metasheet.pipeline.stages.material import auto_choice

    assert auto_choice(None)["source"] == "homogenize" and "plate_thickness" in auto_choice(None)["why"]
    near = auto_choice(_ratios(A_11=1.05, D_66=0.92))
    assert near["source"] == "homogenize" and "D_66 x0.92" in near["why"]
    far = auto_choice(_ratios(A_66=0.22, D_11=1.36))
    assert far["source"] == "plate" and "A_66 x0.22" in far["why"]
    assert auto_choice(_ratios(D_11=1.12))["source"] == "plate"  # stiffer by more than 10 % counts too


def test_material_auto_takes_the_plate_when_the_sheet_is_not_the_bulk(tmp_path):
    from metasheet.homogenize.plate import abd_moduli, equivalent_constants
    from metasheet.mechanics.material import TransverseIsotropic
    from metasheet.pipeline.stages import material as material_stage

    lattice = np.zeros((4, 4, 4), np.uint8)  # square struts along x, y, z: 2 voxels in a 4-voxel cell
    lattice[:2, :2, :] = lattice[:2, :, :2] = lattice[:, :2, :2] = 1
    cell = _cell_dir(tmp_path, lattice, (4.0, 4.0, 4.0), {"1": {"E": 1.0, "nu": 0.3}})
    hom = tmp_path / "homogenize"
    hom.mkdir()
    stage.run(StageContext("homogenize", stage.HomogenizeParams(tolerance=1e-10, plate_thickness=3.0, plate_slabs=2,
                                                                fields=False, picture=False), hom, {"cell": cell},
                           tmp_path))
    plate = json.loads((hom / "plate.json").read_text())
    work = tmp_path / "material"
    work.mkdir()
    summary = material_stage.run(StageContext("material", material_stage.MaterialParams(), work, {"homogenize": hom},
                                              tmp_path))
    written = json.loads((work / "material.json").read_text())
    # 3 mm slabs of a 4 mm lattice cell twist 1.3 times the bulk plate (D_66): beyond 10 %
    assert written["choice"] == material_stage.auto_choice(plate) and written["choice"]["source"] == "plate"
    assert summary["source"] == "plate (membrane)" and summary["why"] == written["choice"]["why"]
    expect = equivalent_constants(abd_moduli(plate["ABD"]["mean"], plate["thickness_mm"])["membrane"],
                                  TransverseIsotropic.from_mapping(json.loads((hom / "constants.json").read_text())))
    assert written["constants"] == pytest.approx(expect.to_dict(), rel=1e-12)
