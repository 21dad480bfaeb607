"""Issue 15, items 4 and 5: messages print verbatim; every fault is a named error.

Every error path of the CLI is rendered and its text compared with the library's message,
character for character: square brackets and units survive (rich markup used to eat them).
Faults (unwritable outputs, a full disk, a missing file, a bad pose, an unreachable goal)
give one ``error: ...`` line and their documented exit status, with no traceback unless
``--debug``. Most calls run ``metasheet.cli.main`` in this process (fast, monkeypatchable).
"""

import errno
import os
import pathlib
import re
import subprocess
import sys
from pathlib import Path

import pytest
from pydantic import Field

from metasheet.cli import main
from metasheet.errors import ConfigError
from metasheet.pipeline import registry
from metasheet.pipeline import runner as runner_module
from metasheet.pipeline.config import load_pipeline
from metasheet.pipeline.registry import Params, Stage, register

ROOT = Path(__file__).resolve().parents[1]


class AParams(Params):
    value: float = Field(1.0, ge=0, le=10, description="a number [-]")
    explode: bool = False


def run_a(ctx):
    ctx.path("a.txt").write_text(f"{ctx.params.value}\n")
    if ctx.params.explode:
        raise RuntimeError("boom [x] at 3 [mm]")
    return {}


def run_b(ctx):
    a = float((ctx.inputs["t_a"] / "a.txt").read_text())
    ctx.path("b.txt").write_text(f"{2 * a}\n")
    return {}


@pytest.fixture
def project(tmp_path, monkeypatch):
    registry.stages()
    register(Stage("t_a", AParams, run_a, outputs=("a.txt",)))
    register(Stage("t_b", AParams, run_b, requires=("t_a",), outputs=("b.txt",)))
    (tmp_path / "cells").mkdir()
    (tmp_path / "pipelines").mkdir()
    monkeypatch.chdir(tmp_path)
    yield tmp_path
    registry._REGISTRY.pop("t_a")
    registry._REGISTRY.pop("t_b")


def cli(capsys, *args) -> tuple[int, str, str]:
    """Run ``metasheet ARGS`` in this process: (exit status, stdout, stderr)."""
    saved = sys.argv
    sys.argv = ["metasheet", *args]
    try:
        with pytest.raises(SystemExit) as exc:
            main()
    finally:
        sys.argv = saved
    out, err = capsys.readouterr()
    code = exc.value.code
    return (0 if code is None else code), out, err


def write(project: Path, text: str, name: str = "p.toml") -> Path:
    p = project / "pipelines" / name
    p.write_text(text)
    return p


GOOD = '[pipeline]\nname = "p"\nstages = ["t_a", "t_b"]\n[t_a]\nvalue = {v}\n'

CONFIG_ERRORS = {
    "no pipeline table": '[t_a]\nvalue = 1.0\n',
    "unknown key, brackets and units in the value": GOOD.format(v=1) + 'bogus = "[x] 3 [mm]"\n',
    "out of range": GOOD.format(v=11),
    "unknown stage": '[pipeline]\nname = "p"\nstages = ["[t_a]"]\n',
    "invalid TOML": "[pipeline\n",
    "missing cell design": '[pipeline]\nname = "p"\nstages = ["cell"]\n[cell]\ndesign = "cells/no[1].toml"\n',
    "missing chart design": '[pipeline]\nname = "p"\nstages = ["chart"]\n[chart]\ndesign = "cells/gone [2].toml"\n',
}


@pytest.mark.parametrize("case", list(CONFIG_ERRORS))
@pytest.mark.parametrize("command", ["validate", "run"])
def test_config_errors_reach_the_terminal_unchanged(project, capsys, case, command):
    """Before: "[pipeline]" vanished from its message, and validate said "ok" for a missing design."""
    path = write(project, CONFIG_ERRORS[case])
    with pytest.raises(ConfigError) as expected:
        load_pipeline(path)
    code, out, err = cli(capsys, command, str(path))
    assert code == 2
    assert err == f"error: {expected.value}\n"
    assert "Traceback" not in out + err


def test_missing_pipeline_file_and_diff_paths_keep_their_brackets(project, capsys):
    code, _, err = cli(capsys, "validate", "pipelines/nope [1].toml")
    assert (code, err) == (2, "error: pipelines/nope [1].toml: pipeline file not found\n")
    (project / "b").mkdir()
    code, _, err = cli(capsys, "diff", "[a]", "b")
    assert (code, err) == (2, "error: [a]: not a directory\n")


