"""The printed sheet's limits from its own walls, to first order in the motor travel (issue 62, item 4).

The continuum's studies stop at a strain of the homogenised foam (0.3), a limit of the model, not
of the printed walls. The printed sheet's own limits are in its walls: the largest strain the
TPU is asked to take, and self-contact, where a void between two walls closes (the paper's
Section VI names it as the real foam's limit at large strain). Both are read here off the
linear voxel DNS (:func:`~metasheet.sheet.voxel_grips.rigid_bodies_stiffness` with its
displacement fields), carried to the robot's motors by the linear printed robot
(:mod:`metasheet.robot.condensed`): a motor direction ``d`` (6,) moves every wall node by
``u(t) = t U_m d`` at travel ``t`` [rad], so that

* the walls' largest principal strain grows as ``t e(d)``, ``e(d)`` the largest eigenvalue of
  the voxel strains of ``U_m d``: the strain limit binds at ``t = limit / e(d)``;
* two surface nodes a, b apart by ``X = X_a - X_b`` at rest are ``|X + t (u_a - u_b)|`` apart:
  the travel at which they come within ``touch`` is a root of a quadratic, exactly, for a
  linear field. The smallest over the pairs is the first contact.

Both are first order: the nonlinear DNS of the same print (:mod:`metasheet.robot.voxel_robot`)
says by how much the walls' response departs from its linearisation (1.5 times stiffer a degree
from rest one way, 0.6 the other): these travels locate where the limits start to matter, they
do not replace the nonlinear reference at the poses where they bind.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..errors import ConfigError
from ..fem.voxel.gaps import surface_nodes


@dataclass(frozen=True)
class SheetWalls:
    """One printed sheet's walls as the linear DNS solved them: ``solid`` (nx, ny, nz) bool, the
    voxels the grips hold (what the solver saw); ``h`` (3,) [mm] the voxel edges; ``U``
    (nx + 1, ny + 1, nz + 1, 3, 24) [mm per mm or rad] the displacement of each unit grip motion
    (:mod:`metasheet.sheet.grips`' 24 coordinates, the sheet's frame), grip nodes included."""

    solid: np.ndarray
    h: np.ndarray
    U: np.ndarray

    def field(self, q) -> np.ndarray:
        """(nx + 1, ny + 1, nz + 1, 3) [mm] the displacement of grip motions ``q`` (24,)."""
        return np.einsum("...ic,c->...i", self.U, np.asarray(q, float).reshape(24))

    def per_motor(self, G) -> np.ndarray:
        """(nx + 1, ny + 1, nz + 1, 3, 6) the fields per unit motor change, from ``G`` (24, 6) the
        grips' motions per motor (:func:`metasheet.robot.condensed.grip_motions_per_motor`)."""
        return np.einsum("...ic,cm->...im", self.U, np.asarray(G, float).reshape(24, -1))


@dataclass(frozen=True)
class WallPairs:
    """Surface node pairs that may touch: ``a``, ``b`` (p,) flat grid nodes, ``X`` (p, 3) [mm]
    their rest offset ``X_a - X_b``; ``separation`` [mm], the least rest distance of a pair (a
    gap must have been open), ``radius`` [mm], the largest (no pair farther apart can close
    within the travel asked); ``touch`` [mm], the distance that counts as contact."""

    a: np.ndarray
    b: np.ndarray
    X: np.ndarray
    separation: float
    radius: float
    touch: float


def voxel_strains(u, h) -> np.ndarray:
    """(nx, ny, nz, 3, 3) small strain at each voxel's centre of the nodal displacement ``u``
    (nx + 1, ny + 1, nz + 1, 3) [mm] on voxels of edges ``h`` (3,) [mm]: the trilinear element's
    gradient there (the mean of the four edge differences along each axis), symmetrised."""
    u = np.asarray(u, float)
    h = np.asarray(h, float).reshape(3)
    G = np.empty(tuple(n - 1 for n in u.shape[:3]) + (3, 3))
    for ax in range(3):
        d = np.diff(u, axis=ax) / h[ax]  # edge differences along ax
        for other in (a for a in range(3) if a != ax):
            d = 0.5 * (d[(slice(None),) * other + (slice(0, -1),)] + d[(slice(None),) * other + (slice(1, None),)])
        G[..., :, ax] = d  # du_i / dx_ax
    return 0.5 * (G + np.swapaxes(G, -1, -2))


