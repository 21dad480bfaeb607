"""A damaged numba cache file is removed and compiled again, with a warning. Before: truncated
``.nbi`` / ``.nbc`` files under ``metasheet/robot/__pycache__`` made ``robot goto`` print a raw
``UnpicklingError`` traceback on every call, and nothing repaired them."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# a small cached kernel of the voxel solver, called on a known input
SCRIPT = """
import metasheet, numpy as np
from metasheet.fem.voxel.vectors import subtract
r = np.ones((4, 3, 2)); subtract(r, np.full((4, 3, 2), 0.25))
print("sum", r.sum())
"""


def call(cache: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), NUMBA_NUM_THREADS="1",
               PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    return subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, timeout=300)


@pytest.mark.parametrize("damaged", ["nbi", "nbc"])
def test_a_truncated_cache_file_is_compiled_again(tmp_path, damaged):
    first = call(tmp_path)
    assert first.returncode == 0, first.stderr
    files = sorted(tmp_path.rglob(f"vectors.subtract-*.{damaged}"))
    assert files, f"no .{damaged} written under {tmp_path}"
    for f in files:
        f.write_bytes(f.read_bytes()[: f.stat().st_size // 3])
    second = call(tmp_path)
    assert second.returncode == 0, second.stderr
    assert "Traceback" not in second.stderr
    assert "sum 18.0" in second.stdout
    assert "is damaged" in second.stderr and "compiled again" in second.stderr
    third = call(tmp_path)  # repaired: loads quietly
    assert third.returncode == 0 and "damaged" not in third.stderr, third.stderr
    assert "sum 18.0" in third.stdout


def test_the_guard_is_in_place_once_numba_caches():
    import numba.core.caching as caching

    import metasheet  # noqa: F401

    assert caching.IndexDataCacheFile._metasheet_guarded
