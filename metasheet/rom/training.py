"""Training a :class:`.model.ReducedRobot`: snapshots, basis, element sample, each by an error target.

1. Snapshots: full-model equilibria (:func:`metasheet.robot.equilibrium.solve_equilibrium`) at motor angles
   spread over the motor box (:func:`motor_design`: a scrambled Sobol sequence plus the rest
   angles and the box's all-low / all-high corners, which bend the sheets most).
2. Basis (:func:`.basis.pod_basis`): the rest equilibrium's static modes plus POD modes
   until every snapshot's worst nodal projection error is below ``basis_tol_mm``, then the
   snapshots' own static responses (:func:`sensitivity`, :func:`.basis.add_sensitivities`)
   until each is captured within ``tangent_tol``: the Jacobian's accuracy.
3. Elements (:func:`.ecsw.ecsw`): per training state, every element's contribution to the
   generalised forces (force rows [N]; moment and torque rows over the effector's length
   scale). Training states are the projected snapshots and, so the sample also fits the
   forces away from equilibrium (the tangent), each one moved along its own static response.
4. The ECSW tolerance is tightened (halved each time) until the reduced model reproduces the
   training equilibria within ``fit_tol_mm`` and the Jacobians of the basis's model with
   every element there within ``fit_jacobian_tol`` (:func:`train`). The Jacobian test
   matters: a sample can hold the positions within 0.03 mm and still miss the held-out
   Jacobians by 2 %.

The certificate (:mod:`.certificate`) then compares reduced and full on held-out angles.
"""

from __future__ import annotations

import time

import numpy as np

from ..errors import ConfigError, ConvergenceError
from ..robot.equilibrium import solve_equilibrium
from ..robot.kinematics import kinematics
from .basis import add_sensitivities, pod_basis
from .coordinates import ReducedBasis, ReducedState, coordinate_jacobian, projected_state, robot_key
from .ecsw import ecsw_path
from .model import ReducedRobot


def motor_design(lo, hi, n: int, seed: int, *, corners: bool = True) -> np.ndarray:
    """(N, na) motor angles [rad]: ``n`` scrambled Sobol points in the box [lo, hi] (na,) [rad],
    and (``corners``) the all-low and all-high corners."""
    from scipy.stats import qmc

    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    if n < 1 or np.any(hi <= lo):
        raise ConfigError(f"motor_design: n {n!r}, box {np.degrees(lo)}..{np.degrees(hi)} deg: need n >= 1, lo < hi")
    # the first n points of the scrambled sequence (n need not be a power of 2 here)
    pts = qmc.Sobol(len(lo), scramble=True, seed=seed).random(2 ** int(np.ceil(np.log2(n))))[:n]
    out = lo + pts * (hi - lo)
    if corners:
        out = np.vstack([lo, hi, out])
    return out


def static_modes(robot, rest) -> np.ndarray:
    """(3 n_f, 6 + na + 1) the free nodes' response at the rest equilibrium ``rest`` to each
    rigid coordinate (eq. 6's ``K_ff^-1 K_fr J_r``) and to the sheets' weight (``K_ff^-1 f_g``)."""
    lz = robot.linearizer()
    lin = lz.linearize(rest)
    c = robot.coupling
    return np.column_stack([lin.Y, lz.factor.solve(robot.f_ext[c.free].ravel())])


def sensitivity(lz, state) -> np.ndarray:
    """(3 n_f, 6 + na) float32: the free nodes' static response to each rigid coordinate at
    the full equilibrium ``state`` (eq. 6's ``K_ff^-1 K_fr J_r``; one fresh linearisation of
    the :class:`~metasheet.robot.statics.Linearizer` ``lz``). float32: POD keeps it to ~1e-3 anyway."""
    return sensitivity_and_jacobian(lz, state)[0]


def sensitivity_and_jacobian(lz, state) -> tuple[np.ndarray, np.ndarray]:
    """(:func:`sensitivity`, the Jacobian (6, na)) at ``state`` from the one linearisation."""
    lin = lz.linearize(state)
    return lin.Y.astype(np.float32), kinematics(lin).J


