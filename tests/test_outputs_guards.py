"""Outputs a reader must not trust: stale ones (the pipeline file was edited since its run),
corrupt meshes, and ``metasheet diff``'s tolerance for values zero up to round-off.

Each test failed before its fix: ``robot goto``/``serve`` answered from outputs of another
version of the pipeline file (exit 0); a corrupt VTU exited 1 (``diff``'s "trees differ")
through meshio's ``sys.exit`` with no ``error:`` line; ``diff --rtol 1e-6`` failed on
3.3e-16 against 4.1e-16.
"""

import json
import socket

import numpy as np
import pytest

from metasheet.cli import main
from metasheet.errors import ConfigError, MeshError
from metasheet.pipeline import manifest as mf
from metasheet.pipeline import registry
from metasheet.pipeline.artefacts import read_mesh, read_orient
from metasheet.pipeline.config import load_pipeline
from metasheet.pipeline.outputs_diff import compare_trees
from metasheet.pipeline.runner import run_pipeline
from metasheet.pipeline.staleness import stage_key, stale_stages
from metasheet.serve.loading import find_outputs

from serve_outputs import PIPELINE, write_outputs


class AParams(registry.Params):
    value: float = 1.0


def run_a(ctx):
    ctx.path("a.txt").write_text(f"{ctx.params.value}\n")
    return {}


def run_b(ctx):
    ctx.path("b.txt").write_text(f"{2 * float((ctx.inputs['t_a'] / 'a.txt').read_text())}\n")
    return {}


def cli(capsys, *args) -> tuple[int, str, str]:
    """``metasheet ARGS`` in this process: (exit status, stdout, stderr)."""
    with pytest.raises(SystemExit) as exc:
        main([str(a) for a in args])
    out, err = capsys.readouterr()
    return (0 if exc.value.code is None else exc.value.code), out, err


def error_line(err: str) -> str:
    """The one ``error:`` line, last on stderr (``serve`` says what it loads first)."""
    lines = err.strip().splitlines()
    assert lines[-1].startswith("error: ") and sum(ln.startswith("error") for ln in lines) == 1, err
    return lines[-1]


def record_run(toml, out):
    """Manifests as ``metasheet run`` writes them (key and outputs) for the hand-built outputs
    of ``toml``: as if it had run (the robot stage itself takes minutes)."""
    p = load_pipeline(toml)
    base = out / p.name
    for name in p.order:
        mf.write_json_atomic(base / name / mf.MANIFEST, {"stage": name, "key": stage_key(p, name, base).key,
                                                         "outputs": mf.output_hashes(base / name)})


# -- stale outputs ---------------------------------------------------------------------------

@pytest.fixture
def toy_stages():
    registry.stages()
    registry.register(registry.Stage("t_a", AParams, run_a, outputs=("a.txt",)))
    registry.register(registry.Stage("t_b", AParams, run_b, requires=("t_a",), outputs=("b.txt",)))
    yield
    registry._REGISTRY.pop("t_a")
    registry._REGISTRY.pop("t_b")


def test_stale_stages_are_those_the_runner_would_rerun(tmp_path, toy_stages):
    toml = tmp_path / "p.toml"
    toml.write_text('[pipeline]\nname = "p"\nstages = ["t_a", "t_b"]\n[t_a]\nvalue = 1.0\n')
    out = tmp_path / "out"
    run_pipeline(load_pipeline(toml), out_root=out)
    assert stale_stages(load_pipeline(toml), out / "p") == ()  # the runner's keys, byte for byte
    toml.write_text(toml.read_text().replace("value = 1.0", "value = 2.0"))
    edited = load_pipeline(toml)
    assert stale_stages(edited, out / "p") == ("t_a",)  # t_b's inputs on disk did not change yet
    assert stale_stages(edited, out / "p", ["t_b"]) == ("t_a",)  # upstream of what is read
    assert [o.status for o in run_pipeline(edited, out_root=out)] == ["ran", "ran"]
    assert stale_stages(edited, out / "p") == ()


def test_goto_and_serve_refuse_outputs_of_an_edited_pipeline(tmp_path, capsys):
    toml, out = write_outputs(tmp_path)
    record_run(toml, out)
    assert find_outputs(toml, out).directory == out / "tiny"  # as run: trusted
    toml.write_text(PIPELINE + "[orient]\nmesh_size = 10.0\n[robot]\nrod_length = 90.0\n")  # same name
    with pytest.raises(ConfigError, match=r"stage\(s\) orient, robot do not match .*run `metasheet run"):
        find_outputs(toml, out)
    code, out_text, err = cli(capsys, "robot", "goto", "--pipeline", toml, "--out", out, "--", 1, 1, -1, 0, 3, 0)
    line = error_line(err)
    assert code == 2 and "orient, robot" in line and f"metasheet run {toml} --out {out}" in line
    code, _, err = cli(capsys, "serve", toml, "--out", out, "--port", free_port())
    assert code == 2 and "orient, robot" in error_line(err)


