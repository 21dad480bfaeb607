"""Parametric search over fibre designs (issue 45, item 2): the design space, one design's
evaluation on the linear rest problem, and a seeded, batched, resumable Optuna loop.

A **design** of the search is the paper's spiral with another pitch, plus an optional
angle-independent correction of the fibre angle along the radius:

    theta(x) = theta_spiral(x; pitch) + sum_k c_k R_k(r),     c_k in [-radial_deg, radial_deg]

``R_k`` the ``n_radial`` open uniform B-splines in r of a symmetric
:class:`~.fibre_field.PolarBSpline` with ``n_angular = 3`` (its three tied periodic functions
sum to 1, so the correction depends on r only, and every design keeps the sheet's 120 deg
symmetry). A log spiral's pitch is a uniform turn of every fibre; the radial correction
makes the pitch vary along the radius.

Each design is scored by two objectives, both maximised, on :func:`.adjoint.solve_rest`:

* ``roll`` [deg/deg]: ``|rod roll per degree|`` of all six motors together (the 6th DOF);
* ``other_min`` [mm/rad]: the smallest singular value of the scaled Jacobian
  ``diag(1, 1, 1, L, L, L) J`` once the roll row is taken out, i.e. of the five other
  directions of the effector (:func:`other_five_min`): must not collapse while the roll grows.

The loop (:func:`run_search`) asks Optuna for ``batch`` trials at a time, evaluates them
through a caller's ``evaluate`` (a process pool, say) and tells the results in trial order.
Each trial is sampled by a sampler seeded with ``seed`` and its trial number, so a trial
depends on the seed, its number and the trials stored before its batch: a search resumed
from the stored trials of a run whose ``n_trials`` was a multiple of ``batch`` gives the same
trials as one run straight through. Trials asked but never told (a killed run) are evaluated
first on resume, with the parameters they were asked with.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from ..errors import ConfigError
from ..sheet import fibers as fb
from . import objectives as obj
from .adjoint import RestProblem, rest_problem, roll_sensitivity, solve_rest  # noqa: F401  (the stage's API)
from ..sheet.fibre_field import PolarBSpline

SAMPLERS = ("nsga2", "tpe")
OBJECTIVES = ("roll", "other_min")  # both maximised
#: what a trial reports besides its objectives (trials.csv's columns): six singular values
#: [mm/rad], parasitic translation [mm/deg], largest principal strain at the goals [-]
EXTRAS = tuple(f"sv{i + 1}_mm_per_rad" for i in range(6)) + ("translation_mm_per_deg", "strain_max")


@dataclass(frozen=True)
class SearchSpace:
    """The search's variables and their box bounds.

    Attributes
    ----------
    pitch_deg : (lo, hi) bounds of the spiral's pitch [deg], -90 <= lo < hi <= 90.
    n_radial : radial correction functions (0: pitch only; else in [2, 8]).
    radial_deg : bound of each radial coefficient, |c_k| <= radial_deg [deg], in (0, 90].
    r_max : [mm] the radial basis' outer radius (the sheet's).
    """

    pitch_deg: tuple[float, float]
    n_radial: int = 0
    radial_deg: float = 30.0
    r_max: float = 70.0

    def __post_init__(self):
        lo, hi = (float(v) for v in self.pitch_deg)
        if not (-90.0 <= lo < hi <= 90.0):
            raise ConfigError(f"pitch_deg: {[lo, hi]!r}: expected [lo, hi] with -90 <= lo < hi <= 90 [deg]")
        if self.n_radial != 0 and not 2 <= self.n_radial <= 8:
            raise ConfigError(f"n_radial: {self.n_radial!r}: allowed values are 0 (pitch only) or [2, 8]")
        if not 0.0 < self.radial_deg <= 90.0:
            raise ConfigError(f"radial_deg: {self.radial_deg!r}: allowed range is (0, 90] [deg]")

    @property
    def names(self) -> list[str]:
        """Variable names: ``pitch_deg``, then ``radial_k_deg`` for k < n_radial."""
        return ["pitch_deg"] + [f"radial_{k}_deg" for k in range(self.n_radial)]

    def bounds(self) -> list[tuple[float, float]]:
        """(lo, hi) per variable [deg], in :attr:`names` order."""
        r = float(self.radial_deg)
        return [tuple(float(v) for v in self.pitch_deg)] + [(-r, r)] * self.n_radial

    def basis(self) -> PolarBSpline:
        """The radial correction's basis: n_angular 3, symmetric, degree min(2, n_radial - 1)
        (the basis needs n_radial >= degree + 1); pitch only: the smallest such basis, unused."""
        if self.n_radial == 0:
            return PolarBSpline(n_radial=2, n_angular=3, degree=1, r_max=float(self.r_max), symmetric=True)
        return PolarBSpline(n_radial=self.n_radial, n_angular=3, degree=min(2, self.n_radial - 1),
                            r_max=float(self.r_max), symmetric=True)

    def split(self, values: Sequence[float]) -> tuple[float, np.ndarray]:
        """(pitch [deg], radial coefficients (n_radial,) [rad]) of a variable vector [deg]."""
        v = np.asarray(values, float)
        return float(v[0]), np.radians(v[1:])


@dataclass(frozen=True)
class Scores:
    """One design's objectives on the rest problem.

    Attributes
    ----------
    roll : rod roll per degree of all motors, signed [deg/deg] (the objective is ``abs(roll)``).
    singular_values : (6,) of the scaled Jacobian, largest first [mm/rad].
    other_min : the smallest singular value of the five directions other than the roll [mm/rad].
    translation : parasitic translation of the all-together move [mm per motor degree]
        (:func:`.objectives.decoupling`).
    strain_max : largest principal small strain at the goals [-] (:func:`.strain.goal_strain`),
        nan when not asked for.
    roll_index : which of ``singular_values`` is the roll's (:func:`.objectives.roll_index`).
    """

    roll: float
    singular_values: tuple[float, ...]
    other_min: float
    translation: float = float("nan")
    strain_max: float = float("nan")
    roll_index: int = 0

    @property
    def others(self) -> tuple[float, ...]:
        """The five singular values other than the roll's [mm/rad], largest first."""
        return tuple(v for k, v in enumerate(self.singular_values) if k != self.roll_index)

    @property
    def objectives(self) -> tuple[float, float]:
        """(|roll| [deg/deg], other_min [mm/rad]), both maximised."""
        return abs(self.roll), self.other_min