def element_contributions(robot, V: np.ndarray, st: ReducedState) -> np.ndarray:
    """(6 + na + k, m) every element's generalised internal force ``T_e^T f_e`` at ``st``
    (rows scaled: forces [N], moments and torques over the effector's length scale [N])."""
    from ..fem.corotational.p2 import corotational_quadrature_numpy

    c, body = robot.coupling, robot.body
    x_f = c.rest[c.free] + (V @ st.a).reshape(-1, 3)
    x = c.positions(st.p, st.R, st.angles, x_f)
    T = coordinate_jacobian(c, x, st.p, c.effector_nodes, [s.nodes for s in c.servos], c.free, V)
    nq = T.shape[2]
    out = np.empty((nq, body.n_elements))
    for start in range(0, body.n_elements, 4096):  # chunks bound the memory of the batched kernel
        sl = slice(start, min(start + 4096, body.n_elements))
        tets = body.tets[sl]
        fe, _ = corotational_quadrature_numpy(x[tets], body.quad_grads[sl], body.quad_weights[sl],
                                              body.stiffness[sl], tangent=False)
        out[:, sl] = np.einsum("mai,maiq->qm", fe.reshape(len(tets), -1, 3), T[tets], optimize=True)
    out[3:6 + c.n_act] /= c.length_scale
    return out


def force_rows(robot, V: np.ndarray, states) -> np.ndarray:
    """(len(states) (6 + na + k), m) float64, Fortran order: ECSW's matrix, each state's
    :func:`element_contributions` over the norm of their sum, written in place. The training's
    largest array (on the quick robot, 194 states at k 331: 2.0 GB): one copy of it, in the
    order :func:`.ecsw.ecsw_path` reads (column by column), not a list, a stack and a reordered
    copy."""
    nq = 6 + robot.coupling.n_act + V.shape[1]
    A = np.empty((len(states) * nq, robot.body.n_elements), order="F")
    for i, st in enumerate(states):
        b = element_contributions(robot, V, st)
        A[i * nq:(i + 1) * nq] = b / max(np.linalg.norm(b.sum(axis=1)), 1e-300)
    return A


def _equilibrium_at(reduced: ReducedRobot, snap, lz):
    """The reduced equilibrium at the snapshot's angles, solved from its projection."""
    return solve_equilibrium(reduced, snap.angles, state=reduced.project(snap), linearizer=lz).state


def galerkin_jacobians(robot, V: np.ndarray, snaps, jacobians=None) -> tuple[list, float]:
    """The Jacobians (each (6, na)) of the reduced model on basis ``V`` with every element (no
    hyper-reduction) at the snapshots' angles, and their worst relative error against the full
    ``jacobians`` (nan when None): the basis's share of the Jacobian error, which no element
    sample can remove."""
    m = robot.body.n_elements
    everything = ReducedRobot(robot, ReducedBasis(V, np.arange(m), np.ones(m), robot.angle_min, robot.angle_max,
                                                  robot_key(robot)))
    lz = everything.linearizer()
    out = [kinematics(lz.linearize(_equilibrium_at(everything, s, lz))).J for s in snaps]
    if jacobians is None:
        return out, float("nan")
    return out, max(_relative(J, Jf) for J, Jf in zip(out, jacobians))


def _relative(J, ref) -> float:
    ref = np.asarray(ref, float)
    return float(np.linalg.norm(J - ref) / np.linalg.norm(ref))