def principal_range(u, h, solid) -> tuple[float, float]:
    """(largest, smallest) principal strain over the ``solid`` (nx, ny, nz) bool voxels of ``u``."""
    return principal_extremes(voxel_strains(u, h)[np.asarray(solid, bool)])


def principal_extremes(E) -> tuple[float, float]:
    """(largest, smallest) eigenvalue over the symmetric ``E`` (n, 3, 3), the same numbers as
    ``eigvalsh`` of every one: only those whose Gershgorin interval reaches past the extremes'
    bounds from the diagonals (a diagonal lies within the eigenvalues) are solved, with a margin
    for the solver's rounding (1e-10 of the largest entry)."""
    E = np.asarray(E, float)
    if not len(E):
        raise ConfigError("solid: no solid voxel")
    diag = np.diagonal(E, axis1=-2, axis2=-1)  # (n, 3)
    radius = np.abs(E).sum(axis=-1) - np.abs(diag)  # Gershgorin: off-diagonal row sums
    margin = 1e-10 * float(np.abs(E).max())
    high = (diag + radius).max(axis=1) >= diag.max() - margin
    low = (diag - radius).min(axis=1) <= diag.min() + margin
    ev = np.linalg.eigvalsh(E[high | low])
    return float(ev[:, -1].max()), float(ev[:, 0].min())


def travel_to_strain(u_unit, h, solid, limit: float) -> tuple[float, float]:
    """(forward, backward) travel [per unit of ``u_unit``] at which the walls' largest principal
    strain reaches ``limit`` (> 0) under ``t u_unit``, t > 0 and t < 0: ``limit / e`` with ``e``
    the largest principal strain of ``u_unit`` (of ``-u_unit`` backward); inf where none stretches."""
    if not limit > 0:
        raise ConfigError(f"limit: {limit!r}: allowed range (0, inf) [-]")
    hi, lo = principal_range(u_unit, h, solid)
    return (limit / hi if hi > 0 else np.inf), (limit / -lo if lo < 0 else np.inf)


def wall_pairs(solid, h, radius: float, *, separation: float | None = None, touch: float | None = None) -> WallPairs:
    """The surface node pairs of ``solid`` (nx, ny, nz) bool (edges ``h`` (3,) [mm]) whose rest
    distance is in [``separation``, ``radius``] [mm] (:mod:`metasheet.fem.voxel.gaps`' rule:
    ``separation`` two voxel edges, ``touch`` a quarter of one by default), each once, a < b."""
    s = np.asarray(solid, bool)
    h = np.asarray(h, float).reshape(3)
    hmin = float(h.min())
    separation = 2.0 * hmin if separation is None else float(separation)
    touch = 0.25 * hmin if touch is None else float(touch)
    if not 0 < touch < separation <= radius:
        raise ConfigError(f"touch, separation, radius: {touch:g}, {separation:g}, {radius:g} mm: need "
                          "0 < touch < separation <= radius")
    nodes, X = surface_points(s, h)
    pairs = cKDTree(X).query_pairs(radius, output_type="ndarray")
    off = X[pairs[:, 0]] - X[pairs[:, 1]]
    keep = np.einsum("pi,pi->p", off, off) >= separation**2
    pairs, off = pairs[keep], off[keep]
    order = np.lexsort((pairs[:, 1], pairs[:, 0]))  # the same pairs in the same order on any run
    return WallPairs(nodes[pairs[order, 0]], nodes[pairs[order, 1]], off[order], separation, float(radius), touch)


