"""Connectivity and percolation of a periodic phase grid.

The solid is labelled with face (6-) connectivity, the only one that carries load between
hexahedral voxels (voxels touching along an edge or a corner share too few nodes). The
grid is a torus: components that meet across opposite faces are one component, and a
component *percolates* along an axis when it contains a loop that winds around the torus
along that axis (a path leaving through the face ``x = L`` comes back through ``x = 0`` into
the same component *and has gained a period*). Merely touching both faces is not enough:
a blob that crosses the boundary once touches both and percolates nowhere.

The windings are found with a union-find that carries, for every label, its offset in
periods from the root of its set: joining two labels that already share a root closes a
loop whose winding is the difference of the offsets.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, InfeasibleError

_AXES = "xyz"


@dataclass(frozen=True)
class ConnectivityReport:
    """Connectivity of the solid (phases > 0) of a periodic grid.

    Attributes
    ----------
    components : number of periodic face-connected solid components.
    largest_fraction : share of the solid voxels in the largest component [-].
    percolates : (3,) bool, whether the largest component winds around x, y, z.
    solid_fraction : solid voxels / all voxels [-].
    windings : independent winding vectors (in periods) of the largest component's loops.
    """

    components: int
    largest_fraction: float
    percolates: tuple[bool, bool, bool]
    solid_fraction: float
    windings: tuple[tuple[int, int, int], ...] = ()

    @property
    def ok(self) -> bool:
        """One component that percolates along x, y and z."""
        return self.components == 1 and all(self.percolates)

    def problems(self) -> list[str]:
        """What is wrong, one short phrase each (empty when :attr:`ok`)."""
        out = []
        if self.components == 0:
            out.append("there is no solid")
        elif self.components > 1:
            out.append(
                f"the solid is in {self.components} pieces (the largest holds "
                f"{100 * self.largest_fraction:.1f} % of it)"
            )
        missing = [a for a, p in zip(_AXES, self.percolates) if not p]
        if self.components and missing:
            out.append(f"it does not percolate along {', '.join(missing)}")
        return out

    def require(self, what: str = "this cell") -> ConnectivityReport:
        """Return self when :attr:`ok`, else raise :class:`InfeasibleError` saying why."""
        if not self.ok:
            raise InfeasibleError(f"{what}: {'; '.join(self.problems())}")
        return self

    def to_dict(self) -> dict:
        return {
            "components": int(self.components),
            "largest_fraction": float(self.largest_fraction),
            "percolates": {a: bool(p) for a, p in zip(_AXES, self.percolates)},
            "solid_fraction": float(self.solid_fraction),
            "windings": [list(w) for w in self.windings],
            "ok": bool(self.ok),
        }


class _OffsetUnionFind:
    """Union-find over labels, each with an integer offset (in periods) from its root."""

    def __init__(self, n: int):
        self.parent = np.arange(n)
        self.offset = np.zeros((n, 3), dtype=np.int64)
        self.loops: dict[int, list[np.ndarray]] = {}

    def find(self, a: int) -> tuple[int, np.ndarray]:
        path = []
        while self.parent[a] != a:
            path.append(a)
            a = self.parent[a]
        root = a
        # compress: offsets accumulate from the node up to the root
        acc = np.zeros(3, dtype=np.int64)
        for node in reversed(path):
            acc = acc + self.offset[node]
            self.offset[node] = acc
            self.parent[node] = root
        return root, (self.offset[path[0]].copy() if path else np.zeros(3, dtype=np.int64))

    def union(self, a: int, b: int, shift: np.ndarray) -> None:
        """Label ``b`` sits at ``shift`` periods from label ``a`` across the boundary."""
        ra, oa = self.find(a)
        rb, ob = self.find(b)
        if ra == rb:
            w = oa + shift - ob
            if np.any(w):
                self.loops.setdefault(ra, []).append(w)
            return
        # position of rb relative to ra: oa + shift - ob
        self.parent[rb] = ra
        self.offset[rb] = oa + shift - ob
        if rb in self.loops:
            self.loops.setdefault(ra, []).extend(self.loops.pop(rb))


def _independent(vectors: list[np.ndarray]) -> tuple[tuple[int, int, int], ...]:
    """A maximal linearly independent subset (greedy), as int tuples."""
    basis: list[np.ndarray] = []
    for v in vectors:
        trial = np.array(basis + [v], dtype=float)
        if np.linalg.matrix_rank(trial) > len(basis):
            basis.append(v)
        if len(basis) == 3:
            break
    return tuple(tuple(int(c) for c in v) for v in basis)


def periodic_labels(solid: np.ndarray):
    """Label a boolean (nx, ny, nz) grid with periodic face connectivity.

    Returns
    -------
    labels : (nx, ny, nz) int, 0 outside the solid, 1..count inside (periodic components).
    count : number of periodic components.
    uf : the union-find over the non-periodic labels (for windings).
    raw : (nx, ny, nz) int, the non-periodic labels ``uf`` works on.
    """
    solid = np.asarray(solid, dtype=bool)
    if solid.ndim != 3:
        raise ConfigError(f"phases: shape is {solid.shape} and should be (nx, ny, nz)")
    from scipy import ndimage  # here: 0.3 s of every command's start

    lab, n = ndimage.label(solid)  # default structure: face connectivity
    uf = _OffsetUnionFind(n + 1)
    for ax in range(3):
        last = np.take(lab, -1, axis=ax)
        first = np.take(lab, 0, axis=ax)
        both = (last > 0) & (first > 0)
        if not np.any(both):
            continue
        pairs = np.unique(np.stack([last[both], first[both]], axis=1), axis=0)
        shift = np.zeros(3, dtype=np.int64)
        shift[ax] = 1
        for a, b in pairs:
            uf.union(int(a), int(b), shift)
    roots = np.array([uf.find(i)[0] for i in range(n + 1)])
    uniq, merged = np.unique(roots[1:], return_inverse=True) if n else (np.array([]), np.array([], int))
    relabel = np.zeros(n + 1, dtype=np.int64)
    relabel[1:] = merged + 1
    return relabel[lab], len(uniq), uf, lab


def check_percolation(phases: np.ndarray) -> ConnectivityReport:
    """Connectivity report of the solid ``phases > 0`` of a periodic grid (nx, ny, nz).

    The homogenize stage can refuse a cell with ``check_percolation(phases).require(...)``.
    """
    phases = np.asarray(phases)
    solid = phases > 0
    labels, count, uf, raw = periodic_labels(solid)
    total_solid = int(solid.sum())
    if count == 0:
        return ConnectivityReport(0, 0.0, (False, False, False), 0.0)
    sizes = np.bincount(labels.ravel(), minlength=count + 1)[1:]
    big = int(np.argmax(sizes)) + 1
    # root (in uf) of the largest component
    member = int(np.argmax(labels.ravel() == big))
    root, _ = uf.find(int(raw.ravel()[member]))
    loops = uf.loops.get(root, [])
    windings = _independent(loops)
    perc = tuple(bool(any(w[i] != 0 for w in windings)) for i in range(3))
    return ConnectivityReport(
        components=count,
        largest_fraction=float(sizes.max()) / total_solid,
        percolates=perc,
        solid_fraction=total_solid / solid.size,
        windings=windings,
    )


def keep_largest(phases: np.ndarray) -> tuple[np.ndarray, int]:
    """Phases with every solid component but the largest (periodic) set to void.

    Returns the new grid (same dtype) and the number of voxels removed.
    """
    phases = np.asarray(phases)
    labels, count, _, _ = periodic_labels(phases > 0)
    if count <= 1:
        return phases.copy(), 0
    sizes = np.bincount(labels.ravel(), minlength=count + 1)
    sizes[0] = 0
    big = int(np.argmax(sizes))
    out = phases.copy()
    drop = (labels != big) & (labels > 0)
    out[drop] = 0
    return out, int(drop.sum())


def settle_phases(phases: np.ndarray, *, target: float, tolerance: float, max_island_fraction: float,
                  setting: str, where: str, hints: tuple[str, str, str]) -> tuple[np.ndarray, ConnectivityReport, int, float]:
    """Drop small islands, then require one percolating piece and the target solid fraction.

    Parameters
    ----------
    phases : (nx, ny, nz) uint8, 0 void.
    target, tolerance : the wanted solid fraction [-] and the allowed |achieved - target|.
    max_island_fraction : share of the solid that may be dropped as islands [-].
    setting : ``"name: value"`` of the design setting the errors name first.
    where : what was built (design, grid), for the messages.
    hints : what to change when (islands, no percolation, density out of tolerance).

    Returns
    -------
    (phases, report, removed island voxels, achieved solid fraction).

    Raises
    ------
    InfeasibleError : too many islands, no percolation along x, y and z, or the density missed.
    """
    report = check_percolation(phases)
    removed = 0
    if report.components > 1:
        if 1.0 - report.largest_fraction > max_island_fraction:
            raise InfeasibleError(f"{setting}: {where}: {'; '.join(report.problems())} (more than "
                                  f"max_island_fraction = {max_island_fraction:g}); {hints[0]}")
        phases, removed = keep_largest(phases)
        report = check_percolation(phases)
    if not report.ok:
        raise InfeasibleError(f"{setting}: {where}: {'; '.join(report.problems())}; {hints[1]}")
    rho = float(np.count_nonzero(phases)) / phases.size
    if abs(rho - target) > tolerance:
        raise InfeasibleError(f"{setting}: {where}: reached a solid fraction {rho:.4f}, outside tolerance "
                              f"{tolerance:g} after dropping {removed} island voxels; {hints[2]}")
    return phases, report, removed, rho
