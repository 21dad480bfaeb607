"""Static equilibrium of the coupled robot (paper eq. 1) by Newton's method with line search.

Each Newton step is the linearisation's (:class:`.statics.Linearization`); the line search
backtracks on the reduced residual's norm, or accepts a step along which the residual's
projection has dropped (:func:`slope`); motor motions are taken in increments, halved when
one fails; the solve stops at the residual's round-off floor (:func:`.statics.residual_floor`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, ConvergenceError
from .statics import Linearization, RobotState


@dataclass(frozen=True)
class Equilibrium:
    """Result of :func:`solve_equilibrium`.

    Attributes
    ----------
    state : the converged :class:`RobotState`.
    iterations : Newton iterations in all.
    residuals : reduced residual norm [N] before each iteration and at the end.
    reference : force scale the relative tolerance refers to [N].
    time : wall time [s].
    floor : round-off floor [N] of the reduced residual at ``state`` (:func:`.statics.residual_floor`).
    at_floor : True when ``tol`` asked for less than round-off allows and the solve stopped
        where Newton stalls, at a residual ``residuals[-1] <= floor``, instead of at
        ``tol * reference``; False when the tolerance itself was met.
    linearization : the last :class:`.statics.Linearization` at ``state`` (its residual is
        ``state``'s, its tangent may be an earlier iterate's), or None: a next solve from
        ``state`` may start its predictor on it (``start``).
    """

    state: RobotState
    iterations: int
    residuals: tuple
    reference: float
    time: float
    floor: float = 0.0
    at_floor: bool = False
    linearization: Linearization | None = None

    @property
    def residual(self) -> float:
        """The achieved reduced residual norm [N] (``residuals[-1]``)."""
        return float(self.residuals[-1])


def slope(lin: Linearization, dq_e, dx_f) -> float:
    """The reduced residual at ``lin`` projected on the step (dq_e, dx_f): the work [N mm] the
    residual forces and moments do along it (negative along an exact Newton step)."""
    return float(dq_e @ lin.res_e + dx_f @ lin.res_f)


def solve_equilibrium(robot, angles, *, state=None, max_angle_step: float = np.radians(10.0),
                      max_cuts: int = 3, **kw) -> Equilibrium:
    """Static equilibrium at motor ``angles`` (na,) [rad] (:func:`solve_increments`); when an
    increment fails, the solve starts again from ``state`` with increments half as large, up
    to ``max_cuts`` times (a large motion whose Newton path crosses a snap of the sheets
    converges in smaller steps), then raises the last :class:`ConvergenceError`. A cut that
    leaves the number of increments unchanged (a motion shorter than the smaller step) would
    repeat the failed solve exactly, so it is skipped."""
    target = np.asarray(angles, dtype=float).reshape(-1)
    if target.shape != (robot.coupling.n_act,):
        raise ConfigError(f"angles: shape {target.shape}: expected ({robot.coupling.n_act},) [rad]")
    if max_cuts < 0:
        raise ConfigError(f"max_cuts: {max_cuts!r}: need max_cuts >= 0")
    start = state.angles if state is not None else robot.coupling.rest_angles
    jump = float(np.max(np.abs(target - start), initial=0.0))
    tried, error = set(), None
    for cut in range(max_cuts + 1):
        step = max_angle_step / 2**cut
        n = n_increments(jump, step)
        if n in tried:
            continue
        tried.add(n)
        try:
            return solve_increments(robot, angles, state=state, max_angle_step=step, **kw)
        except ConvergenceError as e:
            error = e
    raise error


def n_increments(jump: float, step: float) -> int:
    """Increments of at most ``step`` that a motor motion of largest component ``jump`` takes
    [rad, rad]: at least one (a solve at fixed motors is one increment)."""
    return max(1, int(np.ceil(jump / step - 1e-12)))


#: Relative tolerance of a path's intermediate states (:func:`solve_increments`, the studies'
#: ramps): they only start the next increment, whose predictor residual is 1-10 times the
#: force scale; converging them to 1e-8 took 7-13 Newton iterations per 5 deg ramp of the
#: silicone sheets where 1e-4 takes 4-6, for the same end state (the last increment meets ``tol``).
PATH_TOL = 1e-4


def solve_increments(robot, angles, *, state=None, tol: float = 1e-8, max_iter: int = 50,
                     max_angle_step: float = np.radians(10.0), reuse_ratio: float = 0.25,
                     linearizer=None, exact_tangent: bool = True, path_tol: float = PATH_TOL,
                     start: Linearization | None = None) -> Equilibrium:
    """Static equilibrium (eq. 1) at motor ``angles`` (na,) [rad] by Newton + line search.

    Starts from ``state`` (default: the rest state) and moves the motors in increments of at
    most ``max_angle_step`` [rad]; each increment begins with the linearised predictor (the
    motors and the rest of the robot move together) and is then corrected by Newton with a
    backtracking line search on the residual norm. The tangent (and the LU of K_ff) is kept
    while each step cuts the residual by at least ``reuse_ratio`` (a chord step costs one
    force evaluation and one solve) and recomputed otherwise; ``reuse_ratio = 0`` gives plain
    Newton. An increment's predictor starts on the linearisation the previous increment
    ended on, and the first on ``start`` when it was taken at ``state`` (an
    :attr:`Equilibrium.linearization`): a tangent from the last iterates of a converged
    increment predicts as well as a fresh one, which would cost a factorisation (about a
    quarter of a 5 deg ramp of the paper robot's silicone sheets). The increments before the
    last are converged to ``max(tol, path_tol)`` only (:data:`PATH_TOL`), the last to ``tol``.
    Converged when the reduced residual is below ``tol`` times the force scale (forces on
    the rigid nodes plus the external loads); when that scale is itself below the residual's
    round-off floor (:func:`.statics.residual_floor`; no loads, no motion), below the floor:
    an unloaded rest state is an equilibrium as it stands, whatever BLAS evaluated its forces.
    The test is on the true residual, whatever tangent was used.

    A ``tol`` below round-off cannot be met: once the residual is below the floor, Newton
    goes on only while a full step (with a fresh tangent) halves it, which real progress does
    and steps in round-off do not; then, or when ``max_iter`` runs out below the floor, the
    solve has converged as far as it can and returns with ``at_floor`` set and the achieved
    residual in ``residuals[-1]`` (as :func:`.dirichlet.solve_static` stops at its floor).

    ``exact_tangent=False`` starts each increment, and its predictor, on the linearizer's
    inexact tangent (``linearize(state, exact=False)``: the reduced model's nearest stored
    one, :mod:`metasheet.rom.tangents`), and takes an exact one only when a chord step cuts the
    residual by less than ``reuse_ratio`` or the line search fails on it.

    Raises :class:`ConvergenceError` (with the residual history) when an increment fails
    above the floor.
    """
    target = np.asarray(angles, dtype=float).reshape(-1)
    if target.shape != (robot.coupling.n_act,):
        raise ConfigError(f"angles: shape {target.shape}: expected ({robot.coupling.n_act},) [rad]")
    if tol <= 0 or max_iter < 1:
        raise ConfigError(f"tol: {tol!r}, max_iter: {max_iter!r}: need tol > 0, max_iter >= 1")
    if not path_tol > 0:
        raise ConfigError(f"path_tol: {path_tol!r}: need path_tol > 0")
    check_reuse = float(reuse_ratio)
    if not 0.0 <= check_reuse < 1.0:
        raise ConfigError(f"reuse_ratio: {reuse_ratio!r}: allowed range [0, 1)")
    t0 = time.perf_counter()
    lz = linearizer or robot.linearizer()
    st = state if state is not None else lz.robot.rest_state()
    jump = target - st.angles
    n_inc = n_increments(float(np.max(np.abs(jump), initial=0.0)), max_angle_step)
    history, iters, ref, floor = [], 0, 0.0, 0.0
    lin = start if start is not None and start.state is st else None
    for inc in range(n_inc):
        dq_a = jump / n_inc if np.any(jump) else None
        inc_tol = tol if inc == n_inc - 1 else max(tol, path_tol)
        if dq_a is None or lin is None or lin.state is not st:
            lin = lz.linearize(st, exact=exact_tangent)
        at_floor = False
        for it in range(max_iter + 1):
            res = lin.residual_norm
            ref = max(lz.force_scale(lin), 1e-300)
            floor = lz.residual_floor(lin)
            history.append(res)
            unloaded = ref <= floor  # the force scale itself is round-off: nothing to resolve
            if dq_a is None and (res <= inc_tol * ref or res < 1e-13 * max(ref, 1.0) or (unloaded and res <= floor)):
                break
            if it == max_iter:
                if dq_a is None and res <= floor:  # steps that only shuffle round-off: done
                    at_floor = True
                    break
                raise ConvergenceError(
                    f"statics: no convergence in {max_iter} Newton iterations (increment {inc + 1}/"
                    f"{n_inc}); residual {res:.3e} N > {inc_tol:g} x {ref:.3e} N", history)
            dq_e, dx_f = lin.newton_step(dq_a)
            iters += 1
            if dq_a is not None:  # predictor: move the motors with the linearised response
                st = lz.apply(st, dq_e, dx_f, dq_a)
                dq_a = None
                lin = lz.linearize(st, exact=exact_tangent)
                continue
            # Below the floor a step counts only when it is plainly more than noise: the full
            # step must halve the residual. Backtracking there would chase round-off: steps of
            # less than an ulp "succeed" on a residual evaluated in another summation order.
            noise = res <= floor
            alpha = 1.0
            s0 = slope(lin, dq_e, dx_f) if lin.exact and not noise else 0.0
            lo, hi = 0.0, None
            for _ in range(1 if noise else 12):
                trial = lz.apply(st, dq_e, dx_f, alpha=alpha)
                new = lz.update(lin, trial)
                if new.residual_norm <= (0.5 if noise else 1.0 - 1e-4 * alpha) * res:
                    break
                # A thin sheet's exact Newton step can be right along itself while the residual
                # grows across it (the in-plane pull-in a bending step implies, ~ its square):
                # backtracking on the norm then creeps a percent per iteration (50-200 iterations
                # for a sagging silicone sheet). Accept it when the force along the step has
                # dropped (Crisfield's line search on s = step . residual) and the next Newton
                # step, with a fresh tangent, takes the in-plane part.
                if s0 < 0:
                    s_a = slope(new, dq_e, dx_f)
                    if abs(s_a) <= 0.5 * abs(s0) and new.residual_norm <= 1e3 * res:
                        break
                    if s_a > 0:  # past the zero of s: bisect the bracket [lo, hi] around it
                        hi = alpha
                    elif hi is not None:
                        lo = alpha
                alpha = 0.5 * (lo + hi) if hi is not None else 0.5 * alpha
            else:
                if not lin.fresh:  # a stale tangent may give a poor direction: refresh, retry
                    lin = lz.linearize(st)
                    history.pop()
                    continue
                if noise:  # Newton has stalled in round-off: done, on the better of the two states
                    if new.residual_norm < res:
                        st = trial
                        history.append(new.residual_norm)
                    at_floor = True
                    break
                raise ConvergenceError(
                    f"statics: line search failed at residual {res:.3e} N, above the round-off "
                    f"floor {floor:.3e} N (increment {inc + 1}/{n_inc})", history)
            st = trial
            lin = new if new.residual_norm <= reuse_ratio * res else lz.linearize(st)
    return Equilibrium(st, iters, tuple(history), ref, time.perf_counter() - t0, floor, at_floor,
                       lin if lin.state is st else None)
