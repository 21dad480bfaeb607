"""metasheet.fem.mkl: MKL's runtime found once, the library pypardiso's own search loads."""

import ctypes
import glob
import os
import subprocess
import sys

import pytest

from metasheet.fem import mkl


def _pypardisos_choice() -> str | None:
    """pypardiso's search as it is written (pardiso_wrapper.py): the recursive glob, shortest
    path first, the first that loads."""
    for path in sorted(glob.glob(f"{sys.prefix}/[Ll]ib*/**/*mkl_rt*", recursive=True), key=len):
        try:
            ctypes.CDLL(path)
            return path
        except OSError:
            pass
    return None


def test_the_library_found_is_the_one_pypardiso_would_load(monkeypatch):
    monkeypatch.delenv(mkl.ENV, raising=False)
    if mkl.find_library("mkl_rt") or mkl.find_library("mkl_rt.1"):
        pytest.skip("the loader finds mkl_rt here: pypardiso searches nothing")
    assert mkl.mkl_rt_path() == _pypardisos_choice()


def test_a_path_the_user_set_is_kept(monkeypatch):
    monkeypatch.setenv(mkl.ENV, "/somewhere/libmkl_rt.so")
    assert mkl.mkl_rt_path() is None
    mkl.tell_pypardiso()
    assert os.environ[mkl.ENV] == "/somewhere/libmkl_rt.so"


def test_importing_the_solvers_tells_pypardiso_in_a_fresh_process():
    pytest.importorskip("pypardiso")
    env = {k: v for k, v in os.environ.items() if k != mkl.ENV}
    code = "import os, metasheet.fem.solvers as s; print(s.available('pardiso'), os.environ.get('PYPARDISO_MKL_RT'))"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout
    available, path = out.split()
    assert available == "True"
    searched = not (mkl.find_library("mkl_rt") or mkl.find_library("mkl_rt.1"))
    assert path == str(_pypardisos_choice() if searched else None)
