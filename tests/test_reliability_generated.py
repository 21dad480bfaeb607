"""Generated pipeline files and cell designs, valid and invalid (hypothesis): ``metasheet
validate`` and a coarse ``metasheet run`` either succeed or exit 2 with an ``error:`` line,
never with a traceback, and never touch a file outside ``<out>/<name>`` (issue 60).

The values are drawn from what a user types: numbers of every size and sign, nan and inf,
strings (some of them numbers), booleans, arrays, tables, missing and unknown keys, and design
files of random bytes. The run is the material stage (milliseconds); validate covers every
stage's table. ``METASHEET_GENERATED_CASES`` sets the number of cases (default 30: what CI runs;
the slow sibling runs ten times as many).
"""

import contextlib
import io
import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from metasheet.cli import main

CASES = int(os.environ.get("METASHEET_GENERATED_CASES", "30"))
POLYFOAM = (Path(__file__).resolve().parents[1] / "cells" / "paper_polyfoam.toml").read_text()

SCALARS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**30, 10**30), st.booleans(),
    st.sampled_from(["8", "2", "p1", "p2", "", "nan", "polyfoam", "cells/d.toml", "../x", "a/b"]),
    st.text(max_size=8),
)
VALUES = st.one_of(SCALARS, st.lists(SCALARS, max_size=4), st.dictionaries(st.text(max_size=6), SCALARS, max_size=3))

#: Keys a user may write, by table (known ones and a few that are not).
KEYS = {
    "pipeline": ["name", "stages", "workers", "stages_at_once", "typo"],
    "material": ["source", "kind", "E_t", "E_l", "nu_t", "nu_tl", "mu_l", "E", "nu", "density", "model", "typo"],
    "orient": ["mesh_size", "element", "thickness", "scene", "tip_box", "constants", "grip_size", "typo"],
    "cell": ["design", "seed", "voxel_mm", "relative_density", "surface", "typo"],
    "robot": ["delta_deg", "convergence", "picture", "typo"],
    "workspace": ["model", "n_steps", "certify", "columns", "test", "typo"],
}
DESIGN_KEYS = ["kind", "name", "infill_percentage", "kgon_x_shrink", "bead_width", "voxel_mm", "layer_model"]


def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return "nan" if v != v else "inf" if v == float("inf") else "-inf" if v == float("-inf") else repr(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, str):
        return '"' + "".join(c if c.isprintable() and c not in '"\\' else "?" for c in v) + '"'
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    return "{ " + ", ".join(f'"{k.replace(chr(34), "?")}" = {toml_value(x)}' for k, x in v.items()) + " }"


@st.composite
def pipelines(draw) -> str:
    """A pipeline file: a valid frame (name, stages) most of the time, then generated tables."""
    stages = draw(st.lists(st.sampled_from(["material", "orient", "cell", "robot", "workspace"]),
                           min_size=1, max_size=4, unique=True))
    if draw(st.integers(0, 9)) == 0:
        stages.append("banana")  # an unknown stage, now and then: most cases reach the stages' tables
    lines = ["[pipeline]", 'name = "g"', "stages = [" + ", ".join(f'"{s}"' for s in stages) + "]"]
    for table in ["pipeline", *stages]:
        if table != "pipeline":
            lines.append(f"[{table}]")
        most = 1 if table == "pipeline" and draw(st.integers(0, 4)) == 0 else 0 if table == "pipeline" else 3
        for key in draw(st.lists(st.sampled_from(KEYS.get(table, ["typo"])), max_size=most, unique=True)):
            if table == "pipeline" and key in ("name", "stages"):
                continue
            value = draw(st.one_of(VALUES, st.just("cells/d.toml"))) if key == "design" else draw(VALUES)
            lines.append(f"{key} = {toml_value(value)}")
    return "\n".join(lines) + "\n"


@st.composite
def designs(draw) -> bytes:
    """A cell design: random bytes, or the paper's polyfoam with generated keys appended."""
    if draw(st.booleans()):
        return draw(st.binary(max_size=64))
    extra = draw(st.dictionaries(st.sampled_from(DESIGN_KEYS), SCALARS, max_size=3))
    lines = [line for line in POLYFOAM.splitlines() if line.split("=")[0].strip() not in extra]
    head = [f"{k} = {toml_value(v)}" for k, v in extra.items()]  # before the first table
    return ("\n".join(head + lines) + "\n").encode()


def cli(*args: str) -> tuple[int, str]:
    """(exit status, stderr) of ``metasheet ARGS`` in this process; any exception other than
    SystemExit (a traceback) propagates and fails the test."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            main(list(args))
            code = 0
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
    return code, err.getvalue()


def snapshot(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def check(tmp: Path, pipeline: str, design: bytes, run: bool) -> None:
    (tmp / "cells").mkdir(exist_ok=True)
    (tmp / "pipelines").mkdir(exist_ok=True)
    (tmp / "cells" / "d.toml").write_bytes(design)
    path = tmp / "pipelines" / "g.toml"
    path.write_text(pipeline)
    outside = tmp / "elsewhere"
    outside.mkdir(exist_ok=True)
    (outside / "keep.txt").write_text("a user's file")
    before = {k: v for k, v in snapshot(tmp).items() if not k.startswith("out/")}
    code, err = cli("validate", str(path))
    assert code in (0, 2), err
    assert code == 0 or "error:" in err, err
    if run and code == 0 and "orient" not in pipeline and "cell" not in pipeline and "robot" not in pipeline:
        code, err = cli("run", str(path), "--out", str(tmp / "out"))
        assert code in (0, 2), err
        assert code == 0 or "error:" in err, err
    after = {k: v for k, v in snapshot(tmp).items() if not k.startswith("out/")}
    assert after == before, "a file outside <out>/<name> changed"
    out = tmp / "out"
    if out.exists():
        assert {p.name for p in out.iterdir()} <= {"g", ".g.lock", ".g.lock.json"}


def _run_cases(tmp_path_factory, n: int):
    @settings(max_examples=n, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)
    @given(pipeline=pipelines(), design=designs(), run=st.booleans())
    def case(pipeline, design, run):
        check(tmp_path_factory.mktemp("g"), pipeline, design, run)

    case()


def test_generated_files_give_an_error_line_or_work(tmp_path_factory):
    _run_cases(tmp_path_factory, CASES)


@pytest.mark.slow
def test_generated_files_give_an_error_line_or_work_many(tmp_path_factory):
    """Default sibling: :func:`test_generated_files_give_an_error_line_or_work` (a twentieth of the cases)."""
    _run_cases(tmp_path_factory, 20 * CASES)
