"""Stage ``workspace``: the workspace exploration of paper Fig. 5, plus validity (max principal
strain), loss of control (smallest Jacobian singular value) and continuity (components).

Writes ``workspace.csv`` (one row per goal point), ``workspace.vtp`` (the point cloud with
the same fields), ``workspace.png`` (front / side / top views) and ``workspace.json``, which
records the rotation test (``test``: "paper" or "authors_code", see
:data:`metasheet.studies.workspace.ROTATION_TESTS`) with the values it ran, and which model ran
(``model_info``). On the reduced model (``model = "reduced"``) the reachable points (``certify``
of them, 0: all) are re-solved by the full model at their motor angles, position within
``tol_mm`` as the point test (``certification`` in ``workspace.json``); the rotation tests
and continuity paths are not re-certified.
"""

from __future__ import annotations

import time
from typing import Literal

import numpy as np
from pydantic import Field

from ...studies.model import MODELS
from ...studies.workspace import CLASS_NAMES, WorkspaceSettings, explore_workspace, near_rest_control
from ..manifest import write_json_atomic
from ..registry import Stage, StageContext, register
from ._studies import (run_columns, GridParams, build_spec, certification, drop_cache, grid_from, model_record, progress,
                       study_reads, unit_cache, write_csv)

ROT_COLS = ("+x", "-x", "+y", "-y", "+z", "-z")


class WorkspaceParams(GridParams):
    test: Literal["paper", "authors_code"] = Field(
        "paper", description="rotation test: 'paper' (+-10 deg about x, y, z, within 2 deg) or 'authors_code' "
        "(their controller: +-5 deg about y in sequence, within 3 deg, no effector jump > 1 mm)")
    rot_deg: float | None = Field(None, gt=0, le=90, description="rotation tried at each reached point [deg]; "
                                  "None: the test's (10 or 5)")
    tol_rot_deg: float | None = Field(None, gt=0, le=90, description="rotation tolerance [deg]; None: the test's "
                                      "(2 or 3)")
    near_rest_mm: float = Field(3.0, gt=0, le=100, description="radius of the area around rest whose reachable "
                                "points' share of full control (three rotations) the report states [mm]")
    rotations: bool = Field(True, description="try the test's +-rot_deg rotations")
    rot_stop_after: int = Field(0, ge=0, le=100000, description="rotation-tested points in a row on a ray that "
                                "pass no axis before the ray's outer points are reached without rotation tries "
                                "(0: try every reached point) [-]")
    continuity: bool = Field(True, description="test paths between neighbouring reached points")
    substeps: int = Field(3, ge=1, le=1000, description="intermediate goals on a continuity path [-]")
    hold_orientation: bool = Field(False, description="point goals also ask for the rest orientation (paper: position only)")


def settings_from(p) -> WorkspaceSettings:
    return WorkspaceSettings.for_test(
        p.test, tol_mm=p.tol_mm, rot_deg=p.rot_deg, tol_rot_deg=p.tol_rot_deg, max_steps=p.max_steps,
        rotations=p.rotations, rot_stop_after=p.rot_stop_after, stop_after=p.stop_after, strain_limit=p.strain_limit,
        stop_beyond_strain=p.stop_beyond_strain, past_box=p.past_box, continuity=p.continuity,
        substeps=p.substeps, hold_orientation=p.hold_orientation)


def left_out_mask(r, s: WorkspaceSettings) -> np.ndarray:
    """(n,) bool: the reached points of records ``r`` whose rotations ``rot_stop_after`` left
    untried (not those beyond the strain limit, which a study within it never rotation-tests)."""
    beyond = s.stop_beyond_strain & ~(r.strain <= s.strain_limit)
    return r.reached & ~r.rot_tried & ~beyond & s.rotations


def write_vtp(path, points, fields: dict) -> None:
    import pyvista as pv

    cloud = pv.PolyData(np.asarray(points, float))
    for k, v in fields.items():
        cloud.point_data[k] = np.asarray(v)
    cloud.save(str(path), binary=True)


def run(ctx: StageContext) -> dict:
    return run_columns(ctx, _run_one)


