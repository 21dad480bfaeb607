"""The printed robot's walls' limits put together (metasheet/studies/printed_limits.py) and the
printed stage's input check, on hand-made unit results."""

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.pipeline.stages.printed import grip_stiffnesses
from metasheet.studies.printed_limits import BASE_DIRECTIONS, WallUnit, combine, directions


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