def other_five_min(J: np.ndarray, axis, length_scale: float = obj.LENGTH_SCALE) -> float:
    """Smallest singular value [mm/rad] of ``diag(1, 1, 1, L, L, L) J`` (6, na) projected on the
    five effector directions orthogonal to the roll ``(0, 0, 0, axis)``: how much authority is
    left over translation and the two tilts when the roll is not counted."""
    D = obj._scale(length_scale)[:, None] * obj._check_jacobian(J)
    e = np.concatenate([np.zeros(3), obj._unit_axis(axis)])
    # an orthonormal basis of e's complement: the last 5 left singular vectors of e
    U = np.linalg.svd(e[:, None], full_matrices=True)[0][:, 1:]
    return float(np.linalg.svd(U.T @ D, compute_uv=False)[-1])


def spiral_angles(centroids: np.ndarray, *, pitch_deg: float, law: str = "log", r_ref: float = 33.0,
                  tilt_deg: float = 0.0) -> np.ndarray:
    """(m,) sheet A's spiral fibre angles [rad] at ``centroids`` (m, 3) [mm] (in-plane only)."""
    if tilt_deg != 0.0:
        raise ConfigError(f"tilt_deg: {tilt_deg!r}: the design rotates fibres in the sheet plane; allowed 0")
    f = fb.spiral_fibers(np.asarray(centroids, float), pitch_deg=pitch_deg, law=law, r_ref=r_ref)
    return np.arctan2(f[:, 1], f[:, 0])


def scores(problem: RestProblem, c, goal_deg: float | None = None) -> Scores:
    """The objectives of design ``c`` (n,) [rad] on ``problem`` (its field's theta0 the start);
    with ``goal_deg`` [deg], the strain at the goals too (~15 ms more on the coarse robot)."""
    from .strain import goal_strain

    sol = solve_rest(problem, c)
    strain = goal_strain(problem, sol, goal_deg).worst if goal_deg is not None else float("nan")
    return Scores(float(sol.roll), tuple(float(s) for s in sol.singular_values),
                  other_five_min(sol.J, problem.robot.axis, problem.length_scale),
                  obj.decoupling(sol.J, problem.robot.axis).translation_mm_per_deg, float(strain),
                  obj.roll_index(sol.J, problem.robot.axis, problem.length_scale))


@dataclass(frozen=True)
class Trials:
    """A work unit: search designs on one problem (picklable for a process pool; one unit per
    worker and batch, so the problem travels once per unit).

    Attributes
    ----------
    problem : the rest problem whose field uses the space's radial basis (pitch only: any
        basis; its coefficients stay 0 and only theta0 changes).
    centroids : (m, 3) sheet A's element centroids [mm]; spiral : keywords of
        :func:`spiral_angles` but the pitch; values : per design, the variables [deg]
        (:attr:`SearchSpace.names`).
    goal_deg : [deg] score the strain at the goals too (None: not).
    """

    problem: RestProblem
    centroids: np.ndarray
    spiral: dict
    values: tuple[tuple[float, ...], ...]
    goal_deg: float | None = None


