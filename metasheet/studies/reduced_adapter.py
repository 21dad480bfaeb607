"""The reduced-order robot (:mod:`metasheet.robot.reduced`) as a :class:`~.model.RobotModel`.

:class:`ReducedSpec` is the picklable recipe: the full robot's :class:`~.adapter.RobotSpec`,
the path of the ``reduce`` stage's ``basis.npz`` and that file's content hash (both in
:attr:`ReducedSpec.key`, so another basis is another model). :class:`ReducedFem` is the live
model built from it in each worker: the full :class:`~.adapter.FemRobot` (kept for the
fallbacks and the certificate), the :class:`~metasheet.robot.reduced.ReducedRobot` on it and
the eq. (8) controller on the reduced robot, limited to the spec's motor range.

Outside its training box (``basis.box_lo``, ``basis.box_hi`` [rad]) the reduced model would
extrapolate: an equilibrium asked there is solved by the full model, and a reach that ends
there is judged as below (a warning is logged once per model when the full model takes over;
:attr:`ReducedFem.fallbacks` counts those). Such a result carries a full
:class:`~metasheet.robot.statics.RobotState`; a call given a full state continues on the
reduced model from its projection (:meth:`~metasheet.robot.reduced.ReducedRobot.project`)
when it lies in the box, else from the reduced rest.

With a domain strain (:meth:`ReducedSpec.with_domain_strain`, set by the studies that stop
beyond the strain limit) a reach that leaves the box is followed along the straight path in
motor space from its start to its end: first to where that path leaves the box
(:func:`box_exit`), on the reduced model; when the material there is already beyond the limit,
the goal lies outside the homogenised model's domain and the reach returns that edge state
with ``left_domain`` set (not reached). Otherwise the full model takes the path on from the
edge, in steps of at most :data:`WALK_STEP_DEG` (each a full equilibrium from the last, a
second or so on the converged mesh), and stops with ``left_domain`` at the first step beyond
the limit. A path that stays within the limit ends at the full equilibrium at the reduced
answer's motor angles: that is the answer when it meets the goal's tolerances, else the full
model reaches the goal from there.

Without a domain strain, a reach outside the box that the reduced model says reached its goal
is checked by the full model's equilibrium at the reduced answer's motor angles (one solve
instead of a whole reach): when the full pose there meets the goal's tolerances, that full
equilibrium is the answer (a full state, judged as the full model's reach would be). Only
otherwise does the full model reach the goal itself.

A material change (``with_alpha``, ``with_material``) makes the basis invalid (it was trained
for one material): those return the full model's spec, with a logged warning, so a study that
sweeps materials (the anisotropy sweep, the maze's silicone sheets) runs them on the full model.
"""

from __future__ import annotations

import hashlib
import logging
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import ConfigError, ConvergenceError
from .adapter import FemRobot, RobotSpec
from .model import pose_errors

log = logging.getLogger(__name__)

#: Largest motor step [deg] of the full model's walk beyond the box (module docstring): on the
#: authors' P2 robot the strain grows ~0.03 per degree there, so a 2 deg step overshoots the
#: limit by at most ~0.06 and the walk stops one or two solves past the box.
WALK_STEP_DEG = 2.0


