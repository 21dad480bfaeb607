"""Stage ``material``: the sheet's constitutive constants, validated, as ``material.json``.

The constants come from the ``homogenize`` stage when it is in the pipeline (and
``source`` is "auto" or "homogenize"), otherwise from this table. Only the five
independent constants are taken; nu_lt = nu_tl E_l / E_t is derived, so the
compliance is symmetric by construction (the authors' published set lists
nu_tl alone and is used here the same way).
"""

from __future__ import annotations

import json
from typing import Literal

from pydantic import Field

from ...errors import ConfigError
from ...material import Isotropic, TransverseIsotropic
from ..manifest import write_json_atomic
from ..registry import Params, Stage, StageContext, register

#: The paper's foam ("paramPaper" in the authors' code, kPa converted to MPa).
PAPER = {"E_t": 1.39, "E_l": 0.09422, "nu_t": 0.26162, "nu_tl": 0.4161, "mu_l": 0.01628215}


class MaterialParams(Params):
    source: Literal["auto", "config", "homogenize"] = Field(
        "auto", description="'auto': homogenize's constants if that stage runs, else this table"
    )
    kind: Literal["transverse", "isotropic"] = Field("transverse", description="which constants below apply")
    E_t: float = Field(PAPER["E_t"], gt=0, description="transverse Young's modulus [MPa]")
    E_l: float = Field(PAPER["E_l"], gt=0, description="longitudinal Young's modulus [MPa]")
    nu_t: float = Field(PAPER["nu_t"], gt=-1, lt=1, description="transverse Poisson ratio [-]")
    nu_tl: float = Field(PAPER["nu_tl"], description="transverse-longitudinal Poisson ratio [-]")
    mu_l: float = Field(PAPER["mu_l"], gt=0, description="longitudinal shear modulus [MPa]")
    E: float = Field(0.25, gt=0, description="isotropic Young's modulus [MPa] (kind = 'isotropic')")
    nu: float = Field(0.45, gt=-1, lt=0.5, description="isotropic Poisson ratio [-] (kind = 'isotropic')")
    density: float = Field(1.19e-9 * 0.15, gt=0, description="mass density of the sheet [t/mm^3]")


def material_from_params(p: MaterialParams) -> TransverseIsotropic:
    """The material the table describes (isotropic ones as degenerate transverse-isotropic)."""
    if p.kind == "isotropic":
        return Isotropic(p.E, p.nu).as_transverse()
    return TransverseIsotropic(p.E_t, p.E_l, p.nu_t, p.nu_tl, p.mu_l)


def run(ctx: StageContext) -> dict:
    p: MaterialParams = ctx.params
    if p.source == "homogenize" and "homogenize" not in ctx.inputs:
        raise ConfigError("material.source: 'homogenize': the homogenize stage is not in this pipeline")
    if p.source != "config" and "homogenize" in ctx.inputs:
        data = json.loads((ctx.inputs["homogenize"] / "constants.json").read_text())
        m = TransverseIsotropic(*(float(data[k]) for k in ("E_t", "E_l", "nu_t", "nu_tl", "mu_l")))
        origin = "homogenize"
    else:
        m = material_from_params(p)
        origin = "config"
    out = {
        "source": origin,
        "constants": m.to_dict(),
        "units": {"E_t": "MPa", "E_l": "MPa", "nu_t": "-", "nu_tl": "-", "mu_l": "MPa", "density": "t/mm^3"},
        "nu_lt": m.nu_lt,
        "alpha_percent": m.alpha,
        "density": p.density,
        "voigt_order": ["11", "22", "33", "23", "13", "12"],
        "longitudinal_axis": "local 3",
        "stiffness": m.stiffness(),
        "compliance": m.compliance(),
    }
    write_json_atomic(ctx.path("material.json"), out)
    return {"source": origin, **m.to_dict(), "alpha_percent": round(m.alpha, 3)}


register(
    Stage(
        name="material",
        params=MaterialParams,
        run=run,
        optional=("homogenize",),
        outputs=("material.json",),
        doc="constitutive constants (given, or from homogenize) -> material.json",
    )
)
