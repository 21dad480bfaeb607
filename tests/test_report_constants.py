"""The constants section of the report: the literature table, and the comparison it prints."""

import numpy as np
import pytest

from metasheet.published.literature import E_S, authors_constants, authors_table
from metasheet.published.paper import PAPER_FOAM
from metasheet.report.constants import constants_section


def test_the_published_constants_are_the_authors_table_at_15_percent():
    """The paper's constants are the authors' transverse table interpolated at rho = 0.15."""
    at = authors_constants(0.15)
    for k, v in PAPER_FOAM.to_dict().items():
        assert float(at[k]) == pytest.approx(v, rel=0.01), k


def test_isotropic_table_is_isotropic_and_outside_range_is_refused():
    c = authors_constants(0.2, "isotropic")
    assert c["E_t"] == c["E_l"]
    with pytest.raises(Exception, match="relative_density"):
        authors_constants(0.5)


def _rows_from_the_authors():
    """A chart whose shrink-0.2 column is the authors' transverse foam at its four densities."""
    rows = []
    t = authors_table("transverse")
    for i, rho in enumerate(t["density"]):
        c = {k: float(v) for k, v in authors_constants(rho).items()}
        for s in (0.2, 1.0):
            rows.append({"infill_percentage": round(100 * rho, 3), "kgon_x_shrink": s, "seed": 1,
                         "relative_density": rho, **c, "alpha": 0.0, "misfit": 0.0, "n_dof": 1, "solver": "x"})
    return rows


def test_section_compares_three_sources_and_fits_the_same_law():
    h = {"relative_density": 0.15, **{k: 2 * v for k, v in PAPER_FOAM.to_dict().items()}}
    robot = {"foam": {"singular_values": [1.0, 2.0], "rod_rotation_deg_per_deg": 0.5},
             "published": {"singular_values": [1.5, 2.5], "rod_rotation_deg_per_deg": 0.25}}
    lines, diffs = constants_section(h, _rows_from_the_authors(), {"source": "homogenize"}, robot, None, 0.2)
    text = "\n".join(lines)
    assert "| E_t [MPa] | 2.78 | 1.39 | 1.388 | 2.00 |" in text
    assert "| rod rotation per motor degree [deg/deg] | 0.5 | 0.25 |" in text
    # the chart built from the authors' table fits the authors' own power law
    t = authors_table("transverse")
    for name, ref in (("E_t", 0.5 * (t["E_y"] + t["E_z"])), ("E_l", t["E_x"])):
        n, c = np.polyfit(np.log(t["density"]), np.log(ref), 1)
        law = f"{np.exp(c):.3g} rho^{n:.2f}"
        assert f"{name} / E_s = {law} (authors: {law})" in text, name
    assert any("2.00 x the published" in d for d in diffs)
    assert f"E_t / E_s = {2 * 1.39 / E_S:.4f}" in text


def test_scale_separation_is_measured_against_the_sheet():
    cell = {"mean_void_chord_mm": [2.5, 12.6, 23.4], "size_mm": [7.8, 38.9, 80.6], "seed_count": 8}
    lines, diffs = constants_section({"relative_density": 0.15, **PAPER_FOAM.to_dict()}, None, None, None, None,
                                     cell=cell, thickness=5.0)
    assert "0.21 cell(s) through the thickness" in "\n".join(lines)
    assert any("Scale separation fails" in d for d in diffs)
    _, fine = constants_section({"relative_density": 0.15, **PAPER_FOAM.to_dict()}, None, None, None, None,
                                cell={**cell, "mean_void_chord_mm": [0.5, 0.5, 0.5]}, thickness=5.0)
    assert not any("Scale separation" in d for d in fine)


def test_sweep_table_carries_the_charts_intervals():
    from metasheet.homogenize.chart_bars import chart_bars

    # two seeds per point, 3 % apart: the table shows each mean with the chart's half-width
    rows = []
    for r in _rows_from_the_authors():
        for seed, f in ((1, 0.97), (2, 1.03)):
            rows.append({**r, "seed": seed, **{k: f * r[k] for k in ("E_t", "E_l", "nu_t", "nu_tl", "mu_l")}})
    lines, _ = constants_section({"relative_density": 0.15, **PAPER_FOAM.to_dict()}, rows, None, None, None, 0.2)
    b = chart_bars(rows, "E_t", "infill_percentage", "kgon_x_shrink")
    p0 = min(float(r["infill_percentage"]) for r in rows)
    h = b.halfwidths[(b.points[:, 0] == p0) & (b.points[:, 1] == 0.2)][0]
    row = next(ln for ln in lines if ln.startswith(f"| {p0:g} |"))
    assert f" +- {h / E_S:.2g} |" in row.split("|", 3)[3] and b.pooled == "chart"
    assert any(ln.startswith("+- : the 95 % interval of the mean over the chart's seeds (2 per point") for ln in lines)
    one, _ = constants_section({"relative_density": 0.15, **PAPER_FOAM.to_dict()}, _rows_from_the_authors(),
                               None, None, None, 0.2)
    assert not any(" +- " in ln for ln in one if ln.startswith("| 1"))  # one seed: no intervals