def test_the_brackets_of_the_pipeline_table_message(project, capsys):
    """The issue's example, spelled out."""
    code, _, err = cli(capsys, "validate", str(write(project, '[t_a]\nvalue = 1.0\n')))
    assert "a [pipeline] table with name and stages is required" in err and code == 2


def test_unknown_stage_option_and_failed_stage_messages(project, capsys):
    path = write(project, GOOD.format(v=1))
    code, _, err = cli(capsys, "run", str(path), "--stage", "no[pe]")
    assert code == 2
    assert err == f"error: --stage: 'no[pe]': not a stage of {path}; its stages: t_a, t_b\n"
    bad = write(project, GOOD.format(v=1) + "explode = true\n")
    code, _, err = cli(capsys, "run", str(bad))
    assert code == 2
    assert err.splitlines()[-1] == "error: stage 't_a' failed: RuntimeError: boom [x] at 3 [mm]"


def test_usage_errors_print_plain(project, capsys):
    """click's own errors: plain lines, not a rich panel that wraps and boxes them."""
    code, _, err = cli(capsys, "run", "--workers", "0", "x.toml")
    assert code == 2
    assert err.splitlines()[-1].startswith("Error: Invalid value for '--workers': ")
    assert not set("│╭╰─") & set(err)


def test_results_table_keeps_time_unit(project, capsys):
    """Before: the header "time [s]" printed as "time"."""
    code, out, err = cli(capsys, "run", str(write(project, GOOD.format(v=1))))
    assert code == 0, err
    assert "time [s]" in out


@pytest.mark.parametrize("pose, message", [
    (["0", "0", "abc", "0", "0", "0"], "pose component 3 of 6 (Z [mm]): 'abc': expected a number"),
    (["0", "0", "0", "0", "nan", "0"], "pose component 5 of 6 (RY [deg]): 'nan': expected a finite number"),
    (["inf", "0", "0", "0", "0", "0"], "pose component 1 of 6 (X [mm]): 'inf': expected a finite number"),
    (["1", "2"], "pose: 2 numbers given: expected 6 (X Y Z [mm] RX RY RZ [deg])"),
])
def test_bad_pose_component_is_named_with_its_position(capsys, pose, message):
    """Before: "abc" gave click's message without the component; nan printed as "array()"."""
    code, out, err = cli(capsys, "robot", "goto", "--", *pose)
    assert (code, err) == (2, f"error: {message}\n")


def test_help_keeps_units(capsys):
    code, out, _ = cli(capsys, "robot", "goto", "--help")
    assert code == 0
    assert "X Y Z [mm] RX RY RZ [deg]" in " ".join(out.split())


# ------------------------------------------------------------------------------- faults


def listing(base: Path) -> list[str]:
    return sorted(p.name for p in base.iterdir())


def test_unwritable_stage_folder_is_a_named_error_and_keeps_old_outputs(project, capsys, monkeypatch):
    """The issue's ``chattr +i``: creating the temporary folder fails (EPERM). Before: a
    40-line PermissionError traceback from runner.py."""
    path = write(project, GOOD.format(v=1))
    assert cli(capsys, "run", str(path))[0] == 0
    real_mkdir = pathlib.Path.mkdir

    def mkdir(self, *a, **k):
        if self.name.startswith(".t_a.tmp-"):
            raise PermissionError(errno.EPERM, "Operation not permitted", str(self))
        return real_mkdir(self, *a, **k)

    monkeypatch.setattr(pathlib.Path, "mkdir", mkdir)
    code, out, err = cli(capsys, "run", str(write(project, GOOD.format(v=2))))
    base = project / "outputs" / "p"
    assert code == 2 and "Traceback" not in out + err
    assert err.splitlines()[-1] == (f"error: {base}: cannot write {base / f'.t_a.tmp-{os.getpid()}'}: operation "
                                    "not permitted (immutable or not owned): choose another output root (--out) (EPERM)")
    assert listing(base) == ["t_a", "t_b"] and (base / "t_a/a.txt").read_text() == "1.0\n"


