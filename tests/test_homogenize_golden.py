"""Golden regression of homogenised constants: every catalogue cell has one that CI checks.

Each ``tests/golden/<cell>.json`` holds the constants and C of ``cells/<cell>.toml``
built at a fixed, small resolution (the smallest of :data:`RESOLUTIONS` at which the
design is feasible; the design's own seed) and homogenised with the AMG-CG solver (pip-only,
the same everywhere). The check tolerance is stated in the file (relative, on every
constant and on C). Updating is explicit, never silent:

    python -m pytest tests/test_homogenize_golden.py --update-goldens

then review ``git diff tests/golden``. A cell without a golden fails with that hint.

Designs too fine for CI resolutions (their thinnest strut or wall needs n = 64) are checked
through a CI-sized *variant* instead (:data:`VARIANTS`: the same design with fewer, larger
cells, at a resolution where it is feasible); its golden ``<variant>.json`` records the
design, the changes to its [seeds] table, the resolution and the solver. A cell infeasible
at every CI resolution and without a variant fails: no catalogue cell is skipped.

paper_foam also has a golden at the design's own resolution (``<cell>_n<res>.json``, solver
"auto": CHOLMOD or AMG agree far below the tolerance; slow-marked). The catalogue goldens of
SLOW_CELLS are slow too; laminate and solid have a small-grid golden checked by default.
Update with ``python -m pytest tests/test_homogenize_golden.py --update-goldens -m "slow or not slow"``.
"""

import json
import tomllib
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pytest

from metasheet.errors import InfeasibleError

ROOT = Path(__file__).resolve().parents[1]
GOLDEN = Path(__file__).resolve().parent / "golden"
RESOLUTIONS = (16, 24, 32)  # the smallest one at which the design is feasible is used
TOLERANCE = 1e-6  # relative; the pipeline is deterministic, this only absorbs BLAS round-off
CELLS = sorted(p.stem for p in (ROOT / "cells").glob("*.toml"))


class Variant(NamedTuple):
    """A CI-sized variant of a catalogue design, golden in ``tests/golden/<name>.json``."""

    name: str
    seeds: dict  # changes to the design's [seeds] table
    resolution: int | float  # voxels per side; for Polyfoam cells the voxel edge voxel_mm [mm]
    solver: str  # "direct" (CHOLMOD, or SuperLU pip-only) or "amg"


#: CI-sized variants of the designs that are infeasible at CI resolutions, by catalogue cell.
VARIANTS = {
    # 3:1 voxels (15 x 15 x 5 mm box): direct (~30k dofs); AMG needs ~100 iterations per
    # load case on them, a minute of CI for nothing the other goldens do not already cover
    "paper_foam": Variant("paper_foam_coarse", {"count": 8}, 32, "direct"),
    "iso_foam": Variant("iso_foam_coarse", {"count": 8}, 24, "direct"),
    # rho = 0.25 with walls >= 2 voxels: 16 cells need n = 64 (walls ~0.39 mm); 6 cells
    # have walls of 0.53 mm = 2.1 voxels at n = 40. AMG (~15 s): SuperLU's fill-in on the
    # connected walls costs ~2 min and 2.5 GB already at n = 32
    "closed_foam": Variant("closed_foam_coarse", {"count": 6}, 40, "amg"),
    # one-bead walls at 15 % make cells of ~4 x 20 x 40 mm: 8 seeds at 0.2 mm are ~1M dofs.
    # Two seeds at 0.4 mm (walls one voxel thick) keep the whole chain (gauge, density solve,
    # non-cubic grid, fit about x) under regression in seconds
    "paper_polyfoam": Variant("paper_polyfoam_coarse", {"count": 2}, 0.4, "direct"),
}
#: Designs checked at their own resolution in a slow test.
FULL = ("paper_foam",)
#: The cells whose catalogue goldens (test_golden_constants) are slow. The default selection's
#: siblings: the CI variants of iso_foam and paper_foam (foams) and paper_polyfoam (Polyfoams),
#: and for the layered and solid kinds the golden ``<cell>_direct.json`` of test_golden_small:
#: the cell at its CI resolution solved directly (seconds; AMG-CG to 1e-10 is the slow part).
SLOW_CELLS = ("closed_foam", "laminate", "quick_foam", "quick_polyfoam", "solid")
SMALL = ("laminate", "solid")


