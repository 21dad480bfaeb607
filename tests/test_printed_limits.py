"""The printed robot's walls' limits put together (metasheet/studies/printed_limits.py) and the
printed stage's input check, on hand-made unit results."""

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.pipeline.stages.printed import grip_stiffnesses
from metasheet.studies.printed_limits import (
    BASE_DIRECTIONS,
    WallUnit,
    combine,
    directions,
    plane_directions,
    ray_directions,
    validity_map,
)


def _unit(label, contacts, strains, rates):
    return {"label": label, "seed": 1, "kept_share": 1.0, "strain_per_deg": rates,
            "directions": {n: {"contact_deg": c, "contact_nodes": [], "strain_deg": s}
                           for n, c, s in zip(BASE_DIRECTIONS, contacts, strains)}}


def test_the_robots_limit_is_the_first_contact_of_either_sheet_along_any_direction():
    a = _unit("normal", [None, 2.0, 6.0, None, None, 3.0], [30.0] * 6, [[0.01, 0.02]] * 6)
    b = _unit("mirrored", [None, 0.8, None, 5.0, None, None], [20.0, 25.0, 31.0, 40.0, 50.0, 60.0],
              [[0.03, 0.0]] * 3 + [[0.0, 0.04]] * 3)
    c = combine(a, b)
    assert c["valid_deg"] == 0.8 and c["binding"] == "roll down"
    assert c["directions"]["roll down"] == {"contact_deg": 0.8, "contact_sheet": "mirrored", "strain_deg": 25.0,
                                            "strain_sheet": "mirrored"}
    assert c["directions"]["roll up"]["contact_deg"] is None and c["directions"]["roll up"]["contact_sheet"] is None
    assert c["directions"]["A up"]["contact_sheet"] == "normal"
    np.testing.assert_array_equal(c["strain_per_deg"], [[0.03, 0.02]] * 3 + [[0.01, 0.04]] * 3)
    none = combine(_unit("normal", [None] * 6, [None] * 6, [[0, 0]] * 6), _unit("mirrored", [None] * 6, [None] * 6,
                                                                                [[0, 0]] * 6))
    assert none["valid_deg"] is None and none["binding"] is None


def test_the_searched_directions():
    base = directions()
    assert list(base) == list(BASE_DIRECTIONS) and all(max(map(abs, d)) == 1.0 for d in base.values())
    every = directions(motors=True)
    assert len(every) == 18 and every["motor 4 down"] == (0.0, 0.0, 0.0, 0.0, -1.0, 0.0)


def test_the_plane_of_the_common_modes_holds_the_base_directions():
    plane = plane_directions(16)
    assert len(plane) == 16 and set(BASE_DIRECTIONS) <= set(plane)
    for name, d in BASE_DIRECTIONS.items():
        assert plane[name] == d
    for name, d in plane.items():
        assert max(map(abs, d)) == 1.0 and d[0] == d[1] == d[2] and d[3] == d[4] == d[5]
    phi = np.radians(22.5)  # between "A up" and "roll up": sheet B's three at tan(22.5 deg) of sheet A's
    np.testing.assert_allclose(plane["plane 22.5"], [1.0] * 3 + [np.tan(phi)] * 3, rtol=1e-12)
    assert list(plane_directions(4)) == ["A up", "B up", "A down", "B down"] and plane_directions(0) == {}


def test_a_rays_motor_direction_moves_the_rod_along_the_ray_with_its_orientation_held():
    rng = np.random.default_rng(3)
    J = rng.normal(size=(6, 6))
    J[:3] *= 20.0  # mm per rad beside rad per rad
    rays = rng.normal(size=(5, 3))
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    dirs, per = ray_directions(J, rays)
    assert list(dirs) == [f"ray {r}" for r in range(5)]
    for (name, d), e, k in zip(dirs.items(), rays, per):
        assert max(map(abs, d)) == pytest.approx(1.0, abs=0)
        moved = J @ (np.radians(1.0) * np.asarray(d))  # one degree of the largest motor
        np.testing.assert_allclose(moved[:3], k * e, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(moved[3:], 0.0, atol=1e-12)
        assert k > 0
    with pytest.raises(ConfigError, match="J: shape"):
        ray_directions(J[:5], rays)


def test_the_validity_map_says_which_limit_binds_along_each_direction():
    plane = plane_directions(4)
    names = list(plane) + ["ray 0", "ray 1", "ray 2"]
    unit = {"label": "normal", "seed": 1, "kept_share": 1.0, "strain_per_deg": [[0.0, 0.0]] * 6,
            "directions": {n: {"contact_deg": c, "contact_nodes": [], "strain_deg": s}
                           for n, c, s in zip(names, [1.0, None, 2.0, None, 0.5, 3.0, None],
                                              [9.0, 4.0, 1.0, None, 8.0, 2.0, None])}}
    lim = combine(unit, {**unit, "label": "mirrored"})
    rays = [{"name": f"ray {r}", "direction": [1.0, 0.0, 0.0], "azimuth": r, "elevation": 0, "mm_per_deg": 0.2}
            for r in range(3)]
    m = validity_map(lim, plane, rays)
    assert [x["phi_deg"] for x in m["plane"]] == [0.0, 90.0, 180.0, 270.0]
    assert [x["binds"] for x in m["plane"]] == ["contact", "strain", "strain", None]
    assert [x["contact_mm"] for x in m["rays"]] == [pytest.approx(0.1), pytest.approx(0.6), None]
    assert [x["strain_mm"] for x in m["rays"]] == [pytest.approx(1.6), pytest.approx(0.4), None]
    assert [x["binds"] for x in m["rays"]] == ["contact", "strain", None]
    assert lim["valid_deg"] == 0.5 and lim["binding"] == "ray 0"


def test_bad_units_and_old_sheet_files_are_named():
    with pytest.raises(ConfigError, match="search_deg"):
        WallUnit(None, tuple([(0.0,) * 6] * 24), (), 0.0, 0.3)
    with pytest.raises(ConfigError, match="G: shape"):
        WallUnit(None, tuple([(0.0,) * 6] * 23), (), 10.0, 0.3)
    row = {"seed": 3, "sheets": {"normal": {"K": np.eye(24).tolist()}, "mirrored": {}}}
    with pytest.raises(ConfigError, match="seed 3: no .24, 24. grip stiffness K"):
        grip_stiffnesses([row])
    row["sheets"]["mirrored"]["K"] = np.eye(24).tolist()
    (Ka, Kb), = grip_stiffnesses([row])
    assert Ka.shape == Kb.shape == (24, 24)
