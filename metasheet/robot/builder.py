"""The one way to build the paper's 6-DOF robot: a sheet pair, a material, the servo geometry.

The robot stage, the ``metasheet robot goto`` command, the studies (in every worker) and the
tests and benchmarks all call :func:`six_dof_robot`, so the sheets' stiffness is made one
way: per-element constants (a graded design, as the orient stage wrote them) or a single
material, rotated so that its axis 3 (the soft l axis) follows each element's fibre, and one
material model (:mod:`metasheet.mechanics.material_model`: ours, all five constants, or the authors'
force field's tensor) turns constants into a tensor.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..published import paper
from ..conventions import GRAVITY
from ..errors import ConfigError
from ..mechanics.material import Isotropic, TransverseIsotropic
from ..mechanics.material_model import check_model, model_stiffness
from ..sheet.elements import as_element, check_element
from ..sheet.geometry import SheetMesh
from ..sheet.outline import SheetParams
from ..mechanics.voigt import stiffness_along
from .robots import Robot, ServoGeometry, six_dof


@dataclass(frozen=True, eq=False)
class SheetPair:
    """The two sheets of the 6-DOF robot and their fibre fields.

    Attributes
    ----------
    sheet : the normal sheet (tripod A), a :class:`~metasheet.sheet.geometry.SheetMesh`.
    mirrored : its reflection y -> -y (tripod B).
    fibers, fibers_mirrored : (m, 3) float fibre direction (local axis 3) per element of each.
    constants, constants_mirrored : (m, 5) float per-element constants [MPa, -] in
        :data:`~metasheet.mechanics.material.CONSTANT_NAMES` order, or None (a material is then given).
    element : the robot's finite element, "p1" (the sheets' own linear tetrahedra) or "p2"
        (the same tetrahedra made quadratic when the robot is built,
        :func:`metasheet.sheet.elements.as_element`).
    """

    sheet: SheetMesh
    mirrored: SheetMesh
    fibers: np.ndarray
    fibers_mirrored: np.ndarray
    constants: np.ndarray | None = None
    constants_mirrored: np.ndarray | None = None
    element: str = "p1"

    def __post_init__(self):
        check_element(self.element)
        for label, mesh, fib, con in (("fibers", self.sheet, self.fibers, self.constants),
                                      ("fibers_mirrored", self.mirrored, self.fibers_mirrored,
                                       self.constants_mirrored)):
            m = len(mesh.tets)
            if np.shape(fib) != (m, 3):
                raise ConfigError(f"{label}: shape is {np.shape(fib)} and should be ({m}, 3)")
            if con is not None and np.shape(con) != (m, 5):
                raise ConfigError(f"{label.replace('fibers', 'constants')}: shape is {np.shape(con)} "
                                  f"and should be ({m}, 5)")

    @classmethod
    def spiral(cls, params: SheetParams | None = None, element: str = "p1", **fiber_settings) -> "SheetPair":
        """A freshly meshed sheet, its mirror and the spiral fibre field
        (``fiber_settings``: keywords of :func:`metasheet.sheet.fibers.spiral_fibers`)."""
        from ..sheet.fibers import spiral_fibers
        from ..sheet.geometry import mirror_sheet, tripod_sheet

        s = tripod_sheet(params or SheetParams())
        m = mirror_sheet(s)
        return cls(s, m, spiral_fibers(s.centroids(), **fiber_settings),
                   spiral_fibers(m.centroids(), mirrored=True, **fiber_settings), element=element)

    @property
    def has_constants(self) -> bool:
        return self.constants is not None and self.constants_mirrored is not None


def material_stiffness(material, fibers: np.ndarray, model: str = "ours") -> np.ndarray:
    """Sheet-frame stiffness [MPa] of one material: (6, 6) when isotropic, else (m, 6, 6)
    with axis 3 along ``fibers`` (m, 3); ``model``: see :mod:`metasheet.mechanics.material_model`."""
    C = model_stiffness(material, model)
    if isinstance(material, Isotropic):
        return C
    return stiffness_along(C, fibers)


def element_stiffness(fibers: np.ndarray, constants: np.ndarray, model: str = "ours") -> np.ndarray:
    """(m, 6, 6) sheet-frame stiffness [MPa] from per-element constants (m, 5), axis 3 along
    ``fibers`` (m, 3), under ``model`` (:mod:`metasheet.mechanics.material_model`). Elements whose constants agree to 1e-12 share one tensor (a graded
    design has a few distinct materials); each group uses its first element's constants."""
    keys = np.round(np.asarray(constants, float), 12)
    _, first, inv = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    inv = inv.ravel()
    C = np.empty((len(fibers), 6, 6))
    for i, row in enumerate(first):
        sel = np.flatnonzero(inv == i)
        C[sel] = stiffness_along(model_stiffness(TransverseIsotropic(*constants[row]), model), fibers[sel])
    return C


