"""Will this printed foam behave like a continuum in this sheet? (issue 63)

The scale-separation map (``pipelines/scale-map.toml``, :mod:`metasheet.studies.scale_map`)
measured, over Polyfoams and sheet thicknesses, how far the printed sheets' DNS on the robot's
grips is from the continuum, and fitted it against the number of cell heights through the
sheet n: ``|log r| = a n^-b`` (r printed over continuum; the prints are the softer). This module
holds those fits and turns a design and a thickness into the expected ratios and a verdict,
for ``metasheet validate``, the orient stage and the material stage's ``source = "auto"``.
Lengths in mm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import check_range

#: The map's fits (a, b, sign): r = exp(sign a n^-b), printed over continuum. "bulk": the robot's
#: bulk constants (the cell's transverse-isotropic fit, what ``source = "homogenize"`` gives);
#: "plate": the plate's membrane moduli. Measured by ``metasheet run pipelines/scale-map.toml``
#: (2026-11-30: infill 15 / 30 / 50 % x shrink 0.2 / 1 x 2.5 / 5 mm, 3 prints each at 0.25 mm
#: voxels; docs/continuum-map.md). The cell's whole C, the scale effect alone, fits 0.106 n^-0.90.
TRENDS = {
    "bulk": (0.3083, 0.5577, -1.0),
    "plate": (0.0570, 0.2261, -1.0),
}
#: The n range the fits saw [cells through the sheet]: outside it the verdict says it extrapolates.
MAP_RANGE = (0.06, 0.94)
#: A continuum "holds" within this fraction of the prints (the map's wider band).
HOLDS = 0.25


def expected_ratio(model: str, n: float) -> float:
    """Printed over ``model`` ("bulk" or "plate") continuum the map's fit expects at ``n`` cell
    heights through the sheet."""
    a, b, sign = TRENDS[model]
    return math.exp(sign * a * n ** -b)


def cells_needed(model: str, band: float = HOLDS) -> float:
    """Cell heights through the sheet from which ``model`` is within ``band`` of the prints."""
    a, b, _ = TRENDS[model]
    return (a / math.log1p(band)) ** (1.0 / b)


@dataclass(frozen=True)
class ContinuumCheck:
    """A design in a sheet: ``cell_mm`` (3,) one cell's extent [mm]; ``thickness`` [mm];
    ``cells_through`` (thickness over cell height); ``bulk`` and ``plate``: printed over
    continuum the map expects; ``holds``: "bulk", "plate" or "none" (the first within
    :data:`HOLDS`); ``extrapolated``: n outside the map's range."""

    cell_mm: tuple[float, float, float]
    thickness: float
    cells_through: float
    bulk: float
    plate: float
    holds: str
    extrapolated: bool

    def message(self) -> str:
        head = (f"a {self.thickness:g} mm sheet of cells {' x '.join(f'{c:.1f}' for c in self.cell_mm)} mm holds "
                f"{self.cells_through:.2f} cell heights through its thickness: the scale map expects the printed "
                f"sheet at {self.bulk:.2f} x the bulk continuum's stiffness and {self.plate:.2f} x the plate's")
        tail = {"bulk": f"the bulk continuum holds within {HOLDS:.0%}",
                "plate": f"only the plate (sheet-scale) continuum holds within {HOLDS:.0%} "
                         "([material] source = \"plate\" or \"auto\")",
                "none": f"no continuum holds within {HOLDS:.0%}: only a model of the printed walls predicts this sheet "
                        f"(the bulk continuum needs {cells_needed('bulk'):.2g} cell heights through it, the plate "
                        f"{cells_needed('plate'):.2g})"}[self.holds]
        far = (f" (outside the map's {MAP_RANGE[0]:.2g} to {MAP_RANGE[1]:.2g} cell heights: extrapolated)"
               if self.extrapolated else "")
        return f"{head}{far}; {tail}"

    def to_dict(self) -> dict:
        return {**{k: getattr(self, k) for k in ("thickness", "cells_through", "bulk", "plate", "holds",
                                                    "extrapolated")},
                "cell_mm": list(self.cell_mm), "message": self.message(), "source": "docs/continuum-map.md"}


def check_cells(cell_mm, thickness: float) -> ContinuumCheck:
    """The verdict for cells of extent ``cell_mm`` (3,) [mm] (z through the sheet) in a sheet
    ``thickness`` [mm] thick."""
    check_range("thickness", thickness, 0.0, None, lo_open=True)
    c = np.asarray(cell_mm, float)
    n = float(thickness) / float(c[2])
    bulk, plate = expected_ratio("bulk", n), expected_ratio("plate", n)
    ok = lambda r: abs(math.log(r)) <= math.log1p(HOLDS)  # noqa: E731
    holds = "bulk" if ok(bulk) else "plate" if ok(plate) else "none"
    return ContinuumCheck(tuple(c.tolist()), float(thickness), n, bulk, plate, holds,
                          not MAP_RANGE[0] <= n <= MAP_RANGE[1])


def check_design(design, thickness: float) -> ContinuumCheck:
    """:func:`check_cells` for a :class:`~metasheet.cells.polyfoam.PolyfoamDesign` (its cell's
    extent estimated in about a second, :func:`metasheet.cells.polyfoam.cell_extent`)."""
    from ..cells.polyfoam import cell_extent

    return check_cells(cell_extent(design), thickness)
