"""Stage ``orient``: the tripod sheet, its spiral fibre field and per-element constants.

Writes ``sheet.vtu`` (the normal sheet) and ``sheet_mirrored.vtu`` (its reflection
y -> -y, for the second tripod), each with cell data ``fiber`` (m, 3) (local axis 3 of
the transverse-isotropic material, the foam's soft direction), ``material_id`` (m,),
``density`` (m,) [-], ``alpha`` (m,) [%] and the constants ``E_t, E_l, nu_t, nu_tl, mu_l``
(m,) [MPa], and point data ``attach`` (n,) (0 free, k + 1 tip box of arm k, 4 centre);
``sheet.json`` (geometry, arm angles, fibre law, counts, mesh quality, material, and
``scene``: the scene preset, :mod:`metasheet.robot.scenes`, whose numbers the robot and
study stages take: rod, servos, sheet mass, gravity) and
``sheet.png`` (fibre streaks of both sheets side by side, like the paper's Fig. 3).

``fibre_field`` (optional) adds a free-form correction to the spiral: sheet A's fibre angle is
``theta = theta_spiral + sum_j c_j N_j(x)`` on a polar B-spline
(:mod:`metasheet.sheet.fibre_field`), sheet B's its mirror ``-theta``, computed by the
functions the design stage evaluates a design with, so the design stage's ``chosen.toml``
builds the chosen design's sheets with the bytes its evaluation had. ``sheet.json``'s
``fibers`` then records it as ``fibre_field``.
"""

from __future__ import annotations

import logging
from dataclasses import replace
from typing import Annotated, Literal

import numpy as np
from pydantic import Field, model_validator

from ...published import paper
from ...errors import ConfigError
from ...mechanics.material import TransverseIsotropic, interpolate
from ...robot.scenes import PRESETS, get_preset
from ...sheet import fibers as fb
from ...sheet import geometry as geo
from ...sheet import grading as gr
from ..artefacts import SHEET_FILES, read_cell_design, read_material, read_print_model, write_sheet
from ..manifest import write_json_atomic
from ..bounds import MODULUS
from ..registry import Params, Stage, StageContext, register
from .material import check_constants

log = logging.getLogger(__name__)

_FOAM = paper.PAPER_FOAM


class ConstantsParams(Params):
    """Fallback constants when the material stage is not in the pipeline (paper's foam)."""

    E_t: float = Field(_FOAM.E_t, **MODULUS, description="transverse Young's modulus [MPa]")
    E_l: float = Field(_FOAM.E_l, **MODULUS, description="longitudinal Young's modulus [MPa]")
    nu_t: float = Field(_FOAM.nu_t, gt=-1, lt=1, description="transverse Poisson ratio [-]")
    nu_tl: float = Field(_FOAM.nu_tl, gt=-1, lt=2, description="transverse-longitudinal Poisson ratio [-]")
    mu_l: float = Field(_FOAM.mu_l, **MODULUS, description="longitudinal shear modulus [MPa]")

    @model_validator(mode="after")
    def _stable(self):
        check_constants(self)
        return self


class GradingParams(Params):
    """A graded design; empty means uniform (see ``metasheet.sheet.grading``)."""

    table: dict[Literal["hub", "arms", "tips"], dict[Literal["density", "alpha"], float]] = Field(
        default_factory=dict, description="per-region overrides: density [-], alpha [%]"
    )
    density_expr: str | None = Field(None, description="relative density as an expression of x, y, z, r [mm], t [rad]")
    alpha_expr: str | None = Field(None, description="anisotropy alpha [%] as an expression of x, y, z, r, t")


_SCENE = " None: the scene's"


