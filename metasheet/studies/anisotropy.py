"""Anisotropy sweep (paper Fig. 7): rod rotation and lateral translation against alpha.

For each alpha from 0 (isotropic) to the design value, the sheet material is
:func:`metasheet.mechanics.material.interpolate` d (through ``spec.with_alpha``) and all motors move
together from rest: ``pull_deg`` one way, then ``push_deg`` the other way (each as a ramp
of at most ``ramp_deg`` per forward solve, continuing from the previous state). With
isotropic sheets a common motion cannot turn the rod (it translates sideways when a sheet
buckles); anisotropic spiral sheets turn it, progressively with alpha.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, ConvergenceError, check_range
from ..runtime.executor import Executor
from .model import MODELS, ModelSpec
from .resume import UnitCache


@dataclass(frozen=True)
class SweepTask:
    """One work unit: ``case`` 0 pulls all motors by ``pull_deg``, 1 pushes them by ``push_deg``."""

    spec: ModelSpec
    pull_deg: float
    push_deg: float
    ramp_deg: float
    case: int = 0


#: Halvings of a ramp step that fails to converge before the case is given up (reported). The
#: equilibrium solver has already cut its own increments three times by then, to 1.25 deg from
#: its 10: a halved 5 deg step reaches the same finest increment (its cuts stop at 2 x 1.25
#: deg), so a halving here only repeats the failed path. On the paper pipeline no converging
#: case needed one; the push past the homogenised foam's snap (a limit point) spent 136 CPU s
#: with three, 84 with one (its repeat: 39 s).
MAX_CUTS = 0


def _reach(model, q_from, q_to, state, cuts: int = 0, *, last: bool = True):
    """Equilibrium at motors ``q_to`` [deg] from ``state`` (at ``q_from``); a step that does not
    converge is halved, up to :data:`MAX_CUTS` times, before the error is passed on. Unless
    ``last``, the state only starts the ramp's next step (``intermediate``)."""
    try:
        return model.equilibrium(q_to, state=state, intermediate=not last)
    except ConvergenceError:
        if cuts >= MAX_CUTS:
            raise
        mid = 0.5 * (np.asarray(q_from) + np.asarray(q_to))
        _, state = _reach(model, q_from, mid, state, cuts + 1, last=False)
        return _reach(model, mid, q_to, state, cuts + 1, last=last)


def sweep_point(task: SweepTask) -> np.ndarray:
    """Work unit: (7,) for the task's case (pull or push of all motors, from rest): the pose
    change from rest (6,) [mm, rad] and the mean motor change actually applied [deg] (targets
    are clipped to the motor range). A case whose equilibrium cannot be followed to its
    target (after :data:`MAX_CUTS` halvings of a ramp step) has a NaN pose change and the motor
    change it reached: reported as not converged, never as a result."""
    model = MODELS.get(task.spec)
    q0 = model.rest_motors()
    lo, hi = model.motor_range
    out = np.zeros(7)
    sign = getattr(model, "pull_sign", -1.0)
    delta = sign * task.pull_deg if task.case == 0 else -sign * task.push_deg
    target = np.clip(q0 + delta, lo, hi)
    n = max(1, int(np.ceil(np.abs(target - q0).max() / task.ramp_deg)))
    state, q = None, q0
    try:
        for t in np.arange(1, n + 1) / n:
            pose, state = _reach(model, q, q0 + t * (target - q0), state, last=t == 1)
            q = q0 + t * (target - q0)
        out[:6] = pose - model.rest_pose()
    except ConvergenceError:
        out[:6] = np.nan
    out[6] = float(np.mean(q - q0))
    return out


@dataclass(frozen=True)
class AnisotropyResult:
    """alpha : (a,) [%]; delta : (a, 2, 6) pose change from rest for (pull, push) [mm, rad];
    rod_rotation_deg, lateral_mm, axial_mm : (a, 2); applied_deg : (a, 2) mean motor change
    actually applied (the request clipped to the motor range) [deg]; rod_axis : its index."""

    alpha: np.ndarray
    delta: np.ndarray
    rod_rotation_deg: np.ndarray
    lateral_mm: np.ndarray
    axial_mm: np.ndarray
    applied_deg: np.ndarray
    rod_axis: int
    pull_deg: float
    push_deg: float


