"""Time integration of second-order systems against exact solutions of linear and Duffing oscillators."""

import numpy as np
import pytest
import scipy.integrate as si
import scipy.linalg as sla
import scipy.sparse as sp

from metasheet.dynamics import integrate as integrate_module
from metasheet.dynamics.integrate import SecondOrderSystem, integrate
from metasheet.dynamics.schemes import GeneralizedAlpha, ImplicitEuler
from metasheet.errors import ConfigError, ConvergenceError

TWO_PI = 2 * np.pi
M2 = np.diag([1.0, 2.0])  # [t]
K2 = np.array([[3.0, -1.0], [-1.0, 1.0]]) * TWO_PI**2  # [N/mm]: modes at 0.56 and 1.78 Hz
X0, V0 = np.array([1.0, -0.5]), np.array([0.0, 2.0])


def linear(M, K, **kw) -> SecondOrderSystem:
    return SecondOrderSystem(M, lambda x: (K @ x, K), **kw)


def exact_linear(M, K, C, x0, v0, t, force=None):
    """(T, N) exact x(t) of ``M x'' + C x' + K x = force`` (constant) from the state-space exponential."""
    n = len(x0)
    Mi = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Mi @ K, -Mi @ C]])
    xs = np.zeros(n) if force is None else np.linalg.solve(K, force)  # static offset
    z0 = np.r_[x0 - xs, v0]
    return np.array([(sla.expm(A * ti) @ z0)[:n] for ti in t]) + xs


def energy(M, K, tr):
    return 0.5 * np.einsum("ti,ij,tj->t", tr.v, M, tr.v) + 0.5 * np.einsum("ti,ij,tj->t", tr.x, K, tr.x)


@pytest.mark.parametrize("scheme, hs, order", [
    (ImplicitEuler(), (1 / 400, 1 / 800), 1.0),
    (GeneralizedAlpha(0.8), (1 / 100, 1 / 200), 2.0),
    (GeneralizedAlpha(1.0), (1 / 100, 1 / 200), 2.0),
])
def test_damped_two_dof_converges_at_the_scheme_order(scheme, hs, order):
    alpha, beta = 0.3, 2e-3
    sys_ = linear(M2, K2, alpha=alpha, beta=beta)
    C = alpha * M2 + beta * K2
    errors = []
    for h in hs:
        tr = integrate(sys_, X0, V0, h=h, t_end=1.0, scheme=scheme)
        assert np.all(tr.newton_iterations == 1)  # linear: one Newton solve a step
        errors.append(np.abs(tr.x - exact_linear(M2, K2, C, X0, V0, tr.t)).max())
    observed = np.log2(errors[0] / errors[1])
    assert observed == pytest.approx(order, abs=0.1), errors
    assert errors[1] < (0.06 if order == 1 else 0.01)


def test_trapezoidal_alpha_conserves_energy_and_lower_rho_dissipates():
    sys_ = linear(M2, K2)
    tr = integrate(sys_, X0, V0, h=1e-2, t_end=10.0, scheme=GeneralizedAlpha(1.0))
    assert len(tr.t) == 1001
    E = energy(M2, K2, tr)
    assert np.abs(E / E[0] - 1).max() < 1e-9
    # the account agrees: kinetic + elastic (work of f from x0) = the initial energy
    np.testing.assert_allclose(tr.energy.kinetic + tr.energy.elastic + 0.5 * X0 @ K2 @ X0, E, rtol=1e-9)
    tr2 = integrate(sys_, X0, V0, h=1e-2, t_end=10.0, scheme=GeneralizedAlpha(0.5))
    E2 = energy(M2, K2, tr2)
    # rho_inf < 1 damps the high frequencies (the energy of x, v wobbles within a period, so
    # compare the first and the last second)
    assert E2[-100:].max() < 0.998 * E2[:100].min()


