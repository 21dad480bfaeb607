"""Progress of long stages as plain lines when the output is a log, not a terminal."""

import io

from rich.console import Console

from metasheet.cli import _log_progress_factory


def test_log_progress_prints_start_tenths_end_and_a_line_every_interval():
    buf, now = io.StringIO(), [0.0]
    update = _log_progress_factory(Console(file=buf, width=200), every_s=30.0, clock=lambda: now[0])("workspace")
    for done in range(0, 101):  # 1 s per unit: tenths every 10 s, so the 30 s rule never fires
        now[0] = float(done)
        update("rays", done, 100)
    lines = buf.getvalue().splitlines()
    assert lines[0] == "workspace: rays 0/100"  # no "(0 s, ~0 s left)" before a second has passed
    assert lines[-1] == "workspace: rays 100/100 (100 s)"
    assert len(lines) == 11  # 0, 10, 20, ..., 100
    assert lines[5] == "workspace: rays 50/100 (50 s, ~50 s left)"
    # a slow task: no tenth passed, a line after every_s
    buf.truncate(0), buf.seek(0)
    update2 = _log_progress_factory(Console(file=buf, width=200), every_s=30.0, clock=lambda: now[0])("ranges")
    for t, done in ((0.0, 0), (10.0, 1), (31.0, 2), (40.0, 3), (62.0, 4)):
        now[0] = t
        update2("rays", done, 1000)
    assert [x.split(" (")[0] for x in buf.getvalue().splitlines()] == [
        "ranges: rays 0/1000", "ranges: rays 2/1000", "ranges: rays 4/1000"]


def test_a_stage_that_names_itself_is_named_once_and_short_tasks_carry_no_times():
    """Issue 61: "cell: cell: voxels 3/3 (0 s, ~0 s left)" on every step."""
    buf, now = io.StringIO(), [0.0]
    update = _log_progress_factory(Console(file=buf, width=200), clock=lambda: now[0])("cell")
    for done in range(4):
        now[0] = 0.1 * done
        update("cell: voxels", done, 3)
    now[0] = 2.0
    update("surface", 1, 2)
    now[0] = 8.0
    update("surface", 3, 4)
    assert buf.getvalue().splitlines() == ["cell: voxels 0/3", "cell: voxels 1/3", "cell: voxels 2/3",
                                           "cell: voxels 3/3", "cell: surface 1/2", "cell: surface 3/4 (6 s, ~2 s left)"]
