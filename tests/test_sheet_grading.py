"""Graded designs: regions, expressions, per-element constants."""

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.mechanics.material import TransverseIsotropic
from metasheet.sheet.geometry import SheetParams
from metasheet.sheet.grading import element_constants, evaluate, grade, regions, scaling_lookup

FOAM = TransverseIsotropic(1.39, 0.09422, 0.26162, 0.4161, 0.01628215)
P = SheetParams()
PTS = np.array([[0.0, 12.0, 0], [40.0, 0, 0], [64.0, 5.0, 1.0], [-33.0, 57.15, 0], [-20, -30, 0]])


def test_regions_by_position():
    assert regions(PTS, P).tolist() == [0, 1, 2, 2, 1]


def test_uniform_design_returns_the_material_exactly():
    g = grade(PTS, P, density=0.15, alpha=FOAM.alpha)
    c = element_constants(g, scaling_lookup(FOAM, 0.15))
    for k, v in FOAM.to_dict().items():
        assert np.all(c[k] == v)


def test_table_and_gibson_ashby_scaling():
    g = grade(PTS, P, density=0.15, alpha=FOAM.alpha, table={"tips": {"density": 0.30, "alpha": 0.0}})
    assert g.names[g.material_id[2]] == "tips"
    c = element_constants(g, scaling_lookup(FOAM, 0.15, exponent=2.0))
    # tips: twice the density -> 4x the moduli, and isotropic (alpha = 0: E_l = E_t)
    assert c["E_t"][2] == pytest.approx(4 * FOAM.E_t)
    assert c["E_l"][2] == pytest.approx(4 * FOAM.E_t)
    assert c["E_l"][1] == pytest.approx(FOAM.E_l)


def test_expressions():
    v = evaluate("0.1 + 0.001 * r", PTS, "d")
    assert np.allclose(v, 0.1 + 0.001 * np.hypot(PTS[:, 0], PTS[:, 1]))
    g = grade(PTS, P, density=0.15, alpha=50.0, alpha_expr="where(r < 30, 0.0, 80.0)")
    assert g.alpha.tolist() == [0.0, 80.0, 80.0, 80.0, 80.0]


@pytest.mark.parametrize("expr", ["__import__('os')", "x.__class__", "open('f')", "lambda: 1", "q + 1"])
def test_unsafe_or_unknown_expressions_are_rejected(expr):
    with pytest.raises(ConfigError, match="grading.density_expr"):
        grade(PTS, P, density=0.15, alpha=0.0, density_expr=expr)


def test_out_of_range_values_name_the_field():
    with pytest.raises(ConfigError, match="grading.density"):
        grade(PTS, P, density=0.15, alpha=0.0, density_expr="r")
    with pytest.raises(ConfigError, match="region"):
        grade(PTS, P, density=0.15, alpha=0.0, table={"middle": {"density": 0.2}})
    with pytest.raises(ConfigError, match="alpha"):
        element_constants(grade(PTS, P, density=0.15, alpha=99.0), scaling_lookup(FOAM, 0.15))
