"""Print model: settings <-> constants on a synthetic Polyfoam chart with a known answer."""

import numpy as np
import pytest

from metasheet.errors import InfeasibleError
from metasheet.homogenize.chart import lookup, parse_csv, to_csv
from metasheet.homogenize.printmodel import model_from_chart


def _law(p, s):
    """E_t = 12 (p/100)^1.1, E_l = E_t s^2 (power laws: exact under log-bilinear interpolation)."""
    rho = p / 100.0
    e_t = 12 * rho**1.1
    return {"E_t": e_t, "E_l": e_t * s**2, "nu_t": 0.25 + 0.0 * s, "nu_tl": 0.4 * s, "mu_l": 0.1 * e_t * s}


def _rows():
    rows = []
    for p in (9.0, 18.0, 26.0, 34.0):
        for s in (0.2, 0.5, 1.0):
            c = _law(p, s)
            rows.append({"infill_percentage": p, "kgon_x_shrink": s, "seed": 1, "relative_density": p / 100, **c,
                         "alpha": 100 - 100 * c["E_l"] / c["E_t"], "misfit": 0.0, "n_dof": 1, "solver": "splu"})
    return rows


def test_chart_csv_carries_the_polyfoam_settings():
    text = to_csv(_rows())
    assert text.splitlines()[0].startswith("infill_percentage,kgon_x_shrink,seed,")
    r = lookup(parse_csv(text), E_t=_law(18.0, 0.2)["E_t"], E_l=_law(18.0, 0.2)["E_l"])
    assert r["infill_percentage"] == pytest.approx(18.0, rel=1e-5)
    assert r["kgon_x_shrink"] == pytest.approx(0.2, rel=1e-5)


def test_model_reproduces_grid_nodes_and_inverts_itself():
    m = model_from_chart(_rows())
    c = m.constants_at({"infill_percentage": np.array([9.0, 26.0]), "kgon_x_shrink": np.array([0.5, 1.0])})
    for k in ("E_t", "E_l", "mu_l", "nu_tl"):
        np.testing.assert_allclose(c[k], [_law(9.0, 0.5)[k], _law(26.0, 1.0)[k]], rtol=1e-12)
    # between nodes: bilinear in (p, s) of log E is not exact for p^1.1, so compare the inverse only
    s = {"infill_percentage": np.array([15.0, 15.0, 30.0]), "kgon_x_shrink": np.array([0.2, 0.2, 0.7])}
    back = m.settings_for(m.constants_at(s))
    np.testing.assert_allclose(back["infill_percentage"], s["infill_percentage"], rtol=1e-5)
    np.testing.assert_allclose(back["kgon_x_shrink"], s["kgon_x_shrink"], rtol=1e-5)


def test_calibration_anchors_the_model_on_the_cell():
    m = model_from_chart(_rows())
    cell = {"E_t": 1.39, "E_l": 0.0942, "nu_t": 0.262, "nu_tl": 0.416, "mu_l": 0.0163}
    cm = m.calibrated({"infill_percentage": 15.0, "kgon_x_shrink": 0.2}, cell)
    at = cm.constants_at({"infill_percentage": np.array([15.0]), "kgon_x_shrink": np.array([0.2])})
    for k, v in cell.items():
        assert at[k][0] == pytest.approx(v, rel=1e-12)
    back = cm.settings_for({"E_t": np.full(4, 1.39), "E_l": np.full(4, 0.0942)})
    np.testing.assert_allclose(back["infill_percentage"], 15.0, rtol=1e-5)
    np.testing.assert_allclose(back["kgon_x_shrink"], 0.2, rtol=1e-5)
    # moduli scale, Poisson ratios shift: the shape of the chart is kept
    raw = m.constants_at({"infill_percentage": np.array([15.0, 30.0]), "kgon_x_shrink": np.array([0.2, 0.2])})
    cal = cm.constants_at({"infill_percentage": np.array([15.0, 30.0]), "kgon_x_shrink": np.array([0.2, 0.2])})
    assert cal["E_t"][1] / cal["E_t"][0] == pytest.approx(raw["E_t"][1] / raw["E_t"][0], rel=1e-12)
    assert cal["nu_t"][1] - cal["nu_t"][0] == pytest.approx(raw["nu_t"][1] - raw["nu_t"][0], abs=1e-12)
    assert cm.describe()["calibration_kind"]["nu_t"] == "shift"


def test_settings_outside_the_chart_are_named():
    m = model_from_chart(_rows())
    with pytest.raises(InfeasibleError, match=r"kgon_x_shrink: 0\.05 .*\[0\.2, 1\]"):
        m.constants_at({"infill_percentage": np.array([15.0]), "kgon_x_shrink": np.array([0.05])})
    with pytest.raises(InfeasibleError, match="no polyfoam setting prints them"):
        m.settings_for({"E_t": np.array([50.0]), "E_l": np.array([0.001])})
    # within the quantisation slack: clipped, not refused
    c = m.constants_at({"infill_percentage": np.array([8.95]), "kgon_x_shrink": np.array([1.004])})
    assert c["E_t"][0] == pytest.approx(_law(9.0, 1.0)["E_t"], rel=1e-12)


def test_settings_at_density_inverts_density_and_calibrated_alpha():
    m = model_from_chart(_rows())
    cm = m.calibrated({"infill_percentage": 15.0, "kgon_x_shrink": 0.5},
                      {"E_t": 2.0, "E_l": 0.1, "nu_t": 0.3, "nu_tl": 0.3, "mu_l": 0.05})
    s = cm.settings_at_density(0.2, 80.0)
    assert s["infill_percentage"] == pytest.approx(20.0, rel=1e-4)  # rho = p / 100 in this chart
    c = cm.constants_at({k: np.array([v]) for k, v in s.items()})
    assert 100 - 100 * c["E_l"][0] / c["E_t"][0] == pytest.approx(80.0, abs=1e-3)
    with pytest.raises(InfeasibleError, match="no polyfoam setting"):
        cm.settings_at_density(0.6, 80.0)
