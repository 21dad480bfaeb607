"""Stage ``ranges``: the reach test repeated for several motor ranges (paper Fig. 6).

Writes ``ranges.csv`` (one row per goal point; per range: reachable, found by the range's own
search, and the pose error of the path that reached it), ``ranges.png`` and ``ranges.json``
(counts per range, those found by each range's own search and those reached by a narrower
range's path (:func:`~metasheet.studies.ranges.adopt_narrower`), the nesting check, which
model ran: ``model_info``).
On the reduced model (``model = "reduced"``) the points reached in any range (``certify`` of
them over all ranges, 0: all) are re-solved by the full model at their motor angles
(``certification``; a point is labelled "<range>:<point>").
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from ...studies.ranges import motor_range_study
from ...studies.workspace import WorkspaceSettings
from ..manifest import write_json_atomic
from ..registry import Stage, StageContext, register
from ._studies import (run_columns, GridParams, build_spec, certification, drop_cache, grid_from, model_record, progress,
                       study_reads, unit_cache, write_csv)

class RangesParams(GridParams):
    ranges: list[tuple[float, float]] = Field(
        [(0.0, 90.0), (10.0, 80.0), (20.0, 70.0)], description="motor ranges (lo, hi) to compare [deg]")

def run(ctx: StageContext) -> dict:
    return run_columns(ctx, _run_one)


def _run_one(ctx: StageContext) -> dict:
    p: RangesParams = ctx.params
    spec = build_spec(ctx)
    grid = grid_from(p)
    s = WorkspaceSettings(tol_mm=p.tol_mm, max_steps=p.max_steps, stop_after=p.stop_after, strain_limit=p.strain_limit,
                          stop_beyond_strain=p.stop_beyond_strain, past_box=p.past_box)
    res = motor_range_study(spec, grid, p.ranges, s, executor=ctx.executor, progress=progress(ctx),
                            cache=unit_cache(ctx))
    names = [f"{lo:g}-{hi:g}" for lo, hi in res.ranges]
    header = ["point", "ray", "step", "x_mm", "y_mm", "z_mm"] + [f"reached_{n}" for n in names] + [
        f"error_mm_{n}" for n in names] + [f"found_{n}" for n in names]
    write_csv(ctx.path("ranges.csv"), header,
              ([i, grid.ray[i], grid.index[i], *res.goals[i], *res.reached[:, i], *res.error_mm[:, i],
                *res.found[:, i]] for i in range(len(grid))))
    from ...viz.studies import ranges_picture

    ctx.path("ranges.png").write_bytes(ranges_picture(
        res.goals, res.reached, res.ranges, found=res.found,
        title=(f"Reachable workspace per motor range (paper Fig. 6), nested: {res.nested} [{ctx.column}, {p.model}"
               + (f"; within the strain limit {p.strain_limit:g}]" if p.stop_beyond_strain else "]"))))
    summary = {"column": ctx.column, "ranges_deg": res.ranges.tolist(), "reachable": dict(zip(names, res.counts())),
               "found": dict(zip(names, res.found_counts())),
               "via_narrower": {n: int((res.reached[a] & ~res.found[a]).sum()) for a, n in enumerate(names)},
               "motor_span_deg": {n: _span(res.motors_deg[a][res.reached[a]]) for a, n in enumerate(names)},
               "points": len(grid), "nested": res.nested,
               "violations": [{"wide": names[a], "narrow": names[b], "points": len(pts)} for a, b, pts in res.violations],
               "strain_limit": p.strain_limit, "stop_beyond_strain": p.stop_beyond_strain,
               "model": p.model, "model_info": model_record(spec)}
    rr, ii = np.nonzero(res.reached)  # (range, point) of every reached point
    goals = np.column_stack([res.goals[ii], np.tile(res.rest_pose[3:], (len(ii), 1))])
    cert = certification(ctx, spec, goals, res.motors_deg[rr, ii], tol_mm=p.tol_mm,
                         labels=[f"{names[a]}:{i}" for a, i in zip(rr, ii)])
    if cert is not None:
        summary["certification"] = cert
    write_json_atomic(ctx.path("ranges.json"), summary)
    drop_cache(ctx)
    return summary


def _span(motors_deg: np.ndarray) -> list[float] | None:
    """[min, max] [deg] of the motor angles (k, na) of a range's reached goals, None if none."""
    return [round(float(motors_deg.min()), 4), round(float(motors_deg.max()), 4)] if motors_deg.size else None


register(Stage(
    name="ranges", params=RangesParams, run=run, optional=("orient", "material", "robot", "reduce"),
    reads=study_reads,
    outputs=("ranges.csv", "ranges.png", "ranges.json"),
    doc="reachable workspace for several motor ranges (Fig. 6), nesting checked",
))
