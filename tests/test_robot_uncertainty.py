"""The robot at the constants' 95 % bounds (issue 43): bounds, scaled sheets, the stage's spread.

Independent checks: the mean case of the spread equals the stage's own foam case (computed by
another path, robot.compare.evaluate); zero half-widths give ten cases identical to the mean
bit for bit; scaling a constant by f changes that column only; the spread's range is that of
its cases.
"""

import json

import numpy as np
import pytest
from test_robot_stage import _write_orient, orient_dir  # noqa: F401  (the coarse sheets, built once)

from metasheet.errors import ConfigError
from metasheet.mechanics.material import CONSTANT_NAMES
from metasheet.published.paper import FOAM_DENSITY, PAPER_FOAM
from metasheet.pipeline.artefacts import read_material, read_orient, write_material
from metasheet.pipeline.registry import StageContext
from metasheet.pipeline.stages import robot as robot_stage
from metasheet.robot.uncertainty import MODULUS_FLOOR, bounds, scaled_sheets

MEANS = PAPER_FOAM.to_dict()


def test_bounds_are_mean_plus_minus_h_and_clip_named():
    h = {"E_t": 0.1, "E_l": 0.2, "nu_t": 0.05, "nu_tl": 0.1, "mu_l": 0.001}
    bs = bounds(MEANS, h)
    assert [b.name for b in bs] == [f"{k}{s}" for k in CONSTANT_NAMES for s in "-+"]
    for b in bs:
        sign = -1 if b.name.endswith("-") else 1
        want = MEANS[b.constant] + sign * h[b.constant]
        if b.constant == "E_l" and sign < 0:  # 0.094 - 0.2 < 0: clipped to the floor
            assert b.clipped and b.value == pytest.approx(MODULUS_FLOOR * MEANS["E_l"])
        else:
            assert not b.clipped and b.value == pytest.approx(want, rel=1e-15)
        assert b.factor * MEANS[b.constant] == pytest.approx(b.value, rel=1e-14)
    with pytest.raises(ConfigError, match="ci95.halfwidth.E_t"):
        bounds(MEANS, {**h, "E_t": float("nan")})


def test_scaled_sheets_change_one_column(tmp_path):
    _write_orient(tmp_path)
    pair = read_orient(tmp_path).sheets()
    out = scaled_sheets(pair, "mu_l", 1.5)
    j = CONSTANT_NAMES.index("mu_l")
    for a, b in ((pair.constants, out.constants), (pair.constants_mirrored, out.constants_mirrored)):
        assert np.array_equal(np.delete(a, j, axis=1), np.delete(b, j, axis=1))
        assert np.allclose(b[:, j], 1.5 * a[:, j], rtol=1e-15, atol=0)


def _run(orient, tmp_path, halfwidth, executor=None):
    mat = tmp_path / "material"
    mat.mkdir(exist_ok=True)
    ci = {"confidence": 0.95, "k": 3, "n_cells": 8, "halfwidth": halfwidth,
          "rel_halfwidth": {k: halfwidth[k] / abs(MEANS[k]) for k in CONSTANT_NAMES}}
    write_material(mat / "material.json", PAPER_FOAM, density=FOAM_DENSITY, source="homogenize", ci95=ci)
    assert read_material(mat).ci95 == ci
    work = tmp_path / ("work" if executor is None else "work_pool")
    work.mkdir()
    params = robot_stage.RobotParams(picture=False, compare_models=False, compare_published=False)
    ctx = StageContext("robot", params, work, {"orient": orient, "material": mat}, tmp_path,
                       **({"executor": executor} if executor else {}))
    summary = robot_stage.run(ctx)
    return summary, json.loads((work / "jacobian.json").read_text())


H20 = {k: 0.2 * abs(v) for k, v in MEANS.items()}  # half-widths of 20 % of each constant


@pytest.fixture(scope="module")
def serial_run(orient_dir, tmp_path_factory):
    """The stage run serially at the 20 % half-widths: (its folder, summary, jacobian.json)."""
    tmp = tmp_path_factory.mktemp("bounds")
    return (tmp, *_run(orient_dir, tmp, H20))


def test_stage_spread_at_the_bounds(serial_run):
    h = H20
    _, summary, data = serial_run
    u = data["uncertainty"]
    foam = data["materials"]["foam"]
    assert u["cases"]["mean"]["rod_rotation_deg_per_deg"] == pytest.approx(foam["rod_rotation_deg_per_deg"], rel=1e-9)
    assert np.allclose(u["cases"]["mean"]["singular_values"], foam["singular_values"], rtol=1e-9, atol=0)
    assert len(u["cases"]) + len(u["skipped"]) == 11
    roll = [c["rod_rotation_deg_per_deg"] for c in u["cases"].values()]
    assert u["rod_rotation_range"] == [min(roll), max(roll)] and max(roll) > min(roll)
    assert summary["foam_rod_rotation_range_95"] == [round(v, 5) for v in u["rod_rotation_range"]]
    assert u["constants_ci95"]["halfwidth"] == h


def test_a_pool_of_two_writes_the_serial_bytes(orient_dir, serial_run):
    """Every robot of the stage (the cases and the bounds) is a unit of the executor: on two
    workers jacobian.json and rest.vtu are the serial run's bytes."""
    from metasheet.runtime.executor import Executor

    tmp, _, _ = serial_run
    _run(orient_dir, tmp, H20, executor=Executor(workers=2))
    for name in ("jacobian.json", "rest.vtu"):
        assert (tmp / "work_pool" / name).read_bytes() == (tmp / "work" / name).read_bytes(), name


def test_zero_halfwidths_give_the_mean_ten_times(orient_dir, tmp_path):
    _, data = _run(orient_dir, tmp_path, {k: 0.0 for k in CONSTANT_NAMES})
    u = data["uncertainty"]
    mean = u["cases"]["mean"]
    assert not u["skipped"]
    for name, c in u["cases"].items():
        assert c["singular_values"] == mean["singular_values"], name
        assert c["rod_rotation_deg_per_deg"] == mean["rod_rotation_deg_per_deg"], name
