"""tests/conftest.py's xdist groups reach the scheduler: under ``--dist loadgroup`` every test's
id carries its group (the file, or "bytes" for the files holding a byte-comparing test), as
pytest-xdist's scheduler reads it. Under pytest 9.2 with xdist 3.8 they did not (the suffix
was written where pytest no longer reads it), and a file's tests spread over the workers."""

import os

import pytest


def test_this_tests_id_names_its_file_as_its_group(request):
    if not os.environ.get("PYTEST_XDIST_WORKER") or not request.config.getvalue("loadgroup"):
        pytest.skip("not under xdist's loadgroup scheduler")
    path = request.node.nodeid.split("::")[0]
    assert request.node.nodeid.endswith(f"@{path}")
    assert [m.args[0] for m in request.node.iter_markers("xdist_group")] == [path]