def fit_error(reduced: ReducedRobot, snaps, reference_jacobians=None, *,
              give_up_mm: float | None = None) -> tuple[float, float, int]:
    """(position [mm], Jacobian [relative Frobenius]) worst errors of the reduced equilibria at
    the snapshots' angles against the snapshots, and their Jacobians against
    ``reference_jacobians`` (each (6, na); None: nan), each solved from its snapshot's
    projection: the hyper-reduction's error at the training states, not the equilibrium
    path's; and the number of snapshots checked. With ``give_up_mm``, the check ends at the
    first snapshot missed by more [mm]: the errors are then those of the snapshots checked
    (lower bounds), enough to reject the sample (the ECSW rounds' fit, whose first samples
    miss the box's corners: 3 of 4 rounds on the paper robot, 21 of its 93 s of training).
    (From rest, a reduced path can take another branch where the full one stays on a
    symmetric one: on the authors' P2 robot all motors 12 deg below rest hold the effector at
    x = 0 from rest, while a basis that spans the rod's sideways mode lets round-off break the
    symmetry and lands 3.6 mm away; the full model started there settles 10.7 mm to the side.)"""
    pos, jac = 0.0, 0.0 if reference_jacobians is not None else float("nan")
    lz = reduced.linearizer()
    for i, s in enumerate(snaps):
        try:
            eq = _equilibrium_at(reduced, s, lz)
        except ConvergenceError:
            return np.inf, np.inf, i + 1
        pos = max(pos, float(np.linalg.norm(eq.p - s.p)))
        if give_up_mm is not None and pos > give_up_mm:
            return pos, jac, i + 1
        if reference_jacobians is not None:
            jac = max(jac, _relative(kinematics(lz.linearize(eq)).J, reference_jacobians[i]))
    return pos, jac, len(snaps)