class FibreFieldParams(Params):
    """``[orient] fibre_field``: a free-form correction of the spiral's fibre angle,
    ``theta = theta_spiral + sum_j c_j N_j(x)`` on sheet A (sheet B: the mirror), the basis
    :class:`metasheet.sheet.fibre_field.PolarBSpline`; the design stage writes it into
    ``design/chosen.toml``."""

    basis: Literal["polar_bspline"] = Field("polar_bspline", description="the basis: a tensor B-spline in "
                                            "polar coordinates (r, phi) about the sheet's centre")
    n_radial: int = Field(4, ge=2, le=32, description="B-spline functions along r (>= degree + 1)")
    n_angular: int = Field(12, ge=2, le=96, description="B-spline functions around (>= degree + 1; a multiple "
                           "of 3 when symmetric)")
    degree: int = Field(3, ge=1, le=5, description="B-spline degree in r and phi")
    r_max: float | None = Field(None, gt=0, le=1e4, description="[mm] the basis' outer radius; None: the "
                                "sheet's (the largest centre distance of its mesh points, as the design stage)")
    symmetric: bool = Field(False, description="coefficients tied to the sheet's 120 deg symmetry")
    # a turn by pi is the same fibre axis: larger increments add nothing but round-off
    coefficients: list[Annotated[float, Field(ge=-np.pi, le=np.pi)]] = Field(
        ..., description="c [rad], c[i * n_phi + j] on radial function i and angular function j (n_phi = "
        "n_angular, or n_angular / 3 when symmetric): n_radial * n_phi values")

    @model_validator(mode="after")
    def _length(self):
        b = self.spline(1.0)  # the basis' own checks across n_radial, n_angular, degree, symmetric
        n = b.n_coefficients
        if len(self.coefficients) != n:
            how = f"n_radial {self.n_radial} x n_angular {self.n_angular}" + (" / 3, symmetric" if self.symmetric else "")
            raise ConfigError(f"coefficients: {len(self.coefficients)} values: expected {n} ({how}), each in "
                              f"[-pi, pi] [rad]")
        return self

    def spline(self, r_max: float):
        """The :class:`~metasheet.sheet.fibre_field.PolarBSpline`, of outer radius ``self.r_max``
        or else ``r_max`` [mm]."""
        from ...sheet.fibre_field import PolarBSpline

        return PolarBSpline(n_radial=self.n_radial, n_angular=self.n_angular, degree=self.degree,
                            r_max=float(self.r_max if self.r_max is not None else r_max), symmetric=self.symmetric)


class OrientParams(Params):
    scene: Literal[tuple(PRESETS)] = Field(
        "metasheet", description="named scene preset (metasheet/robot/scenes.py): the sheet geometry and fibre "
        "law here, and the rod, servos, sheet mass and gravity of the robot and study stages, which read it "
        "from sheet.json; every key given explicitly overrides its number")
    arm_width: float | None = Field(None, ge=2, le=200, description="arm width [mm];" + _SCENE)
    reach: float | None = Field(None, gt=0, le=1000, description="centre to arm end [mm];" + _SCENE)
    thickness: float | None = Field(None, ge=0.3, le=100, description="sheet thickness [mm];" + _SCENE)
    hole_radius: float | None = Field(None, ge=0, le=90, description="central hole radius [mm];" + _SCENE)
    fillet_radius: float | None = Field(None, ge=0, le=600, description="fillet radius between arms [mm], 0 = "
                                        "sharp;" + _SCENE)
    mesh_size: float = Field(5.0, ge=0.3, le=50, description="target tet edge [mm]; 5 gives ~2,900 tets")
    layers: int = Field(0, ge=0, le=16, description="elements through the thickness; 0: gmsh's free mesh")
    picture: bool = Field(True, description="write sheet.png (the fibre streaks of both sheets: seconds of "
                          "matplotlib, most of a small sheet's stage)")
    grip_size: float = Field(0.0, ge=0, le=50, description="element size at the grip borders (centre circle, "
                             "tip cuts), growing away from them [mm]; 0: uniform")
    element: Literal["p1", "p2"] = Field("p2", description="the robot's element on the sheets: linear "
                                         "or quadratic tetrahedra (sheet.vtu stays linear)")
    tip_box: tuple[float, float, float] | None = Field(
        None, description="arm-tip box (along arm, across, z), centred on the arm end [mm];" + _SCENE
    )
    centre_radius: float | None = Field(None, gt=0, le=1000, description="effector node sphere radius [mm];" + _SCENE)
    law: Literal["log", "archimedean", "circular", "radial"] | None = Field(None, description="fibre law;" + _SCENE)
    pitch_deg: float | None = Field(None, ge=-90, le=90, description="spiral pitch angle beta (fibre to circle) "
                                    "[deg];" + _SCENE)
    sheet_mass_g: float | None = Field(None, gt=0, le=1e4, description="mass of each sheet [g]: the robot's "
                                       "density is mass / sheet volume;" + _SCENE + " (none: the material's density)")
    r_ref: float = Field(33.0, gt=0, le=1000, description="radius where an r-dependent law has pitch_deg [mm]")
    tilt_deg: float = Field(0.0, ge=-90, le=90, description="out-of-plane fibre tilt [deg]")
    fibre_field: FibreFieldParams | None = Field(None, description="free-form correction of the fibre law's "
                                                 "angle (polar B-spline coefficients); None: the law alone")
    isotropic: bool = Field(False, description="isotropic sheet: alpha = 0 (E = E_t, nu = nu_t), iso = 1")
    relative_density: float = Field(paper.FOAM_RELATIVE_DENSITY, gt=0, le=1,
                                    description="the design's relative density [-]")
    rho_exponent: float = Field(2.0, gt=0, le=4, description="modulus ~ rho^n without a chart [-]")
    grading: GradingParams = Field(default_factory=GradingParams, description="graded design")
    constants: ConstantsParams = Field(default_factory=ConstantsParams, description="fallback constants")

    @model_validator(mode="after")
    def _sheet(self):  # the geometry's checks across fields, and its size, before anything is meshed
        check_sheet_size(sheet_params(self), "mesh")
        if self.fibre_field is not None and self.tilt_deg != 0:
            raise ConfigError(f"tilt_deg: {self.tilt_deg!r}: a fibre_field turns fibres in the sheet plane; "
                              "allowed 0 with it")
        return self


