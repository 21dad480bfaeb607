"""orient + printmap stages end to end, and the IceSL script run by a real Lua interpreter.

The Lua test runs the generated ``print.lua`` against a small stand-in for IceSL's
functions (tex3d_r8f, v, load, emit, difference, intersection, set_setting_value,
set_service) and checks that every field file is read, has 64^3 values, and is bound to
the right setting and box; that the script binds every setting the model uses and nothing
else; and that the sheet is split into a foam brush (0) and a solid brush (1).
Each check runs through two Lua runtimes: ``lupa`` (Lua 5.4 bundled in a PyPI wheel, part
of the ``test`` extra, never skipped) and, when installed, the ``lua5.4`` binary (Debian:
``apt-get install lua5.4``), which is skipped without one.
"""

import contextlib
import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.pipeline import printsource
from metasheet.pipeline.registry import StageContext
from metasheet.pipeline.stages import printmap
from metasheet.sheet import icesl, icesl_lua
from test_printmap_consistency import CELL, P_CELL, printmap_run

LUA54 = shutil.which("lua5.4")

STANDIN = r"""
local real_open = io.open
local last_opened = nil
io.open = function(name, mode) last_opened = name; return real_open(name, mode) end
function v(x, y, z) return {x = x, y = y, z = z} end
local textures = {}
function tex3d_r8f(a, b, c)
  local t = {dims = {a, b, c}, file = last_opened, n = 0, sets = 0, sum = 0.0, seen = {}}
  function t:set(i, j, k, val)
    assert(i >= 0 and i < a and j >= 0 and j < b and k >= 0 and k < c, 'texel out of range')
    assert(i == math.floor(i) and j == math.floor(j) and k == math.floor(k), 'non-integer texel')
    local key = i + a * (j + b * k)
    if not self.seen[key] then self.seen[key] = true; self.n = self.n + 1 end
    self.sets = self.sets + 1
    self.sum = self.sum + val.x
  end
  textures[#textures + 1] = t
  return t
end
local loaded, emitted, settings = {}, 0, {}
local emits = {}
function load(path) loaded[#loaded + 1] = path; return {mesh = path, op = 'load'} end
function load_centered(path) error('load_centered would move the part off its texture box') end
function difference(a, b) assert(a.mesh and b.mesh, 'difference of non-shapes'); return {mesh = a.mesh .. '-' .. b.mesh, op = 'difference'} end
function intersection(a, b) assert(a.mesh and b.mesh, 'intersection of non-shapes'); return {mesh = a.mesh .. '*' .. b.mesh, op = 'intersection'} end
function emit(shape, brush)
  assert(shape and shape.mesh, 'emit without a shape'); emitted = emitted + 1
  emits[#emits + 1] = shape.op .. ' ' .. shape.mesh .. ' ' .. tostring(brush or 0)
end
function set_service(name) end
function set_setting_value(name, value, lo, hi) settings[#settings + 1] = {name = name, value = value, lo = lo, hi = hi} end
dofile(arg[1])
for _, s in ipairs(settings) do
  if type(s.value) == 'table' then
    local t = s.value
    print(string.format('FIELD %s %s %d %d %d %d %d %.10f %.6f %.6f %.6f %.6f %.6f %.6f', s.name, t.file,
      t.dims[1], t.dims[2], t.dims[3], t.n, t.sets, t.sum, s.lo.x, s.lo.y, s.lo.z, s.hi.x, s.hi.y, s.hi.z))
  else
    print('SET ' .. s.name .. ' ' .. tostring(s.value))
  end
end
print('LOAD ' .. table.concat(loaded, ' ') .. ' ' .. #loaded)
print('EMIT ' .. emitted)
for _, e in ipairs(emits) do print('BRUSH ' .. e) end
"""

