"""Stage ``printed``: the printed robot, print by print, claim by claim against the paper's
physical robot (issue 62, items 4 and 5; docs/printed-sheet.md).

For each print the ``sheet`` stage solved (its seeds, voxel size and gauge), the robot's two
sheets are corotational superelements of their grips with the print's linear DNS stiffness
(:mod:`metasheet.studies.printed_adapter`). Their validity comes from the print's own walls
(:mod:`metasheet.studies.printed_limits`, one work unit per printed sheet): the walls' first
self-contact along the searched motor directions, the walls' strain rate per motor, and where
each binds; with ``touch`` the first prints' binding direction is searched again on the
finite-strain voxel robot (:mod:`metasheet.studies.nonlinear_touch`). Within them,
:mod:`metasheet.studies.printed_claims` computes the paper's claims (the rod rolled both ways,
pulling 15 deg and pushing 35 deg; 10 deg about each axis at rest),
and the stage states each claim's status over the prints and the print-to-print spread.

Outputs: ``printed.json`` (per print: the walls' limits, the claims; the spread and the
verdicts), ``printed_robot.png`` (the rod's roll against the motor travel per print, where the
walls touch), and the report's section "The printed robot against the paper's robot".
"""

from __future__ import annotations

import json
import shutil

import numpy as np
from pydantic import Field

from ...errors import ConfigError
from ..artefacts import read_material, read_orient
from ..manifest import write_bytes_atomic, write_json_atomic
from ..registry import Params, Stage, StageContext, register
from .sheet import cell_design, check_voxel

#: statuses from best to worst: a claim over the prints is the worst print's
STATUSES = ("predicted", "predicted up to the walls' limit", "not predicted")


class PrintedParams(Params):
    realisations: int | None = Field(None, ge=1, le=20, description="the sheet stage's first n prints (None: all)")
    contact: bool = Field(True, description="search each printed sheet's walls for their first self-contact (on "
                          "the fields the sheet stage kept, sheet.walls, or else one voxel DNS with its fields per "
                          "sheet: 3 to 7 minutes and about 6 GB each at 0.25 mm on the paper's sheet); false: no "
                          "walls' limit (the claims then hold the model alone)")
    motor_directions: bool = Field(False, description="search each motor alone too (12 more directions), not only "
                                   "all six and each sheet's three, up and down")
    map_plane: int = Field(16, ge=0, le=360, description="the validity map: this many directions around the plane "
                           "of the two sheets' common modes (holding the six base directions; 1 to 8 s each per "
                           "sheet at 0.25 mm: about a minute a sheet)")
    map_rays: bool = Field(False, description="the validity map on the rays of Fig. 5: the walls searched along the "
                           "motor direction of each ray of the workspace grid (first order; 62 rays by default, 3 to "
                           "9 s each per sheet at 0.25 mm: about 5 minutes a sheet)")
    touch: int = Field(0, ge=0, le=20, description="the first n prints' binding direction searched again on the "
                       "finite-strain voxel robot (both sheets neo-Hookean, the rod held where the print's linear "
                       "rest model puts it, its miss recorded): its first touch replaces the first-order one there "
                       "and the box is the first contact over the directions again (a pose is 7 to 15 minutes at "
                       "0.25 mm, up to 8 poses: one to two hours a print); 0: first order only")
    touch_tol_deg: float = Field(0.02, gt=0, le=5, description="the finite-strain touch's bracket [deg]")
    search_deg: float = Field(10.0, gt=0, le=90, description="the contact search's motor travel [deg]")
    strain_limit: float = Field(0.3, gt=0, le=5, description="the walls' strain limit [-] (the neo-Hookean law's "
                                "range, not NinjaFlex's failure: docs/printed-sheet.md)")
    pull_deg: float = Field(15.0, gt=0, le=90, description="all motors pulled by (paper Fig. 7) [deg]")
    push_deg: float = Field(35.0, gt=0, le=90, description="all motors pushed by (paper Fig. 7) [deg]")
    rot_deg: float = Field(10.0, gt=0, le=45, description="rotation about each axis at rest (paper Fig. 5) [deg]")
    tol_mm: float = Field(1.0, gt=0, le=10, description="position tolerance of the rotations [mm]")
    tol_deg: float = Field(2.0, gt=0, le=10, description="rotation tolerance of the rotations [deg]")
    studies: bool = Field(True, description="run the paper's Fig. 5 (workspace and rotation test), Fig. 6 (motor "
                          "ranges) and the maze on each print's robot, within its walls' box")
    n_azimuth: int = Field(12, ge=2, le=720, description="workspace grid: ray directions around the rod [-]")
    n_elevation: int = Field(5, ge=1, le=181, description="workspace grid: elevation rings [-]")
    n_steps: int = Field(37, ge=1, le=10000, description="workspace grid: points per ray before thinning [-]")
    extent_mm: float = Field(20.0, gt=0, le=500, description="workspace grid: reach along and across the rod [mm]")
    ranges: list[tuple[float, float]] = Field([(0.0, 90.0), (10.0, 80.0), (20.0, 70.0)], min_length=1,
                                              description="Fig. 6's motor ranges, widest first [deg]")
    maze_tilt_deg: float = Field(1.5, gt=0, le=45, description="the maze's tilt, which rolls the marble [deg] "
                                 "(the prediction column's: a marble on PLA rolls from well under 1 deg)")
    maze_tol_deg: float = Field(0.3, gt=0, le=10, description="the maze's orientation tolerance [deg]")
    maze_tol_mm: float = Field(0.5, gt=0, le=10, description="the maze's position tolerance [mm]")
    max_step_deg: float = Field(5.0, gt=0, le=90, description="largest motor change per control step [deg]")
    rot_weight: float = Field(50.0, gt=0, description="inverse QP weight of rotation errors [mm/rad]")
    picture: bool = Field(True, description="write printed_robot.png")
    ladder: list[float] = Field([], max_length=8, description="voxel sizes besides the sheet stage's own at which "
                                "the first print's two sheets are solved again: its figures converged in the voxel "
                                "size, with their Richardson limits (three sizes or more) [mm]")
    other_gauge: bool = Field(False, description="solve the first print under the other gauge assumption too (the "
                              "sheet stage's voxel size): the unpublished gauge's share of every figure")
    resume: bool = Field(True, description="keep each printed sheet's walls' limits as it finishes, so an "
                         "interrupted run resumes")


