"""A second-order system ``M a + C v + f(x) = f_ext(t)`` stepped in time (schemes of :mod:`.schemes`).

Each step solves the scheme's static problem in ``x_{n+1}`` by Newton's method on the free
dofs; the prescribed dofs are set from their motion before Newton and their velocities and
accelerations follow from the scheme, like the free ones. Damping is Rayleigh's as SOFA
applies it: ``C = alpha M + beta K_0``, with ``K_0`` the tangent at the step's start, held
over the step (so C is linear in v within a step, and the step's tangent is
``c_a M + c_v C + c_x K``).

The trajectory carries an energy account: kinetic ``v^T M v / 2``; elastic, the work of the
internal force along the path (trapezoid rule on ``f . dx``; f alone gives no energy
function, and the rule is exact for a linear f); the work of ``f_ext`` (trapezoid); the
damping dissipation (``C v . dx`` at the scheme's stage); and the work of the supports that
drive the prescribed dofs (their reaction at the stage times their motion). In exact
arithmetic ``kinetic + elastic + dissipated - external - prescribed`` stays at its initial value
up to the scheme's own error: to round-off for generalised-alpha with ``rho_inf = 1`` on a linear
system under constant loads (prescribed motions included), O(h^2) under time-varying loads
(``f_ext`` is taken at the stage time); O(h) with ``rho_inf < 1`` (the stage's offsets) and for
implicit Euler (its numerical dissipation, large: it damps every mode).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import ConfigError, ConvergenceError, check_range
from .schemes import Kinematics

#: Below this many free dofs the Newton systems are solved dense (faster than a sparse LU).
DENSE_MAX = 400


@dataclass(frozen=True)
class SecondOrderSystem:
    """``M a + C v + f(x) = f_ext(t)`` with ``C = alpha M + beta K_0`` (module docstring).

    mass : (N, N) sparse or dense [t]; forces : ``x (N,) -> (f (N,) [N], K (N, N) [N/mm])``,
    the internal restoring force and its tangent ``df/dx`` (sparse or dense); external :
    ``t [s] -> (N,) [N]`` (None: zero); alpha [1/s], beta [s] >= 0 (Rayleigh); fixed : (c,)
    int dofs with prescribed motion; prescribed : ``t -> (c,)`` their positions [mm] (None:
    held where they start).
    """

    mass: object
    forces: Callable
    external: Callable | None = None
    alpha: float = 0.0
    beta: float = 0.0
    fixed: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    prescribed: Callable | None = None

    def __post_init__(self):
        shape = getattr(self.mass, "shape", None)
        if shape is None or len(shape) != 2 or shape[0] != shape[1] or shape[0] < 1:
            raise ConfigError(f"mass: shape is {shape} and should be (N, N) with N >= 1")
        if not sp.issparse(self.mass):
            object.__setattr__(self, "mass", np.asarray(self.mass, dtype=float))
        else:
            object.__setattr__(self, "mass", sp.csr_matrix(self.mass, dtype=float))
        check_range("alpha", self.alpha, 0.0, None)
        check_range("beta", self.beta, 0.0, None)
        if not callable(self.forces):
            raise ConfigError(f"forces: {type(self.forces).__name__}: expected a callable x -> (f, K)")
        fixed = np.asarray(self.fixed)
        if fixed.size == 0:
            fixed = np.zeros(0, np.int64)
        if fixed.ndim != 1 or not np.issubdtype(fixed.dtype, np.integer):
            raise ConfigError(f"fixed: shape {fixed.shape}, dtype {fixed.dtype}: expected a 1-D int array of dofs")
        N = shape[0]
        if len(fixed) and (fixed.min() < 0 or fixed.max() >= N):
            raise ConfigError(f"fixed: dofs span [{fixed.min()}, {fixed.max()}], allowed [0, {N - 1}]")
        if len(np.unique(fixed)) != len(fixed):
            raise ConfigError("fixed: repeated dofs: allowed each dof once")
        object.__setattr__(self, "fixed", fixed.astype(np.int64))

    @property
    def n_dofs(self) -> int:
        return self.mass.shape[0]


@dataclass(frozen=True)
class Energy:
    """Energy account [N mm = mJ] at the kept times, each (T,): kinetic, elastic (work of f
    from x0, so 0 at the start), external (work of f_ext), dissipated (by C), prescribed (work
    of the supports on the prescribed dofs). See the module docstring."""

    kinetic: np.ndarray
    elastic: np.ndarray
    external: np.ndarray
    dissipated: np.ndarray
    prescribed: np.ndarray

    @property
    def balance(self) -> np.ndarray:
        """(T,) ``kinetic + elastic + dissipated - external - prescribed`` [N mm]: constant up to
        the scheme's own dissipation."""
        return self.kinetic + self.elastic + self.dissipated - self.external - self.prescribed


