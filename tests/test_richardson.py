"""Richardson extrapolation of a grid ladder (metasheet/studies/richardson.py) against ladders
whose limit and order are known by construction."""

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.studies.richardson import richardson, triple_order


@pytest.mark.parametrize("p", [0.7, 1.0, 2.0, 3.3])
def test_three_levels_at_any_ratios_give_the_exact_limit_and_order(p):
    h = np.array([0.3, 0.25, 0.175])  # not a constant refinement ratio
    q = 0.41 - 1.7 * h**p
    fit = richardson(h, q)
    assert fit.order == pytest.approx(p, rel=1e-8)
    assert fit.limit == pytest.approx(0.41, rel=1e-9)
    np.testing.assert_allclose(fit.errors, -1.7 * h**p, rtol=1e-7)
    np.testing.assert_allclose(fit.relative, fit.errors / 0.41, rtol=1e-12)


def test_four_levels_fit_all_and_report_each_triple():
    h = np.array([0.175, 0.3, 0.2, 0.25])  # any order in, coarse to fine out
    q = 2.0 + 0.5 * h**1.5
    fit = richardson(h, q)
    np.testing.assert_array_equal(fit.h, [0.3, 0.25, 0.2, 0.175])
    assert fit.order == pytest.approx(1.5, abs=1e-6) and fit.limit == pytest.approx(2.0, abs=1e-8)
    assert all(t == pytest.approx(1.5, rel=1e-8) for t in fit.triple_orders)
    # a second error term: the triple orders drift, the fit still lands near the limit
    q2 = 2.0 + 0.5 * h**1.5 + 0.4 * h**3
    fit2 = richardson(h, q2)
    assert fit2.order is not None and abs(fit2.limit - 2.0) < abs(q2.min() - 2.0)


def test_an_oscillating_ladder_claims_no_order():
    fit = richardson([0.3, 0.25, 0.2], [1.0, 1.2, 1.1])
    assert fit.order is None and fit.limit == 1.1 and "not in its asymptotic range" in fit.note
    assert triple_order([0.3, 0.25, 0.2], [1.0, 1.0, 1.1]) is None  # a vanishing difference


@pytest.mark.parametrize("h, q, match", [([0.3, 0.2], [1, 2], "at least 3"), ([0.3, 0.2, 0.2], [1, 2, 3], "each size once"),
                                         ([0.3, 0.0, 0.2], [1, 2, 3], "> 0"), ([0.3, 0.25, 0.2], [1, np.nan, 3], "finite")])
def test_bad_ladders_are_named(h, q, match):
    with pytest.raises(ConfigError, match=match):
        richardson(h, q)
