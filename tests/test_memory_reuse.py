"""metasheet.runtime.memory: a run's processes reuse freed memory instead of faulting fresh pages."""

import os
import subprocess
import sys
import textwrap

import pytest

from metasheet.runtime import memory

GLIBC = bool(getattr(os, "confstr", None) and os.confstr("CS_GNU_LIBC_VERSION"))

# factorise a 3D Laplacian (18^3 unknowns) with SuperLU 6 times: print the minor page faults
# they took (SuperLU grows its L and U storage by reallocation, as on the robot's tangents)
_CHURN = textwrap.dedent("""
    import resource, sys
    {setup}
    import scipy.sparse as sp
    from scipy.sparse.linalg import splu
    n = 18
    I, T = sp.identity(n), sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n))
    A = (sp.kron(sp.kron(T, I), I) + sp.kron(sp.kron(I, T), I) + sp.kron(sp.kron(I, I), T)).tocsc()
    splu(A)  # the first one's pages out of the count
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(6):
        lu = splu(A)
        del lu
    print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
""")


def _faults(setup: str, env: dict) -> int:
    out = subprocess.run([sys.executable, "-c", _CHURN.format(setup=setup)], env=env, capture_output=True,
                         text=True, check=True)
    return int(out.stdout.split()[-1])


def _clean_env() -> dict:
    return {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_")}


def test_the_environment_names_the_three_settings():
    env = memory.environment()
    assert env == {"MALLOC_MMAP_MAX_": "0", "MALLOC_TRIM_THRESHOLD_": str(memory.TRIM_BYTES),
                   "MALLOC_TOP_PAD_": str(memory.TOP_PAD_BYTES)}


def test_a_users_own_malloc_setting_is_left_as_it_is():
    env = {"MALLOC_TRIM_THRESHOLD_": "0"}
    assert memory.keep_freed_memory(env) is False
    assert env == {"MALLOC_TRIM_THRESHOLD_": "0"}


@pytest.mark.skipif(not GLIBC, reason="glibc's malloc only")
def test_freed_blocks_are_reused_in_this_process_and_in_the_processes_it_starts():
    """Independent count: the kernel's minor page faults. Without the settings each factorisation
    maps its storage afresh (tens of thousands of pages); with them, mallopt in the process or
    the environment given to a new one, the first one's pages serve the six after it."""
    plain = _faults("", _clean_env())
    assert plain > 10_000
    in_process = _faults("from metasheet.runtime.memory import keep_freed_memory as k; env = {}; "
                         "assert k(env) and env", _clean_env())
    started = _faults("", {**_clean_env(), **memory.environment()})
    assert in_process < plain / 5 and started < plain / 5