_SHEET_KEYS = ("arm_width", "reach", "thickness", "hole_radius", "fillet_radius", "tip_box", "centre_radius")


def _scene_value(p: OrientParams, key: str):
    """``p.key`` when given, else the scene preset's number."""
    v = getattr(p, key)
    return getattr(get_preset(p.scene, key="orient.scene"), key) if v is None else v


def sheet_params(p: OrientParams) -> geo.SheetParams:
    """The sheet geometry: the scene's, each key given in ``p`` overriding it."""
    return geo.SheetParams(mesh_size=p.mesh_size, layers=p.layers, grip_size=p.grip_size,
                           **{k: _scene_value(p, k) for k in _SHEET_KEYS})


#: Most tetrahedra one sheet may mesh to (:func:`metasheet.sheet.geometry.estimated_tets`, within
#: ~1.5x of gmsh's count), for a machine of ~32 GB: "mesh" for the orient stage itself, "p1" / "p2"
#: for a robot built on it (two sheets). Measured peaks (default sheet, one process): gmsh +67 MB
#: for 46k tets (~1.5 KB a tet: 3 GB at 2M); robot P1 413 MB at 12.8k tets a sheet, 1.1 GB at 46k
#: (~18 KB a tet and rising with the factorisation's fill: ~10 GB at 400k); robot P2 2.3 GB at 12.8k
#: (136k unknowns), over 10 GB at 46k and still rising when stopped (~220 KB a tet: over 11 GB at
#: 50k). The paper's finest level (P2, 10 mm, 0.7 mm grips) makes 28k.
MAX_SHEET_TETS = {"mesh": 2_000_000, "p1": 400_000, "p2": 50_000}


def check_sheet_size(sp: geo.SheetParams, use: str, field: str = "mesh_size") -> None:
    """Raise :class:`ConfigError` ``field: value: ...`` when the sheet ``sp`` would mesh to more
    tetrahedra than :data:`MAX_SHEET_TETS` ``[use]`` allows, naming the sizes that set the estimate,
    the estimate, the limit and the finest mesh size this sheet can have."""
    est, limit = geo.estimated_tets(sp), MAX_SHEET_TETS[use]
    if est <= limit:
        return
    what = "to mesh it" if use == "mesh" else f"for a robot of {use} elements"
    h = finest_mesh_size(sp, limit)
    fix = (f"allowed range for this sheet is [{h:g}, 50]" if h else
           "no mesh_size in [0.3, 50] fits: a smaller reach, arm_width or thickness, or a larger grip_size")
    raise ConfigError(
        f"{field}: {sp.mesh_size!r}: the sheet (reach {sp.reach:g}, arm_width {sp.arm_width:g}, thickness "
        f"{sp.thickness:g} mm, grip_size {sp.grip_size:g} mm, layers {sp.layers}) makes about {est:,} tetrahedra, "
        f"over the limit of {limit:,} {what} (about 32 GB of memory); {fix}")