def grip_stiffnesses(rows) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each print's (normal, mirrored) grip stiffness (24, 24) from the sheet stage's
    ``realisations`` rows; a :class:`ConfigError` when a row has none (an older sheet stage)."""
    out = []
    for r in rows:
        K = [r["sheets"][label].get("K") for label in ("normal", "mirrored")]
        if any(k is None or np.shape(k) != (24, 24) for k in K):
            raise ConfigError(f"sheet: sheet_dns.json, seed {r.get('seed')}: no (24, 24) grip stiffness K (written "
                              "before issue 62): run the sheet stage again (metasheet run --stage sheet --force)")
        out.append((np.asarray(K[0], float), np.asarray(K[1], float)))
    return out


def _worst(statuses) -> str:
    return max(statuses, key=STATUSES.index)


def _spread(values) -> dict:
    v = np.asarray([x for x in values if x is not None], float)
    if not len(v):
        return {"mean": None, "min": None, "max": None, "std": None, "n": 0}
    return {"mean": float(v.mean()), "min": float(v.min()), "max": float(v.max()),
            "std": float(v.std(ddof=1)) if len(v) > 1 else None, "n": int(len(v))}


def _claims(rows: list, studies: bool) -> tuple[dict, dict]:
    """(claims, spread): each claim's status over the prints (the worst print's), and the
    spread of the figures behind them. With ``studies``, each print's Fig. 5, Fig. 6 and maze
    summary gets its verdict, read as the continuum columns' are
    (:func:`metasheet.report.columns.study_verdict`)."""
    from ...report.columns import study_verdict

    claims = {"roll": _worst(r["roll"]["status"] for r in rows),
              "rotations": _worst(r["rotations"]["status"] for r in rows)}
    spread = {"valid_deg": _spread(r["limits"]["valid_deg"] if r["limits"] else None for r in rows),
              "rod_rotation_pull_deg": _spread(r["roll"]["pull"]["rod_rotation_deg"] for r in rows),
              "rod_rotation_push_deg": _spread(r["roll"]["push"]["rod_rotation_deg"] for r in rows),
              "smallest_singular_value": _spread(min(r["rotations"]["rest_singular_values_mm_per_rad"]) for r in rows)}
    rays = [[x["contact_mm"] for x in r["map"]["rays"] if x["contact_mm"] is not None]
            for r in rows if r.get("map") and r["map"]["rays"]]
    if rays:
        spread["ray_contact_mm_min"] = _spread(min(v) if v else None for v in rays)
        spread["ray_contact_mm_median"] = _spread(float(np.median(v)) if v else None for v in rays)
    if not studies:
        return claims, spread
    for key in ("workspace", "ranges", "maze"):
        for r in rows:
            text, ok = study_verdict(key, r["studies"][key])
            r["studies"][key]["verdict"] = {"text": text, "status": "predicted" if ok else "not predicted"}
        claims[key] = _worst(r["studies"][key]["verdict"]["status"] for r in rows)
    ws = [r["studies"]["workspace"] for r in rows]
    spread["workspace_reachable"] = _spread(w["reachable"] for w in ws)
    spread["workspace_full_control"] = _spread(w["counts"].get("3 rotations", 0) for w in ws)
    spread["workspace_left_domain"] = _spread(w["left_domain"] for w in ws)
    mz = [r["studies"]["maze"] for r in rows]
    spread["maze_segments_solved"] = _spread(m["segments"] - len(m["foam_impossible_segments"]) for m in mz)
    return claims, spread


def _resolution(ctx: StageContext, p: PrintedParams, dns: dict, first: dict, robot, params) -> dict:
    """The first print's figures at the ``ladder``'s voxel sizes beside the sheet stage's own,
    with their Richardson fits, and under the other gauge (``other_gauge``); {} with neither.
    Each sheet is a resumable executor unit."""
    from ...sheet.dns import dns_sheet
    from ...studies.dns_ladder import ladder_fits, ladder_row, study_row
    from ...studies.resume import UnitCache
    from .sheet import sheet_prints

    voxel, gauge = float(dns["voxel_mm"]), dns["gauge"]
    sizes = sorted({float(v) for v in p.ladder} - {voxel}, reverse=True)
    other = "point" if gauge == "seed" else "seed"
    jobs = [(v, gauge) for v in sizes] + ([(voxel, other)] if p.other_gauge else [])
    if not jobs:
        return {}
    for v, _ in jobs:
        check_voxel(v, cell_design(ctx).bead_width, "printed.ladder")
    prints = [s for v, g in jobs for s in sheet_prints(ctx, [first["seed"]], g, v, 1e-6, 200_000_000)]
    cache = UnitCache(ctx.workdir.parent / ".printed.units" if p.resume else None)
    solved = cache.map(ctx.executor, dns_sheet, prints, progress=lambda d, n: ctx.progress("ladder", d, n))
    hom = tuple(np.asarray(dns["homogenised_K"][lab], float) for lab in ("normal", "mirrored"))
    rows = {(v, g): ladder_row(v, solved[2 * i:2 * i + 2], hom, robot, params) for i, (v, g) in enumerate(jobs)}
    own = study_row(voxel, gauge, first, dns["homogenised_robot"])
    out = {}
    if sizes:
        ladder = sorted([own] + [rows[(v, gauge)] for v in sizes], key=lambda r: -r["voxel_mm"])
        out["ladder"] = {"seed": first["seed"], "gauge": gauge, "rows": ladder, "richardson": ladder_fits(ladder)}
    if p.other_gauge:
        r = rows[(voxel, other)]
        out["other_gauge"] = {"seed": first["seed"], "gauge": other, "voxel_mm": voxel, "row": r, "own": own,
                              "ratio": {"rod_roll": r["rod_roll"] / own["rod_roll"],
                                        "geometric_mean": [a / b for a, b in zip(r["geometric_mean_ratio"],
                                                                                 own["geometric_mean_ratio"])],
                                        "singular_values": [a / b for a, b in zip(r["singular_values"],
                                                                                  own["singular_values"])]}}
    return out


def _rays(p: PrintedParams, J) -> tuple[dict, list[dict]]:
    """The validity map's ray directions (:func:`~metasheet.studies.printed_limits.ray_directions`)
    on the rays of the stage's workspace grid, and each ray's description."""
    from ...studies.grid import star_grid
    from ...studies.printed_limits import ray_directions

    grid = star_grid(n_azimuth=p.n_azimuth, n_elevation=p.n_elevation, n_steps=p.n_steps,
                     extent_axial=p.extent_mm, extent_lateral=p.extent_mm)
    dirs, per = ray_directions(J, grid.directions)
    meta = [{"name": name, "direction": [float(v) for v in e], "azimuth": int(a), "elevation": int(el),
             "mm_per_deg": k}
            for name, e, a, el, k in zip(dirs, grid.directions, grid.azimuth, grid.elevation, per)]
    return dirs, meta


def _touched(ctx: StageContext, p: PrintedParams, limits, searched, prints, Ks, robot, refs, cache) -> list:
    """The first ``p.touch`` prints' limits with their binding direction (among each print's
    ``searched`` directions, name -> offsets) searched again on the finite-strain voxel robot
    (:mod:`metasheet.studies.nonlinear_touch`), one unit per print."""
    from ...robot.condensed import condensed_robot_S
    from ...studies.nonlinear_touch import TouchUnit, refine, touch_unit

    todo = [i for i, lim in enumerate(limits[:p.touch]) if lim["valid_deg"] is not None]
    units = [TouchUnit((prints[2 * i], prints[2 * i + 1]), robot,
                       tuple(map(tuple, condensed_robot_S(*Ks[i], robot, refs))), limits[i]["binding"],
                       tuple(searched[i][limits[i]["binding"]]), limits[i]["valid_deg"], p.touch_tol_deg)
             for i in todo]
    found = cache.map(ctx.executor, touch_unit, units, progress=lambda d, n: ctx.progress("printed touch", d, n),
                      journal=True)  # an hour's search a print: a killed run resumes at its last pose
    out = list(limits)
    for i, t in zip(todo, found):
        out[i] = refine(limits[i], t)
    return out


def _kept_walls(ctx: StageContext, spec):
    """The sheet stage's walls' fields of the print ``spec`` (its ``walls``), or None."""
    from ...sheet.wall_fields import WallFields
    from .sheet import walls_file

    path = ctx.inputs["sheet"] / walls_file(spec.label, spec.seed)
    if not path.is_file():
        return None
    return WallFields.load(path, {"label": spec.label, "seed": int(spec.seed), "gauge": spec.gauge,
                                  "voxel_mm": float(spec.voxel_mm)})


def _studies(p: PrintedParams):
    """The :class:`~metasheet.studies.printed_studies.PrintStudies` of the stage's keys: the
    workspace stage's grid and paper rotation test, the maze stage's path."""
    from ...studies.grid import star_grid
    from ...studies.maze import MazeSettings
    from ...studies.printed_studies import PrintStudies
    from ...studies.workspace import WorkspaceSettings
    from .maze import DEFAULT_PATH

    grid = star_grid(n_azimuth=p.n_azimuth, n_elevation=p.n_elevation, n_steps=p.n_steps,
                     extent_axial=p.extent_mm, extent_lateral=p.extent_mm)
    settings = WorkspaceSettings.for_test("paper", tol_mm=p.tol_mm, rot_deg=p.rot_deg, tol_rot_deg=p.tol_deg,
                                          rot_stop_after=2, strain_limit=p.strain_limit)
    maze = MazeSettings(tilt_deg=p.maze_tilt_deg, tol_deg=p.maze_tol_deg, tol_mm=p.maze_tol_mm)
    return PrintStudies(grid, settings, tuple(map(tuple, p.ranges)), tuple(map(tuple, DEFAULT_PATH)), maze)


def run(ctx: StageContext) -> dict:
    from ...robot.condensed import grip_motions_per_motor
    from ...sheet.grips import grip_references
    from ...studies.printed_adapter import printed_spec
    from ...studies.printed_claims import roll_claim, rotation_claim
    from ...studies.printed_limits import WallUnit, combine, directions, plane_directions, validity_map, wall_unit
    from ...studies.printed_studies import print_studies
    from ...studies.resume import UnitCache
    from .sheet import scene_robot, sheet_prints

    p: PrintedParams = ctx.params
    dns = json.loads((ctx.inputs["sheet"] / "sheet_dns.json").read_text())
    rows = dns["realisations"][:p.realisations]
    Ks = grip_stiffnesses(rows)
    orient = read_orient(ctx.inputs["orient"])
    robot = scene_robot(ctx, orient.sheets(), read_material(ctx.inputs["material"]))
    refs = grip_references(orient.sheet_params)
    motor_range = (float(np.degrees(np.min(robot.angle_min))), float(np.degrees(np.max(robot.angle_max))))
    limits = maps = [None] * len(rows)
    if p.contact:
        prints = sheet_prints(ctx, [r["seed"] for r in rows], dns["gauge"], dns["voxel_mm"], 1e-6, 200_000_000)
        plane = plane_directions(p.map_plane)
        units, ray_meta, searched = [], [], []
        for i, (Ka, Kb) in enumerate(Ks):
            Ga, Gb, J = grip_motions_per_motor(Ka, Kb, robot, refs)
            rays, meta = _rays(p, J) if p.map_rays else ({}, [])
            dirs = tuple({**directions(p.motor_directions), **plane, **rays}.items())
            ray_meta.append(meta)
            searched.append(dict(dirs))
            units += [WallUnit(prints[2 * i + j], tuple(map(tuple, G)), dirs, p.search_deg, p.strain_limit,
                               _kept_walls(ctx, prints[2 * i + j])) for j, G in enumerate((Ga, Gb))]
        cache = UnitCache(ctx.workdir.parent / ".printed.units" if p.resume else None)
        found = cache.map(ctx.executor, wall_unit, units, progress=lambda d, n: ctx.progress("printed walls", d, n))
        limits = [combine(found[2 * i], found[2 * i + 1]) for i in range(len(rows))]
        if p.touch:
            limits = _touched(ctx, p, limits, searched, prints, Ks, robot, refs, cache)
        maps = [validity_map(lim, plane, meta) for lim, meta in zip(limits, ray_meta)]
    out_rows = []
    for i, (r, (Ka, Kb)) in enumerate(zip(rows, Ks)):
        ctx.progress("claims", i, len(rows))
        lim = limits[i] or {}
        spec = printed_spec(robot, Ka, Kb, refs, label=f"seed {r['seed']}", motor_range=motor_range,
                            valid_deg=lim.get("valid_deg"), max_step_deg=p.max_step_deg, rot_weight=p.rot_weight,
                            wall_strain_per_deg=lim.get("strain_per_deg"))
        row = {"seed": r["seed"], "limits": limits[i], "map": maps[i],
               "roll": roll_claim(spec, p.pull_deg, p.push_deg, lim),
               "rotations": rotation_claim(spec, p.rot_deg, p.tol_mm, p.tol_deg)}
        if p.studies:
            row["studies"] = print_studies(spec, _studies(p), executor=ctx.executor,
                                           progress=lambda d, j, n, i=i: ctx.progress(f"print {i + 1}: {d}", j, n))
        out_rows.append(row)
    claims, spread = _claims(out_rows, p.studies)
    resolution = _resolution(ctx, p, dns, rows[0], robot, orient.sheet_params)
    out = {"method": "each print's two sheets as corotational superelements of their grips (the sheet stage's "
                     "linear DNS stiffness, metasheet.studies.printed_adapter), valid to the walls' first "
                     "self-contact (first order, metasheet.studies.printed_limits)",
           "voxel_mm": dns["voxel_mm"], "gauge": dns["gauge"], "seeds": [r["seed"] for r in rows],
           "params": p.model_dump(), "motor_range_deg": list(motor_range),
           "realisations": out_rows, "claims": claims, "spread": spread, **resolution}
    write_json_atomic(ctx.path("printed.json"), out)
    shutil.rmtree(ctx.workdir.parent / ".printed.units", ignore_errors=True)
    if p.picture:
        from ...viz.printed_robot import printed_robot_picture

        write_bytes_atomic(ctx.path("printed_robot.png"), printed_robot_picture(out))
    ctx.progress("done", len(rows), len(rows))
    return {"claims": claims, "valid_deg": [r["limits"]["valid_deg"] if r["limits"] else None for r in out_rows]}


register(
    Stage(
        name="printed",
        params=PrintedParams,
        run=run,
        requires=("sheet", "cell", "orient", "material", "printmap", "robot"),
        outputs=("printed.json",),
        doc="the printed robot print by print (superelement sheets from the voxel DNS) within its walls' limits "
            "(first self-contact, wall strain), claim by claim against the paper's physical robot",
    )
)
