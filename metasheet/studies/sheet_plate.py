"""Does the sheet-scale (plate) continuum close the gap to the printed sheet? (issue 63)

The homogenize stage's ``plate.json`` (slabs of the foam cut at the sheet's faces,
:mod:`metasheet.homogenize.plate_slabs`) gives the sheet's membrane and bending moduli. Each
becomes transverse-isotropic constants (:func:`metasheet.homogenize.plate.equivalent_constants`),
the robot's sheets are condensed on their grips with them (each element's constants scaled by
the equivalent's ratio to the bulk's: exactly the equivalent for an ungraded sheet), and the
printed sheets' DNS is compared with them as with the bulk continuum
(:func:`metasheet.sheet.dns.compare`, the rest model's rod roll): printed over model, 1 when the
model is the print.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..errors import ConfigError
from ..homogenize.plate import abd_moduli, equivalent_constants
from ..mechanics.material import TransverseIsotropic
from ..robot.builder import SheetPair, element_stiffness
from ..robot.condensed import rest_numbers_condensed
from ..sheet.dns import DnsSheet, compare
from ..sheet.grips import fem_condensed, grip_references
from .sheet_dns import _spread

#: The plate's moduli a variant takes: its stretching or its bending.
VARIANTS = ("membrane", "bending")
#: How far the plate's thickness may be from the sheets' [-] (a voxel layer of the cell).
THICKNESS_TOL = 0.1


def scaled_constants(constants: np.ndarray, bulk: TransverseIsotropic, equivalent: TransverseIsotropic) -> np.ndarray:
    """(m, 5) per-element constants with each column times equivalent / bulk."""
    return np.asarray(constants, float) * (np.array(equivalent.as_tuple()) / np.array(bulk.as_tuple()))[None, :]


def plate_comparison(pair: SheetPair, model: str, bulk: TransverseIsotropic, plate: dict,
                     sheets: Sequence[tuple[DnsSheet, DnsSheet]], dns_roll: Sequence[float], robot, params, *,
                     length_scale: float) -> dict:
    """``sheet_dns.json``'s ``plate`` block: per variant the equivalent constants, the plate
    continuum's rest numbers and the printed sheets' ratios to it (per realisation and spread).

    pair, model : the robot's sheets and material model; bulk : the constants the sheets were
    built with (the material stage's); plate : ``plate.json``; sheets : (normal, mirrored) DNS
    per realisation; dns_roll : their rest model's rod roll per motor degree.
    """
    t = float(plate["thickness_mm"])
    if abs(t - float(params.thickness)) > THICKNESS_TOL * float(params.thickness):
        raise ConfigError(f"homogenize plate_thickness: {t:.3g} mm, the sheets are {float(params.thickness):.3g} mm "
                          f"thick: set plate_thickness to the sheets' thickness (within {THICKNESS_TOL:.0%})")
    moduli = abd_moduli(np.asarray(plate["ABD"]["mean"]), t)
    refs = grip_references(params)
    out = {"thickness_mm": t, "source": "homogenize/plate.json (mean ABD over its slabs)"}
    for variant in VARIANTS:
        eq = equivalent_constants(moduli[variant], bulk)
        Ks = [fem_condensed(mesh, element_stiffness(fib, scaled_constants(con, bulk, eq), model), pair.element).K
              for mesh, fib, con in ((pair.sheet, pair.fibers, pair.constants),
                                     (pair.mirrored, pair.fibers_mirrored, pair.constants_mirrored))]
        rest = rest_numbers_condensed(Ks[0], Ks[1], robot, refs, length_scale=length_scale)
        rows = []
        for (a, b), roll in zip(sheets, dns_roll):
            ca, cb = compare(a.K, Ks[0], params), compare(b.K, Ks[1], params)
            rows.append({"geometric_mean_ratio_normal": ca["geometric_mean_ratio"],
                         "geometric_mean_ratio_mirrored": cb["geometric_mean_ratio"],
                         "log_ratio_rms_normal": ca["log_ratio_rms"], "log_ratio_rms_mirrored": cb["log_ratio_rms"],
                         "rod_roll_ratio": roll / rest["rod_rotation_deg_per_deg"]})
        out[variant] = {"constants": eq.to_dict(), "nu_t_kept": eq.nu_t == bulk.nu_t, "robot": rest, "realisations": rows,
                        "spread": {k: _spread([r[k] for r in rows]) for k in rows[0]}}
    return out

