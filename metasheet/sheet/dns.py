"""The printed sheet where the robot holds it: a voxel DNS condensed on its four grips (issue 44).

The printed foam (:mod:`.printed_foam`: the print map's fields, the Polyfoam model, one bead
walls, the solid brush) is solved as linear elasticity of its solid voxels (the design's base
material, e.g. TPU) with each grip rigid: the nodes of the centre ring tied to body 0, those of
arm k's tip box to body 1 + k, exactly the node sets the robot ties (:func:`.geometry.attach_tags`
on the grid's nodes, the same regions the print map prints solid). The matrix-free voxel
solver (:func:`metasheet.sheet.voxel_grips.rigid_bodies_stiffness`) condenses it onto the 24
rigid coordinates of :mod:`.grips` (same frame, bodies, reference points and units as the
homogenised sheet FEM's :func:`.grips.fem_condensed`), so the two matrices compare directly.

Only the solid held by the grips carries load: face-connected pieces the grips do not hold
are dropped, and the kept share is reported with the build's own connected share.

:func:`compare` puts a DNS sheet beside the homogenised one: the generalised eigenvalues of
the two (18 stiffness ratios, printed over homogenised, scale-free) and the compliances a reader
knows, with the arm tabs clamped: along the normal, roll about it, tilt, in plane.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, check_range
from .geometry import ATTACH_CENTRE, attach_tags
from .grips import GRIP_TAGS, eigen_ratios, grip_references, readable_compliances
from .outline import SheetParams
from .printed_foam import FoamFields, printed_foam, tripod_region

#: CG tolerance of the grip columns: K is the energy form, second order in CG's error
DNS_RTOL = 1e-6


@dataclass(frozen=True)
class SheetPrint:
    """One printed sheet to simulate (picklable: an executor unit).

    label : "normal" or "mirrored" (which print map); seed : the foam's RNG seed; gauge :
    :data:`.printed_foam.GAUGES`; voxel_mm : wanted voxel edge [mm]; design : the
    :class:`~metasheet.cells.polyfoam.PolyfoamDesign`; params : the sheet's :class:`.outline.SheetParams`;
    fields : the print map's :class:`.printed_fields.FoamFields`; solid : (6, 6) Voigt
    stiffness of the printed material [MPa]; rtol : CG tolerance; max_voxels : grid cap.
    """

    label: str
    seed: int
    gauge: str
    voxel_mm: float
    design: object
    params: SheetParams
    fields: FoamFields
    solid: np.ndarray
    rtol: float = DNS_RTOL
    max_voxels: int = 20_000_000


@dataclass(frozen=True)
class DnsSheet:
    """A printed sheet's grip stiffness from the voxel DNS.

    K : (24, 24) [N/mm | N | N mm], :mod:`.grips`' coordinates; label, seed, gauge : as asked.
    shape : voxel grid; voxel_mm : (3,) edges [mm]; solid_fraction_foam : solid share of the
    foam brush [-]; connected_share : the build's largest face-connected piece [-]; kept_share :
    share of the solid the grips hold (what the solver sees) [-]; n_dof : unknowns;
    iterations : CG iterations per column; coarsening : the multigrid's coarse space;
    asymmetry : the reactions' relative asymmetry (the solver's error) [-];
    build_s, solve_s : wall times [s].
    """

    K: np.ndarray
    label: str
    seed: int
    gauge: str
    shape: tuple[int, int, int]
    voxel_mm: tuple[float, float, float]
    solid_fraction_foam: float
    connected_share: float
    kept_share: float
    n_dof: int
    iterations: tuple[int, ...]
    coarsening: str
    asymmetry: float
    build_s: float
    solve_s: float

    def to_dict(self) -> dict:
        d = {k: (list(v) if isinstance(v, tuple) else v) for k, v in self.__dict__.items() if k != "K"}
        return {**d, "K": np.asarray(self.K).tolist()}


def grip_labels(shape, origin, h, params: SheetParams) -> np.ndarray:
    """(nx + 1, ny + 1, nz + 1) int node labels of a voxel grid of ``shape`` voxels with low
    corner ``origin`` (3,) [mm] and edges ``h`` (3,) [mm]: 0 free, 1 + b tied to grip b
    (:data:`.grips.GRIPS` order), from the robot's own tags (:func:`.geometry.attach_tags`)."""
    N = tuple(int(n) + 1 for n in shape)
    idx = np.indices(N).reshape(3, -1).T
    tags = attach_tags(np.asarray(origin, float) + idx * np.asarray(h, float), params)
    lut = np.zeros(max(ATTACH_CENTRE, *GRIP_TAGS) + 1, dtype=np.int64)
    for b, tag in enumerate(GRIP_TAGS):
        lut[tag] = b + 1
    return lut[tags].reshape(N)