def check_robot_mesh(orient: OrientParams, where: str, element: str | None = None, **changes) -> None:
    """Check the sheet a robot is built on: orient's, re-meshed with ``changes`` (``mesh_size``,
    ``layers``, ``grip_size``) when given, of ``element`` (None: orient's) elements, against
    :data:`MAX_SHEET_TETS`; the :class:`ConfigError` names ``where.field``."""
    try:
        check_sheet_size(replace(sheet_params(orient), **changes), element or orient.element)
    except ConfigError as err:
        raise ConfigError(f"{where}.{err}") from None


def finest_mesh_size(sp: geo.SheetParams, limit: int) -> float | None:
    """The smallest mesh size [mm] in [0.3, 50] whose estimate for ``sp`` is within ``limit``
    (bisection: the estimate falls as the size grows), or None when even 50 mm is over it."""
    def est(h: float) -> int:
        return geo.estimated_tets(replace(sp, mesh_size=h, grip_size=min(sp.grip_size, h)))

    lo, hi = 0.3, 50.0
    if est(hi) > limit:
        return None
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if est(mid) <= limit else (mid, hi)
    step = 10.0 ** (np.floor(np.log10(hi)) - 2)  # 3 digits, rounded up: the size printed passes
    return min(float(f"{np.ceil(hi / step - 1e-9) * step:.3g}"), 50.0)


def fiber_settings(p: OrientParams) -> dict:
    """Keyword arguments of ``spiral_fibers`` (also stored in sheet.json for printmap)."""
    return {"law": _scene_value(p, "law"), "pitch_deg": _scene_value(p, "pitch_deg"), "tilt_deg": p.tilt_deg,
            "r_ref": p.r_ref}


def fibre_field_record(p: OrientParams, r_max: float) -> dict | None:
    """``sheet.json``'s ``fibers.fibre_field``: the basis (its ``r_max`` resolved) and the
    coefficients [rad], as the ``[orient] fibre_field`` key takes them; None without one."""
    if p.fibre_field is None:
        return None
    from ...sheet.fibre_field import basis_record

    return {**basis_record(p.fibre_field.spline(r_max)), "coefficients": list(p.fibre_field.coefficients)}


def sheet_radius(sheet: geo.SheetMesh) -> float:
    """[mm] the largest centre distance of the sheet's mesh points: the default ``r_max`` of a
    fibre field (the design stage's, from the same points)."""
    return float(np.hypot(sheet.points[:, 0], sheet.points[:, 1]).max())


def _fibres(p: OrientParams, normal: geo.SheetMesh, mirrored: geo.SheetMesh, fs: dict):
    """Unit fibres (m, 3) of both sheets and a function ``(points, mirrored) -> fibres`` for the
    picture: the law's spiral, corrected by ``fibre_field`` when given."""
    fib = fb.spiral_fibers(normal.centroids(), mirrored=False, **fs)
    fib_m = fb.spiral_fibers(mirrored.centroids(), mirrored=True, **fs)
    if p.fibre_field is None:
        return fib, fib_m, lambda q, m: fb.spiral_fibers(q, mirrored=m, **fs)
    from ...sheet import fibre_field as ff

    basis, c = p.fibre_field.spline(sheet_radius(normal)), np.asarray(p.fibre_field.coefficients, float)
    fib, fib_m = ff.field_on_sheet(normal.centroids(), fib, basis, c)
    return fib, fib_m, lambda q, m: ff.field_at(q, lambda x: fb.spiral_fibers(x, **fs), basis, c, mirrored=m)


def scene_record(p: OrientParams, volume_mm3: float) -> dict:
    """``sheet.json``'s ``scene``: the preset (numbers and sources), the keys this stage
    overrode, and the sheet mass [g] (or None) with the sheet's volume [mm^3]."""
    preset = get_preset(p.scene, key="orient.scene")
    given = sorted(k for k in (*_SHEET_KEYS, "law", "pitch_deg", "sheet_mass_g") if getattr(p, k) is not None)
    return {**preset.to_dict(), "overridden_by_orient": given, "sheet_mass_g": _scene_value(p, "sheet_mass_g"),
            "sheet_volume_mm3": round(float(volume_mm3), 6)}


