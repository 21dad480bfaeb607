"""Statistics over realisations (issue 43, library layer): intervals, required k, size trend.

Synthetic samples only (no FEM), each test seeded. Statistical checks state their
tolerance: a Monte-Carlo mean within 4 of its standard errors, a coverage within 3
binomial standard deviations of its nominal 95 %.
"""

import io
import json
import math

import numpy as np
import pytest
from scipy import stats as st
from scipy.special import gammaln

from metasheet.errors import ConfigError, InfeasibleError
from metasheet.homogenize.ensemble import (
    ci95_block,
    constant_stats,
    convergence_summary,
    ensemble_stats,
    plan_realisations,
    required_realisations,
    size_trend,
    t_quantile,
)

MU, SIGMA = 10.0, 2.0


def c4(k: int) -> float:
    """E[s] / sigma for k normal samples (s with ddof=1)."""
    return math.sqrt(2.0 / (k - 1)) * math.exp(gammaln(k / 2) - gammaln((k - 1) / 2))


def test_halfwidth_shrinks_as_inverse_sqrt_k():
    # E[h] = t_{k-1} c4(k) sigma / sqrt(k): the Monte-Carlo mean over R ensembles has a
    # relative standard error <= 0.42 / sqrt(R) = 1.3 % (k = 4, the widest); allow 5 %
    rng = np.random.default_rng(43)
    R = 1000
    ks = [4, 16, 64, 256]
    scaled = []
    for k in ks:
        x = rng.normal(MU, SIGMA, size=(R, k))
        h = np.array([constant_stats("E_l", row).halfwidth for row in x])
        expected = t_quantile(k) * c4(k) * SIGMA / math.sqrt(k)
        assert h.mean() / expected == pytest.approx(1.0, abs=0.05), k
        scaled.append(h.mean() / (t_quantile(k) * c4(k)))
    slope = np.polyfit(np.log(ks), np.log(scaled), 1)[0]
    assert slope == pytest.approx(-0.5, abs=0.02)


@pytest.mark.parametrize("k", [3, 8])
def test_interval_covers_the_true_mean_95_percent_of_the_time(k):
    # binomial sd of the coverage over N = 2000 ensembles: sqrt(0.95 * 0.05 / N) = 0.0049;
    # with k = 3 a normal-quantile interval would cover only about 81 %
    rng = np.random.default_rng(1000 + k)
    N = 2000
    x = rng.normal(MU, SIGMA, size=(N, k))
    hits = 0
    for row in x:
        s = constant_stats("E_t", row)
        hits += abs(s.mean - MU) <= s.halfwidth
    tol = 3 * math.sqrt(0.95 * 0.05 / N)
    assert abs(hits / N - 0.95) <= tol


def test_statistics_match_numpy_and_scipy():
    x = np.array([1.0, 1.2, 0.9, 1.1, 1.05])
    s = constant_stats("E_l", x)
    assert s.k == 5
    assert s.mean == pytest.approx(x.mean())
    assert s.std == pytest.approx(x.std(ddof=1))
    assert s.halfwidth == pytest.approx(st.t.ppf(0.975, 4) * x.std(ddof=1) / math.sqrt(5))
    assert s.rel_halfwidth == pytest.approx(s.halfwidth / s.mean)


def test_stiffness_matrices_and_their_zeros():
    rng = np.random.default_rng(7)
    C = np.zeros((4, 6, 6))
    C[:, :3, :3] = 1.0 + 0.1 * rng.normal(size=(4, 3, 3))
    C[:, 3:, 3:] = np.eye(3) * 0.5
    out = ensemble_stats({"E_l": rng.normal(1.0, 0.1, 4), "C": C})
    c = out["C"]
    assert c.mean.shape == c.halfwidth.shape == c.rel_halfwidth.shape == (6, 6)
    assert c.halfwidth[0, 5] == 0.0 and c.rel_halfwidth[0, 5] == 0.0  # exact zero, known exactly
    assert c.rel_halfwidth[3, 3] == 0.0  # deterministic 0.5
    block = ci95_block(out, n_cells=8)
    assert block["k"] == 4 and block["n_cells"] == 8 and set(block["halfwidth"]) == {"E_l"}
    assert np.shape(block["C_halfwidth"]) == (6, 6)
    json.dumps(block, allow_nan=False)


def test_required_k_uses_the_t_quantile():
    # normal approximation: (1.96 * 0.1 / 0.1)^2 -> 4; t_3 = 3.18 gives 0.159 at k = 4
    k = required_realisations(0.1, std=0.1, mean=1.0)
    assert k > 4
    assert t_quantile(k) * 0.1 / math.sqrt(k) <= 0.1 < t_quantile(k - 1) * 0.1 / math.sqrt(k - 1)
    for cv, target in [(0.2, 0.05), (0.5, 0.02), (0.03, 0.05)]:
        k = required_realisations(target, std=cv * 3.0, mean=-3.0)  # |mean| counts
        assert t_quantile(k) * cv / math.sqrt(k) <= target
        assert k == 2 or t_quantile(k - 1) * cv / math.sqrt(k - 1) > target
    assert required_realisations(0.05, std=0.0, mean=1.0) == 2
    with pytest.raises(InfeasibleError, match="k_max"):
        required_realisations(1e-3, std=1.0, mean=1.0, k_max=1000)


