"""The report's section on the reduced model: the certificate's numbers as reduce.json has them."""

from metasheet.rom.certificate import Comparison, summarize
from metasheet.report.build import build_report
from metasheet.report.reduce import reduce_section


def _reduce_json(rows, limit=0.3):
    return {"k": 77, "elements": 1778, "elements_total": 7012, "free_dofs": 30000,
            "box_deg": [[65.3] * 6, [81.3] * 6], "training": {"static_modes": 13, "pod_modes": 26,
                                                              "sensitivity_modes": 38},
            "certificate": summarize(rows, limit)}


def test_section_shows_the_certificate_within_the_strain_limit_and_the_rest_apart():
    rows = [Comparison((0.0,), 0.0123, 0.004, 0.011, 0.02, 0.2), Comparison((0.0,), 0.5, 0.3, 0.4, 3.0, 0.7)]
    lines, diffs = reduce_section(_reduce_json(rows), seconds=124.0)
    text = "\n".join(lines)
    assert "k = 77 modes" in text and "1778 of 7012 elements" in text and "in 124 s" in text
    assert "| effector position [mm] | 0.0123 | 0.0123 | 0 | 0.1 | met |" in text
    assert "within the strain limit 0.3: 1; beyond it: 1" in text and "Certificate: **met**" in text
    assert "| effector position [mm] | 0.5 | 0.5 | 0 |" in text  # the pose beyond, reported apart
    assert diffs == []
    # a pose inside beyond a target: NOT met, and said among the differences
    bad = [*rows, Comparison((0.0,), 0.2, 0.01, 0.01, 0.01, 0.25)]
    lines, diffs = reduce_section(_reduce_json(bad))
    assert "Certificate: **NOT met**" in "\n".join(lines) and len(diffs) == 1
    assert reduce_section(None) == ([], [])


def test_the_report_carries_the_section():
    rows = [Comparison((0.0,), 0.01, 0.004, 0.011, 0.02, 0.2)]
    text = build_report({"reduce_json": _reduce_json(rows)}, {})
    assert "## Reduced-order robot and its certificate (issue 16)" in text


def test_the_surface_has_its_own_certificate_and_difference():
    import numpy as np
    import pytest

    from metasheet.rom.certificate import surface_check

    rows = [Comparison((0.0,), 0.01, 0.004, 0.011, 0.02, 0.2)]
    red = _reduce_json(rows)
    surf_rows = [Comparison((0.0,), 0.036, 0.016, 0.042, 0.06, 0.2)]  # Jacobian 4.2 %: beyond 2 %
    red["surface"] = {"degree": 4, "coefficients": 210, "equilibria": 66, "check_equilibria": 15,
                      "certificate": summarize(surf_rows, 0.3), "box_deg": [[70.0] * 6, [82.0] * 6]}
    lines, diffs = reduce_section(red)
    text = "\n".join(lines)
    assert "### Equilibrium surface (the real-time model)" in text and "degree 4 in the motor angles" in text
    assert "over motor angles 70 to 82 deg" in text
    assert "| Jacobian [relative Frobenius] | 0.042 | 0.042 | 0 | 0.02 | NOT met |" in text
    assert len(diffs) == 1 and diffs[0].startswith("equilibrium surface (issue 16)")
    assert "further equilibria" not in text  # no check recorded: no table
    # the check on reduced-model equilibria: the bound adds the reduced model's own worst error
    errs = {"position_mm": np.array([0.02, 0.05, 0.5]), "orientation_deg": np.array([0.01, 0.02, 1.0]),
            "jacobian_rel": np.array([0.004, 0.012, 0.3])}
    check = surface_check(errs, np.array([0.1, 0.2, 0.6]), 0.3, red["certificate"])
    assert check["within_strain"] == 2 and check["jacobian_rel"]["worst"] == 0.012
    assert check["jacobian_rel"]["bound_with_reduced"] == pytest.approx(0.012 + 0.011)  # over 2 %
    assert check["position_mm"]["met"] and not check["jacobian_rel"]["met"] and check["met"] is False
    red["surface"].update(check=check, certified=False)
    text = "\n".join(reduce_section(red)[0])
    assert "on 2 further equilibria within the strain limit (of 3;" in text
    assert "| effector position [mm] | 0.05 | 0.0485 | 0.06 | 0.1 | met |" in text
    assert "Certificate: **NOT met**" in text
    passing = surface_check({k: v / 10 for k, v in errs.items()}, np.array([0.1, 0.2, 0.6]), 0.3, red["certificate"])
    assert passing["met"] is True
    assert surface_check(errs, np.array([0.4, 0.5, 0.6]), 0.3, red["certificate"])["met"] is False  # none within
