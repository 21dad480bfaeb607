"""Realisations of a foam design: the same design at other seeds and sizes, homogenised (issue 43).

A stochastic foam's constants are random: one seed gives one draw. The homogenize stage
therefore builds further realisations of the cell stage's own design, each a work item for
the executor (picklable, one process each):

- **at the cell's size**: seeds ``seed + 1, seed + 2, ...`` (the cell stage's own voxels are
  realisation 0), for the mean and its 95 % interval (:mod:`.ensemble`);
- **at other sizes** (the cell-size study): the design with ``seeds.count = n`` (n cells in
  the periodic volume; a Polyfoam's box grows with n at a fixed cell size), seeds
  ``seed, seed + 1, ...``.

Only Polyfoam designs have a box that grows with the number of cells; a strut foam's box is
fixed, so more seeds would make smaller cells at the same voxels, not a larger volume: the
size study refuses it (:func:`check_design`).
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence

import numpy as np

from ..errors import ConfigError
from ..mechanics.material import CONSTANT_NAMES

#: The scalar constants whose statistics are kept, in order [MPa, -].
STAT_NAMES = tuple(CONSTANT_NAMES)


def check_design(design: Mapping, *, realisations: int, sizes: Sequence[int]) -> None:
    """Refuse what cannot be realised: a design without seeds, or a size study off a Polyfoam.

    ``design``: the cell stage's design (``cell.json``'s ``design``). ConfigError names the
    homogenize field at fault.
    """
    kind = design.get("kind", "foam")
    if realisations > 1 and "seeds" not in design:
        raise ConfigError(f"homogenize.realisations: {realisations}: a {kind} cell has no seeds, it is "
                          "deterministic: use realisations = 1")
    if sizes and kind != "polyfoam":
        raise ConfigError(f"homogenize.sizes: {list(sizes)}: the cell-size study needs a polyfoam design "
                          f"(its box grows with the number of cells); this cell is a {kind}, whose box is fixed")


def realisation_items(design: Mapping, n_cells: int, seeds: Sequence[int], *, solver: str,
                      rtol: float) -> list[dict]:
    """Work items: ``design`` with ``seeds.count = n_cells`` at each seed of ``seeds``."""
    base = dict(design)
    spec = dict(base.get("seeds", {}))
    return [{"design": {**base, "seeds": {**spec, "count": int(n_cells), "seed": int(s)}},
             "n_cells": int(n_cells), "seed": int(s), "solver": solver, "rtol": float(rtol)}
            for s in seeds]


def evaluate_realisation(item: dict) -> dict:
    """Build and homogenise one realisation (picklable, for the executor).

    Returns ``{"n_cells", "seed", "relative_density", "n_dof", "solver", "misfit", "C"
    (6 x 6 list, MPa), E_t .. mu_l [MPa, -], "seconds"}``; ``seconds`` is the wall time of
    the build and the solve, for the manifest only (never written to a result file).
    """
    from ..cells.catalogue import design_cell, parse_design
    from .voxels import homogenize_voxels

    t0 = time.perf_counter()
    design = parse_design(item["design"], source="homogenize realisation")
    cell = design_cell(design)
    r = homogenize_voxels(cell.phases, cell.size, cell.materials, solver=item["solver"], rtol=item["rtol"],
                          axis=cell.axis_vector, localise=False)
    return {**result_row(r, item["n_cells"], item["seed"]), "seconds": time.perf_counter() - t0}


def result_row(r, n_cells: int, seed: int) -> dict:
    """One realisation's row from a :class:`~.voxels.HomogenizationResult`-like ``r``."""
    m = r.fit.material.to_dict()
    return {"n_cells": int(n_cells), "seed": int(seed), "relative_density": float(r.relative_density),
            "n_dof": int(r.n_dof), "solver": str(r.solver), "misfit": float(r.fit.misfit),
            "C": np.asarray(r.C, float).tolist(), **{k: float(m[k]) for k in STAT_NAMES}}


def ensemble_input(rows: Sequence[Mapping]) -> dict[str, np.ndarray]:
    """name -> (k,) values of each constant and (k, 6, 6) C, from realisation rows of one size."""
    out = {k: np.array([r[k] for r in rows], float) for k in STAT_NAMES}
    out["C"] = np.array([r["C"] for r in rows], float)
    return out


def by_size(rows: Sequence[Mapping]) -> dict[int, list[Mapping]]:
    """Rows grouped by ``n_cells``, ascending, each group in seed order."""
    groups: dict[int, list[Mapping]] = {}
    for r in sorted(rows, key=lambda r: (r["n_cells"], r["seed"])):
        groups.setdefault(int(r["n_cells"]), []).append(r)
    return groups


def public_rows(rows: Sequence[Mapping]) -> list[dict]:
    """The rows without wall times: ``realisations.json`` has the same bytes on every run."""
    return [{k: v for k, v in r.items() if k != "seconds"} for r in rows]
