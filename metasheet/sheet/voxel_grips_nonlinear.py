"""Rigid grips at finite poses on a hyperelastic voxel body: the wrenches they carry.

The finite-strain counterpart of :mod:`.voxel_grips` (issue 62, item 2). Grip ``b`` holds its
tied nodes in a rigid pose: rotation ``R_b`` (a rotation vector ``theta_b`` [rad]) about its
reference point ``r_b`` and translation ``t_b`` [mm],

    x_i = r_b + t_b + R_b (X_i - r_b),

the other nodes of the kept solid find their equilibrium under the neo-Hookean walls
(:func:`metasheet.fem.voxel.nonlinear.solve_hyperelastic`), and each grip carries the wrench

    w_b = (sum_i f_i,  sum_i (x_i - r_b - t_b) x f_i)        [N, N mm]

of the internal forces at its nodes: force, and moment about its reference point where it is
now. At rest this is the linear DNS's condensed stiffness to first order, ``dw = K dq`` with
``q = (t, theta)`` per grip in :mod:`.voxel_grips`' order (tested by central differences), and
a rigid motion of every grip together carries no wrench (tested). The kept solid is
:func:`.voxel_grips.held_solid`'s, as in the linear DNS.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..fem.voxel.hyperelastic import NeoHookean
from ..fem.voxel.nonlinear import HyperelasticBody, NonlinearSolution
from ..mechanics.rotations import rotation_matrix
from .voxel_grips import _bodies, _references, held_solid


@dataclass(frozen=True)
class GripWrenches:
    """``wrenches`` (B, 6) [N, N mm] each grip's (force, moment about its moved reference point);
    ``solution`` the body's :class:`~metasheet.fem.voxel.nonlinear.NonlinearSolution`;
    ``kept_share`` the share of the solid the grips hold [-]."""

    wrenches: np.ndarray
    solution: NonlinearSolution
    kept_share: float


def grip_poses(rotations, translations, B: int) -> tuple[np.ndarray, np.ndarray]:
    """((B, 3, 3) rotation matrices, (B, 3) translations [mm]) of ``rotations`` (B, 3) rotation
    vectors [rad] and ``translations`` (B, 3) [mm]; a ConfigError naming the field otherwise."""
    out = []
    for name, a in (("rotations", rotations), ("translations", translations)):
        a = np.asarray(a, float)
        if a.shape != (B, 3) or not np.all(np.isfinite(a)):
            raise ConfigError(f"{name}: shape {a.shape}: must be ({B}, 3) finite values, one row per grip")
        out.append(a)
    if np.any(np.linalg.norm(out[0], axis=1) > np.pi):
        raise ConfigError("rotations: a rotation vector longer than pi rad: give each grip's rotation within "
                          "[-180, 180] deg")
    return np.stack([rotation_matrix(v) for v in out[0]]), out[1]


class GripBody:
    """A voxel body with its grips, prepared once (the kept solid, the hyperelastic body and its
    multigrid) and solved at any grip poses (:meth:`wrenches`).

    phases : (nx, ny, nz) int, 0 = void, k > 0 solid; size : (3,) grid edges [mm];
    bodies : (nx + 1, ny + 1, nz + 1) int, 0 free, b >= 1 tied to grip b - 1; references :
    (B, 3) [mm] grid coordinates; contact : the walls' penalty contact
    (:class:`~metasheet.fem.voxel.nonlinear.HyperelasticBody`'s: None, True or a Contact).
    """

    def __init__(self, phases, size, law: NeoHookean, *, bodies, references, contact=None):
        ph = np.asarray(phases)
        N = tuple(int(n) + 1 for n in ph.shape)
        body, self.B = _bodies(bodies, N)
        self.refs = _references(references, self.B)
        solid = ph > 0
        kept = held_solid(solid, body > 0)
        if not kept.any():
            raise ConfigError("bodies: no solid piece is held by a grip (three non-collinear tied nodes)")
        self.kept_share = float(kept.sum() / max(solid.sum(), 1))
        h = np.asarray(size, float) / np.array(ph.shape)
        self.X = np.stack(np.indices(N), -1) * h  # (Nx, Ny, Nz, 3) node positions [mm]
        self.tied = body > 0
        self.b = body[self.tied] - 1
        self.N = N
        self.hyper = HyperelasticBody(np.where(kept, ph, 0), size, law, np.repeat(self.tied[..., None], 3, axis=3),
                                      contact)

    def wrenches(self, rotations, translations, initial=None, rtol: float = 1e-8, progress=None,
                 probe: bool = True) -> GripWrenches:
        """The grips' wrenches with every grip at its pose (module docstring): ``rotations``,
        ``translations`` (B, 3) [rad, mm]; ``initial`` (nx + 1, ny + 1, nz + 1, 3) [mm] a start for
        the free nodes (a nearby pose's solution); rtol : Newton's relative residual; probe : the
        equilibrium checked for stability (:meth:`HyperelasticBody.solve`)."""
        R, t = grip_poses(rotations, translations, self.B)
        b, refs = self.b, self.refs
        values = np.zeros(self.N + (3,))
        Xt = self.X[self.tied]
        values[self.tied] = refs[b] + t[b] + np.einsum("nij,nj->ni", R[b], Xt - refs[b]) - Xt
        sol = self.hyper.solve(values, initial, rtol=rtol, probe=probe, progress=progress)
        f = sol.full(sol.forces)[self.tied]
        arm = (self.X + sol.full(sol.u))[self.tied] - (refs + t)[b]
        w = np.zeros((self.B, 6))
        np.add.at(w, b, np.concatenate([f, np.cross(arm, f)], axis=1))
        return GripWrenches(w, sol, self.kept_share)

    def submit(self, rotations, translations, initial=None, rtol: float = 1e-8, probe: bool = True,
               progress=None) -> None:
        """Keep a solve's arguments for :meth:`result` (a :class:`~metasheet.robot.sheet_process.SheetProcess`
        runs it at once in its child; here it runs when the result is asked for)."""
        self._asked = (rotations, translations, initial, rtol, progress, probe)

    def result(self) -> GripWrenches:
        """The :meth:`submit`-ted solve's wrenches."""
        asked, self._asked = getattr(self, "_asked", None), None
        if asked is None:
            raise ConfigError("result: no solve was submitted")
        return self.wrenches(*asked)

    def floor(self, u: np.ndarray) -> float:
        """The forces' round-off [N] at displacements ``u`` (:meth:`HyperelasticBody.floor`)."""
        return self.hyper.floor(u)


def grip_wrenches(phases, size, law: NeoHookean, *, bodies, references, rotations, translations,
                  initial=None, rtol: float = 1e-8, progress=None) -> GripWrenches:
    """The grips' wrenches with every grip at its pose, once (:class:`GripBody` prepared and solved)."""
    return GripBody(phases, size, law, bodies=bodies, references=references).wrenches(
        rotations, translations, initial, rtol, progress)