def test_required_k_meets_its_target_on_synthetic_data():
    # the true cv 0.2 and target 5 % give k = 64; drawn ensembles of that size reach a
    # half-width whose median is at or below the target (E[s] < sigma), R = 400 ensembles
    rng = np.random.default_rng(11)
    cv, target = 0.2, 0.05
    k = required_realisations(target, std=cv * MU, mean=MU)
    rel = np.array([constant_stats("E_l", rng.normal(MU, cv * MU, k)).rel_halfwidth for _ in range(400)])
    assert np.median(rel) <= target * 1.01
    assert 0.4 <= np.mean(rel <= target) <= 0.8
    # from a pilot of 10: the plan's k brings the mean relative half-width to the target +- 10 %
    pilot = ensemble_stats({"E_l": rng.normal(MU, cv * MU, 10), "nu_tl": rng.normal(0.3, 0.003, 10)})
    plan = plan_realisations(pilot, target, seconds_per_realisation=40.0)
    assert plan.governing == "E_l" and plan.k == plan.k_required["E_l"] >= plan.k_required["nu_tl"]
    assert plan.cost_s == pytest.approx(40.0 * plan.k)
    rel = [constant_stats("E_l", rng.normal(MU, cv * MU, plan.k)).rel_halfwidth for _ in range(200)]
    achieved = np.mean(rel) * math.sqrt(plan.k) / t_quantile(plan.k)  # = the pilot-independent cv
    assert achieved == pytest.approx(cv * c4(plan.k), rel=0.1)


def test_trend_recovers_a_and_b_from_noise_free_data():
    n = np.array([8, 27, 64, 125, 216])
    a, b = 0.094, -0.21
    means = a + b * n ** (-1.0 / 3.0)
    t = size_trend(n, means, halfwidths=0.002 * np.ones(5), k=5)
    assert t.a == pytest.approx(a, rel=1e-12) and t.b == pytest.approx(b, rel=1e-12)
    assert t.chi2_reduced == pytest.approx(0.0, abs=1e-20)
    assert t.significant
    assert t.value_at(n) == pytest.approx(means, rel=1e-12)
    two = size_trend(n[:2], means[:2], [0.002, 0.001], k=[5, 3])
    assert two.a == pytest.approx(a, rel=1e-12) and math.isnan(two.chi2_reduced)


def test_trend_flat_noisy_data_is_not_significant():
    # sigma_i known and exact: the false-positive rate must not exceed 5 % by more than
    # 3 binomial sd over 400 flat data sets (the Birge inflation only lowers it)
    rng = np.random.default_rng(5)
    n = np.array([8, 27, 64, 125])
    k = 5
    se = np.array([0.08, 0.05, 0.03, 0.02])
    hw = t_quantile(k) * se
    t = size_trend(n, 1.0 + se * rng.normal(size=4), hw, k)
    assert not t.significant and abs(t.b) <= t.halfwidth_b
    positives = sum(size_trend(n, 1.0 + se * rng.normal(size=4), hw, k).significant for _ in range(400))
    assert positives / 400 <= 0.05 + 3 * math.sqrt(0.05 * 0.95 / 400)
    strong = size_trend(n, 1.0 - 2.0 * n ** (-1.0 / 3.0) + se * rng.normal(size=4), hw, k)
    assert strong.significant


def test_laminate_flat_trend_has_zero_slope():
    # a laminate's constants are exact at every size: zero spread and zero slope
    n = [8, 27, 64]
    per_size = [ensemble_stats({"E_t": [3.7] * 3, "nu_t": [0.31] * 3}) for _ in n]
    t = size_trend(n, [3.7] * 3, [0.0] * 3, 3)
    assert t.b == 0.0 and t.a == 3.7 and not t.significant
    noisy_hw = size_trend(n, [3.7] * 3, [0.1, 0.05, 0.02], 3)
    assert noisy_hw.b == 0.0 and not noisy_hw.significant
    summary = convergence_summary(n, per_size)
    for name in ("E_t", "nu_t"):
        assert summary["trend"][name]["b"] == 0.0
        assert summary["trend"][name]["verdict"] == "no size trend detected"
        assert summary["trend"][name]["extrapolated"] is None


def test_convergence_summary_schema():
    rng = np.random.default_rng(3)
    n = [64, 8, 27]  # any order in, ascending out
    per_size = [ensemble_stats({"E_l": 1.0 - 0.5 * m ** (-1 / 3) + 0.002 * rng.normal(size=6),
                                "C": rng.normal(1.0, 0.01, (6, 6, 6))}) for m in n]
    plan = plan_realisations(per_size[1], 0.05, seconds_per_realisation=12.0)
    s = convergence_summary(n, per_size, seconds_per_realisation=[90.0, 5.0, 30.0], plan=plan)
    text = json.dumps(s, allow_nan=False)
    assert json.loads(text) == s
    assert s["schema"] == "metasheet.convergence/1" and s["constants"] == ["E_l"]
    assert [z["n_cells"] for z in s["sizes"]] == [8, 27, 64]
    assert [z["seconds_per_realisation"] for z in s["sizes"]] == [5.0, 30.0, 90.0]
    assert set(s["sizes"][0]["constants"]["E_l"]) == {"mean", "std", "halfwidth", "rel_halfwidth", "k"}
    tr = s["trend"]["E_l"]
    assert tr["significant"] and tr["extrapolated"] == tr["a"] == pytest.approx(1.0, abs=0.01)
    assert s["plan"]["governing"] == "E_l" and s["plan"]["cost_s"] == 12.0 * s["plan"]["k"]