def _run_one(ctx: StageContext) -> dict:
    p: WorkspaceParams = ctx.params
    spec = build_spec(ctx)
    grid = grid_from(p)
    t0 = time.perf_counter()
    settings = settings_from(p)
    res = explore_workspace(spec, grid, settings, executor=ctx.executor, progress=progress(ctx),
                            cache=unit_cache(ctx))
    r = res.records
    ids = np.flatnonzero(r.reached)  # the point goals: the grid position with the rest orientation
    rest_rot = MODELS.get(spec).rest_pose()[3:]
    cert = certification(ctx, spec, np.column_stack([res.goals[ids], np.tile(rest_rot, (len(ids), 1))]),
                         r.motors_deg[ids], tol_mm=settings.tol_mm, labels=ids.tolist())
    if settings.rotations:  # the paper's test at the rest pose itself (the grid starts a step out)
        from ...studies.rest_rotations import rest_rotations
        from ...studies.workspace import domain_spec

        at_rest = rest_rotations(domain_spec(spec, settings), settings)
    # clocks go to the manifest (timings_s), never into a result: the same run gives the same bytes
    wall = time.perf_counter() - t0
    ctx.timings["points"] = wall
    ctx.timings["s_per_point"] = wall / max(1, int(r.tried.sum()))
    header = (["point", "ray", "step", "x_mm", "y_mm", "z_mm", "class", "class_name", "tried", "reached",
               "error_mm", "error_deg", "iterations"] + [f"motor{k}_deg" for k in range(r.motors_deg.shape[1])]
              + [f"rot{c}_error_deg" for c in ROT_COLS] + [f"rot{c}_error_mm" for c in ROT_COLS]
              + ["rot_x_ok", "rot_y_ok", "rot_z_ok", "rot_jump_mm", "max_principal_strain", "valid",
                 "min_singular_value", "component", "converged", "left_domain", "rot_beyond_strain", "rot_tried"])
    rows = ([i, grid.ray[i], grid.index[i], *res.goals[i], res.cls[i], CLASS_NAMES[res.cls[i]], r.tried[i],
             r.reached[i], r.error_mm[i], r.error_deg[i], r.steps[i], *r.motors_deg[i], *r.rot_error_deg[i],
             *r.rot_error_mm[i], *r.rot_ok[i], r.rot_jump_mm[i], r.strain[i], res.valid[i], r.sigma_min[i],
             res.component[i], r.converged[i], r.left_domain[i], int(r.rot_beyond[i].sum()), r.rot_tried[i]]
            for i in range(len(grid)))
    write_csv(ctx.path("workspace.csv"), header, rows)
    write_vtp(ctx.path("workspace.vtp"), res.goals, {
        "class": res.cls, "error_mm": r.error_mm, "max_principal_strain": r.strain, "valid": res.valid.astype(np.int8),
        "min_singular_value": r.sigma_min, "component": res.component, "ray": grid.ray})
    from ...viz.studies import workspace_picture

    counts = res.counts()
    title = (f"Workspace (paper Fig. 5): {len(grid)} goals, {int(r.reached.sum())} reachable, "
             f"{res.n_components} connected component(s) [{ctx.column}, {p.model}, {settings.test} rotation test"
             + (f", within the strain limit {p.strain_limit:g}" if p.stop_beyond_strain else "")
             + (f", rotations tried until {settings.rot_stop_after} points in a row pass none]"
                if settings.rotations and settings.rot_stop_after else "]"))
    ctx.path("workspace.png").write_bytes(workspace_picture(
        res.goals, res.cls, r.strain, r.sigma_min, res.valid, strain_limit=p.strain_limit, title=title, tried=r.tried,
        rot_untested=left_out_mask(r, settings)))
    reached = r.reached
    summary = {
        "column": ctx.column,
        "points": len(grid), "rays": int(len(grid.directions)), "counts": counts,
        "reachable": int(reached.sum()), "tried": int(r.tried.sum()),
        "solver_failures": int((r.tried & ~r.converged).sum()),
        "invalid_strain": int((reached & ~res.valid).sum()), "strain_limit": p.strain_limit,
        "left_domain": int(r.left_domain.sum()),
        "rotations_beyond_strain": int(r.rot_beyond.sum()),
        "rot_stop_after": settings.rot_stop_after,
        "rotations_left_out": int(left_out_mask(r, settings).sum()),
        "stop_beyond_strain": p.stop_beyond_strain, "strain_band_mm": getattr(spec, "strain_band_mm", None),
        "max_strain": float(np.nanmax(r.strain[reached])) if reached.any() else None,
        "min_singular_value": float(np.nanmin(r.sigma_min)) if reached.any() else None,
        "components": res.n_components, "edges_tested": res.edges_tested, "edges_passed": res.edges_passed,
        "in_rest_component": int((res.component == 0).sum()),
        "near_rest": near_rest_control(res.goals, res.cls, r.reached, MODELS.get(spec).rest_pose()[:3], p.near_rest_mm),
        "executor": ctx.executor.kind, "model": p.model,
        "material_model": getattr(spec, "model", None),
        "rotation_test": {"test": settings.test, "rot_deg": settings.rot_deg, "tol_rot_deg": settings.tol_rot_deg,
                          "axes": settings.rot_axes, "tol_mm": settings.tol_mm, "jump_mm": settings.jump_mm,
                          "sequential": settings.sequential, "rotations": settings.rotations},
        "n_tets_per_sheet": int(len(spec.tets)) if hasattr(spec, "tets") else None,
        "model_info": model_record(spec),
    }
    if cert is not None:
        summary["certification"] = cert
    if settings.rotations:
        summary["rest_rotations"] = at_rest
    write_json_atomic(ctx.path("workspace.json"), summary)
    drop_cache(ctx)
    return summary


register(Stage(
    name="workspace", params=WorkspaceParams, run=run, optional=("orient", "material", "robot", "reduce"),
    reads=study_reads,
    outputs=("workspace.csv", "workspace.vtp", "workspace.png", "workspace.json"),
    doc="workspace exploration (Fig. 5) with strain validity, loss of control and continuity",
))