def evaluate_trials(t: Trials) -> list[Scores]:
    """Work unit: the :class:`Scores` of each search design of ``t``, in order."""
    res = []
    for v in t.values:
        theta0 = spiral_angles(t.centroids, pitch_deg=float(v[0]), **t.spiral)
        c = np.radians(np.asarray(v[1:], float))
        p = replace(t.problem, field=replace(t.problem.field, theta0=theta0))
        res.append(scores(p, c if len(c) else np.zeros(p.n_coefficients), t.goal_deg))
    return res


def design_angles(points: np.ndarray, design: dict, spiral: dict) -> np.ndarray:
    """(q,) sheet A's fibre angles [rad] of ``design`` at ``points`` (q, 3) [mm]: the spiral of
    ``design["pitch_deg"]`` (law and r_ref from ``spiral``) plus ``design["coefficients_rad"]``
    on ``PolarBSpline(**design["basis"])`` (no basis: the spiral alone)."""
    theta = spiral_angles(points, pitch_deg=float(design["pitch_deg"]), **spiral)
    if design.get("basis"):
        theta = theta + PolarBSpline(**design["basis"]).design_matrix(points) @ np.asarray(design["coefficients_rad"])
    return theta


def design_problem(sheets, material, design: dict, spiral: dict, r_max: float, **kw) -> tuple[RestProblem, np.ndarray]:
    """The rest problem of ``design`` (as :func:`design_angles` reads it) on ``sheets`` and
    ``material`` (``kw``: :func:`.adjoint.rest_problem`'s keywords), and its coefficients (n,) [rad]."""
    basis = PolarBSpline(**design["basis"]) if design.get("basis") else SearchSpace((0.0, 1.0), r_max=r_max).basis()
    problem = rest_problem(sheets, material, basis, **kw)
    theta0 = spiral_angles(sheets.sheet.centroids(), pitch_deg=float(design["pitch_deg"]), **spiral)
    p = replace(problem, field=replace(problem.field, theta0=theta0))
    c = np.asarray(design["coefficients_rad"], float) if design.get("basis") else np.zeros(p.n_coefficients)
    return p, c


def design_scores(sheets, material, design: dict, spiral: dict, r_max: float, **kw) -> Scores:
    """The :class:`Scores` of ``design`` on the rest problem of :func:`design_problem`."""
    return scores(*design_problem(sheets, material, design, spiral, r_max, **kw))


def make_sampler(kind: str, seed: int, *, population: int = 8, constrained: bool = False):
    """The Optuna sampler ``kind`` ("nsga2" or "tpe") seeded with ``seed``; ``constrained``: it
    prefers trials whose constraints are <= 0 (NSGA-II's constrained domination, TPE's split of
    the infeasible trials). Optuna >= 5 reads the constraints :func:`run_search` sets on each trial;
    Optuna 4 asks :func:`trial_constraints` for them (its ``constraints_func``)."""
    import optuna

    kw = {"constraints_func": trial_constraints} if constrained and not _trial_constraints_api() else {}
    if kind == "nsga2":
        return optuna.samplers.NSGAIISampler(population_size=int(population), seed=int(seed), **kw)
    if kind == "tpe":
        return optuna.samplers.TPESampler(seed=int(seed), n_startup_trials=min(10, int(population)), multivariate=True,
                                          **kw)
    raise ConfigError(f"sampler: {kind!r}: allowed values are {list(SAMPLERS)}")


def _trial_constraints_api() -> bool:
    """Optuna >= 5: constraints are set on the trial (``Trial.set_constraint``)."""
    import optuna

    return hasattr(optuna.trial.Trial, "set_constraint")


def trial_constraints(trial) -> tuple[float, ...]:
    """A finished trial's constraint values, feasible when all are <= 0: (strain_max - limit,)
    as :func:`run_search` stored them (``user_attrs["constraint"]``)."""
    return tuple(trial.user_attrs.get("constraint", (0.0,)))


def strain_constraint(s: Scores, limit: float) -> float:
    """``strain_max - limit`` [-]: <= 0 when the trial's largest goal strain is within the limit;
    a trial scored without goals (nan strain) counts as infeasible (+inf)."""
    return float(s.strain_max - limit) if np.isfinite(s.strain_max) else float("inf")


def trial_seed(seed: int, number: int) -> int:
    """The seed of trial ``number``'s sampler: fixed by the search's seed and the trial's number."""
    return (int(seed) * 1_000_003 + int(number) * 7919 + 17) % (2**31 - 1)


@dataclass(frozen=True)
class SearchRecord:
    """A finished (or resumed) search: every completed trial in number order.

    Attributes
    ----------
    values : (n, k) variables [deg]; objectives : (n, 2) (|roll| [deg/deg], other_min [mm/rad]).
    roll : (n,) signed roll [deg/deg]; evaluated : trials this call evaluated (not loaded).
    extras : (n, len(EXTRAS)) the trials' reported values (:data:`EXTRAS`; nan where a trial
        stored by an older version has none).
    feasible : (n,) bool, within the search's strain limit (all True for an unconstrained search).
    """

    values: np.ndarray
    objectives: np.ndarray
    roll: np.ndarray
    evaluated: int
    extras: np.ndarray | None = None
    feasible: np.ndarray | None = None