def _plain(material, model: str = "ours"):
    """An exactly isotropic transverse-isotropic material as :class:`Isotropic` (no fibre
    rotation needed: the anisotropy sweep's alpha = 0 end). The authors' model ignores mu_l."""
    if isinstance(material, TransverseIsotropic) and material.alpha < 1e-9 \
            and abs(material.nu_tl - material.nu_t) < 1e-12 \
            and (model == "authors" or abs(material.mu_l - material.mu_t) <= 1e-12 * material.mu_t):
        return Isotropic(material.E_t, material.nu_t)
    return material


def six_dof_robot(sheets: SheetPair, material=None, *, density: float | None = None,
                  sheet_mass_g: float | None = None, rod_length: float = paper.ROD_LENGTH,
                  geometry: ServoGeometry = ServoGeometry(), gravity=(0.0, 0.0, -GRAVITY),
                  model: str = "ours") -> Robot:
    """The paper's 6-DOF robot (two tripods face to face, rod along x) from ``sheets``.

    Parameters
    ----------
    sheets : the sheet pair with fibres (and per-element constants for ``material`` None).
    material : None: each element's own constants (an error when the pair has none);
        :class:`~metasheet.mechanics.material.Isotropic` or
        :class:`~metasheet.mechanics.material.TransverseIsotropic`: that material everywhere, along
        the fibres.
    density : sheet mass density [t/mm^3] (e.g. :data:`metasheet.published.paper.FOAM_DENSITY`), or
    sheet_mass_g : the mass of each sheet [g] (the authors' scene: 32 g); the density is then
        mass / volume of ``sheets.sheet`` (the mirrored sheet has the same volume). Give one.
    rod_length : [mm]; geometry : servo placement and stroke; gravity : (3,) [mm/s^2].
    model : how constants become a tensor, "ours" (all five) or "authors" (their SOFA force
        field: longitudinal shear from E_t and nu_t, mu_l unused); see
        :mod:`metasheet.mechanics.material_model`. The one place the robot's material model is applied.
    """
    check_model(model, "model")
    density = resolve_density(sheets.sheet, density, sheet_mass_g)
    if material is None:
        if not sheets.has_constants:
            raise ConfigError("material: None: the sheets carry no per-element constants; give a material")
        Ca = element_stiffness(sheets.fibers, sheets.constants, model)
        Cb = element_stiffness(sheets.fibers_mirrored, sheets.constants_mirrored, model)
    else:
        if not isinstance(material, (Isotropic, TransverseIsotropic)):
            raise ConfigError(f"material: {type(material).__name__}: expected Isotropic or TransverseIsotropic")
        material = _plain(material, model)
        Ca = material_stiffness(material, sheets.fibers, model)
        Cb = material_stiffness(material, sheets.fibers_mirrored, model)
    return six_dof(as_element(sheets.sheet, sheets.element), Ca, as_element(sheets.mirrored, sheets.element), Cb,
                   rod_length=rod_length, geometry=geometry, density=density, gravity=gravity)


def resolve_density(sheet: SheetMesh, density: float | None, sheet_mass_g: float | None) -> float:
    """The sheet's mass density [t/mm^3]: ``density``, or ``sheet_mass_g`` [g] over the volume
    of ``sheet`` [mm^3]. Exactly one of them must be given."""
    if (density is None) == (sheet_mass_g is None):
        raise ConfigError(f"density/sheet_mass_g: ({density!r}, {sheet_mass_g!r}): give exactly one")
    if density is not None:
        return float(density)
    from .scenes import sheet_density

    return sheet_density(sheet_mass_g, float(np.sum(np.abs(sheet.volumes()))))
