"""The printed sheet's voxel DNS converged in the voxel size, and under the other gauge (issue
62, item 1): one print's two sheets solved at several voxel sizes, each size's figures (the 18
grip modes' stiffness against the homogenised sheet, the printed robot's rod roll and singular
values, :func:`metasheet.studies.sheet_dns.dns_study`), and each figure's Richardson limit and
order over the sizes (:mod:`.richardson`) with each size's error against it.

Used by the ``printed`` stage (its ``ladder`` and ``other_gauge`` keys) and by
``benchmarks/dns_convergence.py``.
"""

from __future__ import annotations

from collections.abc import Sequence

from .richardson import richardson
from .sheet_dns import dns_study

LABELS = ("normal", "mirrored")


def ladder_row(voxel_mm: float, pair: Sequence, homogenised, robot, params, *, length_scale: float = 50.0) -> dict:
    """The figures of voxel size ``voxel_mm`` (asked; each grid's edges are within a few % of
    it) from its two solved sheets ``pair`` ((normal, mirrored)
    :class:`~metasheet.sheet.dns.DnsSheet`), the homogenised grips and the robot."""
    st = dns_study(list(pair), homogenised, robot, params, length_scale=length_scale)
    return study_row(voxel_mm, pair[0].gauge, st["realisations"][0], st["homogenised_robot"])


def study_row(voxel_mm: float, gauge: str, realisation: dict, homogenised_robot: dict) -> dict:
    """A ladder row from one realisation of :func:`~metasheet.studies.sheet_dns.dns_study`'s
    dict (or the ``sheet`` stage's ``sheet_dns.json``) and its ``homogenised_robot``."""
    sheets = realisation["sheets"]
    return {"voxel_mm": float(voxel_mm), "gauge": gauge, "unknowns": [sheets[lab]["n_dof"] for lab in LABELS],
            "kept_share": [sheets[lab]["kept_share"] for lab in LABELS],
            "iterations": [max(sheets[lab]["iterations"]) for lab in LABELS],
            "geometric_mean_ratio": [sheets[lab]["geometric_mean_ratio"] for lab in LABELS],
            "softest_ratio": [min(sheets[lab]["eigen_ratios"]) for lab in LABELS],
            "rod_roll": realisation["robot"]["rod_rotation_deg_per_deg"],
            "singular_values": realisation["robot"]["singular_values"],
            "homogenised": {"rod_roll": homogenised_robot["rod_rotation_deg_per_deg"],
                            "singular_values": homogenised_robot["singular_values"]}}


def ladder_fits(rows: Sequence[dict]) -> dict:
    """Each figure's :class:`~.richardson.RichardsonFit` (as a dict) over ``rows`` (one per voxel
    size, any order; at least three); {} with fewer."""
    rows = sorted(rows, key=lambda r: -r["voxel_mm"])  # coarse to fine
    if len(rows) < 3:
        return {}
    h = [r["voxel_mm"] for r in rows]
    q = {"geometric mean, normal": [r["geometric_mean_ratio"][0] for r in rows],
         "geometric mean, mirrored": [r["geometric_mean_ratio"][1] for r in rows],
         "softest mode, normal": [r["softest_ratio"][0] for r in rows],
         "rod roll [deg/deg]": [r["rod_roll"] for r in rows],
         **{f"singular value {i + 1} [mm/deg]": [r["singular_values"][i] for r in rows] for i in range(6)}}
    return {k: richardson(h, v).to_dict() for k, v in q.items()}