def file_hash(path: Path | str) -> str:
    """sha256 of a file's bytes (hex, 24 characters)."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()[:24]


@dataclass(frozen=True, eq=False)
class ReducedSpec:
    """Recipe of the reduced robot.

    Attributes
    ----------
    full : the full robot's :class:`~.adapter.RobotSpec` (the basis must have been trained on it).
    basis_path : absolute path of the ``reduce`` stage's ``basis.npz`` (workers read it: on a
        dask cluster it must be on a shared file system).
    basis_hash : :func:`file_hash` of that file when the spec was made (checked at build).
    domain_strain : the strain limit [-] a reach leaving the box is checked against on its way
        out (see the module docstring); None: such reaches are checked or redone by the full model.
    """

    full: RobotSpec
    basis_path: str
    basis_hash: str
    domain_strain: float | None = None

    @classmethod
    def from_file(cls, full: RobotSpec, path: Path | str) -> "ReducedSpec":
        """The reduced robot of ``full`` on the basis in ``path`` (basis.npz)."""
        path = Path(path).resolve()
        if not path.is_file():
            raise ConfigError(f"model 'reduced': {path} is missing; run the 'reduce' stage")
        return cls(full, str(path), file_hash(path))

    @property
    def key(self) -> str:
        tail = "" if self.domain_strain is None else f"|{self.domain_strain!r}"
        return "rom-" + hashlib.sha256(f"{self.full.key}|{self.basis_hash}{tail}".encode()).hexdigest()[:24]

    def with_domain_strain(self, limit: float | None) -> "ReducedSpec":
        """The same reduced robot whose reaches leaving the box stop where their motor path
        passes the strain ``limit`` [-] (None: they are checked or redone by the full model)."""
        return replace(self, domain_strain=None if limit is None else float(limit))

    @property
    def design_alpha(self) -> float:
        return self.full.design_alpha

    @property
    def motor_range(self) -> tuple:
        return self.full.motor_range

    @property
    def model(self) -> str:
        """The material model of the full robot ("ours" or "authors")."""
        return self.full.model

    @property
    def tets(self) -> np.ndarray:
        """(m, 4) the full robot's first sheet's tetrahedra."""
        return self.full.tets

    @property
    def strain_band_mm(self) -> float:
        """The full robot's band along the grips left out of the strain check [mm]."""
        return self.full.strain_band_mm

    def build(self) -> "ReducedFem":
        return ReducedFem(self)

    def with_motor_range(self, lo_deg: float, hi_deg: float) -> "ReducedSpec":
        """The same reduced robot with motors limited to [lo_deg, hi_deg] (the basis stays valid:
        angles outside its training box fall back to the full model)."""
        return replace(self, full=self.full.with_motor_range(lo_deg, hi_deg))

    def with_alpha(self, alpha: float) -> RobotSpec:
        """The FULL robot's spec at anisotropy ``alpha`` [%]: the basis is the design material's."""
        log.warning("model 'reduced': another material (alpha %.4g %%) invalidates the basis: "
                    "that case runs on the full model", float(alpha))
        return self.full.with_alpha(alpha)

    def with_material(self, material, density: float | None = None) -> RobotSpec:
        """The FULL robot's spec with another sheet material: the basis is the design material's."""
        log.warning("model 'reduced': another sheet material (%s) invalidates the basis: that case runs "
                    "on the full model", type(material).__name__)
        return self.full.with_material(material, density)