# What `lua5.4 driver script` does, inside a lupa runtime: `arg` and the chunk's `...` as
# the binary sets them, `print` into a buffer (the captured stdout), errors with their
# traceback (the binary's stderr, exit status 1), a CPU-time limit standing in for `timeout=`.
LUPA_MAIN = r"""
local driver, script, timeout = ...
python, package.loaded.python = nil, nil  -- the binary has no `python` module
arg = {[0] = driver, script}
local out, tostring, select = {}, tostring, select
function print(...)
  for i = 1, select('#', ...) do out[#out + 1] = (i > 1 and '\t' or '') .. tostring((select(i, ...))) end
  out[#out + 1] = '\n'
end
local clock, t0, timed_out = os.clock, os.clock(), false
debug.sethook(function()
  if clock() - t0 > timeout then timed_out = true; error('timeout', 0) end
end, '', 1000000)
local ok, err = xpcall(function() return assert(loadfile(driver))(script) end, debug.traceback)
debug.sethook()
return table.concat(out), ok, tostring(err), timed_out
"""


def _lupa_runtime():
    """A fresh Lua 5.4 state from lupa (``lupa.lua54``, else lupa's default Lua)."""
    try:
        import lupa
    except ImportError as err:
        raise RuntimeError('lupa is missing: pip install -e ".[test]" (or pip install "lupa>=2")') from err
    try:
        from lupa import lua54 as lua
    except ImportError:
        lua = lupa
    return lua.LuaRuntime()


def _run_lupa(driver, script: str, *, cwd: Path, timeout: float) -> subprocess.CompletedProcess:
    """Run ``driver`` with argument ``script`` in lupa, from the working directory ``cwd``."""
    lua = _lupa_runtime()
    with contextlib.chdir(cwd):  # io.open and loadfile resolve against the process cwd
        out, ok, err, timed_out = lua.execute(LUPA_MAIN, str(driver), script, float(timeout))
    args = ["lupa", str(driver), script]
    if timed_out:
        raise subprocess.TimeoutExpired(args, timeout, output=out)
    return subprocess.CompletedProcess(args, 0 if ok else 1, out, "" if ok else f"lupa: {err}\n")


def _run_binary(driver, script: str, *, cwd: Path, timeout: float) -> subprocess.CompletedProcess:
    """Run ``lua5.4 driver script`` from the working directory ``cwd``."""
    return subprocess.run([LUA54, str(driver), script], cwd=cwd, capture_output=True, text=True, timeout=timeout)


@pytest.fixture(params=["lupa", pytest.param("lua5.4", marks=pytest.mark.system)])
def run_lua(request):
    """``run(driver, script, cwd=, timeout=) -> CompletedProcess`` through one Lua runtime."""
    if request.param == "lupa":
        return _run_lupa
    if LUA54 is None:
        pytest.skip("no lua5.4 binary on PATH (Debian: apt-get install lua5.4); the same check ran through lupa")
    return _run_binary


# CELL (imported with the shared run): the constants of a polyfoam cell, the paper's foam numbers
# standing in for a homogenised cell


def polyfoam_inputs(root: Path, *, kind="polyfoam", settings=None, constants=None) -> dict:
    """cell/ and homogenize/ outputs as the stages write them: cell.json with the design's IceSL
    settings, constants.json with the homogenised constants."""
    (root / "cell").mkdir(parents=True, exist_ok=True)
    (root / "homogenize").mkdir(parents=True, exist_ok=True)
    icesl_settings = {"infill_percentage": 80.0, "kgon_x_shrink": 0.2} if settings is None else settings
    design = {"kind": kind, "name": f"test_{kind}", "icesl": icesl_settings}
    (root / "cell" / "cell.json").write_text(json.dumps({"kind": kind, "name": design["name"], "design": design}))
    (root / "homogenize" / "constants.json").write_text(json.dumps(constants or CELL))
    return {"cell": root / "cell", "homogenize": root / "homogenize"}


class _Ctx:
    def __init__(self, inputs):
        self.inputs = inputs


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """(orient/, printmap/, their summaries): the session's orient + printmap run of
    tests/test_printmap_consistency.py (8 mm sheets of the cell's constants, the P_CELL % cell,
    every setting a field), shared with it. Read it only."""
    root, o, pm, _ = printmap_run(tmp_path_factory)
    summaries = json.loads((root / "summaries.json").read_text())
    return o, pm, summaries["orient"], summaries["printmap"]