def test_trend_min_cells_leaves_the_small_sizes_out_of_the_fit():
    # the true law a + b n^(-1/3) from 4 cells up; the 2-cell volume is off it (a stronger bias,
    # as the Polyfoam's 2-cell cell), and precise enough to pull the fit over all sizes away
    rng = np.random.default_rng(11)
    a, b = 1.08, -0.3
    n = [2, 4, 8, 27]
    sd = {2: 0.004, 4: 0.01, 8: 0.01, 27: 0.01}
    per_size = [ensemble_stats({"E_t": (a + b * m ** (-1 / 3) - (0.15 if m == 2 else 0.0))
                                + sd[m] * rng.normal(size=4)}) for m in n]
    every = convergence_summary(n, per_size)["trend"]["E_t"]
    fit = convergence_summary(n, per_size, trend_min_cells=4)
    tr = fit["trend"]["E_t"]
    assert fit["trend_sizes"] == [4, 8, 27] and [z["n_cells"] for z in fit["sizes"]] == n
    assert abs(tr["a"] - a) <= tr["halfwidth_a"]  # the true limit inside the fit's interval
    # with the 2-cell size the model misses the data (chi-square) and the limit moves by 0.14
    assert every["chi2_reduced"] > 5 * max(tr["chi2_reduced"], 1.0)
    assert abs(every["a"] - a) > 5 * abs(tr["a"] - a)
    assert convergence_summary(n, per_size, trend_min_cells=27)["trend"] == {}  # one size: no trend
    assert convergence_summary(n, per_size, trend_min_cells=27)["trend_sizes"] == []
    with pytest.raises(ConfigError, match="^trend_min_cells"):
        convergence_summary(n, per_size, trend_min_cells=0)


@pytest.mark.parametrize(
    "call, field",
    [
        (lambda: constant_stats("E_l", [1.0]), "realisations['E_l']"),
        (lambda: constant_stats("E_l", [1.0, float("nan")]), "realisations['E_l']"),
        (lambda: ensemble_stats({"E_t": [1.0, 2.0], "mu_l": [1.0, np.inf]}), "realisations['mu_l']"),
        (lambda: ensemble_stats({"E_t": [1.0, 2.0], "nu_t": [0.3, 0.3, 0.3]}), "realisations"),
        (lambda: constant_stats("E_l", [1.0, 2.0], confidence=1.5), "confidence"),
        (lambda: required_realisations(0.0, 0.1, 1.0), "rel_target"),
        (lambda: required_realisations(0.05, 0.1, 0.0), "mean"),
        (lambda: required_realisations(0.05, float("nan"), 1.0), "std"),
        (lambda: size_trend([8, 8, 27], [1, 1, 1], [0.1] * 3, 3), "n_cells"),
        (lambda: size_trend([0, 8], [1, 1], [0.1] * 2, 3), "n_cells"),
        (lambda: size_trend([8], [1], [0.1], 3), "n_cells"),
        (lambda: size_trend([8, 27], [1, float("inf")], [0.1] * 2, 3), "means"),
        (lambda: size_trend([8, 27], [1, 1], [0.1, -0.1], 3), "halfwidths"),
        (lambda: size_trend([8, 27], [1, 1], [0.1] * 2, [3, 1]), "k"),
        (lambda: size_trend([8, 27], [1, 1, 1], [0.1] * 2, 3), "means"),
        (lambda: ci95_block({}, 8), "stats"),
        (lambda: convergence_summary([8, 27], []), "per_size"),
    ],
)
def test_validation_names_the_field(call, field):
    with pytest.raises(ConfigError) as exc:
        call()
    assert str(exc.value).startswith(field), str(exc.value)


def test_picture_is_a_png():
    import matplotlib.image as mpimg

    from metasheet.viz.convergence import convergence_picture

    rng = np.random.default_rng(9)
    n = [8, 27, 64]
    per_size = [ensemble_stats({"E_t": 2.0 + 0.05 * rng.normal(size=4),
                                "E_l": 1.0 - 0.5 * m ** (-1 / 3) + 0.002 * rng.normal(size=4),
                                "nu_tl": [0.3] * 4}) for m in n]
    summary = json.loads(json.dumps(convergence_summary(n, per_size)))  # as read from the artefact
    assert summary["trend"]["E_l"]["significant"]
    png = convergence_picture(summary, title="synthetic foam")
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    img = mpimg.imread(io.BytesIO(png), format="png")
    assert img.ndim == 3 and img.shape[0] > 100 and img.shape[1] > 300