def peaks(t, x):
    """Times and values of the local maxima of samples x(t), refined by a parabola through three."""
    i = np.flatnonzero((x[1:-1] > x[:-2]) & (x[1:-1] >= x[2:])) + 1
    a, b, c = x[i - 1], x[i], x[i + 1]
    s = 0.5 * (a - c) / (a - 2 * b + c)
    return t[i] + s * (t[1] - t[0]), b - 0.25 * (a - c) * s


def test_rayleigh_damping_ratio_from_the_logarithmic_decrement():
    w, alpha, beta = TWO_PI * 5, 0.5, 1e-3  # zeta = alpha/(2w) + beta w/2 = 0.0236
    zeta = alpha / (2 * w) + beta * w / 2
    K = np.array([[w * w]])
    tr = integrate(linear(np.eye(1), K, alpha=alpha, beta=beta), [1.0], [0.0], h=2.5e-4, t_end=0.65,
                   scheme=GeneralizedAlpha(1.0))
    tp, xp = peaks(tr.t, tr.x[:, 0])
    delta = np.log(xp[0] / xp[-1]) / (len(xp) - 1)
    measured = delta / np.sqrt(4 * np.pi**2 + delta**2)  # delta = 2 pi zeta / sqrt(1 - zeta^2)
    assert measured == pytest.approx(zeta, rel=1e-3)
    assert np.diff(tp).mean() == pytest.approx(TWO_PI / (w * np.sqrt(1 - zeta**2)), rel=1e-4)


def duffing(k=TWO_PI**2, k3=TWO_PI**2):
    return SecondOrderSystem(np.eye(1), lambda x: (k * x + k3 * x**3, np.array([[k + 3 * k3 * x[0] ** 2]])))


def duffing_period(A, k=TWO_PI**2, k3=TWO_PI**2):
    """Exact period of x'' + k x + k3 x^3 = 0 from amplitude A: 4 int_0^A dx / sqrt(2 (U(A) - U(x))),
    with x = A sin(theta) to lift the end singularity."""
    U = lambda x: 0.5 * k * x * x + 0.25 * k3 * x**4
    g = lambda th: A * np.cos(th) / np.sqrt(2 * (U(A) - U(A * np.sin(th))))
    return 4 * si.quad(g, 0, np.pi / 2, epsabs=0, epsrel=1e-13)[0]


def test_duffing_period_exercises_newton():
    T = duffing_period(1.0)  # 0.76 s: stiffer than the linear 1 s
    errors = []
    for h in (T / 100, T / 200):
        tr = integrate(duffing(), [1.0], [0.0], h=h, t_end=3 * T, scheme=GeneralizedAlpha(1.0))
        tp, xp = peaks(tr.t, tr.x[:, 0])
        errors.append(abs(np.diff(tp).mean() / T - 1))
        np.testing.assert_allclose(xp, 1.0, atol=1e-3)  # no drift of the amplitude
        if h == T / 100:
            assert tr.newton_iterations.min() >= 1 and tr.newton_iterations.max() >= 2  # nonlinear solves
    assert np.log2(errors[0] / errors[1]) == pytest.approx(2.0, abs=0.2), errors
    assert errors[1] < 2e-4
    # against an independent high-accuracy solution
    ref = si.solve_ivp(lambda t, z: [z[1], -TWO_PI**2 * (z[0] + z[0] ** 3)], (0, tr.t[-1]), [1.0, 0.0],
                       t_eval=tr.t, rtol=1e-11, atol=1e-12, method="DOP853")
    assert np.abs(tr.x[:, 0] - ref.y[0]).max() < 5e-3


def test_newton_failure_names_the_step_and_time():
    with pytest.raises(ConvergenceError, match=r"step 0 \(t = 0.05 s\).*residual") as err:
        integrate(duffing(), [3.0], [0.0], h=0.05, t_end=1.0, scheme=ImplicitEuler(), max_iter=1)
    assert len(err.value.history) == 2