@dataclass(frozen=True)
class Trajectory:
    """t (T,) [s]; x, v (T, N) [mm], [mm/s]; newton_iterations (T-1,) Newton solves between
    consecutive kept states (summed over the steps in between); energy : :class:`Energy`."""

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    newton_iterations: np.ndarray
    energy: Energy


# --------------------------------------------------------------------------- linear algebra


def _lin(*terms):
    """``sum c A`` over ``(c, A)`` pairs: sparse CSR if every A is sparse, else dense."""
    if all(sp.issparse(A) for _, A in terms):
        return sum(c * A for c, A in terms).tocsr()
    return sum(c * (A.toarray() if sp.issparse(A) else A) for c, A in terms)


def _restrict(A, free: np.ndarray):
    return A[free][:, free] if sp.issparse(A) else A[np.ix_(free, free)]


def _solve(A, b: np.ndarray) -> np.ndarray:
    if sp.issparse(A):
        if A.shape[0] > DENSE_MAX:
            return spla.spsolve(A.tocsc(), b)
        A = A.toarray()
    return np.linalg.solve(A, b)


def _evaluate(system: SecondOrderSystem, x: np.ndarray):
    f, K = system.forces(x)
    f = np.asarray(f, dtype=float).reshape(-1)
    N = system.n_dofs
    if f.shape != (N,) or getattr(K, "shape", None) != (N, N):
        raise ConfigError(f"forces: returned f {f.shape} and K {getattr(K, 'shape', None)}, expected ({N},) "
                          f"and ({N}, {N})")
    return f, (K if sp.issparse(K) else np.asarray(K, dtype=float))


def _external(system: SecondOrderSystem, t: float) -> np.ndarray:
    if system.external is None:
        return np.zeros(system.n_dofs)
    fe = np.asarray(system.external(t), dtype=float)
    if fe.shape != (system.n_dofs,):
        raise ConfigError(f"external: returned shape {fe.shape} at t = {t:g} s, expected ({system.n_dofs},)")
    return fe


def _positions(system: SecondOrderSystem, x0: np.ndarray) -> Callable[[float], np.ndarray]:
    """``t -> (c,)`` positions of the prescribed dofs, shape-checked."""
    if system.prescribed is None:
        held = x0[system.fixed].copy()
        return lambda t: held

    def p(t):
        y = np.asarray(system.prescribed(t), dtype=float)
        if y.shape != system.fixed.shape:
            raise ConfigError(f"prescribed: returned shape {y.shape} at t = {t:g} s, expected {system.fixed.shape}")
        return y
    return p


def _as_state(name: str, x, N: int) -> np.ndarray:
    a = np.array(x, dtype=float).reshape(-1) if np.ndim(x) else np.array([x], float)
    if a.shape != (N,) or not np.all(np.isfinite(a)):
        raise ConfigError(f"{name}: shape is {np.shape(x)} and should be ({N},), finite")
    return a


# --------------------------------------------------------------------------- stepping


def _newton(system, M, C, free, s: Kinematics, x_new, h, scheme, tol, max_iter, step):
    """Solve the step for ``x_new`` (N,) (prescribed dofs already set, modified in place).
    Returns (iterations, stage, residual r (N,) before any reaction)."""
    eps = np.finfo(float).eps
    history, stalled = [], False
    for it in range(max_iter + 1):
        st = scheme.stage(x_new, s, h)
        f, K = _evaluate(system, st.x)
        Ma, Cv, fe = M @ st.a, C @ st.v, _external(system, st.t)
        r = Ma + Cv + f - fe
        res = np.linalg.norm(r[free])
        scale = sum(np.linalg.norm(z[free]) for z in (Ma, Cv, f, fe)) + 1e-300
        history.append(res)
        # a correction at round-off ends the iteration too: the residual cannot drop further
        if res <= tol * scale or stalled:
            return it, st, r
        if it == max_iter:
            break
        J = _restrict(_lin((st.c_a, M), (st.c_v, C), (st.c_x, K)), free)
        dx = _solve(J, -r[free])
        x_new[free] += dx
        stalled = np.linalg.norm(dx) <= 4 * eps * np.linalg.norm(x_new[free])
    raise ConvergenceError(
        f"step {step} (t = {s.t + h:.6g} s): Newton did not converge in {max_iter} iterations: residual "
        f"{history[-1]:.3g} N, allowed <= {tol * scale:.3g} N (tol {tol:g} x force scale)", history)


def _initial_acceleration(system, M, C, free, v0, f0, positions, h) -> np.ndarray:
    """(N,) a0 [mm/s^2]: the prescribed dofs' from their motion (one-sided second-order
    differences with step h, error O(h^2)); the free ones from the equation of motion at t = 0."""
    a = np.zeros(system.n_dofs)
    if system.prescribed is not None and len(system.fixed):
        p = [positions(k * h) for k in range(4)]
        a[system.fixed] = (2 * p[0] - 5 * p[1] + 4 * p[2] - p[3]) / h**2
    rhs = _external(system, 0.0) - f0 - C @ v0 - M @ a
    a[free] = _solve(_restrict(M, free), rhs[free])
    return a


