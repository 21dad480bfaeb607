"""A printed sheet cut from a periodic foam: slabs of the cell through the sheet's thickness,
each homogenised as a plate (:mod:`.plate`), against the bulk continuum of the same foam.

IceSL fills a sheet with its foam and cuts it at the sheet's faces (no shells, no cover on
the paper's foam brush, ``shared/reference/ICESL.md``), so a sheet of thickness t is a slab
of the periodic foam, periodic in plane, at an offset through the cell's height that the
print does not control. The slabs at ``slabs`` evenly spaced offsets are the realisations:
their ABD's mean with its 95 % interval (Student t over the slabs,
:func:`metasheet.homogenize.ensemble.constant_stats`), and their ratio to the bulk plate
``A = Q t, D = Q t^3 / 12`` of the cell's bulk stiffness (:func:`.plate.bulk_plate`): how far
the continuum the robot's sheets use is from a sheet of this foam.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from .ensemble import constant_stats, stats_to_json
from .plate import PLATE_STRAINS, PlateStiffness, bulk_plate, homogenize_plate
from .plate_shear import SHEAR_STRAINS, bulk_shear

#: Diagonal entries of ABD compared with the bulk plate: A_11, A_22, A_66, D_11, D_22, D_66.
DIAGONAL = ("A_11", "A_22", "A_66", "D_11", "D_22", "D_66")
#: Diagonal entries of the transverse-shear stiffness H compared with the bulk sheet's 5/6 G t.
SHEAR_DIAGONAL = ("H_xz", "H_yz")


@dataclass(frozen=True)
class SlabStudy:
    """Slabs of one periodic cell as sheets of one thickness.

    Attributes
    ----------
    thickness : the slabs' thickness [mm] (a whole number of voxel layers).
    offsets_mm : (k,) where each slab starts in the cell's height [mm].
    plates : the k slabs' :class:`~.plate.PlateStiffness`.
    bulk : (6, 6) the bulk plate's ABD (:func:`~.plate.bulk_plate`) of the given bulk C.
    bulk_H : (2, 2) the bulk sheet's transverse shear 5/6 G t (:func:`~.plate_shear.bulk_shear`).
    """

    thickness: float
    offsets_mm: tuple[float, ...]
    plates: tuple[PlateStiffness, ...]
    bulk: np.ndarray
    bulk_H: np.ndarray

    def ratios(self) -> np.ndarray:
        """(k, 6) each slab's :data:`DIAGONAL` entries over the bulk plate's."""
        diag = np.array([np.diag(p.ABD) for p in self.plates])
        return diag / np.diag(self.bulk)[None, :]

    def to_dict(self) -> dict:
        """JSON-ready: the ABD's statistics over the slabs, the ratios to the bulk plate (each
        entry's and their geometric mean, per slab and as statistics), and each slab."""
        abd = constant_stats("ABD", np.array([p.ABD for p in self.plates]))
        r = self.ratios()
        gm = np.exp(np.log(r).mean(axis=1))
        ratio_stats = {n: stats_to_json(constant_stats(n, r[:, i])) for i, n in enumerate(DIAGONAL)}
        return {"thickness_mm": self.thickness, "strains": list(PLATE_STRAINS), "offsets_mm": list(self.offsets_mm),
                "ABD": stats_to_json(abd), "bulk_ABD": self.bulk.tolist(),
                "ratio_to_bulk": {**ratio_stats, "geometric_mean": stats_to_json(constant_stats("geometric_mean", gm))},
                **self._shear_dict(),
                "slabs": [{"offset_mm": o, **p.to_dict(), "ratio_to_bulk": dict(zip(DIAGONAL, row.tolist()))}
                          for o, p, row in zip(self.offsets_mm, self.plates, r)]}

    def _shear_dict(self) -> dict:
        """``{"shear": ...}``: H's statistics over the slabs and each diagonal entry's ratio to the
        bulk sheet's (none when the slabs were homogenised without it)."""
        if any(p.shear is None for p in self.plates):
            return {}
        H = np.array([p.shear.H for p in self.plates])
        r = np.diagonal(H, axis1=1, axis2=2) / np.diag(self.bulk_H)[None, :]
        share = np.array([p.shear.kirchhoff_share for p in self.plates])
        return {"shear": {"strains": list(SHEAR_STRAINS), "H": stats_to_json(constant_stats("H", H)),
                          "bulk_H": self.bulk_H.tolist(), "kirchhoff_share_max": share.max(axis=0).tolist(),
                          "normalisation_spread_max": max(p.shear.normalisation_spread for p in self.plates),
                          "ratio_to_bulk": {n: stats_to_json(constant_stats(n, r[:, i]))
                                            for i, n in enumerate(SHEAR_DIAGONAL)},
                          "slab_ratios": r.tolist()}}


def cut_slab(phases: np.ndarray, size, thickness: float, offset_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """The slab of a periodic cell ``phases`` (nx, ny, nz) of box ``size`` (3,) [mm] that starts
    at height ``offset_mm`` and is ``thickness`` [mm] thick (rounded to whole voxel layers, at
    least 2), wrapping around the cell's height: (slab phases (nx, ny, nt), slab size (3,) [mm])."""
    ph = np.asarray(phases)
    s = np.asarray(size, float)
    hz = s[2] / ph.shape[2]
    nt = int(round(float(thickness) / hz))
    if not (np.isfinite(thickness) and nt >= 2):
        raise ConfigError(f"plate_thickness: {thickness!r} mm: allowed range is [{2 * hz:.3g}, inf) mm "
                          f"(at least two voxel layers of {hz:.3g} mm)")
    k0 = int(round(float(offset_mm) / hz)) % ph.shape[2]
    return np.take(ph, np.arange(k0, k0 + nt), axis=2, mode="wrap"), np.array([s[0], s[1], nt * hz])


def slab_study(phases, size, materials: dict, thickness: float, bulk_C, *, slabs: int = 8, solver: str = "auto",
               rtol: float = 1e-10, shear: bool = False,
               progress: Callable[[int, int], None] | None = None) -> SlabStudy:
    """Homogenise ``slabs`` slabs of the cell (evenly spaced offsets through its height) as
    plates of ``thickness`` [mm] and compare them with the bulk plate of ``bulk_C`` (6, 6) [MPa];
    with ``shear``, their transverse-shear stiffness too (:mod:`.plate_shear`).

    Raises ConfigError (bad input, naming the field), InfeasibleError (a slab falls apart in
    plane: the foam's cells are too tall for this thickness to hold the sheet together)."""
    if not isinstance(slabs, (int, np.integer)) or not 2 <= int(slabs) <= 256:
        raise ConfigError(f"plate_slabs: {slabs!r}: allowed range is [2, 256] (the slabs are the realisations)")
    C = np.asarray(bulk_C, float)
    if C.shape != (6, 6) or not np.all(np.isfinite(C)):
        raise ConfigError(f"bulk_C: shape {C.shape}: expected a finite (6, 6) stiffness [MPa]")
    height = float(np.asarray(size, float)[2])
    offsets, plates = [], []
    for i in range(int(slabs)):
        slab, box = cut_slab(phases, size, thickness, i * height / int(slabs))
        plates.append(homogenize_plate(slab, box, materials, solver=solver, rtol=rtol, shear=shear))
        offsets.append(round(i * height / int(slabs), 6))
        if progress is not None:
            progress(i + 1, int(slabs))
    t = float(box[2])
    return SlabStudy(t, tuple(offsets), tuple(plates), bulk_plate(C, t), bulk_shear(C, t))
