"""The control loop's kept linearisation (paper eq. 6-7, used by the QP of eq. 8).

A fresh linearisation (tangent, factorisation of ``K_ff``, Schur complement ``S`` and the
Jacobian ``J = W_ea W_aa^-1``) costs several chord steps, so the inverse loop
(:mod:`.inverse`) keeps one across control steps and re-evaluates only the forces, with one
solve on the cached factor (a chord / modified-Newton step, :meth:`.statics.Linearizer.update`).
It is never trusted blindly: :class:`TangentCache` takes a fresh one when (defaults in
brackets, from :class:`.inverse_settings.InverseSettings`)

* "age": it is ``refactor_every`` steps old [20];
* "angle": a motor moved more than ``refresh_angle_deg`` from where it was taken [8 deg];
* "residual": the reduced residual exceeds ``chord_tol`` times the force scale [1.0]
  (:func:`.statics.force_scale`; divergence guard);
* "drift": the pending equilibrium correction of the effector, ``dq_e^0`` [mm, rotations
  weighted by ``rot_weight``], exceeds ``drift_tol * pos_tol`` [0.5 * 0.1 mm];

tested in that order, the first that holds counted in :attr:`TangentCache.reasons`. It is not
even tried (a fresh one, nothing counted) when the state is not one of the loop's own (set from
outside: another goal, a reset) or when another user of the shared
:class:`.statics.Linearizer` (the equilibrium solver, the kinematics) factorised since: its
:attr:`~.statics.Linearizer.factorizations` counter moved.

Continuation: the last ``OWN_STATES`` states the loop produced (control steps, certified
equilibria) are remembered; setting one of them back keeps the tangent, the tests above still
run on it.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from .kinematics import jacobian_from_schur
from .qp import weighted_norm
from .statics import Linearization, Linearizer, RobotState

OWN_STATES = 16  # states a loop remembers as its own (continuation without a refresh)
REASONS = ("age", "angle", "residual", "drift")  # why a kept tangent is dropped, in test order


class TangentCache:
    """The kept linearisation of one control loop on a shared :class:`.statics.Linearizer`.

    Parameters
    ----------
    linearizer : builds the linearisations (its factor may be replaced by other users).
    own_states : how many of the loop's own states are remembered.

    Attributes
    ----------
    linearizer : the :class:`.statics.Linearizer` in use (:meth:`use` replaces it).
    lin : the kept :class:`.statics.Linearization` (None: the next one is fresh).
    J : (6, na) direct Jacobian of the last fresh linearisation (eq. 7) [mm/rad, rad/rad].
    angles : (na,) motor angles it was taken at [rad] (None before the first).
    age : linearisations handed out since the last fresh one, that one included.
    generation : ``linearizer.factorizations`` right after the last fresh one (-1: none).
    refreshes : fresh linearisations taken.
    reasons : kept tangents dropped, counted by reason (see the module docstring).
    """

    def __init__(self, linearizer: Linearizer, *, own_states: int = OWN_STATES):
        self.linearizer = linearizer
        self.lin: Linearization | None = None
        self.J: np.ndarray | None = None
        self.angles: np.ndarray | None = None
        self.age = 0
        self.generation = -1
        self.refreshes = 0
        self.reasons: dict = {}
        self._own: deque = deque(maxlen=own_states)  # states the loop produced: anything else came from outside
        self._for = None  # the settings of the last linearisation handed out

    # -- the loop's own states --------------------------------------------------------------
    def remember(self, state: RobotState) -> None:
        """Record ``state`` as one the loop produced (continuation from it keeps the tangent)."""
        self._own.append(state)

    def owns(self, state) -> bool:
        """Whether ``state`` (the object itself, not an equal copy) is one of the recent own states."""
        return any(s is state for s in self._own)

    # -- the kept tangent -------------------------------------------------------------------
    def use(self, linearizer: Linearizer) -> None:
        """Switch to another linearizer (another sparse solver): the kept tangent is dropped."""
        self.linearizer = linearizer
        self.lin = None

    def drop(self) -> None:
        """Forget the kept tangent: the next :meth:`linearization` is a fresh one."""
        self.lin = None

    def kept(self, state: RobotState) -> bool:
        """Whether the kept tangent may be tried at ``state``: there is one, ``state`` is the
        loop's own, and nobody refactorised the shared linearizer since it was taken."""
        return (self.lin is not None and self.owns(state)
                and self.linearizer.factorizations == self.generation)

    def aged(self, state: RobotState, settings) -> str | None:
        """"age" or "angle" when the kept tangent is too old for ``state`` whatever the
        residual there (:meth:`stale`'s first two tests, which need no forces), else None."""
        s = settings
        if self.age >= s.refactor_every:
            return "age"
        if np.max(np.abs(state.angles - self.angles), initial=0.0) > np.radians(s.refresh_angle_deg):
            return "angle"
        return None

    def stale(self, lin: Linearization, state: RobotState, settings) -> str | None:
        """Why the chord update ``lin`` at ``state`` is not good enough (a :data:`REASONS`
        entry), or None. ``settings``: an :class:`.inverse_settings.InverseSettings`."""
        s = settings
        why = self.aged(state, s)
        if why is not None:
            return why
        # written as "not <=" so a NaN residual or step (a chord update gone wrong) is stale too
        if not lin.residual_norm <= s.chord_tol * max(self.linearizer.force_scale(lin), 1e-300):
            return "residual"
        if not weighted_norm(lin.newton_step(None)[0], s.rot_weight) <= s.drift_tol * s.pos_tol:
            return "drift"
        return None

    def linearization(self, state: RobotState, settings) -> Linearization:
        """The linearisation at ``state`` for a control step: the chord update of the kept
        tangent when it passes the tests, else a fresh one (kept for the next steps).

        The residual and the pending correction are evaluated every time, never assumed; asked
        again at the same state (the object) with the same settings and nothing refactorised
        since, the linearisation just handed out is handed out again.
        """
        if (self.lin is not None and self.lin.state is state and self._for is settings
                and self.linearizer.factorizations == self.generation):
            return self.lin
        self._for = settings
        lin = None
        if self.kept(state):
            # the tests in :meth:`stale`'s order, each as early as it can be decided: age and
            # angle before the forces, the residual (where the linearizer can) before the solve
            why = self.aged(state, settings)
            if why is None:
                within = getattr(self.linearizer, "update_within", None)
                lin = (self.linearizer.update(self.lin, state) if within is None
                       else within(self.lin, state, settings.chord_tol))
                why = "residual" if lin is None else self.stale(lin, state, settings)
            if why is not None:
                self.reasons[why] = self.reasons.get(why, 0) + 1
                lin = None
        if lin is None:
            # modified Newton: the factor as it is (CHOLMOD: symmetric part), checked every step
            lin = self.linearizer.linearize(state, exact=False)
            self.J = jacobian_from_schur(lin.S)[1]
            self.age = 0
            self.angles = state.angles.copy()
            self.generation = self.linearizer.factorizations
            self.refreshes += 1
        self.lin = lin
        self.age += 1
        return lin
