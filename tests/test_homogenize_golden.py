"""Golden regression of homogenised constants, one file per catalogue cell.

Each ``tests/golden/<cell>.json`` holds the constants and C of ``cells/<cell>.toml``
built at a fixed, small resolution (the design's own seed) and homogenised with the
AMG-CG solver (pip-only, the same everywhere). The check tolerance is stated in the file (relative, on every
constant and on C). Updating is explicit, never silent:

    python -m pytest tests/test_homogenize_golden.py --update-goldens

then review ``git diff tests/golden``. A cell without a golden fails with that hint.

Designs too fine for CI (paper_foam needs n = 64 for its thin struts) get two goldens:
a CI-sized *variant* (:data:`VARIANTS`: the same design with fewer, larger cells) and a
golden at the design's own resolution (``<cell>_n<res>.json``, solver "auto": CHOLMOD or
AMG agree far below the tolerance; slow-marked when CHOLMOD is missing). Update with
``python -m pytest tests/test_homogenize_golden.py --update-goldens -m "slow or not slow"``.
"""

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

from metasheet.errors import InfeasibleError

ROOT = Path(__file__).resolve().parents[1]
GOLDEN = Path(__file__).resolve().parent / "golden"
RESOLUTIONS = (16, 24, 32)  # the smallest one at which the design is feasible is used
TOLERANCE = 1e-6  # relative; the pipeline is deterministic, this only absorbs BLAS round-off
CELLS = sorted(p.stem for p in (ROOT / "cells").glob("*.toml"))
#: CI-sized variants of designs that are infeasible at CI resolutions:
#: name -> (design file stem, changes to its [seeds] table, resolution).
VARIANTS = {"paper_foam_coarse": ("paper_foam", {"count": 8}, 32),
            "iso_foam_coarse": ("iso_foam", {"count": 8}, 24)}
#: Designs checked at their own resolution in a slow test.
FULL = ("paper_foam",)


def _compute(name: str, resolution: int, *, design: str | None = None, seeds: dict | None = None,
             solver: str = "amg") -> dict:
    from metasheet.cells.design import design_cell, parse_design
    from metasheet.homogenize import homogenize_voxels

    data = tomllib.loads((ROOT / "cells" / f"{design or name}.toml").read_text())
    if seeds:
        data["seeds"] = {**data["seeds"], **seeds}
    cell = design_cell(parse_design(data, overrides={"resolution": resolution}))
    r = homogenize_voxels(cell.phases, cell.size, cell.materials, solver=solver, rtol=1e-10,
                          axis=cell.axis_vector, localise=False)
    out = {"cell": name, "resolution": resolution, "tolerance": TOLERANCE, "solver_asked": solver}
    if design:
        out.update(design=design, seeds=seeds or {})
    return {**out, "relative_density": r.relative_density, **r.fit.material.to_dict(),
            "misfit": r.fit.misfit, "C": r.C.tolist()}


def _check(got: dict, want: dict) -> None:
    tol = want["tolerance"]
    for k in ("relative_density", "E_t", "E_l", "nu_t", "nu_tl", "mu_l"):
        assert got[k] == pytest.approx(want[k], rel=tol), k
    C0 = np.array(want["C"])
    assert np.abs(np.array(got["C"]) - C0).max() <= tol * np.abs(C0).max()


def _golden(path: Path, request, compute) -> None:
    if request.config.getoption("--update-goldens"):
        path.write_text(json.dumps(compute(), indent=2) + "\n")
        return
    if not path.exists():
        pytest.fail(f"no golden {path.name}: run python -m pytest {Path(__file__).name} --update-goldens")
    want = json.loads(path.read_text())
    _check(compute(), want)


@pytest.mark.parametrize("name", sorted(VARIANTS))
def test_golden_variant(name, request):
    design, seeds, n = VARIANTS[name]
    # direct (CHOLMOD or SuperLU, ~30k dofs): AMG needs ~100 iterations per case on these
    # 3:1 voxels, a minute of CI for nothing the other goldens do not already cover
    _golden(GOLDEN / f"{name}.json", request, lambda: _compute(name, n, design=design, seeds=seeds, solver="direct"))


def _full_params():
    from metasheet.homogenize.solvers import HAVE_CHOLMOD

    # paper_foam at n = 64 (224k dofs): ~25 s with CHOLMOD, ~5 min with AMG (pip-only): CI
    # runs it only where CHOLMOD is installed
    return [pytest.param(name, marks=() if HAVE_CHOLMOD else pytest.mark.slow) for name in FULL]


@pytest.mark.parametrize("name", _full_params())
def test_golden_full_resolution(name, request):
    n = tomllib.loads((ROOT / "cells" / f"{name}.toml").read_text())["resolution"]
    _golden(GOLDEN / f"{name}_n{n}.json", request, lambda: _compute(name, n, solver="auto"))


@pytest.mark.parametrize("name", CELLS)
def test_golden_constants(name, request):
    path = GOLDEN / f"{name}.json"
    if request.config.getoption("--update-goldens"):
        for n in RESOLUTIONS:
            try:
                out = _compute(name, n)
                break
            except InfeasibleError as exc:
                last = exc
        else:
            out = {"cell": name, "infeasible": str(last), "resolutions": list(RESOLUTIONS)}
        path.write_text(json.dumps(out, indent=2) + "\n")
        return
    if not path.exists():
        pytest.fail(f"no golden for cell {name!r}: run python -m pytest {Path(__file__).name} --update-goldens")
    want = json.loads(path.read_text())
    if "infeasible" in want:  # recorded at update time: the design needs a finer grid than CI affords
        pytest.skip(f"{name}: no CI-sized golden: {want['infeasible']}")
    _check(_compute(name, want["resolution"]), want)