def _nonblank_png(path: Path):
    import matplotlib.image as mpimg

    img = mpimg.imread(path)
    assert img.shape[0] > 200 and img.shape[1] > 400
    assert img[..., :3].std() > 0.05


def test_orient_outputs(runs):
    import meshio

    o, _, summary, _ = runs
    for name in ("sheet.vtu", "sheet_mirrored.vtu", "sheet.json", "sheet.png"):
        assert (o / name).exists(), name
    info = json.loads((o / "sheet.json").read_text())
    assert info["n_tets"] == summary["n_tets"] and info["quality"]["min_volume"] > 0
    assert all(info["attach_counts"][k] > 0 for k in "1234")
    a, b = meshio.read(o / "sheet.vtu"), meshio.read(o / "sheet_mirrored.vtu")
    fa, fb_ = a.cell_data["fiber"][0], b.cell_data["fiber"][0]
    assert fa.shape == (summary["n_tets"], 3)
    assert np.allclose(fb_, fa * [1, -1, 1])  # element i of the mirror is the image of i
    assert np.allclose(b.points, a.points * [1, -1, 1])
    assert np.allclose(a.cell_data["E_t"][0], CELL["E_t"])
    assert set(np.unique(a.point_data["attach"])) == {0, 1, 2, 3, 4}
    _nonblank_png(o / "sheet.png")


def test_printmap_outputs(runs):
    _, pm, _, summary = runs
    for label in ("normal", "mirrored"):
        for f in ("sheet.stl", "solid.stl", "print.lua", "infill_percentage.txt", "infill_angle.txt"):
            assert (pm / label / f).exists(), f"{label}/{f}"
        assert not (pm / label / "kgon_x_shrink.txt").exists()  # uniform shrink: a value, not a field
        assert summary[f"{label}_infill_percentage_range"] == [P_CELL, P_CELL]
    assert not list(pm.rglob(".*tmp*"))  # atomic writes leave no temporary file
    _nonblank_png(pm / "printmap.png")


# the settings the point model of a polyfoam cell (shrink 0.2, kgon defaults) binds on brush 0
FOAM_FIELDS = {"infill_percentage_0": "infill_percentage.txt", "infill_angle_0": "infill_angle.txt"}
FOAM_VALUES = {"infill_type_0": "Polyfoam", "print_perimeter_0": "false", "num_shells_0": "0",
               "cover_thickness_mm_0": "0.0", "kgon_x_shrink_0": "0.2"}


@pytest.mark.parametrize("label", ["normal", pytest.param("mirrored", marks=pytest.mark.slow)])
def test_lua_script_runs_and_binds_exactly_the_modelled_settings(runs, tmp_path, label, run_lua):
    """Default-selection sibling of the slow mirrored case (its script differs in the box only):
    test_lua_script_runs_and_binds_exactly_the_modelled_settings[lupa-normal]."""
    _, pm, _, _ = runs
    info = json.loads((pm / "printmap.json").read_text())["sheets"][label]
    driver = tmp_path / "standin.lua"
    driver.write_text(STANDIN)
    res = run_lua(driver, "print.lua", cwd=pm / label, timeout=120)
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    fields = {ln.split()[1]: ln.split()[2:] for ln in lines if ln.startswith("FIELD")}
    assert set(fields) == set(FOAM_FIELDS)
    for setting, fname in FOAM_FIELDS.items():
        f = fields[setting]
        assert f[0] == fname
        assert [int(x) for x in f[1:6]] == [64, 64, 64, 64**3, 64**3]
        values = np.loadtxt(pm / label / fname)
        assert float(f[6]) == pytest.approx(values.sum(), rel=1e-9, abs=1e-6)
        assert np.allclose([float(x) for x in f[7:10]], info["box_lo_mm"], atol=1e-6)
        assert np.allclose([float(x) for x in f[10:13]], info["box_hi_mm"], atol=1e-6)
    sets = dict(ln.split()[1:3] for ln in lines if ln.startswith("SET"))
    brush0 = {k: v for k, v in sets.items() if k.endswith("_0") and k != "extruder_temp_degree_c_0"}
    assert brush0 == FOAM_VALUES  # the model's settings, and nothing unmodelled (kgon defaults unset)
    brush1 = {k: v for k, v in sets.items() if k.endswith("_1")}
    assert brush1 == {"infill_percentage_1": "100.0", "num_shells_1": "10", "print_perimeter_1": "true"}
    assert sets["z_layer_height_mm"] == "0.3"
    assert "LOAD sheet.stl solid.stl 2" in lines and "EMIT 2" in lines
    brushes = sorted(ln for ln in lines if ln.startswith("BRUSH"))
    assert brushes == ["BRUSH difference sheet.stl-solid.stl 0", "BRUSH intersection sheet.stl*solid.stl 1"]