def dns_sheet(spec: SheetPrint, progress=None) -> DnsSheet:
    """Build the printed sheet ``spec`` describes and condense its voxel DNS on the four grips."""
    return _solve(spec, progress, False)[0]


def dns_sheet_walls(spec: SheetPrint, progress=None):
    """(:class:`DnsSheet`, :class:`~.wall_limits.SheetWalls`): :func:`dns_sheet` with the
    displacement of each of the 24 unit grip motions on the grid (all 24 columns solved, not 18;
    2.8 GB of fields per sheet of the paper's print at 0.25 mm, 6.7 GB peak, measured) and the
    solid the grips hold."""
    return _solve(spec, progress, True)


def dns_sheet_fields(spec: SheetPrint, progress=None):
    """(:class:`DnsSheet`, :class:`~.wall_fields.WallFields`): :func:`dns_sheet`, the same K (the
    same 18 columns solved), with the walls' fields kept compactly for the searches of the
    walls' limits."""
    return _solve(spec, progress, "relative")


def _solve(spec: SheetPrint, progress, displacements: bool | str):
    check_range("voxel_mm", spec.voxel_mm, 0.0, None, lo_open=True)
    C = np.asarray(spec.solid, float)
    if C.shape != (6, 6):
        raise ConfigError(f"solid: shape {C.shape}: expected the (6, 6) Voigt stiffness [MPa]")
    t0 = time.perf_counter()
    foam = printed_foam(tripod_region(spec.params), spec.fields, spec.design, voxel_mm=spec.voxel_mm,
                        gauge=spec.gauge, seed=spec.seed, max_voxels=spec.max_voxels)
    built = time.perf_counter() - t0
    from .voxel_grips import (  # numba kernels compile on first use only
        held_solid,
        rigid_bodies_stiffness,
    )

    h = np.asarray(foam.voxel_mm, float)
    labels = grip_labels(foam.phases.shape, foam.origin, h, spec.params)
    refs = grip_references(spec.params) - foam.origin  # grid coordinates: node (i, j, k) at (i, j, k) h
    r = rigid_bodies_stiffness(foam.phases.astype(np.int64), foam.size, {1: C}, bodies=labels, references=refs,
                               rtol=spec.rtol, progress=progress, displacements=displacements)
    rep = foam.report
    sheet = DnsSheet(np.asarray(r.K), spec.label, int(spec.seed), spec.gauge, rep.shape, rep.voxel_mm,
                     float(rep.solid_fraction_foam), float(rep.connected_share), float(r.kept_share), int(r.n_dof),
                     tuple(int(i) for i in r.iterations), r.coarsening, float(r.asymmetry), built, float(r.seconds))
    if not displacements:
        return sheet, None
    solid = held_solid(foam.phases > 0, labels > 0)
    if displacements == "relative":
        from .wall_fields import WallFields

        meta = {"label": spec.label, "seed": int(spec.seed), "gauge": spec.gauge, "voxel_mm": float(spec.voxel_mm),
                "kept_share": float(r.kept_share)}
        return sheet, WallFields.from_solve(solid, h, r.U, refs, labels, meta)
    from .wall_limits import SheetWalls

    return sheet, SheetWalls(solid, h, r.U)


def compare(K_dns, K_fem, params: SheetParams) -> dict:
    """The printed sheet (``K_dns``) against the homogenised one (``K_fem``), both (24, 24).

    ``eigen_ratios``: the 18 generalised eigenvalues (ascending), each mode's stiffness printed
    over homogenised; ``log_ratio_rms``: their geometric spread; ``compliances``: each sheet's
    :func:`.grips.readable_compliances` and ``compliance_ratio`` printed over homogenised
    (> 1: the print is softer there).
    """
    refs = grip_references(params)
    lam = eigen_ratios(K_dns, K_fem, refs)
    ca, cb = readable_compliances(K_dns), readable_compliances(K_fem)
    return {"eigen_ratios": lam.tolist(), "log_ratio_rms": float(np.sqrt(np.mean(np.log(lam) ** 2))),
            "geometric_mean_ratio": float(np.exp(np.mean(np.log(lam)))),
            "compliances": {"printed": ca, "homogenised": cb},
            "compliance_ratio": {k: float(ca[k] / cb[k]) for k in ca if isinstance(ca[k], float) and cb[k]}}
