"""The reduced model's linearizer: the :class:`metasheet.robot.statics.Linearizer` interface on dense algebra.

The equilibrium solver, the Jacobian and the inverse controller call the same methods on it
as on the full model's; a linearisation's "free" part is the basis coordinates ``a``.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import scipy.linalg as sla

from ..robot.memo import LinearizationMemo, state_key
from ..robot.statics import Linearization
from ..mechanics.rotations import rotation_matrix
from .coordinates import ReducedState
from .tangents import Tangent, TangentLibrary


class ReducedLinearizer:
    """The reduced model's :class:`metasheet.robot.statics.Linearizer`: same methods, dense algebra.

    A linearisation's ``S`` is the Schur complement of ``a`` in the reduced tangent, ``Y``
    (k, 6 + na) and ``y_r`` (k,) its solves, ``res_f`` (k,) the projected free residual
    ``V^T r_f`` [N] and ``r`` the generalised internal forces (nq,) (the force scale's input).
    Every exact tangent goes to :attr:`library` (:mod:`.tangents`), which serves the
    inexact requests (``exact=False``: the control loop's modified-Newton matrix) with the
    nearest one; with ``background`` the missing ones are computed off the caller's thread.

    ``robot`` is the :class:`.model.ReducedRobot` it linearises (its ``evaluate``, ``na``,
    ``coupling``, ``sub``); the model builds its linearizer, so this module names it only here.
    """

    solver_name = "dense"

    def __init__(self, robot, *, background: bool = False, near_deg: float = 3.0):
        self.robot = robot
        self.factor = None
        self.factorizations = 0
        self.stats = {"tangents": 0, "forces": 0}
        self.library = TangentLibrary(lambda st: self._exact(st)[0], near_deg=near_deg, background=background)
        self._current = None
        self.memo = LinearizationMemo()  # exact tangents at repeated states (:mod:`metasheet.robot.memo`)

    def uses(self, solver: str) -> bool:
        return True  # one dense solver whatever the sparse one asked for

    def _exact(self, state: ReducedState):
        """(:class:`.tangents.Tangent`, g_int, g_ext) at ``state`` (thread-safe: no state kept)."""
        rob = self.robot
        g_int, g_ext, A = rob.evaluate(state, tangent=True)
        nr = 6 + rob.na
        factor = sla.lu_factor(A[nr:, nr:], check_finite=False)
        Y = sla.lu_solve(factor, A[nr:, :nr])
        C = A[:nr, nr:]
        return Tangent(np.array(state.angles, float), A[:nr, :nr] - C @ Y, Y, C, factor, state), g_int, g_ext

    def _use(self, t) -> None:
        if t is not self._current:
            self._current, self.factor = t, t.factor
            self.factorizations += 1

    def _lin(self, st, g_int, g_ext, t, fresh, exact) -> Linearization:
        rob = self.robot
        nr = 6 + rob.na
        G = g_int - g_ext
        y_r = sla.lu_solve(self.factor, G[nr:])
        return Linearization(state=st, r=g_int, S=t.S, Y=t.Y, y_r=y_r, C=t.C, R_rigid=G[:nr] - t.C @ y_r,
                             res_e=G[:6], res_f=G[nr:], fresh=fresh, moment_scale=rob.coupling.length_scale,
                             exact=exact)

    def linearize(self, state: ReducedState, *, exact: bool = True) -> Linearization:
        """The condensed reduced tangent and the residual at ``state``: fresh (``exact``, or
        without a background library), or the library's nearest (``exact=False``; then
        ``fresh`` and ``exact`` are False unless it was taken at this very state)."""
        # the library only in real-time use: studies and certificates keep exact tangents
        # (the inverse loop on stored ones can wander off on a large move: not yet robust)
        if exact or not self.library.background:
            t, g_int, g_ext = self._remembered(state)
            self.stats["tangents"] += 1
            self.library.add(t)
        else:
            t = self.library.get(state)
            g_int, g_ext, _ = self.robot.evaluate(state, tangent=False)
            self.stats["forces"] += 1
            exact = t.state is state  # computed here and now (an empty library)
        self._use(t)
        return self._lin(state, g_int, g_ext, t, exact, exact)

    def _remembered(self, state: ReducedState):
        """:meth:`_exact` at ``state``, or its result at an equal state taken lately (the same
        bits; a new :class:`.tangents.Tangent` object, as a recomputation gives)."""
        key = state_key(state, True)
        hit = self.memo.get(key)
        if hit is not None:
            t, g_int, g_ext = hit
            return replace(t, state=state), g_int, g_ext
        out = self._exact(state)
        self.memo.put(key, out)
        return out

    def update(self, lin: Linearization, state: ReducedState, f=None) -> Linearization:
        """Fresh residual at ``state`` on ``lin``'s tangent (a chord step)."""
        g_int, g_ext, _ = self.robot.evaluate(state, tangent=False)
        self.stats["forces"] += 1
        return self._lin(state, g_int, g_ext, lin, False, False)

    def apply(self, state: ReducedState, dq_e, dx_f, dq_a=None, alpha: float = 1.0) -> ReducedState:
        """The state after the increment alpha (dq_e, dq_a, da); ``dx_f`` is da (k,)."""
        p = state.p + alpha * dq_e[:3]
        R = rotation_matrix(alpha * dq_e[3:]) @ state.R
        angles = state.angles if dq_a is None else state.angles + dq_a
        return ReducedState(p, R, angles, state.a + alpha * np.asarray(dx_f))

    def force_scale(self, lin: Linearization) -> float:
        """Force scale [N]: the rigid bodies' generalised internal forces (moments and torques
        over the effector's ``length_scale``) plus the norm of the nodal weights."""
        rob = self.robot
        L = rob.coupling.length_scale
        g = lin.r[:6 + rob.na].copy()
        g[3:] /= L
        return float(np.linalg.norm(g) + rob.f_ext_norm)

    def residual_floor(self, lin: Linearization) -> float:
        """Round-off floor [N] of the reduced residual: the sampled body's force round-off
        (:func:`metasheet.robot.statics.residual_floor`'s per-entry bound) over its dofs."""
        sub = self.robot.sub
        eps = np.finfo(float).eps
        x = self.robot.sub_positions(lin.state)
        delta = 10 * eps * sub.stiffness_scale * float(np.abs(x).max())
        return float(delta * np.sqrt(3 * sub.n_nodes) + eps * self.force_scale(lin))
