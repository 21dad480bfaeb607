"""metasheet.runtime.cpu: one code path on every x86-64 CPU, decided once and inherited by workers."""

from metasheet.runtime import cpu

AVX2 = "processor\t: 0\nflags\t\t: fpu sse2 avx fma avx2 bmi2\n"
OLD = "processor\t: 0\nflags\t\t: fpu sse2 sse4_2 avx\n"


def test_a_fresh_process_on_an_avx2_cpu_pins_every_library():
    env = {}
    assert cpu.pin_code_paths(env, numpy_loaded=False, cpuinfo=AVX2) == "pinned"
    assert env[cpu.DECISION] == "pinned"
    assert env["OPENBLAS_CORETYPE"] == "Haswell" and env["MKL_CBWR"] == "AVX2"
    assert "AVX512_ICL" in env["NPY_DISABLE_CPU_FEATURES"]


def test_a_value_the_user_or_platform_set_is_kept():
    env = {"OPENBLAS_CORETYPE": "Zen"}
    cpu.pin_code_paths(env, numpy_loaded=False, cpuinfo=AVX2)
    assert env["OPENBLAS_CORETYPE"] == "Zen"


def test_numpy_loaded_first_or_an_old_cpu_keeps_the_native_paths():
    for loaded, info in ((True, AVX2), (False, OLD), (False, "")):
        env = {}
        assert cpu.pin_code_paths(env, numpy_loaded=loaded, cpuinfo=info) == "native"
        assert env == {cpu.DECISION: "native"}


def test_a_worker_follows_its_parents_decision_whatever_it_finds():
    """A pool worker imports metasheet before numpy: were it to decide afresh it would pin
    while a parent that loaded numpy first computes natively, and the pool's bytes would
    differ from the serial run's."""
    env = {cpu.DECISION: "native"}
    assert cpu.pin_code_paths(env, numpy_loaded=False, cpuinfo=AVX2) == "native"
    assert "OPENBLAS_CORETYPE" not in env
    env = {cpu.DECISION: "pinned"}
    assert cpu.pin_code_paths(env, numpy_loaded=True, cpuinfo=OLD) == "pinned"
    assert env["OPENBLAS_CORETYPE"] == "Haswell"


def test_code_paths_reports_what_this_process_uses():
    info = cpu.code_paths()
    assert info["decision"] in ("pinned", "native")
    assert info["numpy_dispatch"] and all(isinstance(t, str) for t in info["numpy_dispatch"])
    assert info["blas"] and all("openblas" in b or "mkl" in b for b in info["blas"])


def test_the_test_processes_compute_on_the_pinned_path_whichever_file_is_collected_first():
    """conftest imports metasheet before any test module loads numpy: a test file that imported
    numpy first had put its whole process on this CPU's own kernels, and a reduced-model test's
    outcome then depended on the file pytest collected first (a bound met within an ulp)."""
    import pytest

    if not cpu.has_avx2_fma():
        pytest.skip("no AVX2 / FMA: nothing is pinned on this CPU")
    paths = cpu.code_paths()
    assert paths["decision"] == "pinned"
    assert not any("512" in t or t == "X86_V4" for t in paths["numpy_dispatch"])