# The hand-made scripts below read textures of n^3 values: the script's reader takes n from the
# box (``local N``), so a 16^3 texture runs the same Lua as IceSL's 64^3 one (read through by the
# printmap's own scripts above), in 1/64 of the time; the 64^3 cases are slow.
TEXTURE_N = [16, pytest.param(64, marks=pytest.mark.slow)]


@pytest.mark.parametrize("n", TEXTURE_N)
def test_graded_shrink_is_a_field_and_kgon_defaults_are_not_written(tmp_path, run_lua, n):
    """Default-selection sibling of the slow 64 case: the 16 case of this test."""
    rng = np.random.default_rng(0)
    files = {"infill_percentage": "p.txt", "kgon_x_shrink": "s.txt", "infill_angle": "a.txt"}
    sums = {}
    for k, fname in files.items():
        v = np.round(rng.random((n, n, n)), 4)
        (tmp_path / fname).write_text(icesl.field_text(v))
        sums[fname] = v.sum()
    box = icesl.GridBox(np.array([-1.0, -2.0, -3.0]), np.array([1.0, 2.0, 3.0]), n)
    (tmp_path / "print.lua").write_text(icesl_lua.lua_script(
        sheet_stl="sheet.stl", solid_stl="solid.stl", infill_type="Polyfoam",
        foam={**icesl.FOAM_BRUSH, "kgon_min_angle": 60.0}, fields=files,
        solid={"num_shells": 10}, box=box, settings={"z_layer_height_mm": 0.3}))
    (tmp_path / "standin.lua").write_text(STANDIN)
    res = run_lua("standin.lua", "print.lua", cwd=tmp_path, timeout=60)
    assert res.returncode == 0, res.stderr
    fields = {ln.split()[1]: ln.split()[2:] for ln in res.stdout.splitlines() if ln.startswith("FIELD")}
    assert {k: v[0] for k, v in fields.items()} == {f"{k}_0": f for k, f in files.items()}
    for f in fields.values():
        assert [int(x) for x in f[1:6]] == [n, n, n, n**3, n**3]  # every texel set once
        assert float(f[6]) == pytest.approx(sums[f[0]], rel=1e-9)
        assert [float(x) for x in f[7:13]] == [-1.0, -2.0, -3.0, 1.0, 2.0, 3.0]
    assert "SET kgon_min_angle_0 60.0" in res.stdout.splitlines()
    assert "kgon_norm_alpha" not in res.stdout
    with pytest.raises(ConfigError, match="both a value and a field"):
        icesl_lua.lua_script(sheet_stl="s", solid_stl="t", infill_type="Polyfoam", foam={"kgon_x_shrink": 0.2},
                         fields={"kgon_x_shrink": "s.txt"}, solid={}, box=box, settings={})


@pytest.mark.parametrize("n", TEXTURE_N)
def test_lua_script_fails_loudly_on_a_short_field(tmp_path, run_lua, n):
    """Default-selection sibling of the slow 64 case: the 16 case of this test."""
    box = icesl.GridBox(np.zeros(3), np.ones(3), n)
    files = {"infill_percentage": "density.txt", "infill_angle": "angle.txt"}
    (tmp_path / "density.txt").write_text(icesl.field_text(np.zeros((n, n, n))))
    (tmp_path / "angle.txt").write_text("0.5 0.5\n")
    (tmp_path / "print.lua").write_text(icesl_lua.lua_script(
        sheet_stl="s.stl", solid_stl="t.stl", infill_type="Polyfoam", foam={}, fields=files, solid={},
        box=box, settings={}))
    (tmp_path / "standin.lua").write_text(STANDIN)
    res = run_lua("standin.lua", "print.lua", cwd=tmp_path, timeout=60)
    assert res.returncode != 0 and f"expected {n**3} values, read 2" in res.stderr