def train(robot, snaps, rest, *, sensitivities=None, jacobians=None, basis_tol_mm: float = 0.01,
          tangent_tol: float = 0.01, ecsw_tol: float = 1e-3, fit_tol_mm: float = 0.02,
          fit_jacobian_tol: float = 0.01, box=None, max_rounds: int = 9, fit_count: int = 8,
          ecsw_batch: float = 0.02, max_elements: int | None = None,
          ecsw_snapshots: int | None = None) -> ReducedBasis:
    """A :class:`ReducedBasis` for the full ``robot`` from snapshot equilibria ``snaps`` (full
    :class:`~metasheet.robot.statics.RobotState` s) and the rest equilibrium ``rest``.

    ``sensitivities`` : (3 n_f, c) the snapshots' static responses (:func:`sensitivity`),
    added by :func:`.basis.add_sensitivities` to relative nodal error ``tangent_tol``
    (None: none; the Jacobian away from rest is then only as good as the POD modes make it);
    ``jacobians`` : the snapshots' full Jacobians (each (6, na); None: not known), for the
    record's ``basis_jacobian_rel`` (:func:`galerkin_jacobians`); ``basis_tol_mm`` : POD target
    (worst nodal projection error) [mm]; ``ecsw_tol`` : the first ECSW tolerance, halved until
    the reduced model reproduces ``fit_count`` training equilibria (the box corners first)
    within ``fit_tol_mm`` [mm] and the Jacobians of the model with every element there within
    ``fit_jacobian_tol`` [relative], at most ``max_rounds`` times (if the Jacobians' target is
    never met, the round with the smallest Jacobian error among those meeting the positions'
    is kept, ``info["fit_jacobian_met"]`` False; the held-out certificate judges it);
    ``box`` : (lo, hi) motor box [rad] (default: the robot's limits);
    ``ecsw_batch`` : :func:`.ecsw.ecsw_path`'s ``batch`` (elements entered per gradient);
    ``max_elements`` : the element budget (None: every element): the tolerances a sample within
    it cannot meet are not tried, the rounds before are judged as above and
    ``info["element_budget_spent"]`` is True (none within it: :class:`ConvergenceError`);
    ``ecsw_snapshots`` : the element sample is fitted on the rest state and at most this many
    snapshots (the first: the box's corners and the design's first points, spread over the
    box), each also pushed (None: all). ECSW's matrix grows with states x k x elements; the
    basis takes every snapshot.
    """
    t0 = time.perf_counter()
    c = robot.coupling
    lo, hi = (robot.angle_min, robot.angle_max) if box is None else box
    U = np.column_stack([(s.x[c.free] - c.rest[c.free]).ravel() for s in [rest, *snaps]])
    statics = static_modes(robot, rest)
    V, record = pod_basis(statics, U, basis_tol_mm)
    if sensitivities is not None:
        V, more = add_sensitivities(V, np.asarray(sensitivities, float), tangent_tol)
        record.update(more)
    t_basis = time.perf_counter() - t0
    fitted = snaps if ecsw_snapshots is None else snaps[:ecsw_snapshots]
    states = [projected_state(robot, V, s) for s in [rest, *fitted]]
    # off-equilibrium states: each snapshot pushed along the static response (the tangent's data)
    k_st = record["static_modes"]
    rng = np.random.default_rng(0)
    pushed = []
    for st in states:
        da = np.zeros(V.shape[1])
        da[:k_st] = rng.normal(scale=0.5, size=k_st)
        pushed.append(ReducedState(st.p, st.R, st.angles, st.a + da))
    A = force_rows(robot, V, states + pushed)
    t_rows = time.perf_counter() - t0 - t_basis
    key = robot_key(robot)
    # halving (not quartering) the tolerance: a sample barely past the target costs every
    # reduced step of every study, and the greedy path gives each tolerance's sample for free
    tols = [ecsw_tol / 2**i for i in range(max_rounds)]
    rounds = []
    check = snaps[:fit_count]
    # the sample answers for its own share of the Jacobian error: against the basis's model
    # with every element, whose own error against the full one no sample can remove
    check_J, basis_jac = galerkin_jacobians(robot, V, check, None if jacobians is None else list(jacobians)[:fit_count])
    samples, met, budget_spent = [], False, None
    try:
        for tol, sample in zip(tols, ecsw_path(A, tols, batch=ecsw_batch, max_elements=max_elements)):
            basis = ReducedBasis(V, sample.elements, sample.weights, np.asarray(lo, float), np.asarray(hi, float), key)
            err, jerr, n_checked = fit_error(ReducedRobot(robot, basis), check, check_J, give_up_mm=fit_tol_mm)
            # a sample missing a corner is rejected there: its errors are over the states checked
            rounds.append({"ecsw_tol": tol, "elements": int(len(sample.elements)), "force_error": sample.error,
                           "fit_error_mm": err, "fit_jacobian_rel": jerr, "fit_checked": n_checked})
            samples.append(sample)
            if err <= fit_tol_mm and jerr <= fit_jacobian_tol:
                met = True
                break
    except ConvergenceError as exc:  # the element budget (or a stalled path) ends the halving early
        if not rounds:
            raise ConvergenceError(f"reduce: no element sample within the budget meets the first ECSW tolerance "
                                   f"{ecsw_tol:.1e}: {exc}") from exc
        budget_spent = str(exc)
    if not met:
        # force rows pin the tangent only along the pushes: with few training states the
        # Jacobian's error can stall above its target; the positions' target is the hard one
        ok = [i for i, r in enumerate(rounds) if r["fit_error_mm"] <= fit_tol_mm]
        if not ok:
            raise ConvergenceError(f"reduce: the reduced model misses the training equilibria by {err:.3g} mm "
                                   f"> {fit_tol_mm:g} mm after {len(rounds)} ECSW rounds (tol {tol:.1e})"
                                   + (f"; {budget_spent}" if budget_spent else ""), rounds)
        best = min(ok, key=lambda i: rounds[i]["fit_jacobian_rel"])
        sample, rounds[best]["chosen"] = samples[best], True
    jacobian_met = met
    info = {**record, "k": int(V.shape[1]), "snapshots": len(snaps), "training_states": len(states) + len(pushed),
            "elements": int(len(sample.elements)), "elements_total": int(robot.body.n_elements),
            "ecsw_rounds": rounds, "fit_tol_mm": fit_tol_mm, "fit_jacobian_tol": fit_jacobian_tol,
            "fit_jacobian_met": jacobian_met, "basis_jacobian_rel": basis_jac,
            "element_budget": None if max_elements is None else int(max_elements),
            "element_budget_spent": budget_spent is not None,
            "seconds": {"basis": t_basis, "ecsw_rows": t_rows, "ecsw_and_fit": time.perf_counter() - t0 - t_basis - t_rows}}
    return ReducedBasis(V, sample.elements, sample.weights, np.asarray(lo, float), np.asarray(hi, float), key, info)
