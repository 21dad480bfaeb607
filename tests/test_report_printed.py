"""The report's section on the printed robot and its picture (metasheet/report/printed.py,
metasheet/viz/printed_robot.py), on a hand-made printed.json: the validity map's sentences
are the map's numbers, a ray that binds is named by its direction, and the picture draws with
and without the walls searched."""

import numpy as np

from metasheet.report.printed import printed_robot_section
from metasheet.studies.printed_limits import combine, plane_directions, validity_map
from metasheet.viz.printed_robot import printed_robot_picture

SPREAD = {"mean": 1.0, "min": 1.0, "max": 1.0, "std": None, "n": 1}


def _study(with_walls: bool) -> dict:
    plane = plane_directions(4)
    names = list(plane) + ["ray 0", "ray 1"]
    contacts, strains = [2.0, None, 3.0, 4.0, 0.4, None], [9.0, 5.0, None, None, 8.0, 1.5]
    unit = {"label": "normal", "seed": 1, "kept_share": 1.0, "strain_per_deg": [[0.01, 0.01]] * 6,
            "directions": {n: {"contact_deg": c, "contact_nodes": [], "strain_deg": s}
                           for n, c, s in zip(names, contacts, strains)}}
    lim = combine(unit, {**unit, "label": "mirrored"})
    rays = [{"name": "ray 0", "direction": [0.0, 1.0, 0.0], "azimuth": 0, "elevation": 0, "mm_per_deg": 0.5},
            {"name": "ray 1", "direction": [1.0, 0.0, 0.0], "azimuth": -1, "elevation": 1, "mm_per_deg": 0.25}]
    path = [[0.0, 0.0], [1.0, -2.0], [2.0, -4.0]]
    roll = {"status": "predicted up to the walls' limit", "rod_rotation_within_limits_deg": {"pull": -1.0, "push": 2.0},
            "pull": {"path": path, "travel_deg": 2.0, "contact_deg": 1.5, "rod_rotation_deg": -4.0,
                     "rod_rotation_at_contact_deg": -3.0},
            "push": {"path": path, "travel_deg": 2.0, "contact_deg": None, "rod_rotation_deg": 4.0}}
    row = {"seed": 1, "limits": lim if with_walls else None, "map": validity_map(lim, plane, rays) if with_walls else None,
           "roll": roll, "rotations": {"status": "not predicted", "rest_singular_values_mm_per_rad": [12.0] * 6}}
    return {"params": {"pull_deg": 15.0, "push_deg": 35.0, "rot_deg": 10.0, "tol_deg": 2.0, "search_deg": 10.0},
            "voxel_mm": 0.25, "gauge": "seed", "realisations": [row],
            "claims": {"roll": roll["status"], "rotations": "not predicted"},
            "spread": {k: SPREAD for k in ("valid_deg", "rod_rotation_pull_deg", "rod_rotation_push_deg",
                                           "smallest_singular_value")}}


def test_the_validity_map_is_stated_from_its_numbers():
    d = _study(True)
    lines, diffs = printed_robot_section(d)
    text = "\n".join(lines)
    # ray 0 binds the box (0.4 deg), named by its direction; along it the rod moves 0.4 * 0.5 mm
    assert d["realisations"][0]["limits"]["binding"] == "ray 0"
    assert '"ray 0" (the rod moved along (+0.00, +1.00, +0.00), orientation held) at 0.4 deg' in text
    assert "(4 directions), the walls first touch after 2 to 4 deg (seed 1) of the largest motor's" in text
    assert "the rod moves 0.2 to 0.2 mm (seed 1, median 0.2) before two walls touch" in text
    # ray 1: no contact, strain at 1.5 deg: the strain binds on one ray of two
    assert "the walls' strain limit binds first on 1 of the 2 rays over the prints, and neither limit within the " \
        "search on 0" in text
    assert any("not predicted" in x for x in diffs)


def test_the_picture_draws_with_and_without_the_walls():
    for with_walls in (True, False):
        png = printed_robot_picture(_study(with_walls))
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000
    assert printed_robot_section(_study(False))[0]  # a section without the map still states the claims
    assert not np.isnan(_study(True)["realisations"][0]["map"]["rays"][0]["contact_mm"])


def test_the_printed_robot_is_the_side_by_side_tables_third_column():
    """Issue 62 item 5: the paper's table gains a printed-robot column, each cell the claim's
    status over the prints then each print's figure; without it the table keeps its two columns."""
    from metasheet.report.columns import columns_section
    from metasheet.report.printed import printed_column

    d = _study(True)
    maze = {"foam_impossible_segments": [3], "segments": 8, "silicone_impossible_segments": None, "tilt_deg": 1.5}
    d["realisations"].append({**d["realisations"][0], "seed": 2,
                              "roll": {**d["realisations"][0]["roll"],
                                       "rod_rotation_within_limits_deg": {"pull": -2.5, "push": None}}})
    d["realisations"].append({**d["realisations"][0], "seed": 3})
    for r, status in zip(d["realisations"], ("predicted", "not predicted", "predicted")):
        r["studies"] = {"maze": {**maze, "verdict": {"text": f"maze of seed {r['seed']}", "status": status}}}
    d["claims"]["maze"] = "not predicted"
    cells = printed_column(d)
    assert set(cells) == {"anisotropy", "maze"}  # the roll is Fig. 7's claim; no workspace or ranges here
    assert cells["anisotropy"] == ("**predicted up to the walls' limit** (seeds 1, 3: -1 deg pulled, 2 deg pushed; "
                                   "seed 2: -2.5 deg pulled, - deg pushed)")  # equal figures said once
    assert cells["maze"] == "**not predicted** (seed 1: maze of seed 1; seed 2: maze of seed 2; seed 3: maze of seed 3)"
    assert printed_column(None) == {}
    columns = {"maze": {"reproduction": {**maze, "foam_impossible_segments": []}}}
    two = columns_section(columns, {})
    three = columns_section(columns, {}, cells, ["From beside.", ""])
    head = [line for line in three if line.startswith("| figure |")][0]
    assert head == "| figure | the paper | reproduction | prediction | printed robot | verdict |"
    row = [line for line in three if line.startswith("| maze |")][0]
    assert row.split(" | ")[4] == cells["maze"] and row.endswith("| reproduced |")
    assert "From beside." in three and "printed robot" not in "\n".join(two)
    assert [line for line in two if line.startswith("| figure |")][0].count("|") == 6