def integrate(system: SecondOrderSystem, x0, v0, *, h: float, t_end: float, scheme, tol: float = 1e-10,
              max_iter: int = 20, progress: Callable | None = None, keep_every: int = 1) -> Trajectory:
    """Step ``system`` from ``x0``, ``v0`` (N,) [mm], [mm/s] at t = 0 to ``t_end`` [s] by steps ``h`` [s].

    ``ceil(t_end / h)`` steps (the last time may pass ``t_end`` by less than h); ``scheme``: one of
    :mod:`.schemes`. Newton on the free dofs stops when ``|r| <= tol * (|M a| + |C v| + |f| +
    |f_ext|)`` (free parts, at the stage) or when its correction is at round-off; after
    ``max_iter`` solves it raises :class:`ConvergenceError` naming the step, the time and the
    residual. The prescribed dofs must start where ``system.prescribed(0)`` puts them (held
    ones: at rest). ``progress(step, n_steps)`` is called after each step; every
    ``keep_every``-th state is kept (and the last one).
    """
    if not isinstance(system, SecondOrderSystem):
        raise ConfigError(f"system: {type(system).__name__}: expected SecondOrderSystem")
    check_range("h", h, 0.0, None, lo_open=True)
    check_range("t_end", t_end, 0.0, None, lo_open=True)
    check_range("tol", tol, 0.0, None, lo_open=True)
    if int(max_iter) != max_iter or max_iter < 1:
        raise ConfigError(f"max_iter: {max_iter!r}: allowed an integer >= 1")
    if int(keep_every) != keep_every or keep_every < 1:
        raise ConfigError(f"keep_every: {keep_every!r}: allowed an integer >= 1")
    if not all(hasattr(scheme, k) for k in ("predict", "stage", "finish", "needs_acceleration")):
        raise ConfigError(f"scheme: {scheme!r}: expected a scheme of metasheet.dynamics.schemes")
    N, fixed = system.n_dofs, system.fixed
    x, v = _as_state("x0", x0, N), _as_state("v0", v0, N)
    free = np.setdiff1d(np.arange(N), fixed)
    positions = _positions(system, x)
    p0 = positions(0.0)
    if np.abs(p0 - x[fixed]).max(initial=0.0) > 1e-9 * (np.abs(x).max() + 1.0):
        raise ConfigError("x0: the prescribed dofs start away from prescribed(0): allowed x0[fixed] == prescribed(0)")
    if system.prescribed is None and np.any(v[fixed] != 0):
        raise ConfigError("v0: held dofs (fixed, no prescribed motion) have a velocity: allowed v0[fixed] == 0")
    M = system.mass
    n_steps = max(1, int(np.ceil(t_end / h * (1 - 1e-12))))
    f, K = _evaluate(system, x)
    C = _lin((system.alpha, M), (system.beta, K))
    a = (_initial_acceleration(system, M, C, free, v, f, positions, h) if scheme.needs_acceleration
         else np.zeros(N))
    s = Kinematics(x, v, a, 0.0)
    fe = _external(system, 0.0)
    acc = np.array([0.5 * v @ (M @ v), 0.0, 0.0, 0.0, 0.0])  # kinetic, elastic, external, dissipated, prescribed
    kept_t, kept_x, kept_v, kept_e, iters = [0.0], [x.copy()], [v.copy()], [acc.copy()], []
    pending = 0
    for n in range(n_steps):
        x_new = np.array(scheme.predict(s, h), dtype=float)
        x_new[fixed] = positions((n + 1) * h)
        it, st, r = _newton(system, M, C, free, s, x_new, h, scheme, tol, int(max_iter), n)
        new = scheme.finish(x_new, s, h)
        new = Kinematics(new.x, new.v, new.a, (n + 1) * h)  # times as n h, not summed
        dx = new.x - s.x
        f_new, K_new = _evaluate(system, new.x)
        fe_new = _external(system, new.t)
        acc[0] = 0.5 * new.v @ (M @ new.v)
        acc[1] += 0.5 * (f + f_new) @ dx
        acc[2] += 0.5 * (fe + fe_new) @ dx
        acc[3] += (C @ st.v) @ dx
        acc[4] += r[fixed] @ dx[fixed]  # the supports' reaction r_c at the stage
        s, f, fe = new, f_new, fe_new
        C = _lin((system.alpha, M), (system.beta, K_new))
        pending += it
        if (n + 1) % keep_every == 0 or n + 1 == n_steps:
            kept_t.append(new.t)
            kept_x.append(new.x.copy())
            kept_v.append(new.v.copy())
            kept_e.append(acc.copy())
            iters.append(pending)
            pending = 0
        if progress is not None:
            progress(n + 1, n_steps)
    e = np.array(kept_e)
    return Trajectory(np.array(kept_t), np.array(kept_x), np.array(kept_v), np.array(iters, dtype=np.int64),
                      Energy(*(e[:, k].copy() for k in range(5))))
