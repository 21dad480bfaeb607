"""Frozen results of a homogenisation, carrying their own diagnostics."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..mechanics.material import TransverseFit

#: Names of the six unit macro-strain load cases, Voigt order.
LOAD_CASES = ("11", "22", "33", "23", "13", "12")


@dataclass(frozen=True)
class LoadCase:
    """Diagnostics of one unit macro-strain load case.

    Attributes
    ----------
    name : Voigt component of the unit macro strain ("11", ..., "12"; shear is engineering).
    solver : the linear solver that ran.
    iterations : CG iterations (0 for a direct solver).
    residual : relative residual ||K u + f|| / ||f||.
    """

    name: str
    solver: str
    iterations: int
    residual: float


@dataclass(frozen=True)
class Localisation:
    """Local strains of the corrector solutions.

    Attributes
    ----------
    strain : (m, 6, 6) float [-], ``strain[e, I]`` = Voigt strain (engineering shear) of
        element ``e`` under unit macro strain ``I`` (element average).
    max_principal : (m, 6) float [-], largest |principal strain| per element and load case.
    ratio_max : (6,) float [-], max over elements of ``max_principal`` divided by the
        largest |principal strain| of the macro strain (1 for normal, 0.5 for unit
        engineering shear), per load case.
    ratio_p99 : (6,) float [-], the same with the 99th percentile over the solid volume
        (less sensitive to single re-entrant corners than the max).
    """

    strain: np.ndarray
    max_principal: np.ndarray
    ratio_max: np.ndarray
    ratio_p99: np.ndarray


@dataclass(frozen=True)
class HomogenizationResult:
    """Effective stiffness of a periodic cell with its diagnostics.

    Attributes
    ----------
    C : (6, 6) float [MPa], effective Voigt stiffness (11, 22, 33, 23, 13, 12,
        engineering shear), energy form: symmetric and second-order accurate in the
        solver error.
    C_raw : (6, 6) float [MPa], ``<C (E_I + eps_I)> : E_J`` (first-order form, not
        symmetrised); ``symmetry_error`` is measured on it.
    fit : transverse-isotropic fit of ``C`` (``.material``, ``.axis``, ``.misfit``).
    relative_density : solid volume fraction of the cell (before removing islands) [-].
    removed_fraction : fraction of the solid volume removed as non-percolating islands [-].
    symmetry_error : ||C_raw - C_raw^T|| / ||C_raw|| [-].
    load_cases : per-load-case diagnostics.
    solver : the linear solver that ran.
    n_dof : free dofs of the solved system.
    n_elements : solid elements used.
    resolution : grid shape (voxels) or (number of tets,) (tet mesh).
    localisation : local strain field and ratios, or None when not kept.
    element_ids : (m,) int, which input element (flat voxel index or tet index) each
        localisation row belongs to.
    timings : wall-clock seconds spent in "assembly", "setup", "solve", "post"; not in
        :meth:`constants` (the homogenize stage records them in its manifest only).
    """

    C: np.ndarray
    C_raw: np.ndarray
    fit: TransverseFit
    relative_density: float
    removed_fraction: float
    symmetry_error: float
    load_cases: tuple[LoadCase, ...]
    solver: str
    n_dof: int
    n_elements: int
    resolution: tuple[int, ...]
    localisation: Localisation | None
    element_ids: np.ndarray
    timings: dict = field(default_factory=dict)

    @property
    def material(self):
        """The fitted :class:`~metasheet.mechanics.material.TransverseIsotropic` material."""
        return self.fit.material

    def constants(self) -> dict:
        """Flat JSON-able summary: the five constants [MPa, -], axis, misfit and diagnostics."""
        out = self.fit.material.to_dict()
        out.update(
            C=np.asarray(self.C).tolist(),
            axis=np.asarray(self.fit.axis).tolist(),
            misfit=float(self.fit.misfit),
            relative_density=float(self.relative_density),
            removed_fraction=float(self.removed_fraction),
            symmetry_error=float(self.symmetry_error),
            solver=self.solver,
            n_dof=int(self.n_dof),
            resolution=list(self.resolution),
            load_cases=[vars(lc) for lc in self.load_cases],
        )
        if self.localisation is not None:
            out["localisation"] = {
                "ratio_max": dict(zip(LOAD_CASES, map(float, self.localisation.ratio_max))),
                "ratio_p99": dict(zip(LOAD_CASES, map(float, self.localisation.ratio_p99))),
            }
        return out
