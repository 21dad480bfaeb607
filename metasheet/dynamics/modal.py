"""A modal model of the robot in time: the quasi-static path plus the first modes' response to
it (the mode-acceleration method), a reduced dynamic model whose step is a few scalar updates.

Linearised about the quasi-static path ``y_qs(t)`` (the equilibria at the program's motor
angles), the dynamic part ``y_d = y - y_qs`` obeys ``M y_d'' + C y_d' + K y_d = -M y_qs'' - C
y_qs'``. On the first k modes at rest (``K phi = w^2 M phi``, M-normalised, Rayleigh
``C = alpha M + beta K`` so ``phi^T C phi = 2 zeta w`` with ``zeta = alpha / 2w + beta w / 2``),
``y_d = sum_i phi_i eta_i`` and

    eta_i'' + 2 zeta_i w_i eta_i' + w_i^2 eta_i = -m_i'' - alpha m_i',
    m_i(t) = phi_i^T M x_qs(t)          (the path's modal coordinate: the sheets' nodes, servo
                                         horns included, and the rod's six point masses).

The stiffness part of the damping loads nothing: along the quasi-static path ``K_yy y_qs' +
K_ya x_a' = 0`` (the equilibrium's derivative), so ``beta K`` of the path's velocity, horns
included, vanishes.

The program joins its samples linearly, so ``m_i`` is taken piecewise linear between them: its
rate is constant on each interval and its acceleration is an impulse at each sample. Each mode
is then integrated exactly (the damped oscillator's transition matrix over an interval, with a
constant load, and a jump of its velocity by ``-(m'_after - m'_before)`` at a sample). Playing
``speed`` times faster scales the rates by ``speed``: the response at any speed costs a few
operations per interval and mode.

The rod's pose is the path's plus ``sum_i phi_e,i eta_i`` (the modes' rod parts). Valid where
the motion about the path is small and the modes at rest hold along it (the maze's tilts);
:mod:`tests.test_dynamics_modal` compares it with the full model in time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError


@dataclass(frozen=True)
class ModalModel:
    """omega (k,) [rad/s]; zeta (k,) [-]; effector (k, 6) the rod's (mm, rad) per unit modal
    coordinate; alpha [1/s], beta [s] the Rayleigh coefficients."""

    omega: np.ndarray
    zeta: np.ndarray
    effector: np.ndarray
    alpha: float
    beta: float

    @property
    def frequencies_hz(self) -> np.ndarray:
        return self.omega / (2 * np.pi)


def modal_model(modes, alpha: float, beta: float) -> ModalModel:
    """The :class:`ModalModel` of :class:`.robot_modes.RobotModes` ``modes`` with Rayleigh damping."""
    w = 2 * np.pi * np.asarray(modes.frequencies_hz, float)
    if np.any(w <= 0):
        raise ConfigError("modes: a frequency <= 0 (a mechanism or an unstable equilibrium): no modal model")
    return ModalModel(w, alpha / (2 * w) + beta * w / 2, np.asarray(modes.effector, float), float(alpha), float(beta))


def path_coordinates(shapes: np.ndarray, effector: np.ndarray, M, x_path: np.ndarray, points_path: np.ndarray,
                     point_masses: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """(T, k) the path's modal coordinates ``m_i = phi_i^T M x``: ``shapes`` (k, n, 3) the modes'
    node motions (:class:`.robot_modes.RobotModes`), ``effector`` (k, 6) their rod parts (about
    ``origin`` (3,) [mm], the rod's reference point at rest), ``M`` (3n, 3n) [t] the sheets'
    mass, ``x_path`` (T, n, 3) [mm] the nodes along the path and ``points_path`` (T, 6, 3) [mm]
    the rod's six point masses ``point_masses`` (6,) [t] (:func:`.robot.point_masses`). Taken
    from the first sample (a constant drops out of the derivatives)."""
    k = len(shapes)
    S = np.asarray(shapes).reshape(k, -1)
    SM = np.asarray((M @ S.T).T)  # (k, 3n): phi^T M
    d = (x_path - x_path[:1]).reshape(len(x_path), -1)
    out = d @ SM.T
    arm = points_path[0] - origin  # the points' motion under mode i: dp + dtheta x arm (first order)
    u = effector[:, None, :3] + np.cross(effector[:, None, 3:], arm[None])  # (k, 6, 3)
    out += np.einsum("tpj,kpj,p->tk", points_path - points_path[:1], u, point_masses)
    return out


def respond(model: ModalModel, times: np.ndarray, m: np.ndarray, h: float, *, speed: float = 1.0,
            tail: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """The modal coordinates ``eta`` (N, k) on the grid ``t`` (N,) [s] of step ``h`` [s] of the
    program played ``speed`` times faster (``times`` (T,) [s] its samples at speed 1, ``m``
    (T, k) the path's modal coordinates there), from rest, ``tail`` [s] past its end.

    With ``xi = eta + m`` the modal equation (module docstring) is ``xi'' + 2 zeta w xi' + w^2
    xi = w^2 (m + beta m')``: each mode is a base-excited oscillator whose damper is tied to the
    base, solved exactly for ``m`` linear between grid points (scipy's ``lsim``, a first-order
    hold); a sample between grid points is smoothed over one step."""
    from scipy.signal import lsim

    if h <= 0 or speed <= 0:
        raise ConfigError(f"h, speed: {h!r}, {speed!r}: allowed > 0")
    tt = np.asarray(times, float) / speed
    m = np.asarray(m, float)
    t = np.arange(0.0, tt[-1] + tail + 0.5 * h, h)
    mg = np.stack([np.interp(t, tt, m[:, i]) for i in range(m.shape[1])], axis=1)
    k = len(model.omega)
    w2 = model.omega**2
    # per mode, controllable canonical form of xi / m = w^2 (1 + beta s) / (s^2 + 2 zeta w s + w^2)
    A = np.zeros((2 * k, 2 * k))
    A[0::2, 1::2] = np.eye(k)
    A[1::2, 0::2] = -np.diag(w2)
    A[1::2, 1::2] = -np.diag(2 * model.zeta * model.omega)
    B = np.zeros((2 * k, k))
    B[1::2] = np.eye(k)
    C = np.zeros((k, 2 * k))
    C[:, 0::2] = np.diag(w2)
    C[:, 1::2] = np.diag(model.beta * w2)
    x0 = np.zeros(2 * k)
    x0[0::2] = mg[0] / w2  # at rest on the path: xi = m, xi' = 0
    _, xi, _ = lsim((A, B, C, np.zeros((k, k))), mg, t, X0=x0)
    return t, np.asarray(xi).reshape(len(t), k) - mg


def rod_gap(model: ModalModel, times, m, h: float, speed: float) -> float:
    """The largest distance [mm] of the rod from the quasi-static path when the program (``times``
    (T,) [s], path modal coordinates ``m`` (T, k)) plays ``speed`` times faster, on a grid of ``h``
    [s] (or a quarter of the shortest sample interval) divided by the speed, a second of settling
    after its end included."""
    step = min(h, float(np.diff(np.asarray(times, float)).min()) / 4) / speed  # resolve the samples' kinks
    _, eta = respond(model, times, m, step, speed=speed, tail=1.0)
    return float(np.linalg.norm(eta @ model.effector[:, :3], axis=1).max())


def fastest_speed(model: ModalModel, times, m, h: float, tol_mm: float, *, hi: float = 1024.0,
                  rel: float = 0.02) -> dict:
    """The largest speed-up in [1, ``hi``] whose rod stays within ``tol_mm`` [mm] of the
    quasi-static path on the modal model, by bisection in log(speed) to ``rel``; {speed (None
    when even 1 fails; ``hi`` when it never does), gap_mm at that speed, evaluations}. The gap
    grows with the speed (the loads scale with its square), so the first crossing is found."""
    evals = []

    def gap(s):
        g = rod_gap(model, times, m, h, s)
        evals.append((float(s), g))
        return g

    if gap(1.0) > tol_mm:
        return {"speed": None, "gap_mm": evals[0][1], "evaluations": evals}
    if gap(hi) <= tol_mm:
        return {"speed": hi, "gap_mm": evals[-1][1], "evaluations": evals}
    lo, up = 1.0, hi
    while up / lo > 1 + rel:
        mid = float(np.sqrt(lo * up))
        if gap(mid) <= tol_mm:
            lo = mid
        else:
            up = mid
    return {"speed": lo, "gap_mm": dict(evals)[lo] if lo in dict(evals) else rod_gap(model, times, m, h, lo),
            "evaluations": evals}
