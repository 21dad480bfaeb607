"""The reduced-order robot (:mod:`metasheet.rom`) as a :class:`~.model.RobotModel`.

:class:`ReducedSpec` is the picklable recipe: the full robot's :class:`~.adapter.RobotSpec`,
the path of the ``reduce`` stage's ``basis.npz`` and that file's content hash (both in
:attr:`ReducedSpec.key`, so another basis is another model). :class:`ReducedFem` is the live
model built from it in each worker: the full :class:`~.adapter.FemRobot` (kept for the
fallbacks and the certificate), the :class:`~metasheet.rom.model.ReducedRobot` on it and
the eq. (8) controller on the reduced robot, limited to the spec's motor range.

Outside its training box (``basis.box_lo``, ``basis.box_hi`` [rad]) the reduced model would
extrapolate: an equilibrium asked there is solved by the full model, and a reach is stopped
before the control step that would leave the box (``stop`` of
:meth:`~metasheet.robot.inverse.InverseController.goto`); from that state, lifted to the full
mesh, the full model carries the reach on (a warning is logged once per model when the full
model takes over; :attr:`ReducedFem.fallbacks` counts those). Within a strain limit the reduced
model may take one control step past the box first (``past_box``, below). Such a result carries a full
:class:`~metasheet.robot.statics.RobotState`; a reach given a full state continues on the
reduced model from its projection (:meth:`~metasheet.rom.model.ReducedRobot.project`)
when it lies in the box, else on the full model.

With a domain strain (:meth:`ReducedSpec.with_domain_strain`, set by the studies that stop
beyond the strain limit), a reach that stops at the box's edge (``past_box = "full"``) with the material there already
beyond the limit ends there: the goal lies outside the homogenised model's domain, and the
reach returns that edge state with ``left_domain`` set (not reached), without the full model.
Past the box, two ways (``past_box``):

- ``"reduced"`` (the default): the reduced model carries the reach on past its box, and the
  strain limit (on the full mesh's positions it lifts to) stops it as it stops the full model.
  A reach that ends reached past the box is confirmed by the full model: the full equilibrium
  at the same motor angles, started from the lifted state, must meet the reach's tolerances
  and the strain limit; when it does not (or the reach stalls past the box), the reach is redone
  the ``"full"`` way; so is a reach going more than one control step past the box
  (:data:`EXTRAPOLATE_STEPS`). On the paper pipeline's prediction: 194 of 228 workspace reaches
  past the box decided without the full model's continuation, the same classes at all 1,798
  points, 2.6 times less CPU (docs/performance.md, "Past the box on the reduced model").
- ``"full"``: the full model's continuation from the box's edge (the edge state lifted to the
  full mesh) stops at its first control step beyond the limit and returns that step's state,
  also with ``left_domain``: the study pays a few full steps past the box, not a full reach to
  angles where the material model no longer holds (minutes each on the converged mesh).

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
from .adapter import FemRobot, RobotSpec, remembered_strain
from .model import ReachResult, pose_errors

log = logging.getLogger(__name__)


#: Which model carries a reach on past the reduced model's training box (module docstring).
PAST_BOX = ("reduced", "full")

#: How far past its training box the reduced model carries a reach on (``past_box =
#: "reduced"``), in control steps (the spec's ``max_step_deg`` of any motor); a reach going
#: further is redone the ``"full"`` way. Far outside the box the extrapolated model steers
#: elsewhere: on the paper pipeline's 20-70 motor range, reaches 20 deg below the box stopped at
#: the strain limit where the full model reached.
EXTRAPOLATE_STEPS = 1.0
#: Rounding allowed on that bound [deg]: a full control step from the box's edge lands 5 deg
#: outside it give or take an ulp, and which side of the bound it fell on changed with the CPU's
#: kernels (AVX2 against AVX-512), and with it whether the reach was redone.
OUTSIDE_EPS_DEG = 1e-9


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
    domain_strain : the strain limit [-] a reach leaving the box is stopped at (see the module
        docstring); None: such reaches are carried on by the full model to their end.
    past_box : with a domain strain, which model carries a reach on past the box (one of
        :data:`PAST_BOX`; the module docstring).
    """

    full: RobotSpec
    basis_path: str
    basis_hash: str
    domain_strain: float | None = None
    past_box: str = "reduced"

    def __post_init__(self):
        if self.past_box not in PAST_BOX:
            raise ConfigError(f"past_box: {self.past_box!r}: allowed values are {', '.join(map(repr, PAST_BOX))}")

    @classmethod
    def from_file(cls, full: RobotSpec, path: Path | str) -> "ReducedSpec":
        """The reduced robot of ``full`` on the basis in ``path`` (basis.npz)."""
        path = Path(path).resolve()
        if not path.is_file():
            raise ConfigError(f"model 'reduced': {path} is missing; run the 'reduce' stage")
        return cls(full, str(path), file_hash(path))

    @property
    def key(self) -> str:
        tail = "" if self.domain_strain is None else f"|{self.domain_strain!r}|{self.past_box}"
        return "rom-" + hashlib.sha256(f"{self.full.key}|{self.basis_hash}{tail}".encode()).hexdigest()[:24]

    def with_domain_strain(self, limit: float | None, past_box: str | None = None) -> "ReducedSpec":
        """The same reduced robot whose reaches leaving the box stop where the material passes
        the strain ``limit`` [-] (None: the full model carries them on to their end), carried on
        past the box by ``past_box``'s model (None: unchanged)."""
        return replace(self, domain_strain=None if limit is None else float(limit),
                       past_box=self.past_box if past_box is None else past_box)

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
    robot : the :class:`~metasheet.rom.model.ReducedRobot`, limits = the spec's motor range.
    basis : its :class:`~metasheet.rom.coordinates.ReducedBasis`. fallbacks : calls redone by the full model.
    """

    def __init__(self, spec: ReducedSpec):
        from ..robot.inverse import InverseController
        from ..rom.coordinates import ReducedBasis, robot_key
        from ..rom.model import ReducedRobot

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
        self.strain_stops = 0  # continuations stopped at the strain limit past the box
        self.past_box_reaches = 0  # reaches the reduced model carried past its box ("reduced")
        self.redone = 0  # of those, redone the "full" way (not confirmed, or stalled past the box)
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

    def _to_reduced(self, state, anywhere: bool = False):
        """A reduced equilibrium near a full ``state`` (None: the reduced rest; also when the state
        lies outside the box, unless ``anywhere``, or the solve fails)."""
        from ..robot.equilibrium import solve_equilibrium

        if not self._is_full(state):
            return state
        if not (anywhere or self.robot.in_box(state.angles)):
            return None
        try:
            start = self.robot.project(state)
            return solve_equilibrium(self.robot, state.angles, state=start, linearizer=self.lz).state
        except ConvergenceError:
            return None

    # -- the protocol ----------------------------------------------------------------------
    def reach(self, goal, *, state=None, **kw):
        """:meth:`FemRobot.reach` on the reduced model within its box, carried on past it by the
        spec's ``past_box`` model (module docstring)."""
        limit = self.spec.domain_strain
        if limit is not None and self.spec.past_box == "reduced":
            return self._reduced_reach(goal, state, limit, **kw)
        return self._box_reach(goal, state, limit, **kw)

    def _box_reach(self, goal, state, limit, **kw):
        """The reach on the reduced model stopped at the box's edge, carried on by the full model."""
        if self._is_full(state) and not self.robot.in_box(state.angles):  # already past the box
            return self._full_reach(goal, state, limit, **kw)
        r = super().reach(goal, state=self._to_reduced(state), stop=self._leaves_box, **kw)
        if not r.stopped:
            return r
        if limit is not None and not self.max_principal_strain(r.state) <= limit:
            self.edge_stops += 1
            return replace(r, left_domain=True)
        self._fallback("reach", r.motors_deg)
        # the edge state lifted to the full mesh starts the full loop as it is: its first
        # linearisation corrects the reduced model's small residual along with the step
        return self._full_reach(goal, self.robot.full_state(r.state), limit, **kw)

    def _reduced_reach(self, goal, state, limit, **kw):
        """The reduced model's reach, past its box too, stopped at its first control step past the
        box beyond the strain ``limit`` (returned with ``left_domain``, that step's state, as
        :meth:`_full_reach`); a goal reached past the box is confirmed by the full model
        (:meth:`_confirmed`), else the reach is redone by :meth:`_box_reach`."""
        start = self._to_reduced(state, anywhere=True)
        if self._is_full(state) and start is None:  # no reduced equilibrium there: the full model's
            return self._box_reach(goal, state, limit, **kw)
        fired, far = [], []

        def beyond(st) -> bool:
            out = self.degrees_outside(st.angles)
            if out <= 0.0:
                return False
            if out > EXTRAPOLATE_STEPS * self.spec.full.max_step_deg + OUTSIDE_EPS_DEG:
                far.append(st)
                return True
            if self.max_principal_strain(st) <= limit:
                return False
            fired.append(st)
            return True

        r = super().reach(goal, state=start, stop=beyond, certify_stop=False, **kw)
        if not r.stopped and self.robot.in_box(r.state.angles):
            return r
        self.past_box_reaches += 1
        if r.stopped and not far:
            self.strain_stops += 1
            return self._left_domain(goal, fired[-1], r.steps)
        if r.reached:
            confirmed = self._confirmed(goal, r, limit, kw.get("tol_mm", 1.0), kw.get("tol_deg"))
            if confirmed is not None:
                return confirmed
        self.redone += 1
        self._fallback("reach too far past the box or not confirmed", r.motors_deg)
        return self._box_reach(goal, state, limit, **kw)

    def _confirmed(self, goal, r, limit: float, tol_mm: float, tol_deg: float | None):
        """The full equilibrium at reach ``r``'s motor angles, started from its state lifted to
        the full mesh, as a reached result when it meets the tolerances [mm], [deg] (None: the
        position only) and the strain ``limit``; None when it does not or does not converge."""
        from ..robot.equilibrium import solve_equilibrium

        try:
            full = solve_equilibrium(self.full.robot, r.state.angles, state=self.robot.full_state(r.state),
                                     linearizer=self.full.lz).state
        except ConvergenceError:
            return None
        e_mm, e_deg = pose_errors(np.asarray(goal, float), full.pose)
        if e_mm <= tol_mm and (tol_deg is None or e_deg <= tol_deg) and self.full.max_principal_strain(full) <= limit:
            return ReachResult(True, full.pose, np.degrees(full.angles), e_mm, e_deg, r.steps, full, True)
        return None

    @staticmethod
    def _left_domain(goal, st, steps: int):
        """A reach stopped at state ``st``, beyond the strain limit: not reached, ``left_domain``."""
        e_mm, e_deg = pose_errors(np.asarray(goal, float), st.pose)
        return ReachResult(False, st.pose, np.degrees(st.angles), e_mm, e_deg, steps, st, True, left_domain=True)

    def degrees_outside(self, angles) -> float:
        """How far motor ``angles`` (na,) [rad] lie outside the training box: the largest
        excess over its bounds [deg] (0 inside)."""
        a = np.asarray(angles, float)
        return float(np.degrees(max(0.0, np.max(self.basis.box_lo - a), np.max(a - self.basis.box_hi))))

    def _leaves_box(self, state) -> bool:
        return not self.robot.in_box(state.angles)

    def _full_reach(self, goal, state, limit, **kw):
        """The full model's reach from the full ``state``; with a strain ``limit``, stopped at
        the first control step beyond it, returned with ``left_domain`` (that control state:
        one Newton step from equilibrium, as every step of the loop). Neither it nor the state
        before it is certified as an equilibrium: on the paper robot that cost more than the
        reach, for a point not reached."""
        if limit is None:
            return self.full.reach(goal, state=state, **kw)
        fired = []

        def beyond(st) -> bool:
            if self.full.max_principal_strain(st) <= limit:
                return False
            fired.append(st)
            return True

        r = self.full.reach(goal, state=state, stop=beyond, certify_stop=False, **kw)
        if not r.stopped:
            return r
        self.strain_stops += 1
        return self._left_domain(goal, fired[-1], r.steps)

    def equilibrium(self, motors_deg, *, state=None, intermediate: bool = False):
        """:meth:`FemRobot.equilibrium` on the reduced model, or the full one outside the training box."""
        q = np.asarray(motors_deg, float)
        if not self.in_box(q):
            self._fallback("equilibrium", q)
            return self.full.equilibrium(q, state=self._to_full(state), intermediate=intermediate)
        return super().equilibrium(q, state=self._to_reduced(state), intermediate=intermediate)

    def max_principal_strain(self, state) -> float:
        """:meth:`FemRobot.max_principal_strain` of the full mesh at ``state``'s node positions [-]."""
        from ..robot.validity import validity_strain

        if self._is_full(state):
            return self.full.max_principal_strain(state)
        return remembered_strain(self._strains, state, lambda: validity_strain(
            self.full.robot.body, self.robot.positions(state), self.full.strain_elements))

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
        Outside the training box the reduced equilibrium is an extrapolation (its error is
        reported, ``in_box`` False) and a poor start: the full solve starts from the reduced
        equilibrium at the angles clipped to the box instead (on the paper robot the
        extrapolated start was 20 deg off and the full Newton solve failed from it), and
        from the full rest if that fails.
        """
        from ..robot.equilibrium import solve_equilibrium

        goal = np.asarray(goal, float)
        ang = np.radians(np.asarray(motors_deg, float))
        box = self.robot.basis
        inside = self.robot.in_box(ang)
        nan = (np.nan, np.nan)
        starts = []
        try:
            st = solve_equilibrium(self.robot, ang, state=self.rest, linearizer=self.lz).state
            red_err = pose_errors(goal, st.pose)
            if inside:
                starts.append(self.robot.full_state(st))
        except ConvergenceError:
            red_err = nan
        if not inside:
            try:
                edge = np.clip(ang, box.box_lo, box.box_hi)
                st = solve_equilibrium(self.robot, edge, state=self.rest, linearizer=self.lz).state
                starts.append(self.robot.full_state(st))
            except ConvergenceError:
                pass
        starts.append(self.full.rest)
        full_err, conv = nan, False
        for start in starts:
            try:
                full = solve_equilibrium(self.full.robot, ang, state=start, linearizer=self.full.lz).state
                full_err, conv = pose_errors(goal, full.pose), True
                break
            except ConvergenceError:
                continue
        ok = conv and full_err[0] <= tol_mm and (tol_deg is None or full_err[1] <= tol_deg)
        return PointCertificate(*red_err, *full_err, conv, bool(ok), inside)


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