def base_excited(m, k, c, Y, Om):
    """Dof 0 the base, moved as Y sin(Om t), dof 1 the mass on a spring k and damper c (= beta k)."""
    K = np.array([[k, -k], [-k, k]])
    return SecondOrderSystem(np.diag([1.0, m]), lambda x: (K @ x, K), beta=c / k, fixed=np.array([0]),
                             prescribed=lambda t: np.array([Y * np.sin(Om * t)]))


def test_base_excitation_reaches_the_exact_steady_amplitude():
    m, w, zeta, Y = 1.0, TWO_PI * 5, 0.1, 0.2
    k, c, Om = m * w * w, 2 * zeta * m * w, 1.3 * w
    sys_ = base_excited(m, k, c, Y, Om)
    h = TWO_PI / Om / 200  # amplitude error O((Om h)^2): -1.5e-3 at 100 steps a period, -4.4e-4 at 200
    tr = integrate(sys_, [0.0, 0.0], [Y * Om, 0.0], h=h, t_end=4.0, scheme=GeneralizedAlpha(1.0))
    np.testing.assert_array_equal(tr.x[:, 0], Y * np.sin(Om * tr.t))  # set, not solved
    tail = tr.t > 3.4  # transient: exp(-zeta w t) = 2e-5 by then
    amp = 0.5 * np.ptp(tr.x[tail, 1])
    exact = Y * np.sqrt((k**2 + (c * Om) ** 2) / ((k - m * Om**2) ** 2 + (c * Om) ** 2))
    assert amp == pytest.approx(exact, rel=1e-3)
    # the supports' work feeds the damper; linear, trapezoidal: the account closes to round-off
    b = tr.energy.balance
    assert tr.energy.prescribed[-1] > 0
    assert np.abs(b - b[0]).max() < 1e-12 * tr.energy.dissipated[-1]


def test_energy_balance_with_damping_and_loads():
    alpha, beta, F = 0.3, 2e-3, np.array([5.0, -3.0])
    # constant load, trapezoidal alpha: the account closes to round-off
    sys_ = linear(M2, K2, alpha=alpha, beta=beta, external=lambda t: F)
    tr = integrate(sys_, X0, V0, h=1e-2, t_end=5.0, scheme=GeneralizedAlpha(1.0))
    b, e = tr.energy.balance, tr.energy
    assert e.dissipated[-1] > 0.5 * e.kinetic[0] and e.external[-1] != 0
    assert np.abs(b - b[0]).max() < 1e-10 * e.dissipated[-1]
    C = alpha * M2 + beta * K2
    # the static offset of the load is there; the phase error (w h)^2 w t / 12 bounds the rest
    np.testing.assert_allclose(tr.x, exact_linear(M2, K2, C, X0, V0, tr.t, F), atol=0.03)
    # a time-varying load: the account's error falls as h^2 (trapezoidal alpha: f_ext at the
    # stage time against the trapezoid of its work) or h (Euler's numerical dissipation)
    sys_ = linear(M2, K2, alpha=alpha, beta=beta, external=lambda t: F * np.sin(7 * t))
    for scheme, hs, order in ((GeneralizedAlpha(1.0), (1e-2, 5e-3), 2), (ImplicitEuler(), (1e-3, 5e-4), 1)):
        drift = []
        for h in hs:
            b = integrate(sys_, X0, V0, h=h, t_end=0.5, scheme=scheme).energy.balance
            drift.append(np.abs(b - b[0]).max())
        assert np.log2(drift[0] / drift[1]) == pytest.approx(order, abs=0.15), drift


