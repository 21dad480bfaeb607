"""The plate continuum against printed sheets (issue 63): exact cases on the paper's sheets."""

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.homogenize.plate import bulk_plate
from metasheet.mechanics.voigt import stiffness_along
from metasheet.published.paper import PAPER_FOAM
from metasheet.robot.builder import SheetPair, six_dof_robot
from metasheet.robot.condensed import rest_numbers_condensed
from metasheet.sheet.geometry import SheetParams
from metasheet.sheet.grips import grip_references
from metasheet.studies.sheet_dns import homogenised_grips
from metasheet.studies.sheet_plate import plate_comparison


@pytest.fixture(scope="module")
def setup():
    params = SheetParams()
    pair = SheetPair.spiral(params, element="p1")
    rows = lambda mesh: np.tile(PAPER_FOAM.as_tuple(), (len(mesh.tets), 1))  # noqa: E731
    pair = replace(pair, constants=rows(pair.sheet), constants_mirrored=rows(pair.mirrored))
    robot = six_dof_robot(pair, PAPER_FOAM, density=1.2e-9)
    Ka, Kb = homogenised_grips(pair, "ours")
    # "prints" half as stiff as the bulk continuum everywhere: their rest kinematics are the bulk's
    prints = [(SimpleNamespace(K=0.5 * Ka), SimpleNamespace(K=0.5 * Kb))]
    roll = rest_numbers_condensed(0.5 * Ka, 0.5 * Kb, robot, grip_references(params))["rod_rotation_deg_per_deg"]
    C_x = stiffness_along(PAPER_FOAM.stiffness(), np.array([[1.0, 0.0, 0.0]]))[0]  # l along the sheet's x
    return params, pair, robot, prints, [roll], C_x


def _plate(ABD, t):
    return {"thickness_mm": t, "ABD": {"mean": np.asarray(ABD).tolist()}}


def test_a_bulk_plate_is_the_bulk_continuum(setup):
    params, pair, robot, prints, roll, C_x = setup
    out = plate_comparison(pair, "ours", PAPER_FOAM, _plate(bulk_plate(C_x, params.thickness), params.thickness),
                           prints, roll, robot, params, length_scale=50.0)
    for variant in ("membrane", "bending"):
        got = np.array(list(out[variant]["constants"].values()))
        assert np.allclose(got, PAPER_FOAM.as_tuple(), rtol=1e-9)
        row = out[variant]["realisations"][0]
        assert row["geometric_mean_ratio_normal"] == pytest.approx(0.5, rel=1e-6)
        assert row["geometric_mean_ratio_mirrored"] == pytest.approx(0.5, rel=1e-6)
        assert row["rod_roll_ratio"] == pytest.approx(1.0, rel=1e-6)


def test_a_plate_as_soft_as_the_prints_closes_the_gap(setup):
    params, pair, robot, prints, roll, C_x = setup
    out = plate_comparison(pair, "ours", PAPER_FOAM, _plate(0.5 * bulk_plate(C_x, params.thickness),
                                                             params.thickness),
                           prints, roll, robot, params, length_scale=50.0)
    row = out["membrane"]["realisations"][0]
    assert row["geometric_mean_ratio_normal"] == pytest.approx(1.0, rel=1e-6)
    assert row["log_ratio_rms_mirrored"] < 1e-6
    assert out["membrane"]["constants"]["E_l"] == pytest.approx(0.5 * PAPER_FOAM.E_l, rel=1e-9)
    assert out["membrane"]["spread"]["rod_roll_ratio"]["mean"] == pytest.approx(1.0, rel=1e-6)


def test_a_plate_of_another_thickness_is_refused(setup):
    params, pair, robot, prints, roll, C_x = setup
    with pytest.raises(ConfigError, match="plate_thickness"):
        plate_comparison(pair, "ours", PAPER_FOAM, _plate(bulk_plate(C_x, 2.0), 2.0 * params.thickness),
                         prints, roll, robot, params, length_scale=50.0)