# ------------------------------------------------------------------ the print source

def test_print_source_point_model_from_the_cell(tmp_path):
    ctx = _Ctx(polyfoam_inputs(tmp_path, settings={"infill_percentage": 40.0, "kgon_x_shrink": 0.3,
                                                  "kgon_min_angle": 60.0, "kgon_norm_alpha": 0.5}))
    src = printsource.print_source(ctx, "auto")
    assert isinstance(src, printsource.PrintSource)
    assert (src.family, src.infill_type) == ("polyfoam", "Polyfoam")
    assert src.fixed == {"kgon_x_shrink": 0.3, "kgon_min_angle": 60.0}  # alpha at its default: not written
    assert src.field_names == ("infill_percentage",)
    assert printsource.print_source(ctx, "polyfoam").fixed == src.fixed
    # the cell itself maps to the cell's setting and back
    one = {k: np.array([v]) for k, v in CELL.items()}
    assert src.settings_for(one)["infill_percentage"] == pytest.approx([40.0])
    # local power law: moduli x (p / p_cell)^1.1, Poisson ratios unchanged
    c = src.constants_at({"infill_percentage": np.array([40.0, 60.0])})
    assert c["E_t"] == pytest.approx(CELL["E_t"] * np.array([1.0, 1.5 ** printsource.WALL_EXPONENT]))
    assert c["nu_tl"] == pytest.approx([CELL["nu_tl"]] * 2)
    back = src.settings_for(c)["infill_percentage"]
    assert back == pytest.approx([40.0, 60.0])
    with pytest.raises(ConfigError, match="no chart to map a different shrink"):
        src.constants_at({"infill_percentage": np.array([40.0]), "kgon_x_shrink": np.array([0.25])})


def test_phasor_and_unprintable_cells_are_refused(tmp_path):
    ctx = _Ctx(polyfoam_inputs(tmp_path / "a"))
    with pytest.raises(ConfigError, match=r"printmap\.infill: 'phasor': no modelled phasor cell family"):
        printsource.print_source(ctx, "phasor")
    foam = _Ctx(polyfoam_inputs(tmp_path / "b", kind="foam"))
    with pytest.raises(ConfigError, match=r"printmap\.infill: 'auto': the cell 'test_foam' is of family 'foam'"):
        printsource.print_source(foam, "auto")
    with pytest.raises(ConfigError, match=r"printmap\.infill: 'polyfoam': the cell 'test_foam' is of family 'foam'"):
        printsource.print_source(foam, "polyfoam")
    with pytest.raises(ConfigError, match=r"needs the cell and homogenize stages: add 'cell', 'homogenize'"):
        printsource.print_source(_Ctx({}), "auto")
    with pytest.raises(ConfigError, match=r"needs the homogenize stage"):
        printsource.print_source(_Ctx({"cell": tmp_path / "a" / "cell"}), "auto")


def test_stage_refuses_phasor_and_overriding_modelled_settings(runs, tmp_path):
    o, _, _, _ = runs
    inputs = {"orient": o, **polyfoam_inputs(tmp_path)}
    out = tmp_path / "pm"
    out.mkdir()
    with pytest.raises(ConfigError, match="no modelled phasor cell family"):
        printmap.run(StageContext("printmap", printmap.PrintmapParams(infill="phasor"), out, inputs, tmp_path))
    with pytest.raises(ConfigError, match=r"printmap\.settings: \['num_shells_0'\]"):
        printmap.run(StageContext("printmap", printmap.PrintmapParams(settings={"num_shells_0": 2}), out,
                                  inputs, tmp_path))
    assert not list(out.iterdir())