def test_outputs_written_by_hand_are_not_judged(tmp_path):
    toml, out = write_outputs(tmp_path)  # no manifests: nothing recorded to compare with
    assert find_outputs(toml, out).directory == out / "tiny"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# -- corrupt meshes --------------------------------------------------------------------------

GARBAGE = {"bytes": b"\x00\x01garbage\xff" * 40, "truncated": None, "empty": b""}


def corrupt(path, how: str) -> None:
    data = GARBAGE[how]
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2] if data is None else data)


@pytest.mark.parametrize("how", list(GARBAGE))
def test_a_corrupt_mesh_is_a_mesh_error_naming_the_file(tmp_path, how, capsys):
    _, out = write_outputs(tmp_path)
    vtu = out / "tiny" / "orient" / "sheet.vtu"
    corrupt(vtu, how)
    with pytest.raises(MeshError, match=rf"{vtu}: unreadable mesh file .*rerun the stage"):
        read_mesh(vtu)
    with pytest.raises(MeshError, match="sheet.vtu"):
        read_orient(vtu.parent)
    assert capsys.readouterr().out == ""  # meshio's own "Couldn't read file" is not printed


@pytest.mark.parametrize("command", ["goto", "serve"])
def test_cli_on_a_corrupt_mesh_exits_2_naming_the_file(tmp_path, capsys, command):
    toml, out = write_outputs(tmp_path)
    vtu = out / "tiny" / "orient" / "sheet.vtu"
    corrupt(vtu, "bytes")
    args = (["robot", "goto", "--pipeline", toml, "--out", out, "--", 1, 1, -1, 0, 3, 0] if command == "goto"
            else ["serve", toml, "--out", out, "--port", free_port()])
    code, _, err = cli(capsys, *args)
    assert code == 2 and str(vtu) in error_line(err) and "unreadable mesh file" in err
    assert "Traceback" not in err


def test_diff_reports_a_corrupt_mesh_as_a_difference(tmp_path, capsys):
    (tmp_path / "a").mkdir(), (tmp_path / "b").mkdir()
    _, a = write_outputs(tmp_path / "a")
    _, b = write_outputs(tmp_path / "b")
    corrupt(b / "tiny" / "orient" / "sheet_mirrored.vtu", "bytes")
    rows = {r.path: r for r in compare_trees(a, b)}
    bad = rows["tiny/orient/sheet_mirrored.vtu"]
    assert bad.status == "different" and bad.note.startswith("unreadable in b: ") and not bad.within
    code, out, err = cli(capsys, "diff", a, b)
    assert code == 1 and "4 of 5 files identical" in out and "error" not in err.lower()


# -- diff's absolute floor -------------------------------------------------------------------

def _moments(root, tiny: float, big: float = 12.5):
    root.mkdir(parents=True)
    (root / "r.json").write_text(json.dumps({"moment_z": tiny, "force": [big, 0.5 * big]}))
    np.savez(root / "u.npz", u=np.array([big, tiny]))
    return root


def test_diff_atol_is_a_floor_for_values_zero_by_symmetry(tmp_path):
    a = _moments(tmp_path / "a", 3.3e-16)
    b = _moments(tmp_path / "b", -4.1e-16)  # zero by symmetry, in both runs
    rows = {r.path: r for r in compare_trees(a, b, rtol=1e-6)}
    assert rows["r.json"].max_rel > 1.0 and not rows["r.json"].within  # 7.4e-16 / 4.1e-16
    assert rows["u.npz"].within  # normwise: the array's scale 12.5 covers it
    rows = {r.path: r for r in compare_trees(a, b, rtol=1e-6, atol=1e-12)}
    assert all(r.within for r in rows.values())
    assert rows["r.json"].max_abs == pytest.approx(7.4e-16)
    c = _moments(tmp_path / "c", 3.3e-16, big=12.5 * (1 + 1e-5))  # a real change still fails
    assert not {r.path: r for r in compare_trees(a, c, rtol=1e-6, atol=1e-12)}["r.json"].within
    # the rule is symmetric: a against b is b against a
    assert [r.within for r in compare_trees(b, a, rtol=1e-6, atol=1e-12)] == [True, True]


def test_cli_diff_atol(tmp_path, capsys):
    a, b = _moments(tmp_path / "a", 3.3e-16), _moments(tmp_path / "b", -4.1e-16)
    code, out, _ = cli(capsys, "diff", a, b, "--rtol", "1e-6")
    assert code == 1 and "7.40e-16" in out  # the absolute difference is shown: a hint for --atol
    code, out, _ = cli(capsys, "diff", a, b, "--rtol", "1e-6", "--atol", "1e-12")
    assert code == 0 and "2 of 2 files identical or within rtol 1e-06, atol 1e-12" in out
    for bad in ("nan", "-1"):
        code, _, err = cli(capsys, "diff", a, b, "--atol", bad)
        assert code == 2 and "--atol" in err
