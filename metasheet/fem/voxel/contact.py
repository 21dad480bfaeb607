"""Penalty contact between the walls of a voxel body: two surfaces that were apart push each
other away when they come closer than a gap (issue 62: the printed foam's walls touch at large
strain, Section VI of the paper, and past the first touch a model without contact lets them
pass through each other).

The surface is the nodes the solid shares with the void (:func:`.gaps.surface_nodes`). Two
surface nodes ``a``, ``b`` whose rest distance is at least ``separation`` (two voxel edges by
default: across a void or around a wall's end, never two neighbours in one wall) form a pair
when their distance ``d`` is below ``gap``; each pair stores the energy

    E_ab = k / 2 (gap - d)^2,        d = |x_a - x_b|,   k = ``stiffness`` [N/mm],

so the force on ``a`` is ``k (gap - d) n``, ``n = (x_a - x_b) / d``, and its consistent
tangent is ``k n n^T - k (gap - d) / d (I - n n^T)`` (``-`` that on ``b``, the cross blocks
with the other sign). The energy is continuous in the positions and its gradient too, so the
trust-region Newton method of :mod:`.nonlinear` minimises the walls' energy plus this one
with its own acceptance test; the pairs are found again at every force evaluation (a k-d tree
on the moved surface), in a fixed order: the same bits on any run.

A node-to-node penalty can be stepped over: a step that carries a node through the wall it
faces lands where no pair is within the gap. So each evaluation also keeps the pairs within
``separation`` (the approaching ones) with their direction, and a trial state in which one of
them has turned by more than a right angle (the two nodes have passed each other) is refused
like a state that inverts an element: the solver halves its load step or shrinks its trust
region. A step that moves two nodes by more than ``separation`` past each other is not seen.

A penalty lets the surfaces come within ``gap - F / k`` of each other under a pair force F: the
default stiffness, 10 E h per pair (E the walls' modulus, h the smallest voxel edge: ten times a
voxel's own stiffness), keeps that to a small fraction of a voxel at the wall's own stresses.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ...errors import ConfigError


@dataclass(frozen=True)
class Contact:
    """The penalty's parameters: ``gap`` [mm] the distance below which two surface nodes push
    apart, ``stiffness`` [N/mm] per pair, ``separation`` [mm] the rest distance a pair must have
    had (module docstring). :meth:`default` sizes them on the voxel edge and the walls' modulus."""

    gap: float
    stiffness: float
    separation: float

    def __post_init__(self):
        for name in ("gap", "stiffness", "separation"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ConfigError(f"contact.{name}: {v!r}: must be finite and > 0")
        if not self.gap < self.separation:
            raise ConfigError(f"contact.gap: {self.gap:g} mm: must be below separation = {self.separation:g} mm "
                              "(two nodes in contact must have been apart)")

    @staticmethod
    def default(h, E: float) -> "Contact":
        """``gap`` a quarter of the smallest voxel edge (the surface's staircase error, as
        :func:`.gaps.closest_approach`'s touch), ``stiffness`` 10 E h, ``separation`` 2 h."""
        hmin = float(np.min(np.asarray(h, float)))
        return Contact(0.25 * hmin, 10.0 * float(E) * hmin, 2.0 * hmin)


class SurfacePairs:
    """The penalty on one body: its surface nodes (body numbering) and their rest positions,
    the pairs in contact at the last :meth:`forces` call (their tangent for :meth:`tangent`).

    nodes : (s,) int body-numbered surface nodes; rest : (s, 3) [mm] their rest positions.
    """

    def __init__(self, nodes: np.ndarray, rest: np.ndarray, contact: Contact):
        self.nodes = np.asarray(nodes, np.int64)
        self.rest = np.asarray(rest, float)
        self.contact = contact
        self.pairs = np.zeros((0, 2), np.int64)  # (p, 2) into nodes, each row (a, b) with a < b
        self._H = np.zeros((0, 3, 3))  # (p, 3, 3) the pairs' d f_a / d x_a
        self.reset()

    def reset(self) -> None:
        """Forget the approaching pairs (a solve from another start)."""
        self._near = np.zeros((0, 2), np.int64)  # approaching pairs at the last state evaluated
        self._near_r = np.zeros((0, 3))  # their x_a - x_b there [mm]

    def forces(self, u: np.ndarray) -> tuple[np.ndarray, float, int]:
        """(n, 3) [N] the penalty's forces (the gradient of its energy, as the body's internal
        forces), its energy [mJ] and the approaching pairs that passed each other since the last
        call (module docstring; the state is then refused) at body displacements ``u`` (n, 3)
        [mm]; keeps the pairs in contact and the approaching ones."""
        c = self.contact
        x = self.rest + u[self.nodes]
        f = np.zeros_like(u)
        if len(self._near):
            now = x[self._near[:, 0]] - x[self._near[:, 1]]
            crossed = int(np.count_nonzero(np.einsum("ij,ij->i", now, self._near_r) <= 0.0))
            if crossed:
                return f, 0.0, crossed
        near = cKDTree(x).query_pairs(c.separation, output_type="ndarray")
        if len(near):
            near = np.sort(near, axis=1)
            near = near[np.linalg.norm(self.rest[near[:, 0]] - self.rest[near[:, 1]], axis=1) >= c.separation]
            near = near[np.lexsort((near[:, 1], near[:, 0]))]  # a fixed order: the same sums each run
        near = near.reshape(-1, 2).astype(np.int64)
        r = x[near[:, 0]] - x[near[:, 1]]
        d = np.linalg.norm(r, axis=1)
        self._near, self._near_r = near, r
        inside = d < c.gap
        self.pairs = near[inside]
        if not len(self.pairs):
            self._H = np.zeros((0, 3, 3))
            return f, 0.0, 0
        a, b = self.pairs[:, 0], self.pairs[:, 1]
        r, d = r[inside], d[inside]
        if np.any(d <= 0.0):
            raise ConfigError("contact: two surface nodes at the same point: the penalty has no direction there")
        n = r / d[:, None]
        over = c.gap - d  # > 0
        g = -c.stiffness * over[:, None] * n  # dE/dx_a
        np.add.at(f, self.nodes[a], g)
        np.add.at(f, self.nodes[b], -g)
        nn = n[:, :, None] * n[:, None, :]
        self._H = c.stiffness * (nn - (over / d)[:, None, None] * (np.eye(3) - nn))
        return f, float(0.5 * c.stiffness * np.sum(over * over)), 0

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

    def summary(self, u: np.ndarray) -> dict:
        """The pairs in contact at ``u``: their count, the smallest distance [mm] and the sum of
        the pair forces' magnitudes [N] (at the last :meth:`forces` call's pairs)."""
        if not len(self.pairs):
            return {"pairs": 0, "min_distance_mm": None, "force_N": 0.0}
        x = self.rest + u[self.nodes]
        d = np.linalg.norm(x[self.pairs[:, 0]] - x[self.pairs[:, 1]], axis=1)
        return {"pairs": int(len(d)), "min_distance_mm": float(d.min()),
                "force_N": float(self.contact.stiffness * np.sum(self.contact.gap - d))}