def _material(ctx: StageContext) -> tuple[TransverseIsotropic, str]:
    if "material" in ctx.inputs:
        return read_material(ctx.inputs["material"]).material, "material stage"
    c = ctx.params.constants
    return TransverseIsotropic(c.E_t, c.E_l, c.nu_t, c.nu_tl, c.mu_l), "orient.constants"


def _reads(p) -> tuple[str, ...]:
    """The material and the cell (is the foam's cell small enough for a continuum?) always; the
    chart (and the constants it is calibrated on) for a graded design only: a uniform one need
    not wait for the chart."""
    g = p.grading
    graded = g.table or g.density_expr or g.alpha_expr
    return ("material", "chart", "cell", "homogenize") if graded else ("material", "cell")


def continuum(cell_dir, thickness: float) -> dict | None:
    """``sheet.json``'s ``continuum``: the scale map's verdict on the cell stage's Polyfoam in a
    sheet this thick (:mod:`metasheet.studies.continuum_check`), logged as a warning when the bulk
    continuum does not hold; None for other cells or without a cell stage."""
    if cell_dir is None:
        return None
    from ...cells.catalogue import parse_design
    from ...cells.polyfoam import PolyfoamDesign
    from ...studies.continuum_check import check_design

    design = parse_design(read_cell_design(cell_dir), source="cell.json design")
    if not isinstance(design, PolyfoamDesign):
        return None
    chk = check_design(design, thickness)
    if chk.holds != "bulk":
        log.warning("orient: %s", chk.message())
    return chk.to_dict()


def _chart_lookup(ctx: StageContext):
    """The design chart's inverse look-up as (rho [-], alpha [%]) -> TransverseIsotropic, or None.

    Reads ``chart.csv`` of the chart stage through the print model
    (:func:`~metasheet.pipeline.artefacts.read_print_model`), calibrated on the homogenised
    cell when the cell and homogenize stages ran, so the constants given to each element are
    the ones the print map's round trip finds again. A target outside the chart is an error
    (:class:`~metasheet.errors.InfeasibleError`), not a silent fallback.
    """
    if "chart" not in ctx.inputs:
        return None, "no chart stage"
    calibrate = "cell" in ctx.inputs and "homogenize" in ctx.inputs
    model = read_print_model(ctx.inputs["chart"], ctx.inputs.get("cell") if calibrate else None,
                             ctx.inputs.get("homogenize") if calibrate else None)

    def material_at(rho: float, alpha: float) -> TransverseIsotropic:
        settings = model.settings_at_density(rho, alpha)
        c = model.constants_at({k: np.array([v]) for k, v in settings.items()})
        return TransverseIsotropic.from_mapping({k: float(v[0]) for k, v in c.items()})

    how = "design chart (homogenize)" + (", calibrated on the homogenised cell" if calibrate else "")
    return material_at, how