def _compute(name: str, resolution: int, *, design: str | None = None, seeds: dict | None = None,
             solver: str = "amg") -> dict:
    from metasheet.cells.catalogue import design_cell, parse_design
    from metasheet.homogenize import homogenize_voxels

    data = tomllib.loads((ROOT / "cells" / f"{design or name}.toml").read_text())
    if seeds:
        data["seeds"] = {**data["seeds"], **seeds}
    # a Polyfoam grid follows its voxel edge: "resolution" is voxel_mm [mm] for them
    grid = {"voxel_mm": resolution} if data.get("kind") == "polyfoam" else {"resolution": resolution}
    cell = design_cell(parse_design(data, overrides=grid))
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


def _at_ci_resolution(name: str) -> dict:
    """The golden of a catalogue design at the smallest feasible CI resolution (Polyfoam:
    the design's own voxel edge)."""
    data = tomllib.loads((ROOT / "cells" / f"{name}.toml").read_text())
    if data.get("kind") == "polyfoam":
        return _compute(name, float(data["voxel_mm"]))
    for n in RESOLUTIONS:
        try:
            return _compute(name, n)
        except InfeasibleError as exc:
            last = exc
    pytest.fail(f"{name}: infeasible at every CI resolution {RESOLUTIONS} ({last}): add a "
                f"CI-sized variant of it to VARIANTS in {Path(__file__).name}")


@pytest.mark.parametrize("name", [pytest.param(c, marks=pytest.mark.slow) if c in SLOW_CELLS else c
                                  for c in CELLS])
def test_golden_constants(name, request):
    """Every catalogue cell: its own golden at a CI resolution, or its CI variant's.
    Default-selection siblings of the slow cells: test_golden_small (laminate, solid) and the
    CI variants' cases of this test (iso_foam, paper_foam: foams; paper_polyfoam: Polyfoams)."""
    if name in VARIANTS:
        v = VARIANTS[name]
        _golden(GOLDEN / f"{v.name}.json", request,
                lambda: _compute(v.name, v.resolution, design=name, seeds=v.seeds, solver=v.solver))
        return
    path = GOLDEN / f"{name}.json"
    if request.config.getoption("--update-goldens"):
        path.write_text(json.dumps(_at_ci_resolution(name), indent=2) + "\n")
        return
    if not path.exists():
        pytest.fail(f"no golden for cell {name!r}: run python -m pytest {Path(__file__).name} --update-goldens")
    want = json.loads(path.read_text())
    _check(_compute(name, want["resolution"]), want)


@pytest.mark.parametrize("name", SMALL)
def test_golden_small(name, request):
    """A deterministic catalogue cell at its CI resolution, solved directly: the default
    selection's check of the catalogue-golden path (test_golden_constants of these cells is slow)."""
    n = tomllib.loads((ROOT / "cells" / f"{name}.toml").read_text())["resolution"]
    _golden(GOLDEN / f"{name}_direct.json", request, lambda: _compute(name, n, solver="direct"))


def test_every_golden_is_checked():
    """No golden file left over (e.g. a design's record of being infeasible at CI sizes)."""
    full = {f"{name}_n{tomllib.loads((ROOT / 'cells' / f'{name}.toml').read_text())['resolution']}"
            for name in FULL} | {f"{name}_direct" for name in SMALL}
    expected = {VARIANTS[c].name if c in VARIANTS else c for c in CELLS} | full
    assert {p.stem for p in GOLDEN.glob("*.json")} == expected


@pytest.mark.slow
@pytest.mark.parametrize("name", FULL)
def test_golden_full_resolution(name, request):
    """paper_foam at n = 64 (224k dofs): ~25 s with CHOLMOD or PARDISO (pip), ~2-5 min with
    AMG-CG. Default-selection sibling: test_golden_constants[paper_foam] (its CI variant)."""
    n = tomllib.loads((ROOT / "cells" / f"{name}.toml").read_text())["resolution"]
    _golden(GOLDEN / f"{name}_n{n}.json", request, lambda: _compute(name, n, solver="auto"))
