"""Stage ``material``: the sheet's constitutive constants, validated, as ``material.json``.

The constants come from the ``homogenize`` stage when it is in the pipeline (and
``source`` is "auto" or "homogenize"), otherwise from this table. Only the five
independent constants are taken; nu_lt = nu_tl E_l / E_t is derived, so the
compliance is symmetric by construction (the authors' published set lists
nu_tl alone and is used here the same way).

``model`` chooses how the robot turns the constants into a tensor (everywhere: robot stage,
studies, ``metasheet robot goto``): "ours" uses all five; "authors" is the authors' SOFA force
field, whose longitudinal shear is E_t / (2 (1 + nu_t)) whatever mu_l, and whose c13 differs
(:mod:`metasheet.mechanics.material_model`). ``material.json`` records it with the tensor it gives.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Literal

import numpy as np

from pydantic import Field, model_validator

from ...published import paper
from ...errors import ConfigError
from ...mechanics.material import Isotropic, TransverseIsotropic
from ...mechanics.material_model import model_stiffness
from ..artefacts import constants_material, read_constants, write_material
from ..bounds import MASS_DENSITY, MODULUS
from ..registry import Params, Stage, StageContext, register

_FOAM = paper.PAPER_FOAM


class MaterialParams(Params):
    source: Literal["auto", "config", "homogenize", "sheet", "plate"] = Field(
        "auto", description="'auto': homogenize's constants if that stage runs (its plate's when homogenize wrote "
        "plate.json and the bulk is not within 10 % of that sheet), else this table; 'sheet': the "
        "apparent constants of the printed sheet (sheet_file); 'plate': the sheet cut from the foam "
        "(homogenize's plate.json, plate_variant)"
    )
    plate_variant: Literal["membrane", "bending"] = Field(
        "membrane", description="source = 'plate': the constants of the sheet's stretching or of its bending")
    sheet_file: str | None = Field(None, description="source = 'sheet': a sheet stage's sheet_dns.json (relative to "
                                   "the project root), whose apparent constants (mean over its realisations) are used")
    kind: Literal["transverse", "isotropic"] = Field("transverse", description="which constants below apply")
    E_t: float = Field(_FOAM.E_t, **MODULUS, description="transverse Young's modulus [MPa]")
    E_l: float = Field(_FOAM.E_l, **MODULUS, description="longitudinal Young's modulus [MPa]")
    nu_t: float = Field(_FOAM.nu_t, gt=-1, lt=1, description="transverse Poisson ratio [-]")
    nu_tl: float = Field(_FOAM.nu_tl, description="transverse-longitudinal Poisson ratio [-]; with the others "
                         "|nu_tl| < sqrt((1 - nu_t) E_t / (2 E_l)) (positive-definite stiffness)")
    mu_l: float = Field(_FOAM.mu_l, **MODULUS, description="longitudinal shear modulus [MPa]")
    E: float = Field(paper.SILICONE.E, **MODULUS, description="isotropic Young's modulus [MPa] (kind = 'isotropic')")
    nu: float = Field(paper.SILICONE.nu, gt=-1, lt=0.5, description="isotropic Poisson ratio [-] (kind = 'isotropic')")
    density: float = Field(paper.FOAM_DENSITY, **MASS_DENSITY, description="mass density of the sheet [t/mm^3]")
    model: Literal["ours", "authors"] = Field(
        "ours", description="'ours': the tensor of all five constants; 'authors': the authors' SOFA force field's "
        "(longitudinal shear E_t / (2 (1 + nu_t)), mu_l unused; c13 as their code)")

    @model_validator(mode="after")
    def _stable(self):
        if (self.source == "sheet") != (self.sheet_file is not None):
            raise ConfigError(f"sheet_file: {self.sheet_file!r}: give it with source = 'sheet' (and only then)")
        if self.kind == "transverse":
            m = check_constants(self)
            if self.source == "config" and self.model == "authors":  # the constants this table gives are used
                try:
                    model_stiffness(m, "authors")
                except ConfigError as err:
                    raise ConfigError(f"model: 'authors': {str(err).split(': ', 2)[-1]}") from None
        return self


def check_constants(p) -> TransverseIsotropic:
    """The material of the five constants ``p.E_t, E_l, nu_t, nu_tl, mu_l`` (each already in its
    field's range), or :class:`ConfigError` ``nu_tl: value: allowed range is (-b, b)`` when they
    give no positive-definite stiffness (1 - nu_t - 2 nu_tl^2 E_l / E_t > 0: only nu_tl's range
    depends on the others; :class:`~metasheet.mechanics.material.TransverseIsotropic` checks it)."""
    try:
        return TransverseIsotropic(p.E_t, p.E_l, p.nu_t, p.nu_tl, p.mu_l)
    except ConfigError:
        b = ((1.0 - p.nu_t) * p.E_t / (2.0 * p.E_l)) ** 0.5
        raise ConfigError(f"nu_tl: {p.nu_tl!r}: allowed range is (-{b:.6g}, {b:.6g}) for E_t = {p.E_t:g}, "
                          f"E_l = {p.E_l:g}, nu_t = {p.nu_t:g} (positive-definite stiffness: "
                          "1 - nu_t - 2 nu_tl^2 E_l / E_t > 0)") from None


def material_from_params(p: MaterialParams) -> TransverseIsotropic:
    """The material the table describes (isotropic ones as degenerate transverse-isotropic)."""
    if p.kind == "isotropic":
        return Isotropic(p.E, p.nu).as_transverse()
    return TransverseIsotropic(p.E_t, p.E_l, p.nu_t, p.nu_tl, p.mu_l)


def sheet_material(root, p: MaterialParams) -> TransverseIsotropic:
    """The apparent constants of ``p.sheet_file`` (a sheet stage's sheet_dns.json: their mean
    over its realisations), fitted under the same material model as ``p.model``."""
    import json
    from pathlib import Path

    path = Path(root) / p.sheet_file
    if not path.is_file():
        raise ConfigError(f"material.sheet_file: {p.sheet_file!r}: no such file under {root} (run a pipeline "
                          "with the sheet stage first)")
    data = json.loads(path.read_text())
    app = data.get("spread", {}).get("apparent")
    if not app:
        raise ConfigError(f"material.sheet_file: {p.sheet_file!r}: no apparent constants (run the sheet stage "
                          "with fit = true)")
    fitted = data.get("material", {}).get("model")
    if fitted != p.model:
        raise ConfigError(f"material.model: {p.model!r}: the apparent constants of {p.sheet_file!r} were fitted "
                          f"under {fitted!r}; use that model")
    return TransverseIsotropic.from_mapping({k: v["mean"] for k, v in app.items()},
                                            where=f"{p.sheet_file}: spread.apparent means")


#: ``source = "auto"`` keeps the bulk continuum when every diagonal stiffness of the sheet cut from
#: the foam (plate.json's mean ratios to the bulk plate) is within this fraction of the bulk's.
AUTO_PLATE_TOLERANCE = 0.10


def auto_choice(plate: dict | None, check=None) -> dict:
    """``{"source": "homogenize" | "plate", "why": ...}``: what ``source = "auto"`` takes when the
    homogenize stage runs, from its ``plate.json`` (None: it wrote none) and, for a Polyfoam cell,
    the scale map's verdict on it in a sheet of the plate's thickness (``check``, a
    :class:`~metasheet.studies.continuum_check.ContinuumCheck`): the bulk constants where the
    map expects them within :data:`AUTO_PLATE_TOLERANCE` of the prints, else the plate's
    membrane moduli. Without the map's verdict, the plate's own: every mean diagonal stiffness of
    the sheet cut from the foam within that tolerance of the bulk plate's."""
    tol = AUTO_PLATE_TOLERANCE
    if check is not None:
        n, b = check.cells_through, check.bulk
        seen = (f"the scale map expects a {check.thickness:.3g} mm sheet of this foam ({n:.2f} cell heights through "
                f"it) at {b:.2f} x the bulk continuum's stiffness")
        if abs(np.log(b)) <= np.log1p(tol):
            return {"source": "homogenize", "why": f"the bulk constants: {seen}, within {tol:.0%} (docs/continuum-map.md)"}
        if plate is None:
            return {"source": "homogenize", "why": f"the bulk constants, though {seen}: set [homogenize] "
                    "plate_thickness to the sheets' thickness for the plate model (docs/continuum-map.md)"}
        holds = ("within 25 % of the prints" if check.holds == "plate" else
                 "yet no continuum holds within 25 %: only a model of the printed walls predicts this sheet")
        return {"source": "plate", "why": f"the plate's membrane moduli: {seen}, and at {check.plate:.2f} x the "
                f"plate's, {holds} (docs/continuum-map.md)"}
    if plate is None:
        return {"source": "homogenize", "why": "the bulk constants: the homogenize stage wrote no plate.json "
                "([homogenize] plate_thickness unset), so the sheet cut from the foam was not compared"}
    ratios = {k: float(v["mean"]) for k, v in plate["ratio_to_bulk"].items() if k != "geometric_mean"}
    worst = max(ratios, key=lambda k: abs(np.log(ratios[k])))
    r, t = ratios[worst], float(plate["thickness_mm"])
    if abs(np.log(r)) <= np.log1p(tol):
        return {"source": "homogenize", "why": f"the bulk constants: a {t:.3g} mm sheet cut from the foam is within "
                f"{tol:.0%} of the bulk continuum in every stiffness (furthest: {worst} x{r:.3g})"}
    return {"source": "plate", "why": f"the plate's membrane moduli: a {t:.3g} mm sheet cut from the foam differs from "
            f"the bulk continuum by more than {tol:.0%} ({worst} x{r:.3g}); the sheets on the robot's "
            "grips are loaded mostly in their plane (docs/plate.md)"}


def map_check(cell_dir, plate: dict | None):
    """The scale map's verdict on the cell stage's Polyfoam in a sheet of the plate's thickness, or
    None (no cell stage, another kind of cell, or no plate.json: no thickness to judge)."""
    if cell_dir is None or plate is None:
        return None
    from ...cells.catalogue import parse_design
    from ...cells.polyfoam import PolyfoamDesign
    from ...studies.continuum_check import check_design
    from ..artefacts import read_cell_design

    design = parse_design(read_cell_design(cell_dir), source="cell.json design")
    return check_design(design, float(plate["thickness_mm"])) if isinstance(design, PolyfoamDesign) else None


def plate_material(homogenize, variant: str) -> TransverseIsotropic:
    """The equivalent constants of the sheet cut from the foam (homogenize's ``plate.json``, its
    mean ABD's ``variant`` moduli: :func:`metasheet.homogenize.plate.equivalent_constants`)."""
    from ...homogenize.plate import abd_moduli, equivalent_constants

    path = Path(homogenize) / "plate.json"
    if not path.exists():
        raise ConfigError("material.source: 'plate': the homogenize stage wrote no plate.json: set "
                          "[homogenize] plate_thickness to the sheets' thickness [mm]")
    plate = json.loads(path.read_text())
    moduli = abd_moduli(plate["ABD"]["mean"], plate["thickness_mm"])[variant]
    return equivalent_constants(moduli, constants_material(homogenize))


def run(ctx: StageContext) -> dict:
    p: MaterialParams = ctx.params
    if p.source in ("homogenize", "plate") and "homogenize" not in ctx.inputs:
        raise ConfigError(f"material.source: {p.source!r}: the homogenize stage is not in this pipeline")
    ci95 = choice = None
    if p.source == "auto" and "homogenize" in ctx.inputs:
        plate_file = ctx.inputs["homogenize"] / "plate.json"
        plate = json.loads(plate_file.read_text()) if plate_file.exists() else None
        choice = auto_choice(plate, map_check(ctx.inputs.get("cell"), plate))
    if p.source == "plate" or (choice and choice["source"] == "plate"):
        variant = p.plate_variant if p.source == "plate" else "membrane"
        m, origin = plate_material(ctx.inputs["homogenize"], variant), f"plate ({variant})"
    elif p.source == "sheet":
        m, origin = sheet_material(ctx.root, p), "sheet"
    elif p.source != "config" and "homogenize" in ctx.inputs:
        m, origin = constants_material(ctx.inputs["homogenize"]), "homogenize"
        block = read_constants(ctx.inputs["homogenize"]).get("ci95")
        if block:  # the constants are means over realisations: their uncertainty travels with them
            ci95 = {k: block[k] for k in ("confidence", "k", "n_cells", "halfwidth", "rel_halfwidth")}
    else:
        m, origin = material_from_params(p), "config"
    write_material(ctx.path("material.json"), m, density=p.density, source=origin, model=p.model, ci95=ci95,
                   choice=choice)
    return {"source": origin, "model": p.model, **m.to_dict(), "alpha_percent": round(m.alpha, 3),
            **({"why": choice["why"]} if choice else {})}


register(
    Stage(
        name="material",
        params=MaterialParams,
        run=run,
        optional=("homogenize", "cell"),
        # given constants (or a sheet's file) do not wait for a homogenisation they do not read; auto reads
        # the cell for the scale map's verdict on it
        reads=lambda p: (() if p.source in ("config", "sheet") else ("homogenize", "cell") if p.source == "auto"
                         else ("homogenize",)),
        outputs=("material.json",),
        doc="constitutive constants (given, or from homogenize) -> material.json",
    )
)