def anisotropy_sweep(
    spec: ModelSpec,
    alphas: Sequence[float],
    *,
    pull_deg: float = 15.0,
    push_deg: float = 35.0,
    ramp_deg: float = 5.0,
    executor: Executor = Executor(),
    progress: Callable[[str, int, int], None] = lambda d, i, n: None,
    cache: UnitCache | None = None,
) -> AnisotropyResult:
    """Sweep ``alphas`` [%] (each within [0, spec.design_alpha]); see the module docstring.

    Pulling moves every motor by ``pull_deg`` in the direction ``model.pull_sign`` (+1: towards
    larger angles), pushing by ``push_deg`` the other way [deg]; targets are clipped to the
    motor range and the applied amplitude is reported.
    """
    return anisotropy_sweeps([(spec, alphas)], pull_deg=pull_deg, push_deg=push_deg, ramp_deg=ramp_deg,
                             executor=executor, progress=progress, cache=cache)[0]


def anisotropy_sweeps(
    sweeps: Sequence[tuple[ModelSpec, Sequence[float]]],
    *,
    pull_deg: float = 15.0,
    push_deg: float = 35.0,
    ramp_deg: float = 5.0,
    executor: Executor = Executor(),
    progress: Callable[[str, int, int], None] = lambda d, i, n: None,
    cache: UnitCache | None = None,
) -> list[AnisotropyResult]:
    """:func:`anisotropy_sweep` of each (spec, alphas) of ``sweeps``, their units in one map:
    a long unit of one sweep (a push near a limit point) runs beside the others' units instead
    of leaving a worker idle at the end of each map. Units go longest first (pushes, then the
    most anisotropic), the results come back in order."""
    check_range("pull_deg", pull_deg, 0.0, 90.0)
    check_range("push_deg", push_deg, 0.0, 90.0)
    check_range("ramp_deg", ramp_deg, 0.0, 90.0, lo_open=True)
    sweeps = [(spec, _alphas(spec, alphas)) for spec, alphas in sweeps]
    # pull and push start from rest each: two units per alpha, so that both run at once
    tasks = [SweepTask(spec.with_alpha(float(a)), float(pull_deg), float(push_deg), float(ramp_deg), case)
             for spec, alphas in sweeps for a in alphas for case in (0, 1)]
    order = sorted(range(len(tasks)), key=lambda i: (-tasks[i].case, -tasks[i].spec.design_alpha))
    done = (cache or UnitCache(None)).map(executor, sweep_point, [tasks[i] for i in order],
                                          progress=lambda d, n: progress("anisotropy", d, n))
    out = np.empty((len(tasks), 7))
    out[order] = np.array(done)
    results, start = [], 0
    for spec, alphas in sweeps:
        block = out[start:start + 2 * len(alphas)].reshape(len(alphas), 2, 7)
        start += 2 * len(alphas)
        results.append(_result(MODELS.get(spec).rod_axis, alphas, block, pull_deg, push_deg))
    return results


def _alphas(spec: ModelSpec, alphas) -> np.ndarray:
    alphas = np.asarray(alphas, float)
    if alphas.ndim != 1 or len(alphas) == 0:
        raise ConfigError(f"alphas: shape {alphas.shape}: expected a non-empty list of percentages")
    for i, a in enumerate(alphas):
        check_range(f"alphas[{i}]", a, 0.0, spec.design_alpha + 1e-9)
    return alphas


def _result(ax: int, alphas: np.ndarray, out: np.ndarray, pull_deg: float, push_deg: float) -> AnisotropyResult:
    """The :class:`AnisotropyResult` of the units' rows ``out`` (a, 2, 7) (pose change, applied)."""
    delta, applied = out[:, :, :6], out[:, :, 6]
    lateral = np.linalg.norm(np.delete(delta[:, :, :3], ax, axis=2), axis=2)
    return AnisotropyResult(alphas, delta, np.degrees(delta[:, :, 3 + ax]), lateral, delta[:, :, ax], applied, ax,
                            float(pull_deg), float(push_deg))
