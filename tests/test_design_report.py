"""The report's design section (metasheet.report.design) on a hand-made comparison:
its verdict against issue 45's targets, computed from the numbers."""

import metasheet  # noqa: F401  (pins numpy's code paths before numpy is imported)

# isort: split
from metasheet.design.evaluation import comparison
from metasheet.report.design import design_section, targets
from metasheet.report.build import build_report


def _eval(roll, sv, strain):
    return {"roll_deg_per_deg": roll, "singular_values_mm_per_rad": sv, "other_min_mm_per_rad": sv[-1],
            "decoupling": {"translation_mm_per_deg": 0.01, "tilt_deg_per_deg": 0.0,
                           "translation_mm_per_roll_deg": 0.01 / abs(roll), "tilt_per_roll": 0.0},
            "strain": {"goal_deg": 10.0, "limit": 0.3, "goals": {"all +10 deg": strain, "motor 0 +10 deg": strain / 2}}}


def _summary(chosen_sv, strain):
    spiral = {"pipeline": _eval(-1.0, [50.0, 17, 15, 15, 12, 12], 0.2)}
    chosen = {"pipeline": _eval(-2.0, chosen_sv, strain)}
    pr = {"spiral": {"in_range": True}, "chosen": {"in_range": True}}
    return {"model": "linear rest problem", "n_tets_per_sheet": 852, "element": "p1", "chosen": {"name": "gradient"},
            "comparison": {"table": comparison(spiral, chosen, pr), "evaluations": {"spiral": spiral}}}


def test_targets_from_the_numbers():
    met = _summary([100.0, 18, 16, 15, 13, 12], 0.25)
    t = targets(met["comparison"]["table"])
    assert t["roll_ratio"] == 2.0 and t["roll_met"] and t["others_not_lower"] and t["strain_within"]
    low = targets(_summary([100.0, 18, 16, 14.9, 13, 12], 0.31)["comparison"]["table"])
    assert low["others_not_lower"] is False and low["strain_within"] is False and low["strain_max"] == 0.31
    assert low["spiral_strain_max"] == 0.2


def test_section_and_its_absence():
    assert design_section(None) == ([], []) and design_section({"model": "old, no comparison"}) == ([], [])
    lines, diffs = design_section(_summary([100.0, 18, 16, 15, 13, 12], 0.31), {"design_field": "design_field.png"})
    text = "\n".join(lines)
    assert "rod roll per motor degree 2 x the spiral's (target 1.5: met)" in text
    assert "| rod roll per motor degree | deg/deg | -1 | -2 | 2 |" in text
    assert "![fibre fields](design_field.png)" in text
    assert diffs == [("Design: the chosen design's linearised strain at the goals reaches 0.31, beyond the "
                      "validity limit 0.3.")]
    assert "## Design: the chosen fibre field" in build_report({"design_json": _summary([100.0] * 6, 0.1)}, {})
    assert "## Design" not in build_report({"material": None}, {})


def test_trade_off_is_stated():
    """The constrained run's reach and strain front appear in the section, with the issue's
    overall target (roll, other DOF and strain together) judged from the numbers."""
    d = _summary([100.0, 18, 16, 15, 13, 12], 0.29)
    d["chosen"].update({"strain_constrained": True, "reach": {
        "spiral": {"motor_deg_at_limit": 9.6, "roll_deg_at_limit": 16.0},
        "chosen": {"motor_deg_at_limit": 10.0, "roll_deg_at_limit": 22.0}}})
    d["strain_front"] = {"goal_deg": 10.0, "reach_limit": 0.3, "rows": [
        {"strain_limit": 0.4, "roll_deg_per_deg": -3.6, "ratio_abs_roll": 2.18, "goal_strain": 0.399,
         "satisfied": True, "roll_deg_at_limit": 27.3}]}
    lines, diffs = design_section(d)
    text = "\n".join(lines)
    assert "Issue 45's target (all three together): met" in text
    assert "optimised subject to the strain limit" in text
    assert "the chosen design 22 deg of rod roll at 10 deg of the motors, the spiral 16 deg at 9.6 deg (1.38 x)" in text
    assert "| 0.4 | -3.6 | 2.18 | 0.399 | yes | 27.3 |" in text and diffs == []


def test_an_unconverged_optimisation_is_said():
    d = _summary([100.0, 18, 16, 15, 13, 12], 0.31)
    assert "did not converge" not in "\n".join(design_section(d)[0])
    d["gradient"] = {"converged": False, "iterations": 30, "message": "Iteration limit reached"}
    text = "\n".join(design_section(d)[0])
    assert "**The gradient optimisation did not converge** after 30 iterations: Iteration limit reached." in text