def test_failed_swap_leaves_no_complete_temporary_folder(project, capsys, monkeypatch):
    """Before: a rename refused at the end left a complete ``.t_b.tmp-*`` behind, with a traceback."""
    path = write(project, GOOD.format(v=1))
    assert cli(capsys, "run", str(path))[0] == 0
    real_replace = os.replace

    def replace(src, dst):
        if Path(dst).name == "t_b" and ".tmp-" in Path(src).name:
            raise PermissionError(errno.EACCES, "Permission denied", str(dst))
        return real_replace(src, dst)

    monkeypatch.setattr(runner_module.os, "replace", replace)
    code, out, err = cli(capsys, "run", str(write(project, GOOD.format(v=3))))
    base = project / "outputs" / "p"
    assert code == 2 and "Traceback" not in out + err
    assert err.splitlines()[-1] == (f"error: stage 't_b': cannot write {base / 't_b'}: permission denied: make it "
                                    "writable or choose another output root (--out) (EACCES)")
    assert listing(base) == ["t_a", "t_b"]
    assert (base / "t_b/b.txt").read_text() == "2.0\n"  # the old outputs, back in place


def test_outputs_root_that_is_a_file(project, capsys):
    (project / "taken").write_text("a file, not a folder")
    code, out, err = cli(capsys, "run", str(write(project, GOOD.format(v=1))), "--out", "taken")
    assert code == 2 and "Traceback" not in out + err
    assert err.startswith("error: taken/p: cannot write taken: ") and err.rstrip().endswith("(EEXIST)")


@pytest.mark.parametrize("where", ["stage file", pytest.param("manifest", marks=pytest.mark.skipif(
    not Path("/proc/self/fd").is_dir(), reason="finds the manifest's file descriptor in /proc"))])
def test_disk_full_is_a_named_error_and_writes_nothing_half(project, capsys, monkeypatch, where):
    """ENOSPC, simulated: while the stage writes b.txt, or while the runner flushes the manifest."""
    path = write(project, GOOD.format(v=1))
    assert cli(capsys, "run", str(path))[0] == 0
    if where == "stage file":
        real = pathlib.Path.write_text

        def write_text(self, *a, **k):
            if self.name == "b.txt":
                raise OSError(errno.ENOSPC, "No space left on device", str(self))
            return real(self, *a, **k)

        monkeypatch.setattr(pathlib.Path, "write_text", write_text)
    else:
        from metasheet.pipeline import manifest

        real_fsync = manifest.os.fsync

        def fsync(fd):  # the manifest's temporary file only (not the lock's side file)
            if ".manifest.json.tmp-" in os.readlink(f"/proc/self/fd/{fd}"):
                raise OSError(errno.ENOSPC, "No space left on device")
            return real_fsync(fd)

        monkeypatch.setattr(manifest.os, "fsync", fsync)
    code, out, err = cli(capsys, "run", str(path), "--stage", "t_b", "--force")
    base = project / "outputs" / "p"
    assert code == 2 and "Traceback" not in out + err
    cause = "no space left on device: free some space or choose another output root (--out) (ENOSPC)"
    target = f"cannot write {base / f'.t_b.tmp-{os.getpid()}' / 'b.txt'}: " if where == "stage file" else "cannot write: "
    assert err.splitlines()[-1] == f"error: stage 't_b': {target}{cause}"
    assert listing(base) == ["t_a", "t_b"]
    assert (base / "t_b/b.txt").read_text() == "2.0\n"
    assert not [p for p in base.rglob("*") if ".tmp-" in p.name]


def test_debug_shows_the_traceback(project, capsys):
    for args in (["--debug", "validate", "missing.toml"], ["validate", "missing.toml", "--debug"]):
        code, _, err = cli(capsys, *args)
        assert code == 2 and "Traceback" in err and err.endswith("error: missing.toml: pipeline file not found\n")


def test_unreachable_goal_exits_4_with_the_closest_pose(tmp_path):
    """Before: "stalled ... remaining error 981.9 mm" and exit status 0."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    r = subprocess.run([sys.executable, "-m", "metasheet.cli", "robot", "goto", "1000", "0", "0", "0", "0", "0"],
                       cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert r.returncode == 4, r.stdout + r.stderr
    assert "Traceback" not in r.stderr
    assert re.search(r"^pose reached: X Y Z \[mm\] \S+ \S+ \S+ \| RX RY RZ \[deg\] \S+ \S+ \S+$", r.stdout, re.M)
    m = re.fullmatch(r"error: goal not reached \((stalled|max_steps)\): remaining error ([\d.]+) mm, [\d.]+ deg; "
                     r"closest pose X Y Z \[mm\] .+ \| RX RY RZ \[deg\] .+\n", r.stderr)
    assert m, r.stderr
    assert float(m[2]) > 900.0
