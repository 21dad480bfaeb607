"""Time-stepping schemes for ``M a + C v + f(x) = f_ext(t)``: where to evaluate it for a candidate
``x_{n+1}``, and the step's velocity and acceleration once ``x_{n+1}`` solves it.

A scheme turns the equation of motion at one step into a static problem in the new positions:
for a candidate ``x_{n+1}`` :meth:`stage` returns the positions, velocities and accelerations
where the equation is evaluated and their derivatives with respect to ``x_{n+1}`` (scalars,
the same for every dof), so the step's tangent is ``c_a M + c_v C + c_x K``. Positions may be
any array shape (elementwise).

* :class:`ImplicitEuler` (backward Euler; SOFA's ``EulerImplicitSolver``): ``v_{n+1} = (x_{n+1} -
  x_n) / h``, ``a_{n+1} = (v_{n+1} - v_n) / h``, the equation at ``t_{n+1}``. First order, and it
  damps: a mode of frequency w loses a fraction of about ``w^2 h^2 / 2`` of its energy a step.
* :class:`GeneralizedAlpha` (Chung & Hulbert 1993, J. Appl. Mech. 60:371): Newmark's update
  with the equation at ``(1 - alpha_f) t_{n+1} + alpha_f t_n`` for the forces and
  ``(1 - alpha_m)`` for the inertia; second order, with the spectral radius at infinite
  frequency ``rho_inf`` in [0, 1] the only parameter (1: the trapezoidal rule, no dissipation;
  0: the high modes annihilated in one step)::

      alpha_m = (2 rho - 1) / (rho + 1),  alpha_f = rho / (rho + 1),
      gamma = 1/2 - alpha_m + alpha_f,    beta = (1 - alpha_m + alpha_f)^2 / 4.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import check_range


@dataclass(frozen=True)
class Kinematics:
    """A state in time: x [mm], v [mm/s], a [mm/s^2] (any shape, the same for the three), t [s]."""

    x: np.ndarray
    v: np.ndarray
    a: np.ndarray
    t: float


@dataclass(frozen=True)
class Stage:
    """Where the equation of motion is evaluated for a candidate ``x_{n+1}``.

    x, v, a : the evaluation point's positions, velocities, accelerations (as ``x_{n+1}``);
    t : its time [s]; c_x, c_v, c_a : d x / d x_{n+1} [-], d v / d x_{n+1} [1/s],
    d a / d x_{n+1} [1/s^2] (the tangent is ``c_a M + c_v C + c_x K``).
    """

    x: np.ndarray
    v: np.ndarray
    a: np.ndarray
    t: float
    c_x: float
    c_v: float
    c_a: float


@dataclass(frozen=True)
class ImplicitEuler:
    """Backward Euler (see the module docstring): ``needs_acceleration`` False."""

    name: str = "implicit_euler"
    needs_acceleration: bool = False

    def predict(self, s: Kinematics, h: float) -> np.ndarray:
        """First guess of ``x_{n+1}`` [mm]: the positions carried on at the current velocity."""
        return s.x + h * s.v

    def stage(self, x_new: np.ndarray, s: Kinematics, h: float) -> Stage:
        v = (x_new - s.x) / h
        return Stage(x_new, v, (v - s.v) / h, s.t + h, 1.0, 1.0 / h, 1.0 / h**2)

    def finish(self, x_new: np.ndarray, s: Kinematics, h: float) -> Kinematics:
        v = (x_new - s.x) / h
        return Kinematics(x_new, v, (v - s.v) / h, s.t + h)


@dataclass(frozen=True)
class GeneralizedAlpha:
    """Chung-Hulbert generalised-alpha with spectral radius ``rho_inf`` (module docstring)."""

    rho_inf: float = 0.8
    name: str = "generalized_alpha"
    needs_acceleration: bool = True

    def __post_init__(self):
        check_range("rho_inf", self.rho_inf, 0.0, 1.0)

    @property
    def coefficients(self) -> tuple[float, float, float, float]:
        """(alpha_m, alpha_f, gamma, beta)."""
        r = self.rho_inf
        am, af = (2 * r - 1) / (r + 1), r / (r + 1)
        return am, af, 0.5 - am + af, 0.25 * (1 - am + af) ** 2

    def _new(self, x_new, s: Kinematics, h: float):
        _, _, g, b = self.coefficients
        a = (x_new - s.x - h * s.v - h * h * (0.5 - b) * s.a) / (b * h * h)
        return s.v + h * ((1 - g) * s.a + g * a), a

    def predict(self, s: Kinematics, h: float) -> np.ndarray:
        """First guess of ``x_{n+1}`` [mm]: constant acceleration."""
        return s.x + h * s.v + 0.5 * h * h * s.a

    def stage(self, x_new: np.ndarray, s: Kinematics, h: float) -> Stage:
        am, af, g, b = self.coefficients
        v, a = self._new(x_new, s, h)
        return Stage((1 - af) * x_new + af * s.x, (1 - af) * v + af * s.v, (1 - am) * a + am * s.a,
                     s.t + (1 - af) * h, 1 - af, (1 - af) * g / (b * h), (1 - am) / (b * h * h))

    def finish(self, x_new: np.ndarray, s: Kinematics, h: float) -> Kinematics:
        v, a = self._new(x_new, s, h)
        return Kinematics(x_new, v, a, s.t + h)


@dataclass(frozen=True)
class QuasiStatic:
    """No inertia, no damping: the equation of motion's static limit ``f(x) = f_ext`` at each
    step (the quasi-static path a dynamic run is compared with); velocities and accelerations zero."""

    name: str = "quasi_static"
    needs_acceleration: bool = False

    def predict(self, s: Kinematics, h: float) -> np.ndarray:
        return s.x

    def stage(self, x_new: np.ndarray, s: Kinematics, h: float) -> Stage:
        zero = np.zeros_like(x_new)
        return Stage(x_new, zero, zero, s.t + h, 1.0, 0.0, 0.0)

    def finish(self, x_new: np.ndarray, s: Kinematics, h: float) -> Kinematics:
        zero = np.zeros_like(x_new)
        return Kinematics(x_new, zero, zero.copy(), s.t + h)


SCHEMES = {"implicit_euler": ImplicitEuler, "generalized_alpha": GeneralizedAlpha, "quasi_static": QuasiStatic}


def scheme(name: str, rho_inf: float = 0.8):
    """The scheme called ``name`` (:data:`SCHEMES`); ConfigError naming the allowed ones."""
    from ..errors import ConfigError

    if name not in SCHEMES:
        raise ConfigError(f"scheme: {name!r}: allowed {sorted(SCHEMES)}")
    return GeneralizedAlpha(rho_inf) if name == "generalized_alpha" else SCHEMES[name]()