def contact_travel(pairs: WallPairs, u_unit) -> tuple[float, int]:
    """(t, pair) the smallest travel t > 0 at which a pair of ``pairs`` comes within its
    ``touch`` under ``t u_unit`` ((nx + 1, ny + 1, nz + 1, 3) or (n, 3) [mm per unit]), exact for
    the linear field: the first root of ``|X + t w|^2 = touch^2``, ``w = u_a - u_b``; (inf, -1)
    when none does. A pair already within ``touch`` at rest is not one (pairs start apart)."""
    u = np.asarray(u_unit, float).reshape(-1, 3)
    w = u[pairs.a] - u[pairs.b]
    A = np.einsum("pi,pi->p", w, w)
    B = np.einsum("pi,pi->p", pairs.X, w)
    C = np.einsum("pi,pi->p", pairs.X, pairs.X) - pairs.touch**2
    disc = B * B - A * C
    ok = (A > 0) & (disc >= 0) & (B < 0)  # approaching, and the line passes within touch
    if not ok.any():
        return np.inf, -1
    # the smaller root (C > 0: both roots of one sign, positive when B < 0), cancellation-free
    t = np.full(len(A), np.inf)
    t[ok] = C[ok] / (-B[ok] + np.sqrt(disc[ok]))
    k = int(np.argmin(t))
    return float(t[k]), k


def first_contact(solid, h, u_unit, t_max: float, *, steps: int | None = None, separation: float | None = None,
                  touch: float | None = None) -> tuple[float, tuple[int, int]]:
    """(t, (a, b)) the smallest travel t in (0, ``t_max``] at which two surface nodes of ``solid``
    that were at least ``separation`` apart come within ``touch`` under ``t u_unit``
    ((nx + 1, ny + 1, nz + 1, 3) [mm per unit]); (inf, ()) when none does.

    Exact for the linear field, without the all-pairs search of :func:`wall_pairs`: the travel is
    cut into ``steps`` (default: each moving a node by at most one voxel edge); at each step's
    middle, the pairs within ``touch`` plus the largest node motion of a step are found among the
    moved surface nodes (a KD-tree), and :func:`contact_travel`'s quadratic, solved from the step's
    start, gives the first contact within the step. A pair out of that reach at the middle cannot
    close in the step: in half a step either way its offset changes by at most twice a node's
    largest motion in half a step, the reach beyond ``touch``. (Measured from the middle rather
    than the start, the reach is half as far beyond ``touch``: it holds the voxel's neighbours at
    one edge but not the same wall's nodes two edges apart: a seventh of the pairs, and a quarter
    to a half of the time, ``benchmarks/bench_wall_map.py``.)
    """
    s = np.asarray(solid, bool)
    h = np.asarray(h, float).reshape(3)
    nodes, X = surface_points(s, h)
    return contact_along(nodes, X, np.asarray(u_unit, float).reshape(-1, 3)[nodes], float(h.min()), t_max,
                         steps=steps, separation=separation, touch=touch)


def surface_points(solid, h) -> tuple[np.ndarray, np.ndarray]:
    """(nodes (s,) flat grid indices, X (s, 3) [mm] their rest positions): the surface nodes of
    ``solid`` (nx, ny, nz) bool with voxel edges ``h`` (3,) [mm], those :func:`first_contact` searches."""
    s = np.asarray(solid, bool)
    nodes = surface_nodes(s)
    N = tuple(n + 1 for n in s.shape)
    return nodes, np.stack(np.unravel_index(nodes, N), 1) * np.asarray(h, float).reshape(3)


