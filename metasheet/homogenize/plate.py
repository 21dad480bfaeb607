"""Sheet-scale (plate) homogenisation: a voxel cell through the sheet's whole thickness,
periodic in the plane, free on its two faces, to the sheet's membrane, coupling and bending
stiffness (A, B, D).

A printed foam sheet whose cells are not small against its thickness is not the bulk foam:
the cells cut by the faces are free there (Anderson & Lakes 1994; Onck, Andrews & Gibson
2001). The periodic plate cell (Caillerie 1984; Kohn & Vogelius 1984) keeps those faces: the
displacement is the Kirchhoff plate's macro field plus a fluctuation ``w`` periodic in x and y
and free in z,

    eps(u) = e_I(z) + eps(w),  e_I(z) = E_I + z K_I   (in-plane components only)
    K w_I = -f_I,  f_I = int B^T C e_I(z) dV                                    (cell problem)
    ABD_IJ = (int e_I C e_J dV + f_I . w_J + w_I . f_J + w_I . K w_J) / S         (energy form)

with ``S`` the cell's area and ``z`` measured from the cell's mid-height. The generalised
strains are (eps_xx, eps_yy, gamma_xy, kappa_xx, kappa_yy, kappa_xy), engineering shear and
twist as in classical laminate theory, so ``[N; M] = ABD [eps; kappa]`` with N [N/mm] and
M [N mm/mm]. The fluctuation carries the faces' freedom: for a homogeneous solid it makes the
plane-stress plate ``A = Q t``, ``D = Q t^3 / 12`` (:func:`bulk_plate`), exactly for A
(a piecewise-linear ``w_z`` that trilinear voxels hold) and to O(h^2) for D (``w_z`` is
quadratic in z under bending). The transverse-shear stiffness H comes from the next-order cell
problem, driven by these fields (:mod:`.plate_shear`).

Array axis 0 is x, axis 1 is y, axis 2 is z (through the thickness); voxel (i, j, k) spans
[i hx, (i + 1) hx] x [j hy, (j + 1) hy] x [k hz - t/2, (k + 1) hz - t/2], h = size / shape.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..cells.connectivity import periodic_labels
from ..errors import ConfigError, InfeasibleError
from ..fem.assembly import SparsityPattern
from ..fem.hex8 import HEX8_CORNERS, hex8_box_matrices, hex8_box_moment
from ..fem.voxel.element import check_phases
from ..mechanics.material import TransverseIsotropic
from ..mechanics.voigt import IN_PLANE, OUT_OF_PLANE
from ..fem.solvers import solve_spd
from .corrector import material_stiffness, pinned_dofs

if TYPE_CHECKING:
    from .plate_shear import PlateShear

#: Names of the six generalised strains, in the order of :attr:`PlateStiffness.ABD`.
PLATE_STRAINS = ("eps_xx", "eps_yy", "gamma_xy", "kappa_xx", "kappa_yy", "kappa_xy")


@dataclass(frozen=True)
class PlateStiffness:
    """The sheet-scale stiffness of a plate cell.

    Attributes
    ----------
    ABD : (6, 6) float, ``[[A, B], [B, D]]`` (symmetrised energy form) on :data:`PLATE_STRAINS`.
    thickness : t [mm]; area : S [mm^2], the cell's in-plane area.
    relative_density : solid voxel fraction; removed_fraction : share of the solid removed
        (parts that do not wrap around the cell in x and y).
    symmetry_error : relative asymmetry of the first-order form (the solver's error).
    n_dof : unknowns; solver : the linear solver that ran; resolution : (nx, ny, nz).
    shear : the transverse-shear stiffness (:class:`~.plate_shear.PlateShear`) when asked for.
    """

    ABD: np.ndarray
    thickness: float
    area: float
    relative_density: float
    removed_fraction: float
    symmetry_error: float
    n_dof: int
    solver: str
    resolution: tuple[int, int, int]
    shear: "PlateShear | None" = None

    @property
    def A(self) -> np.ndarray:
        """(3, 3) membrane stiffness [N/mm]."""
        return self.ABD[:3, :3]

    @property
    def B(self) -> np.ndarray:
        """(3, 3) membrane-bending coupling [N]."""
        return self.ABD[:3, 3:]

    @property
    def D(self) -> np.ndarray:
        """(3, 3) bending stiffness [N mm]."""
        return self.ABD[3:, 3:]

    def moduli(self) -> dict:
        """The sheet's equivalent in-plane moduli, from membrane and from bending [MPa]:
        ``E_x = 1 / (t (A^-1)_11)`` and ``E_x = 12 / (t^3 (D^-1)_11)`` (and E_y, G_xy, nu_xy
        alike); for a homogeneous sheet both are its plane-stress moduli."""
        return abd_moduli(self.ABD, self.thickness)

    def to_dict(self) -> dict:
        """JSON-ready: A, B, D, the moduli and the cell's figures."""
        return {"A_N_per_mm": self.A.tolist(), "B_N": self.B.tolist(), "D_N_mm": self.D.tolist(),
                "strains": list(PLATE_STRAINS), "thickness_mm": self.thickness, "area_mm2": self.area,
                "moduli_MPa": self.moduli(), "relative_density": self.relative_density,
                "removed_fraction": self.removed_fraction, "symmetry_error": self.symmetry_error,
                "n_dof": self.n_dof, "solver": self.solver, "resolution": list(self.resolution),
                **({"shear": self.shear.to_dict()} if self.shear is not None else {})}


def abd_moduli(ABD, thickness: float) -> dict:
    """``{"membrane": ..., "bending": ...}`` equivalent in-plane moduli [MPa, -] of a (6, 6) ABD
    of a sheet ``thickness`` [mm] thick (:meth:`PlateStiffness.moduli`)."""
    ABD, t = np.asarray(ABD, float), float(thickness)
    if ABD.shape != (6, 6) or not t > 0:
        raise ConfigError(f"ABD, thickness: shape {ABD.shape}, {thickness!r}: expected (6, 6) and t > 0 [mm]")
    return {"membrane": _moduli(np.linalg.inv(ABD[:3, :3]) * t),
            "bending": _moduli(np.linalg.inv(ABD[3:, 3:]) * t**3 / 12.0)}


def _moduli(compliance: np.ndarray) -> dict:
    """E_x, E_y, G_xy, nu_xy [MPa, -] of an in-plane compliance (3, 3) [1/MPa]."""
    return {"E_x": float(1.0 / compliance[0, 0]), "E_y": float(1.0 / compliance[1, 1]),
            "G_xy": float(1.0 / compliance[2, 2]), "nu_xy": float(-compliance[0, 1] / compliance[0, 0])}


def equivalent_constants(moduli: dict, bulk: TransverseIsotropic) -> TransverseIsotropic:
    """The transverse-isotropic constants, axis l along the sheet's x (a Polyfoam's shrunk axis),
    whose plane-stress in-plane moduli are ``moduli`` (E_x, E_y, G_xy, nu_xy [MPa, -]: one entry
    of :meth:`PlateStiffness.moduli`): E_l = E_x, E_t = E_y, mu_l = G_xy, nu_tl = nu_xy E_y / E_x.
    A sheet of thickness t made of them has ``A = Q t`` with the moduli's Q (the cell's in-plane
    shear coupling, the compliance's 16 and 26 entries, dropped).

    nu_t, through the thickness, is what a thin sheet's plane stress does not see: it stays
    ``bulk``'s when the material is then positive definite (``-1 < nu_t < 1 - 2 nu_tl nu_lt``),
    else it takes that interval's midpoint ``-nu_tl nu_lt`` (a sheet stiff along y and soft along
    x, the tie E_z = E_t of transverse isotropy makes nu_tl large). ConfigError when the moduli
    themselves make no positive-definite sheet."""
    try:
        E_x, E_y, G, nu = (float(moduli[k]) for k in ("E_x", "E_y", "G_xy", "nu_xy"))
    except (KeyError, TypeError, ValueError) as exc:
        raise ConfigError(f"moduli: {moduli!r}: expected E_x, E_y, G_xy, nu_xy") from exc
    if not (E_x > 0 and E_y > 0 and G > 0 and nu * nu < E_x / E_y):
        raise ConfigError(f"moduli: {moduli!r}: not a positive-definite sheet (need E_x, E_y, G_xy > 0 and "
                          "nu_xy^2 < E_x / E_y)")
    nu_tl = nu * E_y / E_x
    couple = nu_tl * nu  # nu_tl nu_lt, < 1 for a positive-definite sheet
    lo, hi = -1.0, 1.0 - 2.0 * couple
    margin = 0.05 * (hi - lo)
    nu_t = float(bulk.nu_t) if lo + margin < float(bulk.nu_t) < hi - margin else -couple
    return TransverseIsotropic(E_t=E_y, E_l=E_x, nu_t=nu_t, nu_tl=nu_tl, mu_l=G)


def plane_stress(C: np.ndarray) -> np.ndarray:
    """(3, 3) reduced stiffness Q [MPa] of a (6, 6) Voigt stiffness C with sigma_33 = sigma_23 =
    sigma_13 = 0 (rows 11, 22, 12, engineering shear): ``Q = C_pp - C_pz C_zz^-1 C_zp``."""
    C = np.asarray(C, float)
    if C.shape != (6, 6):
        raise ConfigError(f"C: shape {C.shape}: expected (6, 6) [MPa]")
    p, z = np.ix_(IN_PLANE, IN_PLANE), np.ix_(OUT_OF_PLANE, OUT_OF_PLANE)
    Cpz = C[np.ix_(IN_PLANE, OUT_OF_PLANE)]
    return C[p] - Cpz @ np.linalg.solve(C[z], C[np.ix_(OUT_OF_PLANE, IN_PLANE)])


def laminate_abd(layers) -> np.ndarray:
    """(6, 6) ABD of classical laminate theory for ``layers``: (C (6, 6) [MPa], z0, z1 [mm])
    each, z from the mid-plane: ``A = sum Q (z1 - z0)``, ``B = sum Q (z1^2 - z0^2) / 2``,
    ``D = sum Q (z1^3 - z0^3) / 3`` with Q = :func:`plane_stress` (C)."""
    ABD = np.zeros((6, 6))
    for C, z0, z1 in layers:
        if not z1 > z0:
            raise ConfigError(f"layers: z0 {z0!r}, z1 {z1!r}: need z1 > z0 [mm]")
        Q = plane_stress(C)
        ABD[:3, :3] += Q * (z1 - z0)
        ABD[:3, 3:] += Q * (z1**2 - z0**2) / 2.0
        ABD[3:, 3:] += Q * (z1**3 - z0**3) / 3.0
    ABD[3:, :3] = ABD[:3, 3:]
    return ABD


def bulk_plate(C: np.ndarray, thickness: float) -> np.ndarray:
    """(6, 6) ABD of a homogeneous sheet of thickness t [mm] made of a bulk material C (6, 6)
    [MPa]: the continuum the robot's sheets use (A = Q t, B = 0, D = Q t^3 / 12)."""
    t = float(thickness)
    if not t > 0:
        raise ConfigError(f"thickness: {thickness!r}: allowed range is (0, inf) [mm]")
    return laminate_abd([(C, -t / 2.0, t / 2.0)])


def plate_percolating(solid: np.ndarray) -> np.ndarray:
    """(nx, ny, nz) bool: the face-connected parts of ``solid`` that wrap around the cell in x
    and in y (periodic there; z is open: the sheet's faces). Another part floats: it would add
    rigid motions to the cell problem and carries no membrane or bending load.

    Raises InfeasibleError when no part wraps around both in-plane directions."""
    padded = np.concatenate([solid, np.zeros(solid.shape[:2] + (1,), bool)], axis=2)  # no wrap through z
    labels, n, _, _ = periodic_labels(padded)
    if n == 0:
        raise InfeasibleError("phases: the plate cell has no solid voxel (all phases are 0 = void)")
    labs, first = np.unique(labels.ravel(), return_index=True)
    first = first[labs > 0]
    idx = np.array(np.unravel_index(first, padded.shape))
    wraps = np.ones(n, bool)
    for d in (0, 1):
        lab2, _, _, _ = periodic_labels(np.concatenate([padded, padded], axis=d))
        shifted = idx.copy()
        shifted[d] += padded.shape[d]
        wraps &= lab2[tuple(idx)] == lab2[tuple(shifted)]
    ok = np.flatnonzero(wraps)
    if len(ok) == 0:
        raise InfeasibleError("phases: no connected part of the plate cell wraps around it in both x and y: "
                              "the sheet falls apart and has no membrane or bending stiffness")
    return np.isin(labels[..., :-1], ok + 1)


def plate_elements(keep: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Hex connectivity of the voxels in ``keep`` (nx, ny, nz) bool, periodic in x and y only.

    Returns (elements (m,) flat voxel index, nodes (m, 8) compact node index, grid_nodes (n,)
    flat index ``(i ny + j) (nz + 1) + k`` on the (nx, ny, nz + 1) node grid)."""
    nx, ny, nz = keep.shape
    elements = np.flatnonzero(keep.ravel())
    ijk = np.stack(np.unravel_index(elements, keep.shape), axis=1)
    corner = ijk[:, None, :] + HEX8_CORNERS[None, :, :]
    corner[..., 0] %= nx
    corner[..., 1] %= ny
    flat = (corner[..., 0] * ny + corner[..., 1]) * (nz + 1) + corner[..., 2]
    grid_nodes, inv = np.unique(flat, return_inverse=True)
    return elements, inv.reshape(-1, 8), grid_nodes


@dataclass(frozen=True)
class PlateCell:
    """The discrete plate cell problem (internal to :mod:`.plate` and :mod:`.plate_shear`).

    elements (m,) flat voxel index; nodes (m, 8) compact node index; kind (m,) ``phase nz +
    layer``; phase_kind (m,) index into ``Cs``; Cs (p, 6, 6) [MPa]; h (3,) [mm]; z_c (nz,) layer
    centres from the mid-plane [mm]; K (3n, 3n); F (3n, 6) loads of the unit generalised
    strains; E_vol (6, 6) their energy; free (k,) unpinned dofs; coords (n, 3) [mm]; area [mm^2].
    """

    elements: np.ndarray
    nodes: np.ndarray
    kind: np.ndarray
    phase_kind: np.ndarray
    Cs: np.ndarray
    h: np.ndarray
    z_c: np.ndarray
    pattern: SparsityPattern
    K: object
    F: np.ndarray
    E_vol: np.ndarray
    free: np.ndarray
    coords: np.ndarray
    area: float

    def solve(self, rhs: np.ndarray, solver: str, rtol: float):
        """(3n, r) solution of ``K U = rhs`` on the free dofs (pinned dofs 0), and the report."""
        U = np.zeros_like(rhs)
        U[self.free], report = solve_spd(self.K[self.free][:, self.free], rhs[self.free], solver=solver, rtol=rtol,
                                         coords=self.coords[self.free[::3] // 3])
        return U, report


def plate_cell(ph: np.ndarray, size: np.ndarray, materials: dict, present: np.ndarray, keep: np.ndarray) -> PlateCell:
    """Assemble the cell problem of the checked ``ph`` (nx, ny, nz) on the kept voxels."""
    nz = ph.shape[2]
    h = size / np.array(ph.shape)
    elements, nodes, grid_nodes = plate_elements(keep)
    phase_kind = np.searchsorted(present, ph.ravel()[elements])
    layer = elements % nz
    z_c = (np.arange(nz) + 0.5) * h[2] - size[2] / 2.0
    Cs = np.array([material_stiffness(p, materials[p]) for p in present])
    Ke = np.array([hex8_box_matrices(C, h)[0] for C in Cs])
    loads, energy = _layer_loads(Cs, h, z_c)  # (p nz, 24, 6), (p nz, 6, 6)
    kind = phase_kind * nz + layer
    pattern = SparsityPattern.from_elements(nodes, len(grid_nodes))
    K = pattern.assemble(Ke, phase_kind)
    F = pattern.assemble_vector(loads, kind)
    E_vol = np.einsum("k,kij->ij", np.bincount(kind, minlength=len(energy)).astype(float), energy)
    free = np.setdiff1d(np.arange(K.shape[0]), pinned_dofs(K))
    coords = np.stack(np.unravel_index(grid_nodes, (ph.shape[0], ph.shape[1], nz + 1)), axis=1) * h
    return PlateCell(elements, nodes, kind, phase_kind, Cs, h, z_c, pattern, K, F, E_vol, free, coords,
                     float(size[0] * size[1]))


def homogenize_plate(phases, size, materials: dict, *, solver: str = "auto", rtol: float = 1e-10,
                     shear: bool = False) -> PlateStiffness:
    """Membrane, coupling and bending stiffness of a periodic plate cell (module docstring).

    Parameters
    ----------
    phases : (nx, ny, nz) int, 0 = void, k > 0 = ``materials[k]``; z spans the whole thickness.
    size : (3,) float [mm]: the cell's in-plane periods and the sheet's thickness t.
    materials : dict phase -> :class:`~metasheet.mechanics.material.Isotropic` or
        :class:`~metasheet.mechanics.material.TransverseIsotropic` (axis 3 = global z).
    solver, rtol : :func:`metasheet.fem.solvers.solve_spd` ("auto", "direct" or "amg").
    shear : also the transverse-shear stiffness H (:mod:`.plate_shear`, two more solves).

    Returns :class:`PlateStiffness`. Raises ConfigError (bad input), InfeasibleError (no part
    wraps around the cell in x and y), ConvergenceError (the solver missed ``rtol``).
    """
    ph, size, present = check_phases(phases, size, materials, name="materials", item="material",
                                     integral_floats=True)
    if not (0 < float(rtol) < 1e-3):
        raise ConfigError(f"rtol: {rtol!r}: allowed range is (0, 1e-3)")
    solid = ph > 0
    keep = plate_percolating(solid)
    cell = plate_cell(ph, size, materials, present, keep)
    U, report = cell.solve(-cell.F, solver, rtol)
    F, K, area = cell.F, cell.K, cell.area
    raw = (cell.E_vol + U.T @ F) / area
    ABD = (cell.E_vol + F.T @ U + U.T @ F + U.T @ (K @ U)) / area
    ABD = 0.5 * (ABD + ABD.T)
    scale = max(float(np.abs(raw).max()), 1e-300)
    H = None
    if shear:
        from .plate_shear import transverse_shear
        H = transverse_shear(cell, U, ABD, solver=solver, rtol=rtol)
    return PlateStiffness(ABD=ABD, thickness=float(size[2]), area=area, relative_density=float(solid.mean()),
                          removed_fraction=float(1.0 - keep.sum() / max(solid.sum(), 1)),
                          symmetry_error=float(np.abs(raw - raw.T).max() / scale), n_dof=int(len(cell.free)),
                          solver=report.solver, resolution=tuple(int(n) for n in ph.shape), shear=H)


def _layer_loads(Cs, h: np.ndarray, z_c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per (phase, layer) kind ``p nz + k``: the element forces of the six unit generalised
    strains (24, 6) [N, N mm] and their energy ``int e_I C e_J dV`` (6, 6) over one voxel."""
    v_el = float(np.prod(h))
    loads, energy = [], []
    for C in Cs:
        F = hex8_box_matrices(C, h)[1][:, IN_PLANE]
        G = hex8_box_moment(C, h)[:, IN_PLANE]
        Cp = C[np.ix_(IN_PLANE, IN_PLANE)]
        for z in z_c:
            loads.append(np.hstack([F, z * F + G]))
            second = z * z + h[2] ** 2 / 12.0  # mean of z^2 over the layer
            energy.append(v_el * np.block([[Cp, z * Cp], [z * Cp, second * Cp]]))
    return np.array(loads), np.array(energy)