class ReducedFem(FemRobot):
    """The reduced robot of a :class:`ReducedSpec` behind the study protocol (see the module docstring).

    Attributes
    ----------
    full : the full :class:`~.adapter.FemRobot` (fallbacks, strains, certificate).
    robot : the :class:`~metasheet.robot.reduced.ReducedRobot`, limits = the spec's motor range.
    basis : its :class:`~metasheet.robot.reduced.ReducedBasis`. fallbacks : calls redone by the full model.
    """

    def __init__(self, spec: ReducedSpec):
        from ..robot.inverse import InverseController
        from ..robot.reduced import ReducedBasis, ReducedRobot, robot_key

        if file_hash(spec.basis_path) != spec.basis_hash:
            raise ConfigError(f"model 'reduced': {spec.basis_path} changed since the study started; run it again")
        self.spec = spec
        self.full = FemRobot(spec.full)
        basis = ReducedBasis.load(Path(spec.basis_path))
        if basis.robot_key != robot_key(self.full.robot):
            raise ConfigError("model 'reduced': reduce/basis.npz was trained on another robot: give [reduce] the "
                              "same mesh settings (mesh_size, layers, grip_size, element) and scene as this study")
        full_rob = self.full.robot
        self.robot = ReducedRobot(full_rob, basis, check_key=False).with_limits(full_rob.angle_min, full_rob.angle_max)
        self.basis = basis
        self.settings = self.full.settings
        self.ctrl = InverseController(self.robot, settings=self.settings)
        self.lz = self.ctrl.linearizer
        self.rest = self.ctrl.state
        self.motor_range = self.full.motor_range
        self.rod_axis = self.full.rod_axis
        self.fallbacks = 0
        self.edge_stops = 0  # reaches stopped at the box's edge beyond the domain strain
        self.walk_stops = 0  # reaches stopped by the full model's walk beyond the box
        self.full_checks = 0  # reaches outside the box answered by one full equilibrium
        self._warned = False

    # -- which model a state belongs to ----------------------------------------------------
    @staticmethod
    def _is_full(state) -> bool:
        return state is not None and hasattr(state, "x")  # a full RobotState carries node positions

    def in_box(self, motors_deg) -> bool:
        """Whether motor angles (na,) [deg] lie in the basis's training box."""
        return self.robot.in_box(np.radians(np.asarray(motors_deg, float)))

    def _fallback(self, what: str, motors_deg) -> None:
        self.fallbacks += 1
        if not self._warned:
            self._warned = True
            lo, hi = np.degrees(self.basis.box_lo), np.degrees(self.basis.box_hi)
            log.warning("model 'reduced': %s at motors %s deg, outside the training box [%s, %s] deg: redone with "
                        "the full model (warned once per model)", what, np.round(motors_deg, 2).tolist(),
                        f"{lo.min():.4g}", f"{hi.max():.4g}")

    def _to_full(self, state):
        """A full equilibrium to start the full model from (None: its rest)."""
        from ..robot.equilibrium import solve_equilibrium

        if state is None or self._is_full(state):
            return state
        try:
            return solve_equilibrium(self.full.robot, state.angles, state=self.robot.full_state(state),
                                     linearizer=self.full.lz).state
        except ConvergenceError:
            return None

    def _to_reduced(self, state):
        """A reduced equilibrium near a full ``state`` (None: the reduced rest)."""
        from ..robot.equilibrium import solve_equilibrium

        if not self._is_full(state):
            return state
        if not self.robot.in_box(state.angles):
            return None
        try:
            start = self.robot.project(state)
            return solve_equilibrium(self.robot, state.angles, state=start, linearizer=self.lz).state
        except ConvergenceError:
            return None

    # -- the protocol ----------------------------------------------------------------------
    def reach(self, goal, *, state=None, **kw):
        """:meth:`FemRobot.reach` on the reduced model (from ``state``'s reduced counterpart, or
        the reduced rest when ``state`` lies outside the box); an answer outside the box is
        followed beyond the box by the full model, checked by it, or redone by it (module docstring)."""
        start = self._to_reduced(state)
        r = super().reach(goal, state=start, **kw)
        if self.in_box(r.motors_deg):
            return r
        if self.spec.domain_strain is not None:
            walked, end = self._walk_beyond_box(goal, r, start, **kw)
            if walked is not None:
                return walked
            full_start = end if end is not None else self._to_full(state)
        else:
            checked = self._checked_by_full(goal, r, **kw)
            if checked is not None:
                return checked
            full_start = self._to_full(state)
        self._fallback("reach", r.motors_deg)
        return self.full.reach(goal, state=full_start, **kw)

    def _checked_by_full(self, goal, r, *, tol_mm=1.0, tol_deg=None, **_):
        """A reduced reach ``r`` that reached its goal outside the box, checked by the full
        model's equilibrium at its motor angles (one solve, from the reduced state's
        reconstruction): that equilibrium, when it meets the goal's tolerances (a full
        :class:`ReachResult`, as the full model's reach would be judged); else None."""
        from ..robot.equilibrium import solve_equilibrium
        from .model import ReachResult

        if not r.reached:
            return None
        try:
            st = solve_equilibrium(self.full.robot, np.radians(r.motors_deg), state=self.robot.full_state(r.state),
                                   linearizer=self.full.lz).state
        except ConvergenceError:
            return None
        e_mm, e_deg = pose_errors(np.asarray(goal, float), st.pose)
        if not (e_mm <= tol_mm and (tol_deg is None or e_deg <= tol_deg)):
            return None
        self.full_checks += 1
        return ReachResult(True, st.pose, np.degrees(st.angles), e_mm, e_deg, r.steps, st, True)

    def _walk_beyond_box(self, goal, r, start, *, tol_mm=1.0, tol_deg=None, **_):
        """Follow the reduced reach ``r`` that left the box along its straight motor path (module
        docstring). Returns ``(result, None)`` with a :class:`ReachResult` when the path leaves
        the strain limit (``left_domain``) or ends at a full equilibrium meeting the goal's
        tolerances; else ``(None, end)``, ``end`` the full equilibrium at ``r``'s motors (None
        when a full solve on the way failed)."""
        from ..robot.equilibrium import solve_equilibrium
        from .model import ReachResult

        limit = self.spec.domain_strain
        goal = np.asarray(goal, float)
        start = self.rest if start is None else start
        q_end = np.radians(r.motors_deg)
        edge = box_exit(start.angles, q_end, self.basis.box_lo, self.basis.box_hi)

        def result(st, reached, stopped):
            e_mm, e_deg = pose_errors(goal, st.pose)
            return ReachResult(reached, st.pose, np.degrees(st.angles), e_mm, e_deg, r.steps, st, True,
                               left_domain=stopped)

        try:
            st = solve_equilibrium(self.robot, edge, state=start, linearizer=self.lz).state
        except ConvergenceError:
            return None, None
        if not self.max_principal_strain(st) <= limit:
            self.edge_stops += 1
            return result(st, False, True), None
        n = max(1, int(np.ceil(np.degrees(np.abs(q_end - edge).max()) / WALK_STEP_DEG)))
        st = self.robot.full_state(st)
        for q in [edge] + [edge + (q_end - edge) * i / n for i in range(1, n + 1)]:
            try:
                st = solve_equilibrium(self.full.robot, q, state=st, linearizer=self.full.lz).state
            except ConvergenceError:
                return None, None
            if not self.full.max_principal_strain(st) <= limit:
                self.walk_stops += 1
                return result(st, False, True), None
        out = result(st, False, False)
        if r.reached and out.error_mm <= tol_mm and (tol_deg is None or out.error_deg <= tol_deg):
            self.full_checks += 1
            return replace(out, reached=True), None
        return None, st

    def equilibrium(self, motors_deg, *, state=None):
        """:meth:`FemRobot.equilibrium` on the reduced model, or the full one outside the training box."""
        q = np.asarray(motors_deg, float)
        if not self.in_box(q):
            self._fallback("equilibrium", q)
            return self.full.equilibrium(q, state=self._to_full(state))
        return super().equilibrium(q, state=self._to_reduced(state))

    def max_principal_strain(self, state) -> float:
        """:meth:`FemRobot.max_principal_strain` of the full mesh at ``state``'s node positions [-]."""
        from ..robot.validity import validity_strain

        if self._is_full(state):
            return self.full.max_principal_strain(state)
        return validity_strain(self.full.robot.body, self.robot.positions(state), self.full.strain_elements)

    def min_singular_value(self, state) -> float:
        if self._is_full(state):
            return self.full.min_singular_value(state)
        return super().min_singular_value(state)

    # -- the certificate -------------------------------------------------------------------
    def certify(self, goal, motors_deg, *, tol_mm: float, tol_deg: float | None = None) -> "PointCertificate":
        """Re-solve one reduced result with the full model.

        The reduced equilibrium at ``motors_deg`` (na,) [deg] (from the reduced rest, the
        solver's motor increments), then the full equilibrium at the same angles started from
        its reconstruction (``full_state``); both poses' errors against ``goal`` (6,) [mm, rad].
        """
        from ..robot.equilibrium import solve_equilibrium

        goal = np.asarray(goal, float)
        ang = np.radians(np.asarray(motors_deg, float))
        nan = (np.nan, np.nan)
        try:
            st = solve_equilibrium(self.robot, ang, state=self.rest, linearizer=self.lz).state
            red_err = pose_errors(goal, st.pose)
            start = self.robot.full_state(st)
        except ConvergenceError:
            red_err, start = nan, self.full.rest
        try:
            full = solve_equilibrium(self.full.robot, ang, state=start, linearizer=self.full.lz).state
            full_err, conv = pose_errors(goal, full.pose), True
        except ConvergenceError:
            full_err, conv = nan, False
        ok = conv and full_err[0] <= tol_mm and (tol_deg is None or full_err[1] <= tol_deg)
        return PointCertificate(*red_err, *full_err, conv, bool(ok), self.robot.in_box(ang))


def box_exit(q0, q1, lo, hi) -> np.ndarray:
    """(na,) the point where the segment from ``q0`` (in the box [lo, hi]) to ``q1`` leaves the
    box (``q1`` itself when it does not); all (na,) in the same unit."""
    q0, q1, lo, hi = (np.asarray(a, float) for a in (q0, q1, lo, hi))
    d = q1 - q0
    with np.errstate(divide="ignore", invalid="ignore"):
        room = np.where(d > 0, (hi - q0) / d, np.where(d < 0, (lo - q0) / d, np.inf))
    t = float(np.clip(room.min(initial=1.0), 0.0, 1.0))
    return np.clip(q0 + t * d, lo, hi)  # the clip: round-off only


@dataclass(frozen=True)
class PointCertificate:
    """One reduced result re-solved by the full model: errors of the reduced and the full
    equilibrium at the same motor angles against the goal ([mm], [deg]; NaN: not converged);
    ``full_converged``; ``agree``: the full pose meets the study's tolerances; ``in_box``."""

    reduced_error_mm: float
    reduced_error_deg: float
    full_error_mm: float
    full_error_deg: float
    full_converged: bool
    agree: bool
    in_box: bool