def contact_along(nodes, X, u, hmin: float, t_max: float, *, steps: int | None = None,
                  separation: float | None = None, touch: float | None = None) -> tuple[float, tuple[int, int]]:
    """:func:`first_contact` on the surface nodes ``nodes`` (s,) at rest positions ``X`` (s, 3) [mm]
    (:func:`surface_points`) moving by ``u`` (s, 3) [mm per unit]; ``hmin`` [mm] the smallest voxel
    edge (the step's length and the default ``separation`` and ``touch``)."""
    separation = 2.0 * hmin if separation is None else float(separation)
    touch = 0.25 * hmin if touch is None else float(touch)
    if not 0 < touch < separation:
        raise ConfigError(f"touch, separation: {touch:g}, {separation:g} mm: need 0 < touch < separation")
    if not t_max > 0:
        raise ConfigError(f"t_max: {t_max!r}: allowed range (0, inf)")
    u = np.asarray(u, float)
    speed = float(np.sqrt(np.einsum("pi,pi->p", u, u).max())) if len(u) else 0.0
    if speed == 0.0:
        return np.inf, ()
    n = max(1, int(np.ceil(t_max * speed / hmin))) if steps is None else int(steps)
    dt = t_max / n
    reach = touch + speed * dt
    for i in range(n):
        t0 = i * dt
        # an unbalanced, uncompacted tree: the same pairs, built in a third of the time
        tree = cKDTree(X + (t0 + 0.5 * dt) * u, balanced_tree=False, compact_nodes=False)
        pairs = tree.query_pairs(reach, output_type="ndarray")
        if not len(pairs):
            continue
        rest = X[pairs[:, 0]] - X[pairs[:, 1]]
        keep = np.einsum("pi,pi->p", rest, rest) >= separation**2
        pairs, rest = pairs[keep], rest[keep]
        if not len(pairs):
            continue
        # apart at the step's start: a pair within touch there closed in an earlier step (or at
        # rest, which separation excludes), where it was within that step's reach
        here = WallPairs(pairs[:, 0], pairs[:, 1], rest + t0 * (u[pairs[:, 0]] - u[pairs[:, 1]]),
                         separation, reach, touch)
        t, k = contact_travel(here, u)
        if t <= dt:
            return t0 + t, (int(nodes[pairs[k, 0]]), int(nodes[pairs[k, 1]]))
    return np.inf, ()


@dataclass(frozen=True)
class MotorWalls:
    """A sheet's walls per unit motor change, ready to search along many motor directions: the
    surface nodes ``nodes`` (s,) at rest ``X`` (s, 3) [mm] with their motion ``u`` (6, s, 3)
    [mm per rad of each motor], the solid voxels' small strain ``E`` (6, v, 3, 3) [per rad],
    ``hmin`` [mm] the smallest voxel edge. A direction's fields are sums of these six (the
    fields are linear in the motors), so each search skips the grid: :meth:`from_fields`."""

    nodes: np.ndarray
    X: np.ndarray
    u: np.ndarray
    E: np.ndarray
    hmin: float

    @classmethod
    def from_fields(cls, walls: SheetWalls, G) -> MotorWalls:
        """From a sheet's :class:`SheetWalls` and ``G`` (24, 6), its grips' motions per motor."""
        F = walls.per_motor(G)  # (nx + 1, ny + 1, nz + 1, 3, 6)
        nodes, X = surface_points(walls.solid, walls.h)
        solid = np.asarray(walls.solid, bool)
        u = np.stack([F[..., m].reshape(-1, 3)[nodes] for m in range(6)])
        E = np.stack([voxel_strains(F[..., m], walls.h)[solid] for m in range(6)])
        return cls(nodes, X, u, E, float(np.min(walls.h)))

    def _along(self, a, d) -> np.ndarray:
        d = np.asarray(d, float).reshape(6)
        out = d[0] * a[0]
        for m in range(1, 6):  # a fixed order of sums: the same bits on any BLAS and thread count
            out = out + d[m] * a[m]
        return out

    def rates(self) -> list[list[float]]:
        """Per motor, the walls' largest principal strain per rad turned up and down alone."""
        out = []
        for m in range(6):
            hi, lo = principal_extremes(self.E[m])
            out.append([max(hi, 0.0), max(-lo, 0.0)])
        return out

    def contact(self, d, t_max: float) -> tuple[float, tuple[int, int]]:
        """:func:`first_contact` along the motor direction ``d`` (6,) to ``t_max`` [rad of ``d``]."""
        return contact_along(self.nodes, self.X, self._along(self.u, d), self.hmin, t_max)

    def strain_travel(self, d, limit: float) -> float:
        """The travel along ``d`` (6,) [rad of ``d``] at which the walls' largest principal
        strain reaches ``limit``, :func:`travel_to_strain`'s forward one (inf: none stretches)."""
        if not limit > 0:
            raise ConfigError(f"limit: {limit!r}: allowed range (0, inf) [-]")
        hi = principal_extremes(self._along(self.E, d))[0]
        return limit / hi if hi > 0 else np.inf
