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


def test_a_truncated_index_or_data_file_is_removed_and_reads_as_absent(tmp_path, caplog):
    """numba's own cache file object, guarded: what it writes loads back; truncated, it is
    logged, removed and read as no entry (numba then compiles)."""
    import numba.core.caching as caching

    import metasheet  # noqa: F401  (the guard)

    f = caching.IndexDataCacheFile(str(tmp_path), "k.f-1.py311", source_stamp=("stamp", 1))
    f.save("key", ("some", "kernel"))
    assert f.load("key") == ("some", "kernel")
    data = sorted(tmp_path.glob("*.nbc"))[0]
    data.write_bytes(data.read_bytes()[:5])
    assert f.load("key") is None and not data.exists()
    f.save("key", ("some", "kernel"))
    index = tmp_path / "k.f-1.py311.nbi"
    index.write_bytes(index.read_bytes()[:-7])
    assert f.load("key") is None and not index.exists()
    assert sum("is damaged" in r.getMessage() for r in caplog.records) == 2


@pytest.mark.slow
@pytest.mark.parametrize("damaged", ["nbi", "nbc"])
def test_a_truncated_cache_file_is_compiled_again(tmp_path, damaged):
    """Default sibling: :func:`test_a_truncated_index_or_data_file_is_removed_and_reads_as_absent`
    (the same guard, in process)."""
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
