"""Penalty contact between the walls of a voxel body: two surfaces that were apart push each
other away when they come closer than a gap (issue 62: the printed foam's walls touch at large
strain, Section VI of the paper, and past the first touch a model without contact lets them
pass through each other).

The surface is the nodes of the voxel faces the solid shares with the void inside the grid
(:func:`surface_areas`). Two surface nodes ``a``, ``b`` whose rest distance is at least
``separation`` (two voxel edges by default: across a void or around a wall's end, never two
neighbours in one wall) and that come within ``reach`` of each other (one voxel edge by
default) are a pair; its
direction ``m`` is fixed when it is first met (the unit vector from b to a then), and its gap
is measured along it. A pair whose gap ``d`` is below ``gap`` stores the energy ``phi(o)`` of its overlap
``o = gap - d`` (``d = (x_a - x_b) . m``), a penalty whose stiffness ``phi''`` grows linearly from
zero to ``k = stiffness (A_a + A_b) / 2`` [N/mm] over the first ``ramp`` of overlap and stays
there:

    phi(o) = k o^3 / (6 ramp)                        for 0 <= o <= ramp,
    phi(o) = k / 2 (o - ramp / 2)^2 + k ramp^2 / 24  beyond,

with ``A`` a node's share of those faces (a quarter of each face it is a corner of): a pressure
per unit overlap [N/mm^3] spread over the nodes as a uniform pressure's consistent nodal forces
are, so that two flat faces pressed together carry a uniform stress. The force on ``a`` is
``phi'(o) m`` (``-`` that on ``b``) and the tangent ``phi''(o) m m^T``. The ramp makes the energy
twice continuously differentiable where a pair starts to push: with a plain ``k/2 o^2`` (``ramp``
0) the tangent jumps by ``k`` (ten voxels' stiffness) as each pair enters, so that on a printed
sheet, with pairs entering and leaving at every step, the trust region's quadratic model
mispredicts every step that changes the set.

Measured along a fixed direction, the gap is a half-space's: sliding sideways costs nothing (no
friction), and a node pushed past the other one meets a growing force, not a vanishing one.
(Measured along the nodes' own distance, two flat faces pressed together slid sideways until
their nodes interleaved: the distance grows that way, so the energy falls.) The energy and its
gradient are continuous while a pair is met, so the trust-region Newton method of
:mod:`.nonlinear` minimises the walls' energy plus this one with its own acceptance test; the
pairs are found again at every force evaluation (a k-d tree on the moved surface, in a fixed
order: the same bits each run) and their directions kept for the solve (:meth:`SurfacePairs.reset`
at its start). A pair met for the first time already past itself (a step carried a node
through the wall it faces) is refused like a state that inverts an element: the solver halves
its load step or shrinks its trust region.

A penalty lets the surfaces come within ``gap - p / stiffness`` of each other under a contact
pressure p: the default stiffness, 10 E / h (E the walls' modulus, h the smallest voxel edge:
ten times a voxel's own stiffness per unit area), keeps that to a hundredth of a voxel at a
tenth of E.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ...errors import ConfigError


@dataclass(frozen=True)
class Contact:
    """The penalty's parameters: ``gap`` [mm] the distance below which two surface nodes push
    apart, ``stiffness`` [N/mm^3] the pressure per unit overlap, ``separation`` [mm] the rest
    distance a pair must have had, ``reach`` [mm] the distance at which a pair is met and its
    direction fixed (None: ``separation``; module docstring), ``ramp`` [mm] the overlap over which
    a pair's stiffness grows to its full value (None: half the gap; 0: none, a plain quadratic
    penalty). :meth:`default` sizes them on the voxel edge and the walls' modulus."""

    gap: float
    stiffness: float
    separation: float
    reach: float | None = None
    ramp: float | None = None

    def __post_init__(self):
        if self.reach is None:
            object.__setattr__(self, "reach", self.separation)
        if self.ramp is None:
            object.__setattr__(self, "ramp", 0.5 * self.gap)
        for name in ("gap", "stiffness", "separation", "reach"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ConfigError(f"contact.{name}: {v!r}: must be finite and > 0")
        if not self.gap < self.reach <= self.separation:
            raise ConfigError(f"contact.gap, reach, separation: {self.gap:g}, {self.reach:g}, {self.separation:g} mm: "
                              "need gap < reach <= separation (two nodes in contact must have been apart)")
        if not (np.isfinite(self.ramp) and 0 <= self.ramp <= self.gap):
            raise ConfigError(f"contact.ramp: {self.ramp!r}: allowed range [0, gap = {self.gap:g}] mm")

    def penalty(self, over: np.ndarray, k: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(energy [mJ], force [N], stiffness [N/mm]), each (p,), of pairs of full stiffness ``k``
        (p,) [N/mm] at overlaps ``over`` (p,) >= 0 [mm]: ``phi``, ``phi'`` and ``phi''`` of the
        module docstring."""
        w = self.ramp
        if w == 0:
            return 0.5 * k * over * over, k * over, k.copy()
        low = over <= w
        lo = np.where(low, over, w)
        hi = np.where(low, 0.5 * w, over) - 0.5 * w  # o - w/2 beyond the ramp, 0 within it
        energy = np.where(low, k * lo**3 / (6 * w), 0.5 * k * hi * hi + k * w * w / 24)
        force = np.where(low, 0.5 * k * lo * lo / w, k * hi)
        return energy, force, np.where(low, k * lo / w, k)

    @staticmethod
    def default(h, E: float) -> "Contact":
        """``gap`` a quarter of the smallest voxel edge (the surface's staircase error, as
        :func:`.gaps.closest_approach`'s touch), ``stiffness`` 10 E / h, ``separation`` 2 h,
        ``reach`` h (the pairs within a voxel: on a printed sheet's 10^5 to 10^6 surface nodes
        the search within two voxels would list every wall's own neighbours by the ten million)."""
        hmin = float(np.min(np.asarray(h, float)))
        return Contact(0.25 * hmin, 10.0 * float(E) / hmin, 2.0 * hmin, hmin)


def surface_areas(solid: np.ndarray, h) -> tuple[np.ndarray, np.ndarray]:
    """(flat node indices (s,), their areas (s,) [mm^2]) of the faces between solid and void
    voxels of ``solid`` (nx, ny, nz) bool with edges ``h`` (3,) [mm]: each node a quarter of every
    such face it is a corner of (the grid's outer faces do not count: nothing lies beyond them)."""
    sol = np.asarray(solid, bool)
    h = np.asarray(h, float)
    N = tuple(n + 1 for n in sol.shape)
    area = np.zeros(N)
    for d in range(3):
        a, b = (d + 1) % 3, (d + 2) % 3
        lo = [slice(None)] * 3
        hi = [slice(None)] * 3
        lo[d], hi[d] = slice(0, -1), slice(1, None)
        face = sol[tuple(lo)] != sol[tuple(hi)]  # between voxels i and i + 1 along d: node plane i + 1
        quarter = 0.25 * h[a] * h[b] * face
        for da in (0, 1):
            for db in (0, 1):
                idx = [slice(None)] * 3
                idx[d] = slice(1, N[d] - 1)
                idx[a] = slice(da, N[a] - 1 + da)
                idx[b] = slice(db, N[b] - 1 + db)
                area[tuple(idx)] += quarter
    flat = np.flatnonzero(area.ravel() > 0)
    return flat, area.ravel()[flat]


class SurfacePairs:
    """The penalty on one body: its surface nodes (body numbering), their rest positions and
    areas, the pairs in contact at the last :meth:`forces` call (their tangent for :meth:`tangent`).

    nodes : (s,) int body-numbered surface nodes; rest : (s, 3) [mm] their rest positions;
    areas : (s,) [mm^2] their shares of the surface (:func:`surface_areas`).
    """

    def __init__(self, nodes: np.ndarray, rest: np.ndarray, areas: np.ndarray, contact: Contact):
        self.nodes = np.asarray(nodes, np.int64)
        self.rest = np.asarray(rest, float)
        self.areas = np.asarray(areas, float)
        if not (self.nodes.shape == self.areas.shape == self.rest.shape[:1]):
            raise ConfigError("contact: nodes, rest positions and areas must have one row per surface node")
        self.contact = contact
        self.pairs = np.zeros((0, 2), np.int64)  # (p, 2) into nodes, each row (a, b) with a < b
        self._H = np.zeros((0, 3, 3))  # (p, 3, 3) the pairs' d f_a / d x_a
        self._force = np.zeros(0)  # (p,) their forces [N]
        self._m, self._over = np.zeros((0, 3)), np.zeros(0)  # their directions and overlaps [mm]
        self.reset()

    def reset(self) -> None:
        """Forget the pairs' directions (a solve from another start)."""
        self._keys = np.zeros(0, np.int64)  # pairs met so far, a * s + b, increasing
        self._dirs = np.zeros((0, 3))  # their directions m, fixed when first met

    def forces(self, u: np.ndarray) -> tuple[np.ndarray, float, int]:
        """(n, 3) [N] the penalty's forces (the gradient of its energy, as the body's internal
        forces), its energy [mJ] and the pairs met already past each other (module docstring:
        the state is then refused) at body displacements ``u`` (n, 3) [mm]; keeps the pairs in
        contact."""
        c = self.contact
        x = self.rest + u[self.nodes]
        f = np.zeros_like(u)
        near = cKDTree(x).query_pairs(c.reach, output_type="ndarray")
        if len(near):
            near = np.sort(near, axis=1)
            near = near[np.linalg.norm(self.rest[near[:, 0]] - self.rest[near[:, 1]], axis=1) >= c.separation]
            near = near[np.lexsort((near[:, 1], near[:, 0]))]  # a fixed order: the same sums each run
        near = near.reshape(-1, 2).astype(np.int64)
        a, b = near[:, 0], near[:, 1]
        r = x[a] - x[b]
        keys = a * len(self.nodes) + b  # increasing, as near is sorted
        at = np.minimum(np.searchsorted(self._keys, keys), max(len(self._keys) - 1, 0))
        known = (self._keys[at] == keys) if len(self._keys) else np.zeros(len(keys), bool)
        m = np.empty_like(r)
        m[known] = self._dirs[at[known]]
        new = ~known
        d_new = np.linalg.norm(r[new], axis=1)
        if np.any(d_new <= 0.0):
            raise ConfigError("contact: two surface nodes at the same point: the pair has no direction")
        m[new] = r[new] / d_new[:, None]
        # a pair met for the first time the wrong way round (its nodes' order along it reversed
        # since rest) has passed through itself in one step: refused
        crossed = int(np.count_nonzero(np.einsum("ij,ij->i", m[new], self.rest[a[new]] - self.rest[b[new]]) <= 0))
        if crossed:
            return f, 0.0, crossed
        if new.any():
            keys_all = np.concatenate([self._keys, keys[new]])
            order = np.argsort(keys_all, kind="stable")
            self._keys, self._dirs = keys_all[order], np.concatenate([self._dirs, m[new]])[order]
        gn = np.einsum("ij,ij->i", r, m)  # the gap along the pair's direction [mm]
        inside = gn < c.gap
        self.pairs, self._m = near[inside], m[inside]
        a, b = a[inside], b[inside]
        over = c.gap - gn[inside]  # > 0
        energy, force, stiff = c.penalty(over, c.stiffness * 0.5 * (self.areas[a] + self.areas[b]))
        self._force, self._over = force, over
        g = -force[:, None] * self._m  # dE/dx_a
        np.add.at(f, self.nodes[a], g)
        np.add.at(f, self.nodes[b], -g)
        self._H = stiff[:, None, None] * (self._m[:, :, None] * self._m[:, None, :])
        return f, float(np.sum(energy)), 0

    def save(self) -> tuple[np.ndarray, np.ndarray]:
        """The pairs' directions met so far, for :meth:`restore`."""
        return self._keys, self._dirs

    def restore(self, saved: tuple[np.ndarray, np.ndarray]) -> None:
        """Forget the directions met since :meth:`save` gave ``saved``: a refused trial state
        leaves no pair's direction behind, so the energy stays a function of the kept state."""
        self._keys, self._dirs = saved

    def tangent(self, v: np.ndarray) -> np.ndarray:
        """(n, 3) the penalty's tangent times ``v`` (n, 3), at the last :meth:`forces` call's pairs."""
        y = np.zeros_like(v)
        if not len(self.pairs):
            return y
        a, b = self.nodes[self.pairs[:, 0]], self.nodes[self.pairs[:, 1]]
        w = np.einsum("pij,pj->pi", self._H, v[a] - v[b])
        np.add.at(y, a, w)
        np.add.at(y, b, -w)
        return y

    def summary(self) -> dict:
        """The pairs in contact at the last :meth:`forces` call: their count, the smallest gap
        along a pair's direction [mm] and the sum of the pair forces [N]."""
        if not len(self.pairs):
            return {"pairs": 0, "min_distance_mm": None, "force_N": 0.0}
        return {"pairs": int(len(self.pairs)), "min_distance_mm": float(self.contact.gap - self._over.max()),
                "force_N": float(np.sum(self._force))}