def run(ctx: StageContext) -> dict:
    p: OrientParams = ctx.params
    sp = sheet_params(p)
    ctx.progress("meshing the sheet", 0, 4)
    normal = geo.tripod_sheet(sp)
    mirrored = geo.mirror_sheet(normal)
    material, source = _material(ctx)
    if p.isotropic:
        material = interpolate(material, 0.0) if material.alpha > 0 else material
    ctx.progress("fibres and grading", 1, 4)
    fs = fiber_settings(p)
    fib, fib_m, fibres_at = _fibres(p, normal, mirrored, fs)
    g = p.grading
    grading = gr.grade(
        normal.centroids(), sp, density=p.relative_density, alpha=material.alpha,
        table={k: dict(v) for k, v in g.table.items()} or None,
        density_expr=g.density_expr, alpha_expr=None if p.isotropic else g.alpha_expr,
    )
    if p.isotropic:
        grading = gr.Grading(grading.density, np.zeros_like(grading.alpha), grading.material_id, grading.names)
    graded = bool(g.table or g.density_expr or g.alpha_expr)
    lookup, how = (None, "uniform design: the material itself")
    if graded:
        lookup, how = _chart_lookup(ctx)
        if lookup is not None:
            consts = gr.element_constants(grading, lookup)
        else:
            how = f"scaling (rho/{p.relative_density:g})^{p.rho_exponent:g} + interpolate; {how}"
    if lookup is None:
        base = gr.scaling_lookup(material, p.relative_density, p.rho_exponent)
        consts = gr.element_constants(grading, base)
    ctx.progress("writing meshes", 2, 4)
    common = {"material_id": grading.material_id.astype(np.int32), "density": grading.density,
              "alpha": grading.alpha, **consts}
    write_sheet(ctx.path(SHEET_FILES["normal"]), normal, {"fiber": fib, **common})
    write_sheet(ctx.path(SHEET_FILES["mirrored"]), mirrored, {"fiber": fib_m, **common})
    counts = {str(k): int(np.sum(normal.attach == k)) for k in range(5)}
    field = fibre_field_record(p, sheet_radius(normal))
    info = {
        "geometry": sp.to_dict(),
        "element": p.element,
        "units": {"lengths": "mm", "angles": "deg", "moduli": "MPa"},
        "frame": "centre at origin, mid-plane z = 0, arm k along 120 deg * k from +x",
        "arm_angles_deg": np.degrees(normal.arm_angles).tolist(),
        "attach_tags": {"0": "free", "1": "tip arm 0", "2": "tip arm 1", "3": "tip arm 2", "4": "centre"},
        "attach_counts": counts,
        "n_points": int(len(normal.points)),
        "n_tets": int(len(normal.tets)),
        "quality": normal.quality.to_dict(),
        "quality_mirrored": mirrored.quality.to_dict(),
        "fibers": {**fs, "mirror": "l_m(p) = M l(M p), M = diag(1, -1, 1)", "axis": "local 3 (soft l)",
                   **({"fibre_field": field} if field else {})},
        "scene": scene_record(p, float(np.sum(np.abs(normal.volumes())))),
        "isotropic": p.isotropic,
        "material": {**material.to_dict(), "alpha_percent": material.alpha, "source": source},
        "relative_density": p.relative_density,
        "graded": graded,
        "regions": list(grading.names),
        "constants_source": how,
        "files": dict(SHEET_FILES),
    }
    cont = continuum(ctx.inputs.get("cell"), sp.thickness)
    if cont is not None:
        info["continuum"] = cont
    write_json_atomic(ctx.path("sheet.json"), info)
    if p.picture:
        ctx.progress("picture", 3, 4)
        _picture(ctx, p, sp, fs, normal, mirrored, fibres_at)
    ctx.progress("done", 4, 4)
    return {
        "n_tets": int(len(normal.tets)), "n_points": int(len(normal.points)),
        "worst_aspect": round(normal.quality.worst_aspect, 3),
        "min_volume_mm3": round(normal.quality.min_volume, 4),
        "attach_counts": counts, "constants_source": how, "material_source": source, "scene": p.scene,
        **({"continuum_holds": cont["holds"]} if cont else {}),
    }


def _picture(ctx: StageContext, p: OrientParams, sp, fs: dict, normal, mirrored, fibres_at) -> None:
    """sheet.png: the fibre streaks of both sheets, their grips' nodes dotted."""
    from ...viz.sheet import sheet_picture

    extra = " + fibre_field" if p.fibre_field is not None else ""
    panels = [
        (f"normal sheet (pitch {fs['pitch_deg']:g} deg{extra})", lambda q: fibres_at(q, False),
         normal.points[normal.attach > 0]),
        ("mirrored sheet (reflection y -> -y)", lambda q: fibres_at(q, True),
         mirrored.points[mirrored.attach > 0]),
    ]
    ctx.path("sheet.png").write_bytes(sheet_picture(geo.outline_polygon(sp), sp.hole_radius, panels))


register(
    Stage(
        name="orient",
        params=OrientParams,
        run=run,
        requires=(),
        optional=("material", "chart", "cell", "homogenize"),
        reads=_reads,
        outputs=(*SHEET_FILES.values(), "sheet.json"),
        doc="tripod sheet mesh + spiral fibre field (normal and mirrored) -> sheet.vtu, sheet.png",
    )
)
