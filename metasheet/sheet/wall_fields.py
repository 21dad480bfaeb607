"""A printed sheet's walls kept from its linear DNS for the searches of their limits (issue 62).

The walls' first contact and strain (:mod:`.wall_limits`) need each print's displacement fields,
which the ``sheet`` stage's DNS computes on its way to the grip stiffness and, before this, the
``printed`` stage solved again. :class:`WallFields` keeps them compactly: the 18 fields of
bodies 1..3's unit motions with the centre held (the columns the stiffness's relative solve has,
:func:`.voxel_grips.relative_fields` gives every motion's field from them) at the nodes of the
held solid's free nodes only (a tied node moves with its grip), in float32 (the CG tolerance,
1e-6, is 16 times float32's rounding): about 80 MB a sheet of the paper's print at 0.25 mm
(340,000 free nodes of the 930,000 the held solid touches) against 2.8 GB for the grid's 24
fields in float64.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from ..fem.voxel.operator import touched_nodes

#: the file's format, checked on reading
FORMAT = 2


@dataclass(frozen=True)
class WallFields:
    """One printed sheet's walls: ``shape`` (3,) voxels, ``h`` (3,) [mm] voxel edges,
    ``solid_bits`` the held solid (:attr:`solid`) packed, ``nodes`` (n,) flat grid nodes the held
    solid touches, ``body`` (n,) int8 there 0 free or 1 + the grip it is tied to, ``U`` (f, 3, 18)
    float32 [mm per mm or rad] the relative unit fields at the free ones (a tied node moves with
    its grip: nothing to keep), ``references`` (4, 3) [mm] the grips' reference points in grid
    coordinates (node (i, j, k) at (i, j, k) h), ``meta`` what print they are (label, seed,
    gauge, voxel_mm, kept_share)."""

    shape: tuple[int, int, int]
    h: np.ndarray
    solid_bits: np.ndarray
    nodes: np.ndarray
    body: np.ndarray
    U: np.ndarray
    references: np.ndarray
    meta: dict

    @classmethod
    def from_solve(cls, solid, h, U_rel, references, bodies, meta: dict) -> WallFields:
        """From the held ``solid`` (nx, ny, nz) bool, the grid's relative fields ``U_rel``
        (nx + 1, ny + 1, nz + 1, 3, 18) of :func:`.voxel_grips.rigid_bodies_stiffness` and its
        ``bodies`` (nx + 1, ny + 1, nz + 1) int node labels (0 free, 1 + b tied to grip b)."""
        s = np.asarray(solid, bool)
        nodes = np.flatnonzero(touched_nodes(np.where(s, 0, -1), False).ravel())
        body = np.asarray(bodies).ravel()[nodes].astype(np.int8)
        U = np.asarray(U_rel).reshape(-1, 3, np.shape(U_rel)[-1])[nodes[body == 0]].astype(np.float32)
        return cls(tuple(int(n) for n in s.shape), np.asarray(h, float).reshape(3), np.packbits(s.ravel()), nodes,
                   body, U, np.asarray(references, float), dict(meta))

    @property
    def solid(self) -> np.ndarray:
        """(nx, ny, nz) bool the voxels the grips hold."""
        n = int(np.prod(self.shape))
        return np.unpackbits(self.solid_bits, count=n).astype(bool).reshape(self.shape)

    def per_motor(self, G) -> np.ndarray:
        """(nx + 1, ny + 1, nz + 1, 3, m) [mm per unit] the fields of the grips' motions ``G``
        (24, m) (:meth:`.wall_limits.SheetWalls.per_motor`'s), zero off the held solid's nodes."""
        from .voxel_grips import point_modes, relative_fields

        N = tuple(n + 1 for n in self.shape)
        G = np.asarray(G, float).reshape(24, -1)
        x = np.stack(np.unravel_index(self.nodes, N), 1) * self.h
        F = np.zeros((int(np.prod(N)), 3, G.shape[1]))
        free = self.body == 0
        F[self.nodes[free]] = relative_fields(self.U, x[free], self.references, G)
        for b in range(len(self.references)):  # a tied node moves with its grip, exactly
            on = self.body == b + 1
            F[self.nodes[on]] = np.einsum("nic,cm->nim", point_modes(x[on] - self.references[b]), G[6 * b:6 * b + 6])
        return F.reshape(N + (3, G.shape[1]))

    def save(self, path) -> None:
        """Write to ``path`` (.npz) through a temporary name: never half-written."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.stem}.tmp-{os.getpid()}.npz")
        try:
            np.savez(tmp, format=FORMAT, shape=np.asarray(self.shape), h=self.h, solid_bits=self.solid_bits,
                     nodes=self.nodes, body=self.body, U=self.U, references=self.references, meta=json.dumps(self.meta, sort_keys=True))
            os.replace(tmp, path)
        finally:
            tmp.unlink(missing_ok=True)

    @classmethod
    def load(cls, path, expect: dict | None = None) -> WallFields:
        """Read ``path``; each key of ``expect`` must match the file's meta (else ConfigError)."""
        with np.load(path) as d:
            if int(d["format"]) != FORMAT:
                raise ConfigError(f"{path}: walls' fields of format {int(d['format'])}, this version reads {FORMAT}: "
                                  "run the sheet stage again")
            out = cls(tuple(int(v) for v in d["shape"]), d["h"], d["solid_bits"], d["nodes"], d["body"], d["U"],
                      d["references"], json.loads(str(d["meta"])))
        for k, v in (expect or {}).items():
            if out.meta.get(k) != v:
                raise ConfigError(f"{path}: its {k} is {out.meta.get(k)!r}, the print asked has {v!r}: run the sheet "
                                  "stage again")
        return out
