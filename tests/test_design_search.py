"""The design search's library (metasheet.design.search): the space, the objectives, the
Pareto mask, and a resumable, seeded Optuna loop on the coarse robot's rest problem."""

import metasheet  # noqa: F401  (pins numpy's code paths before numpy is imported)

# isort: split
import numpy as np
import pytest

from metasheet.published import paper
from metasheet.design import search as ds
from metasheet.design.adjoint import solve_rest
from metasheet.errors import ConfigError
from metasheet.robot import SheetPair
from metasheet.sheet import SheetParams

SPIRAL = {"law": "log", "r_ref": 33.0}


@pytest.fixture(scope="module")
def coarse():
    sheets = SheetPair.spiral(SheetParams(mesh_size=15.0), pitch_deg=30.0)
    space = ds.SearchSpace((5.0, 60.0), n_radial=2, radial_deg=30.0, r_max=68.0)
    return sheets, space, ds.rest_problem(sheets, paper.PAPER_FOAM, space.basis())


def _evaluate(coarse, log=None):
    sheets, _, problem = coarse

    def evaluate(values):
        if log is not None:
            log.extend(values)
        return ds.evaluate_trials(ds.Trials(problem, sheets.sheet.centroids(), SPIRAL, tuple(values)))
    return evaluate


def _storage(path):
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend

    return JournalStorage(JournalFileBackend(str(path)))


def _search(coarse, path, n, evaluate, sampler="nsga2", **kw):
    return ds.run_search(_storage(path), "s", coarse[1], n_trials=n, batch=4, sampler=sampler, seed=3,
                         population=4, evaluate=evaluate, **kw)


def test_space_and_bad_values():
    s = ds.SearchSpace((0.0, 45.0), n_radial=3, radial_deg=20.0)
    assert s.names == ["pitch_deg", "radial_0_deg", "radial_1_deg", "radial_2_deg"]
    assert s.bounds()[1] == (-20.0, 20.0) and s.basis().n_coefficients == 3
    for kw, field in (({"pitch_deg": (50.0, 10.0)}, "pitch_deg"), ({"pitch_deg": (0.0, 95.0)}, "pitch_deg"),
                      ({"pitch_deg": (0.0, 9.0), "n_radial": 1}, "n_radial"),
                      ({"pitch_deg": (0.0, 9.0), "radial_deg": 0.0}, "radial_deg")):
        with pytest.raises(ConfigError, match=field):
            ds.SearchSpace(**kw)
    with pytest.raises(ConfigError, match="sampler"):
        ds.make_sampler("cmaes", 0)


def test_pareto_mask():
    F = np.array([[1.0, 1.0], [2.0, 0.5], [0.5, 2.0], [0.9, 0.9], [2.0, 0.5], [1.0, 0.2]])
    assert ds.pareto_mask(F).tolist() == [True, True, True, False, True, False]
    # infeasible rows are never on the front and dominate nothing: (0.9, 0.9) and (1.0, 0.2) come up
    feasible = np.array([False, False, True, True, False, True])
    assert ds.pareto_mask(F, feasible).tolist() == [False, False, True, True, False, True]
    assert not ds.pareto_mask(F, np.zeros(6, bool)).any()


def _evaluate_strain(coarse, log=None):
    sheets, _, problem = coarse

    def evaluate(values):
        if log is not None:
            log.extend(values)
        return ds.evaluate_trials(ds.Trials(problem, sheets.sheet.centroids(), SPIRAL, tuple(values), 10.0))
    return evaluate


def test_constrained_search_records_feasibility_and_resumes(coarse, tmp_path):
    """With a strain limit the sampler sees each trial's ``strain_max - limit`` (Optuna's
    constraints_func) and the record says which trials keep to it; a constrained search resumes
    to the same trials as one run straight through."""
    free = ds.run_search(_storage(tmp_path / "f.journal"), "s", coarse[1], n_trials=8, batch=4, sampler="nsga2",
                         seed=3, population=4, evaluate=_evaluate_strain(coarse))
    strain = free.extras[:, ds.EXTRAS.index("strain_max")]
    assert free.feasible.all() and np.isfinite(strain).all()
    limit = float(np.median(strain))  # about half the trials within it

    def run(path, n):
        return ds.run_search(_storage(path), "c", coarse[1], n_trials=n, batch=4, sampler="nsga2", seed=3,
                             population=4, evaluate=_evaluate_strain(coarse), strain_limit=limit)

    first = run(tmp_path / "c.journal", 8)
    strain_c = first.extras[:, ds.EXTRAS.index("strain_max")]
    assert np.array_equal(first.feasible, strain_c <= limit)
    study = __import__("optuna").load_study(study_name="c", storage=_storage(tmp_path / "c.journal"))
    stored = [ds.trial_constraints(t)[0] for t in study.get_trials(deepcopy=False)]
    np.testing.assert_allclose(stored, strain_c - limit, rtol=0, atol=1e-15)
    resumed, straight = run(tmp_path / "c.journal", 12), run(tmp_path / "d.journal", 12)
    assert resumed.evaluated == 4 and np.array_equal(resumed.values, straight.values)
    assert np.array_equal(resumed.feasible, straight.feasible)
    front = ds.pareto_mask(straight.objectives, straight.feasible)
    assert not (front & ~straight.feasible).any()
    if hasattr(study.trials[0], "constraints"):  # Optuna >= 5: the sampler's own record of them
        assert [t.constraints["strain"] for t in study.get_trials()][:8] == pytest.approx(list(strain_c - limit))


