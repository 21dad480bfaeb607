"""A printed sheet solved in a process of its own (metasheet/robot/sheet_process.py): its errors
come back as the parent's, and it does not outlive its parent, even one killed by SIGKILL."""

import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.fem.voxel.hyperelastic import NeoHookean
from metasheet.robot.sheet_process import SheetProcess
from metasheet.robot.voxel_robot import VoxelSheet


def _block(n: int = 4, m: int = 2) -> VoxelSheet:
    """An n x m x m mm block of 1 mm voxels held at both ends: grip 1 at x = 0, grip 2 at x = n."""
    phases = np.ones((n, m, m), np.int64)
    bodies = np.zeros((n + 1, m + 1, m + 1), np.int64)
    bodies[0], bodies[-1] = 1, 2
    refs = np.array([[0.0, m / 2, m / 2], [float(n), m / 2, m / 2]])
    return VoxelSheet(phases, np.array([n, m, m], float), np.zeros(3), bodies, refs, NeoHookean(12.0, 0.3))


def test_a_sheet_process_answers_as_this_process_and_sends_its_errors_back():
    from metasheet.sheet.voxel_grips_nonlinear import GripBody

    sheet = _block()
    here = GripBody(sheet.phases, sheet.size, sheet.law, bodies=sheet.bodies, references=sheet.references)
    rot = np.array([[0.0, 0.0, 0.0], [0.05, 0.0, 0.0]])
    trans = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]])
    p = SheetProcess(sheet)
    try:
        there = p.wrenches(rot, trans, rtol=1e-10)
        np.testing.assert_array_equal(there.wrenches, here.wrenches(rot, trans, rtol=1e-10).wrenches)
        with pytest.raises(ConfigError, match="rotations: shape"):
            p.wrenches(rot[:1], trans)
        with pytest.raises(ConfigError, match="no solve was submitted"):
            p.result()
        assert p.floor(np.ones((3, 3))) == pytest.approx(here.floor(np.ones((3, 3))), rel=1e-15)
    finally:
        p.close()
    assert not p._proc.is_alive()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux's")
def test_a_sheet_process_dies_with_a_parent_killed_by_sigkill(tmp_path):
    script = textwrap.dedent(f"""
        import sys, time
        sys.path.insert(0, {os.path.dirname(__file__)!r})
        from test_sheet_process import _block
        from metasheet.robot.sheet_process import SheetProcess
        import numpy as np
        p = SheetProcess(_block(40, 12))
        p.submit(np.array([[0.0, 0, 0], [1.5, 0, 0]]), np.zeros((2, 3)), rtol=1e-10)  # busy for seconds
        print(p._proc.pid, flush=True)
        time.sleep(600)
    """)
    parent = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    child = int(parent.stdout.readline())
    os.kill(parent.pid, signal.SIGKILL)
    parent.wait()
    deadline = time.monotonic() + 1.5  # killed mid-solve, not once the solve ends and the pipe is found closed
    while time.monotonic() < deadline:
        try:
            with open(f"/proc/{child}/stat") as f:
                if f.read().split(")")[-1].split()[0] == "Z":  # a zombie: gone, waiting for its reaper
                    return
        except FileNotFoundError:
            return
        time.sleep(0.05)
    os.kill(child, signal.SIGKILL)
    pytest.fail("the sheet's process outlived its SIGKILLed parent")
