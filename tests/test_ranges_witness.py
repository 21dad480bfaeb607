"""Fig. 6's reachable sets: a narrower range's path counts in a wider range that holds rest
(metasheet.studies.ranges.adopt_narrower), and the verdict and report read the counts."""

import numpy as np

from metasheet.studies.ranges import adopt_narrower

RANGES = [(0.0, 90.0), (10.0, 80.0), (20.0, 70.0)]


def test_wider_range_holding_rest_adopts_the_narrower_paths():
    found = np.array([[1, 0, 0, 0, 1],    # 0-90 missed points 1, 2 and 3
                      [1, 1, 0, 0, 0],    # 10-80 reached 1
                      [0, 0, 1, 1, 0]], bool)  # 20-70 reached 2 and 3, and not 1
    via = adopt_narrower(found, RANGES, np.full(6, 45.0))
    assert via.tolist() == [[0, 1, 2, 2, 0],
                            [1, 1, 2, 2, -1],
                            [-1, -1, 2, 2, -1]]
    reached = via >= 0
    assert np.all(found <= reached)  # a range keeps what its own search found
    assert np.all(reached[2] <= reached[1]) and np.all(reached[1] <= reached[0])  # nested


def test_no_witness_for_a_range_that_excludes_rest():
    # rest at 73.3 deg (the authors' preset): 0-90 and 10-80 hold it, 20-70 does not
    found = np.array([[0, 0], [0, 0], [1, 0]], bool)
    via = adopt_narrower(found, [(0.0, 90.0), (10.0, 80.0), (20.0, 70.0)], np.full(6, 73.3))
    assert via[:, 0].tolist() == [2, 2, 2]
    # a wider range that excludes rest (35-90 against rest 30): the narrower path starts where
    # it cannot, so nothing is adopted
    found = np.array([[0], [1]], bool)
    via = adopt_narrower(found, [(35.0, 90.0), (40.0, 80.0)], np.full(6, 30.0))
    assert via[:, 0].tolist() == [-1, 1]
    # one motor outside the range is enough to exclude rest
    via = adopt_narrower(found, [(0.0, 90.0), (10.0, 80.0)], np.array([45.0] * 5 + [85.0]))
    assert via[:, 0].tolist() == [1, 1]  # 0-90 holds all six rest angles
    via = adopt_narrower(np.array([[0], [0], [1]], bool), [(0.0, 84.0), (10.0, 80.0), (20.0, 70.0)],
                         np.array([45.0] * 5 + [85.0]))
    assert via[:, 0].tolist() == [-1, -1, 2]


def test_ranges_verdict_needs_nested_and_strictly_smaller():
    from metasheet.report.columns import _ranges

    deg = [[0, 90], [10, 80], [20, 70]]
    ok = {"reachable": {"0-90": 317, "10-80": 119, "20-70": 74}, "nested": True, "ranges_deg": deg,
          "via_narrower": {"0-90": 4, "10-80": 14, "20-70": 0}}
    text, holds = _ranges(ok)
    assert holds and "0-90: 317 (4 by a narrower range's path)" in text and "20-70: 74;" in text
    same = dict(ok, reachable={"0-90": 63, "10-80": 63, "20-70": 13})  # the strain limit binds before the motors
    assert not _ranges(same)[1]
    assert not _ranges(dict(ok, nested=False))[1]
    # listed narrowest first: containment, not the order, decides which must be larger
    rev = {"reachable": {"20-70": 74, "10-80": 119, "0-90": 317}, "nested": True, "ranges_deg": deg[::-1]}
    assert _ranges(rev)[1]


def test_report_says_which_points_came_from_a_narrower_path():
    from metasheet.report.build import build_report

    ranges = {"reachable": {"0-90": 317, "10-80": 119, "20-70": 74}, "nested": True, "violations": [],
              "via_narrower": {"0-90": 4, "10-80": 14, "20-70": 0}, "model": "robot"}
    text = build_report({"ranges": ranges}, {"ranges": "ranges.png"})
    assert "| of which by a narrower range's path, 10-80 deg | 14 |" in text
    assert "of which by a narrower range's path, 20-70" not in text
    diffs = text.split("## Differences from the paper")[1]
    assert "0-90 deg: 4, 10-80 deg: 14" in diffs and "do not nest" not in diffs


def test_report_says_when_the_stroke_does_not_bound_the_workspace():
    from metasheet.report.build import build_report

    base = {"ranges_deg": [[0, 90], [10, 80], [20, 70]], "nested": True, "violations": [], "model": "robot",
            "strain_limit": 0.3, "stop_beyond_strain": True}
    same = dict(base, reachable={"0-90": 63, "10-80": 63, "20-70": 13},
                motor_span_deg={"0-90": [67.1, 79.4], "10-80": [67.1, 79.4], "20-70": [52.0, 70.0]})
    text = build_report({"ranges": same}, {})
    assert "| motors of the reached goals, 0-90 deg | 67.1 to 79.4 |" in text
    diffs = text.split("## Differences from the paper")[1]
    assert ("the 0-90 and 10-80 deg ranges reach the same 63 goals (motors 67.1 to 79.4 deg): within the strain "
            "limit 0.3, the narrower stroke costs no goal") in diffs
    # a motor beyond the narrower range, or a different count: nothing to say
    wider = dict(same, motor_span_deg={**same["motor_span_deg"], "0-90": [67.1, 84.0]})
    fewer = dict(same, reachable={"0-90": 70, "10-80": 63, "20-70": 13})
    for r in (wider, fewer):
        assert "reach the same" not in build_report({"ranges": r}, {})