def test_other_five_between_the_two_smallest_singular_values(coarse):
    sheets, _, problem = coarse
    sol = solve_rest(problem, np.zeros(problem.n_coefficients))
    v = ds.other_five_min(sol.J, problem.robot.axis)
    s = sol.singular_values  # removing one row interlaces: s6 <= v <= s5
    assert s[-1] - 1e-12 <= v <= s[-2] + 1e-12
    # the pitch-30 spiral at c = 0 is the problem's own start
    t = ds.evaluate_trials(ds.Trials(problem, sheets.sheet.centroids(), SPIRAL, ((30.0, 0.0, 0.0),)))[0]
    assert t.roll == pytest.approx(sol.roll, rel=1e-12) and t.other_min == pytest.approx(v, rel=1e-12)


@pytest.mark.parametrize("sampler", ["nsga2", "tpe"])
def test_resumed_search_continues_from_stored_trials(coarse, tmp_path, sampler):
    first = _search(coarse, tmp_path / "a.journal", 8, _evaluate(coarse), sampler)
    log = []
    second = _search(coarse, tmp_path / "a.journal", 16, _evaluate(coarse, log), sampler)
    assert first.evaluated == 8 and second.evaluated == 8 and len(log) == 8
    assert np.array_equal(second.values[:8], first.values)
    assert np.array_equal(second.objectives[:8], first.objectives)
    straight = _search(coarse, tmp_path / "b.journal", 16, _evaluate(coarse), sampler)
    assert np.array_equal(straight.values, second.values)  # resumed at a multiple of batch: the same trials
    assert np.array_equal(straight.objectives, second.objectives)


@pytest.mark.parametrize("limit", [None, 0.05])
def test_a_killed_batch_is_evaluated_on_resume(coarse, tmp_path, limit):
    calls = []
    scorer = _evaluate(coarse) if limit is None else _evaluate_strain(coarse)

    def dies(values):
        calls.append(len(values))
        if len(calls) == 2:
            raise KeyboardInterrupt  # the second batch was asked, never told
        return scorer(values)

    with pytest.raises(KeyboardInterrupt):
        _search(coarse, tmp_path / "k.journal", 12, dies, strain_limit=limit)
    resumed = _search(coarse, tmp_path / "k.journal", 12, scorer, strain_limit=limit)
    assert resumed.evaluated == 8  # the stale batch, then the last one
    straight = _search(coarse, tmp_path / "s.journal", 12, scorer, strain_limit=limit)
    assert np.array_equal(straight.values, resumed.values)
    assert np.array_equal(straight.objectives, resumed.objectives)
    assert np.array_equal(straight.feasible, resumed.feasible)


def test_sobol_indices_of_a_known_function_and_the_same_bits_at_seed_0():
    from metasheet.design import sensitivity as sens

    space = ds.SearchSpace((0.0, 60.0), n_radial=2, radial_deg=30.0)
    X = sens.sobol_designs(space, 256, seed=0)
    assert X.shape == (256 * 5, 3) and np.array_equal(X, sens.sobol_designs(space, 256, seed=0))
    y = X[:, 0] + 0.5 * X[:, 1]  # radial_1 unused; variances 60^2 / 12 : 0.25 x 60^2 / 12 = 4 : 1
    a, b = sens.sobol_indices(space, y, 0), sens.sobol_indices(space, y, 0)
    assert np.array_equal(a.ST_conf, b.ST_conf)  # SALib ignores seed 0: the module passes seed + 1
    assert a.ST[0] == pytest.approx(0.8, abs=0.03) and a.ST[1] == pytest.approx(0.2, abs=0.03)
    assert abs(a.ST[2]) < 1e-9 and abs(a.S1[2]) < 1e-9
    X2, which = sens.oat_designs(space, np.array([30.0, 0.0, 0.0]), 3)
    assert X2.shape == (9, 3) and which.tolist() == [0, 0, 0, 1, 1, 1, 2, 2, 2]
    assert X2[:3, 0].tolist() == [0.0, 30.0, 60.0] and X2[3:6, 1].tolist() == [-30.0, 0.0, 30.0]
    with pytest.raises(ConfigError, match="sobol_n"):
        sens.sobol_designs(space, 12, 0)
