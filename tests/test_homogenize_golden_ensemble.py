"""Ensemble goldens (issue 43): the mean and 95 % half-width of every stochastic catalogue cell.

The single-seed goldens (test_homogenize_golden.py) catch any change of the numbers, at 1e-6.
These hold what a foam's constants *are*: the mean over K realisations (seeds s .. s+K-1 of
the same CI-sized variant as the single-seed golden) with its 95 % Student-t half-width h.
Two checks, each with its factor stated:

- **regression** (every stochastic cell): the mean recomputed with the golden's seeds must
  lie within ``W_SAME * h`` of the golden mean, W_SAME = 1: a change of the physics smaller
  than the foam's own sampling uncertainty passes, a larger one fails;
- **honesty** (quick_polyfoam; quick_foam by default): K *new* seeds. The difference of two independent means of K
  draws each has sqrt(2) times the standard error of one, and five constants are tested at
  once, so each uses the 99 % quantile (Bonferroni: about 5 % family-wise):
  ``W_NEW = sqrt(2) * t_{0.995, K-1} / t_{0.975, K-1}``.

The laminate and the solid are deterministic (no seeds): their single-seed goldens are exact.
Update with ``python -m pytest tests/test_homogenize_golden_ensemble.py --update-goldens``.
"""

import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from metasheet.homogenize.ensemble import ensemble_stats
from metasheet.homogenize.realisations import ensemble_input, evaluate_realisation, realisation_items
from metasheet.mechanics.material import CONSTANT_NAMES

from test_homogenize_golden import VARIANTS

ROOT = Path(__file__).resolve().parents[1]
GOLDEN = Path(__file__).resolve().parent / "golden" / "ensemble"
K = 4
W_SAME = 1.0
W_NEW = math.sqrt(2) * stats.t.ppf(0.995, K - 1) / stats.t.ppf(0.975, K - 1)
#: the stochastic catalogue cells, each at its CI variant or its own (CI-sized) grid
STOCHASTIC = sorted(p.stem for p in (ROOT / "cells").glob("*.toml")
                    if "seeds" in tomllib.loads(p.read_text()))


def _design(name: str) -> tuple[dict, str]:
    """(design dict at the CI grid, golden name) of a catalogue cell."""
    data = tomllib.loads((ROOT / "cells" / f"{name}.toml").read_text())
    if name in VARIANTS:
        v = VARIANTS[name]
        data["seeds"] = {**data["seeds"], **v.seeds}
        data["voxel_mm" if data.get("kind") == "polyfoam" else "resolution"] = v.resolution
        return data, v.name
    return data, name


def _ensemble(name: str, first_seed: int) -> dict:
    data, _ = _design(name)
    items = realisation_items(data, data["seeds"]["count"], range(first_seed, first_seed + K),
                              solver="auto", rtol=1e-10)
    st = ensemble_stats(ensemble_input([evaluate_realisation(it) for it in items]))
    return {"cell": name, "k": K, "seeds": list(range(first_seed, first_seed + K)),
            "mean": {k: st[k].mean for k in CONSTANT_NAMES}, "halfwidth": {k: st[k].halfwidth for k in CONSTANT_NAMES}}


def check(got: dict, want: dict, factor: float) -> list[str]:
    """Constants whose mean leaves the golden interval widened by ``factor`` (empty: pass)."""
    return [f"{k}: mean {got['mean'][k]:.6g} outside {want['mean'][k]:.6g} +- {factor:.3g} x "
            f"{want['halfwidth'][k]:.3g}" for k in CONSTANT_NAMES
            if abs(got["mean"][k] - want["mean"][k]) > factor * want["halfwidth"][k]]


def _want(name: str, request) -> dict:
    data, golden = _design(name)
    path = GOLDEN / f"{golden}.json"
    if request.config.getoption("--update-goldens"):
        GOLDEN.mkdir(exist_ok=True)
        path.write_text(json.dumps(_ensemble(name, int(data["seeds"]["seed"])), indent=2) + "\n")
    if not path.exists():
        pytest.fail(f"no ensemble golden {path.name}: run python -m pytest {Path(__file__).name} --update-goldens")
    return json.loads(path.read_text())


#: cells whose ensemble regression is slow; the default selection's siblings are the same check
#: on the CI-sized foams iso_foam (its variant) and quick_foam
SLOW = ("closed_foam", "paper_foam", "paper_polyfoam", "quick_polyfoam")


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in SLOW else n
                                  for n in STOCHASTIC])
def test_mean_within_the_golden_interval(name, request):
    """Default-selection siblings of the slow cells: the iso_foam and quick_foam cases."""
    want = _want(name, request)
    got = _ensemble(name, want["seeds"][0])
    assert not check(got, want, W_SAME)
    assert all(want["halfwidth"][k] > 0 for k in CONSTANT_NAMES)  # K distinct foams, a real interval


@pytest.mark.parametrize("name", ["quick_foam", pytest.param("quick_polyfoam", marks=pytest.mark.slow)])
def test_new_seeds_fall_inside_the_interval(request, name):
    """The interval is honest: four new foams agree with it at the stated factor.
    The slow quick_polyfoam case's default-selection sibling: the quick_foam case."""
    want = _want(name, request)
    got = _ensemble(name, want["seeds"][-1] + 1)
    assert not set(got["seeds"]) & set(want["seeds"])
    assert not check(got, want, W_NEW)


def test_a_perturbed_constant_fails():
    want = {"mean": {k: 1.0 for k in CONSTANT_NAMES}, "halfwidth": {k: 0.1 for k in CONSTANT_NAMES}}
    inside = {"mean": {**want["mean"], "E_l": 1.099}}
    outside = {"mean": {**want["mean"], "E_l": 1.101}}
    assert check(inside, want, 1.0) == []
    assert check(outside, want, 1.0) == ["E_l: mean 1.101 outside 1 +- 1 x 0.1"]
    assert check(outside, want, 1.02) == []  # the factor is what widens, nothing else
    assert 1.9 < W_NEW < 2.6 and np.isfinite(W_NEW)


def test_every_ensemble_golden_is_checked():
    assert {p.stem for p in GOLDEN.glob("*.json")} == {_design(n)[1] for n in STOCHASTIC}