def run_search(storage, study_name: str, space: SearchSpace, *, n_trials: int, batch: int, sampler: str,
               seed: int, population: int, evaluate: Callable[[list[tuple[float, ...]]], list[Scores]],
               progress: Callable[[int, int], None] = lambda d, n: None,
               strain_limit: float | None = None) -> SearchRecord:
    """Run (or resume) the multi-objective search ``study_name`` in ``storage`` until it holds
    ``n_trials`` completed trials; ``evaluate(values_list) -> [Scores]`` scores a batch in order.
    ``strain_limit`` [-]: the sampler is constrained to trials whose goal strain is within it
    (:func:`strain_constraint`; the scores must carry the strain); None: unconstrained."""
    import optuna
    from optuna.distributions import FloatDistribution
    from optuna.trial import TrialState

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    constrained = strain_limit is not None
    study = optuna.create_study(storage=storage, study_name=study_name, directions=["maximize", "maximize"],
                                sampler=make_sampler(sampler, seed, population=population, constrained=constrained),
                                load_if_exists=True)
    dists = {n: FloatDistribution(lo, hi) for n, (lo, hi) in zip(space.names, space.bounds())}
    evaluated = 0

    def tell(trials: list) -> None:
        nonlocal evaluated
        res = evaluate([tuple(float(t.params[n]) for n in space.names) for t in trials])
        for t, s in zip(trials, res):
            # the signed roll rides along (a finished trial's attributes can no longer be set)
            study._storage.set_trial_user_attr(t._trial_id, "roll", float(s.roll))
            study._storage.set_trial_user_attr(t._trial_id, "extras", _extras(s))
            if constrained:  # the sampler reads it when the trial is told (Optuna 4: through constraints_func)
                g = strain_constraint(s, strain_limit)
                study._storage.set_trial_user_attr(t._trial_id, "constraint", [g])
                if _trial_constraints_api():  # a live Trial also for a stale (frozen) one of a killed run
                    optuna.trial.Trial(study, t._trial_id).set_constraint("strain", g)
            study.tell(t.number, list(s.objectives))
        evaluated += len(trials)

    # trials a killed run asked but never told: the same parameters, evaluated now
    stale = study.get_trials(deepcopy=False, states=(TrialState.RUNNING,))
    if stale:
        tell(sorted(stale, key=lambda t: t.number))
    while True:
        done = len(study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,)))
        progress(done, n_trials)
        if done >= n_trials:
            break
        end = min(n_trials, (done // batch + 1) * batch)  # batches end at multiples of batch
        asked = []
        for _ in range(end - done):
            number = len(study.get_trials(deepcopy=False))
            study.sampler = make_sampler(sampler, trial_seed(seed, number), population=population,
                                         constrained=constrained)
            asked.append(study.ask(dists))
        tell(asked)
    complete = sorted(study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,)), key=lambda t: t.number)
    complete = complete[:n_trials] if len(complete) > n_trials else complete
    return SearchRecord(np.array([[t.params[n] for n in space.names] for t in complete], float).reshape(-1, len(space.names)),
                        np.array([t.values for t in complete], float).reshape(-1, 2),
                        np.array([t.user_attrs.get("roll", np.nan) for t in complete], float), evaluated,
                        np.array([t.user_attrs.get("extras", [np.nan] * len(EXTRAS)) for t in complete],
                                 float).reshape(-1, len(EXTRAS)),
                        np.array([max(trial_constraints(t)) <= 0 for t in complete], bool))


def _extras(s: Scores) -> list:
    """A trial's :data:`EXTRAS` as JSON numbers (None for nan: the journal is JSON)."""
    v = [*s.singular_values, s.translation, s.strain_max]
    return [float(x) if np.isfinite(x) else None for x in v]


def pareto_mask(F: np.ndarray, feasible: np.ndarray | None = None) -> np.ndarray:
    """(n,) True where row i of ``F`` (n, k) (all maximised) is not dominated by another row
    (>= in every column, > in one); exact ties are all kept. With ``feasible`` (n,) bool, the
    front of the feasible rows only (no front when none is feasible)."""
    F = np.asarray(F, float)
    ok = np.ones(len(F), bool) if feasible is None else np.asarray(feasible, bool)
    ge = np.all(F[None, :, :] >= F[:, None, :], axis=2)   # ge[i, j]: j >= i everywhere
    gt = np.any(F[None, :, :] > F[:, None, :], axis=2)
    return ok & ~np.any(ge & gt & ok[None, :], axis=1)