def test_sparse_and_dense_inputs_agree(monkeypatch):
    n = 30  # a chain of springs, clamped at dof 0
    K = sp.diags([2 * np.ones(n), -np.ones(n - 1), -np.ones(n - 1)], [0, 1, -1], format="csr") * 1e3
    M = sp.identity(n, format="csr") * 1e-3
    x0 = np.sin(np.linspace(0, np.pi, n))  # x0[0] = 0: the clamp
    kw = dict(h=1e-3, t_end=0.05, scheme=GeneralizedAlpha(0.8))
    dense = integrate(linear(M.toarray(), K.toarray(), beta=1e-4, fixed=np.array([0])), x0, 0 * x0, **kw)
    monkeypatch.setattr(integrate_module, "DENSE_MAX", 4)  # the sparse LU path
    sparse = integrate(linear(M, K, beta=1e-4, fixed=np.array([0])), x0, 0 * x0, **kw)
    np.testing.assert_allclose(sparse.x, dense.x, rtol=0, atol=1e-12)
    assert np.all(sparse.x[:, 0] == 0)


def test_keep_every_and_progress():
    calls = []
    tr = integrate(linear(M2, K2), X0, V0, h=0.01, t_end=0.095, scheme=ImplicitEuler(), keep_every=3,
                   progress=lambda i, n: calls.append((i, n)))
    assert calls == [(i, 10) for i in range(1, 11)]  # ceil(0.095 / 0.01) steps
    np.testing.assert_allclose(tr.t, [0, 0.03, 0.06, 0.09, 0.1], rtol=1e-15)
    assert tr.x.shape == (5, 2) and tr.v.shape == (5, 2)
    np.testing.assert_array_equal(tr.newton_iterations, [3, 3, 3, 1])
    full = integrate(linear(M2, K2), X0, V0, h=0.01, t_end=0.1, scheme=ImplicitEuler())
    np.testing.assert_array_equal(tr.x, full.x[[0, 3, 6, 9, 10]])
    np.testing.assert_array_equal(tr.energy.elastic, full.energy.elastic[[0, 3, 6, 9, 10]])


@pytest.mark.parametrize("kw, match", [
    (dict(h=0.0), "h:"),
    (dict(t_end=-1.0), "t_end"),
    (dict(x0=np.zeros(3)), "x0: shape"),
    (dict(v0=[np.nan, 0.0]), "v0"),
    (dict(max_iter=0), "max_iter"),
    (dict(keep_every=1.5), "keep_every"),
    (dict(scheme="euler"), "scheme"),
    (dict(system=linear(M2, K2, fixed=np.array([0]), prescribed=lambda t: np.array([2.0]))),
     "x0: the prescribed dofs"),
    (dict(system=linear(M2, K2, fixed=np.array([0]), prescribed=lambda t: np.zeros(2)), x0=[0.0, 0.0]),
     "prescribed: returned shape"),
    (dict(system=linear(M2, K2, fixed=np.array([1]))), "v0: held dofs"),
    (dict(system=SecondOrderSystem(M2, lambda x: (x, np.eye(3)))), "forces: returned"),
    (dict(system=linear(M2, K2, external=lambda t: np.zeros(3))), "external: returned"),
])
def test_integrate_validation(kw, match):
    args = dict(system=linear(M2, K2), x0=X0, v0=V0, h=0.01, t_end=0.1, scheme=ImplicitEuler())
    args.update(kw)
    with pytest.raises(ConfigError, match=match):
        integrate(args.pop("system"), args.pop("x0"), args.pop("v0"), **args)


@pytest.mark.parametrize("make, match", [
    (lambda: SecondOrderSystem(np.zeros((2, 3)), lambda x: x), "mass: shape"),
    (lambda: SecondOrderSystem(M2, lambda x: x, alpha=-1.0), "alpha"),
    (lambda: SecondOrderSystem(M2, lambda x: x, beta=np.inf), "beta"),
    (lambda: SecondOrderSystem(M2, None), "forces"),
    (lambda: SecondOrderSystem(M2, lambda x: x, fixed=np.array([2])), "fixed: dofs span"),
    (lambda: SecondOrderSystem(M2, lambda x: x, fixed=np.array([1, 1])), "fixed: repeated"),
    (lambda: SecondOrderSystem(M2, lambda x: x, fixed=np.array([0.5])), "fixed: shape"),
])
def test_system_validation(make, match):
    with pytest.raises(ConfigError, match=match):
        make()
