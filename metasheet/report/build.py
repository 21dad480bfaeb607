"""The studies' report: Markdown text from the stages' summaries and picture paths.

Every section names the paper figure it reproduces, shows the picture and a small table,
and the closing list states where our results differ from the paper's (computed from the
numbers, not written in advance).
"""

from __future__ import annotations

from collections.abc import Mapping

from ..mechanics.material import CONSTANT_NAMES
from .columns import columns_section, scene_facts_section
from .constants import constants_section
from .convergence import HEADING as CONVERGENCE_HEADING, convergence_section
from .design import design_section, print_check_section
from .dynamics import HEADING as DYNAMICS_HEADING, dynamics_section
from .model import model_section
from .printed import printed_column, printed_robot_section
from .reduce import reduce_section
from .scale_map import scale_map_section
from .sheet import sheet_dns_section
from .siblings import missing_lines, source_lines
from .uncertainty import SIZE_HEADING, print_rows, robot_spread_rows, size_study_rows, uncertainty_rows


def _maze_strain_rows(z: dict) -> list:
    """The maze's strain rows (absent from maze.json before the strain was recorded)."""
    if "max_strain" not in z:
        return []
    return [("foam: largest principal strain, max [-]", z["max_strain"]),
            (f"foam: samples beyond the strain limit {z['strain_limit']:g}", z["samples_beyond_strain"])]


def _silicone_cell(segments) -> str | list:
    """The maze table's silicone cell: the impossible segments, "none", or not run."""
    if segments is None:
        return "not run in this column (silicone = false)"
    return segments or "none"


def _table(rows: list[tuple[str, object]]) -> str:
    out = ["| quantity | value |", "|---|---|"]
    for k, v in rows:
        out.append(f"| {k} | {_fmt(v)} |")
    return "\n".join(out)


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, (list, tuple)):
        return ", ".join(_fmt(x) for x in v)
    if isinstance(v, dict):
        return "; ".join(f"{k}: {_fmt(x)}" for k, x in v.items())
    return str(v)


def _point_time(w: Mapping, timings: Mapping | None) -> list[tuple[str, object]]:
    """The workspace's wall time and time per tried point, from its manifest's ``timings_s``
    (keys prefixed ``<column>.`` when the stage ran two columns); none when unknown."""
    t = timings or {}
    col = w.get("column")
    wall = t.get(f"{col}.points", t.get("points"))
    per = t.get(f"{col}.s_per_point", t.get("s_per_point"))
    if wall is None or per is None:
        return []
    return [("wall time [s]", round(wall, 1)), ("time per tried point [s]", round(per, 3))]


def _untested_rows(w: dict) -> list:
    """The workspace table's rows on what was left untested: the reaches and rotation tries the
    strain limit stopped (only when the study stops there) and the points whose rotation tries
    ``rot_stop_after`` left out (only when it is set)."""
    rows = []
    if w.get("rot_stop_after"):
        rows.append((f"reached points not rotation-tested ({w['rot_stop_after']} tested in a row passed no axis "
                     "before them on their ray; counted as reachable only)", w.get("rotations_left_out", 0)))
    if not w.get("stop_beyond_strain"):
        return rows
    return [("reaches stopped where the material left the strain limit", w.get("left_domain", 0)),
            ("rotation tries failed beyond the strain limit", w.get("rotations_beyond_strain", 0)), *rows]


def _rotation_test(t: Mapping | None) -> str:
    """One line for the workspace's rotation test (``workspace.json``'s ``rotation_test``)."""
    if not t:
        return "paper (+-10 deg about x, y, z, within 2 deg)"
    jump = f", no jump > {t['jump_mm']:g} mm" if t.get("jump_mm") is not None else ""
    order = ", in sequence" if t.get("sequential") else ""
    return (f"{t['test']} (+-{t['rot_deg']:g} deg about {', '.join(t['axes'])}{order}, within "
            f"{t['tol_rot_deg']:g} deg and {t['tol_mm']:g} mm{jump})")


def _stroke_unused(r: Mapping) -> list[str]:
    """Differences: a wider motor range that reaches the same goals as a narrower one inside it,
    with every reached goal's motors inside the narrower range (the stroke does not bound it)."""
    lims, counts, span = r.get("ranges_deg") or [], list(r["reachable"].items()), r.get("motor_span_deg") or {}
    out = []
    for (wide, n_w), (lo_w, hi_w) in zip(counts, lims):
        for (narrow, n_n), (lo_n, hi_n) in zip(counts, lims):
            s = span.get(wide)
            if (wide != narrow and lo_w <= lo_n and hi_n <= hi_w and n_w == n_n and s
                    and lo_n <= s[0] and s[1] <= hi_n):
                within = f"within the strain limit {r['strain_limit']:g}, " if r.get("stop_beyond_strain") else ""
                out.append(f"Fig. 6: the {wide} and {narrow} deg ranges reach the same {n_w} goals (motors "
                           f"{s[0]:.1f} to {s[1]:.1f} deg): {within}the narrower stroke costs no goal.")
    return out


def _reduced(name: str, summary: Mapping) -> tuple[list[str], list[str]]:
    """Lines on the model a study ran on (``model_info``) and the full model's certification of
    its reduced results (``certification``), and the differences they show."""
    info = summary.get("model_info") or {}
    cert = summary.get("certification")
    lines, diffs = [], []
    if info.get("model") == "reduced":
        lo, hi = info["box_deg"]
        box = (f"{lo[0]:g} to {hi[0]:g} deg (every motor)" if len(set(lo)) == 1 and len(set(hi)) == 1
               else f"{_fmt(lo)} to {_fmt(hi)} deg")
        lines.append(f"Reduced-order model: k = {info['k']} modes, {info['elements']} sampled elements, basis "
                     f"{info['basis_key']}, training box {box}; outside it the full model answers.")
    elif info.get("requested") == "reduced":
        lines.append(f"Full model (reduced requested: {info.get('reason', '')}).")
    if cert:
        scope = "all" if cert["requested"] == 0 or cert["certified"] >= cert["reachable"] else \
            f"a random sample (seed {cert['seed']})"
        solves = cert.get("solves", -1)  # -1: a record from before distinct points shared a solve
        shared = (f" ({cert['certified'] - solves} of them the same goal and motors as another: {solves} full "
                  "solves)" if 0 <= solves < cert["certified"] else "")
        lines.append(f"Full-model certification of the reachable points ({scope}): {cert['certified']} of "
                     f"{cert['reachable']} re-solved{shared}, {cert['disagree']} disagree (rate {cert['rate']:.3g}).")
        for pt in cert["points"][:10]:
            lines.append(f"- point {pt['point']}: reduced error {_fmt(pt['reduced_error_mm'])} mm, full error "
                         f"{_fmt(pt['full_error_mm'])} mm{'' if pt['in_box'] else ' (outside the training box)'}")
        if len(cert["points"]) > 10:
            lines.append(f"- ... {len(cert['points']) - 10} more in {name}.json")
        if cert["disagree"]:
            diffs.append(f"{name}: {cert['disagree']} of {cert['certified']} points the reduced model reached are "
                         "missed by the full model at the same motor angles (see the certification).")
    return ([*lines, ""] if lines else []), diffs


def _plate_line(h: Mapping | None) -> list[str]:
    """The sheet cut from the foam (homogenize's plate.json), when the stage made one."""
    if not h or h.get("plate_ratio_to_bulk") is None:
        return []
    shear = h.get("plate_shear_ratio_to_bulk")
    tail = (f"; its transverse shear H_xz {shear[0]:.2f}, H_yz {shear[1]:.2f} of the bulk's 5/6 G t" if shear else "")
    return [f"The sheet cut from the foam ({h.get('plate_thickness_mm', float('nan')):.2f} mm slabs, free faces, "
            f"plate.json): its membrane and bending stiffness {h['plate_ratio_to_bulk']:.2f} of the bulk plate's "
            f"(geometric mean){tail} (docs/plate.md).", ""]


def build_report(summaries: Mapping[str, dict | None], pictures: Mapping[str, str], *,
                 title: str = "metasheet: reproduction of the paper's studies") -> str:
    """Markdown report.

    summaries : stage name -> its summary dict (``workspace``, ``ranges``, ``anisotropy``,
        ``maze``, ``material``, ``robot``...), None or absent when the stage did not run.
    pictures : stage name -> relative path of its picture.
    """
    s = {k: v for k, v in summaries.items() if v}
    lines = [f"# {title}", ""]
    diffs: list[str] = []
    if "material" in s:
        m = s["material"]
        keys = (*CONSTANT_NAMES, "alpha_percent", "source", "model")
        lines += ["## Constants (paper Section II, FACTS)", "", _table([(k, m[k]) for k in keys if k in m]), ""]
        lines += [f"Chosen (`source = \"auto\"`): {m['why']}.", ""] if m.get("why") else []
    lines += _plate_line(s.get("homogenize"))
    if "continuum" in s:  # the orient stage's verdict: is the printed foam a continuum in this sheet?
        c = s["continuum"]
        lines += [f"**The foam in this sheet ({'a continuum holds' if c['holds'] != 'none' else 'no continuum holds'}"
                  f"): {c['message']}** (docs/continuum-map.md).", ""]
    if "scene" in s:
        sc = s["scene"]
        over = sc.get("overridden_by_orient") or []
        rows = [(k, f"{_fmt(v)}{' (overridden by orient)' if k in over else ''}: {sc['sources'].get(k, '')}")
                for k, v in sc["values"].items()]
        lines += [f"## Scene: {sc['name']} (metasheet/robot/scenes.py; robot and study keys may override)", "",
                  _table(rows), ""]
    # the studies of our own model in pipelines of their own (issue 59): where each came from
    beside = s.get("siblings") or {}
    chart_note = source_lines(beside.get("chart"), "cell")[0] + missing_lines(beside.get("chart"))
    section, found = constants_section(s.get("homogenize"), s.get("chart", {}).get("rows"), s.get("material"),
                                       s.get("robot"), s.get("anisotropy"), s.get("chart", {}).get("shrink"),
                                       cell=s.get("cell"), thickness=summaries.get("sheet_thickness_mm"),
                                       chart_note=chart_note)
    lines += section or missing_lines(beside.get("chart"))  # without the constants, where the chart would be
    diffs += found
    section, found = uncertainty_rows(s["homogenize"], s.get("homogenize_timings")) if "homogenize" in s else ([], [])
    size_note, size_diffs = source_lines(beside.get("cell_size"), "cell")
    size_file = (beside.get("cell_size") or {}).get("file", "homogenize/convergence.json")
    lines += section + size_study_rows(s.get("size_study"), pictures.get("size_study"),
                                       s.get("size_study_timings") or s.get("homogenize_timings"),
                                       source=size_file, preface=size_note)
    lines += missing_lines(beside.get("cell_size"), SIZE_HEADING)
    lines += robot_spread_rows(s.get("robot")) + print_rows(s.get("print_consistency"))
    diffs += found + size_diffs
    if "robot" in s:
        flat = []
        for k, v in sorted(s["robot"].items()):
            flat += [(f"{k}: {k2}", v2) for k2, v2 in sorted(v.items())] if isinstance(v, dict) else [(k, v)]
        pic = [f"![robot]({pictures['robot']})", ""] if "robot" in pictures else []
        lines += ["## Robot, silicone vs foam (reproduces paper Fig. 4 and Fig. 8)", "", *pic, _table(flat), ""]
    section, found = sheet_dns_section(s.get("sheet_dns"), pictures, s.get("material"))
    lines += section
    diffs += found
    section, found = printed_robot_section(s.get("printed"), pictures)
    lines += section
    diffs += found
    section, found = scale_map_section(s.get("scale_map"), pictures)
    lines += section
    diffs += found
    section, found = design_section(s.get("design_json"), pictures)
    lines += section
    diffs += found
    section, found = print_check_section(s.get("print_check"))
    lines += section
    diffs += found
    section, found = model_section(s.get("robot"), s.get("anisotropy"))
    lines += section
    diffs += found
    conv_note, conv_diffs = source_lines(beside.get("convergence"), "robot")
    section, found = convergence_section(s.get("convergence"), summaries.get("meshes") or {}, preface=conv_note)
    lines += section + missing_lines(beside.get("convergence"), CONVERGENCE_HEADING)
    diffs += found + conv_diffs
    section, found = reduce_section(s.get("reduce_json"), summaries.get("reduce_seconds"))
    lines += section
    diffs += found
    section, found = reduce_section(s.get("reduce_reproduction_json"))
    if section:  # the reproduction column's own basis
        section[0] += ": the reproduction column's basis"
    lines += section
    diffs += [f"Reproduction column: {d}" for d in found]
    lines += scene_facts_section(s.get("scene"), s.get("robot"), s.get("columns") or {})
    printed_note, printed_diffs = source_lines(beside.get("printed"), "robot")
    section = columns_section(s.get("columns") or {}, pictures, printed_column(s.get("printed_column")),
                              printed_note)
    lines += section + (missing_lines(beside.get("printed")) if section else [])
    diffs += printed_diffs if section else []
    if "workspace" in s:
        w = s["workspace"]
        lines += ["## Workspace exploration (reproduces paper Fig. 5)", "",
                  f"![workspace]({pictures.get('workspace', 'workspace.png')})", "",
                  _table([("goal points", w["points"]), ("rays", w["rays"]), ("points tried", w["tried"]),
                          ("reachable", w["reachable"]),
                          ("equilibrium failures (counted unreachable)", w.get("solver_failures", 0)), *[(f"class: {k}", v) for k, v in w["counts"].items()],
                          ("max principal strain", w["max_strain"]),
                          (f"points beyond the strain limit {w['strain_limit']}", w["invalid_strain"]),
                          *_untested_rows(w),
                          ("smallest Jacobian singular value", w["min_singular_value"]),
                          ("connected components", w["components"]),
                          ("continuity paths passed / tested", f"{w['edges_passed']} / {w['edges_tested']}"),
                          *_point_time(w, s.get("workspace_timings")),
                          ("executor", w["executor"]), ("robot model", w["model"]),
                          ("rotation test", _rotation_test(w.get("rotation_test")))]), ""]
        section, found = _reduced("workspace", w)
        lines += section
        diffs += found
        if abs(w["points"] - 1800) > 200:
            diffs.append(f"Fig. 5: {w['points']} goal points instead of the paper's ~1,800 (a smaller grid).")
        full = w["counts"].get("3 rotations", 0)
        test = (w.get("rotation_test") or {}).get("test", "paper")
        if test != "paper":
            diffs.append(f"Fig. 5: rotation test {_rotation_test(w['rotation_test'])}, as the authors' code ran it "
                         "(the paper describes +-10 deg about x, y and z within 2 deg): class 1 = the y rotation passes.")
        elif w["reachable"] and full < 0.2 * w["reachable"]:
            diffs.append(f"Fig. 5: only {full} of {w['reachable']} reachable points allow all three +-rotations; "
                         "the paper shows full 6-DOF control in a whole area around the rest pose.")
        if w.get("stop_beyond_strain"):
            diffs.append(f"Fig. 5 (beyond the paper): the study stays within the strain limit {w['strain_limit']}: "
                         "a ray ends at its first point beyond it and a rotation try counts only within it "
                         f"({w.get('rotations_beyond_strain', 0)} tries failed there); the paper counts them all.")
        if w["invalid_strain"]:
            diffs.append(f"Fig. 5 (beyond the paper): {w['invalid_strain']} reachable points exceed the strain "
                         f"limit {w['strain_limit']}: the paper counts them, we flag them as outside the "
                         "homogenisation's domain of validity (its workspace is overestimated, as its authors say).")
        if w["components"] > 1:
            diffs.append(f"Continuity (beyond the paper): the reachable set splits into {w['components']} "
                         "components linked by no tested inverse path.")
    if "ranges" in s:
        r = s["ranges"]
        lines += ["## Motor ranges (reproduces paper Fig. 6)", "",
                  f"![ranges]({pictures.get('ranges', 'ranges.png')})", "",
                  _table([*[(f"reachable, {k} deg", v) for k, v in r["reachable"].items()],
                          *[(f"of which by a narrower range's path, {k} deg", v)
                            for k, v in r.get("via_narrower", {}).items() if v],
                          *[(f"motors of the reached goals, {k} deg", f"{v[0]:.1f} to {v[1]:.1f}")
                            for k, v in r.get("motor_span_deg", {}).items() if v],
                          ("workspaces nest", r["nested"])]), ""]
        section, found = _reduced("ranges", r)
        lines += section
        diffs += found
        via = {k: v for k, v in r.get("via_narrower", {}).items() if v}
        if via:
            diffs.append(f"Fig. 6 (method): the continuation of a range missed points a narrower range's path reached "
                         f"({', '.join(f'{k} deg: {v}' for k, v in via.items())}); that path is a motor path inside "
                         "the wider range from rest, so they are counted reachable there.")
        diffs += _stroke_unused(r)
        if not r["nested"]:
            diffs.append(f"Fig. 6: the workspaces do not nest exactly: {r['violations']} (continuation paths "
                         "differ between ranges).")
    if "anisotropy" in s:
        a = s["anisotropy"]
        rot = a["rod_rotation_deg"]
        lines += ["## Anisotropy sweep (reproduces paper Fig. 7)", "",
                  f"![anisotropy]({pictures.get('anisotropy', 'anisotropy.png')})", "",
                  "| alpha [%] | rod rotation, pull [deg] | rod rotation, push [deg] | lateral, pull [mm] | "
                  "lateral, push [mm] |", "|---|---|---|---|---|"]
        def val(v):
            return "not converged" if v is None else f"{v:.3g}"

        for i, al in enumerate(a["alpha_percent"]):
            lines.append(f"| {al:.3g} | {val(rot['pull'][i])} | {val(rot['push'][i])} | "
                         f"{val(a['lateral_mm']['pull'][i])} | {val(a['lateral_mm']['push'][i])} |")
        lines.append("")
        lines += _reduced("anisotropy", a)[0]
        for f in a.get("not_converged", []):
            diffs.append(f"Fig. 7: at alpha {f['alpha_percent']:.3g} % the {f['case']} case did not converge "
                         f"beyond a motor change of {f['reached_deg']:.3g} deg (equilibrium lost: a limit point "
                         "of the sheets, or the solver); that point is left out, not guessed.")

        def finite(v):
            return [abs(x) for x in v if x is not None] or [0.0]
        r0 = max(finite([rot["pull"][0], rot["push"][0]]))
        r1 = max(finite([rot["pull"][-1], rot["push"][-1]]))
        if r0 > 0.05 * max(r1, 1e-12):
            diffs.append(f"Fig. 7: isotropic sheets still turn the rod by {r0:.3g} deg ({r1:.3g} deg at the design "
                         "alpha); the paper finds no rotation without anisotropy.")
        lat0 = max(finite([a["lateral_mm"]["pull"][0], a["lateral_mm"]["push"][0]]))
        if lat0 < 1.0:
            diffs.append(f"Fig. 7/8: with isotropic sheets the effector moves sideways by only {lat0:.3g} mm: the "
                         "static model shows no buckling-like lateral translation as the real silicone robot does.")
        req, app = a["requested_deg"], a["applied_deg"]
        if abs(abs(app["pull"]) - req["pull"]) > 0.5 or abs(abs(app["push"]) - req["push"]) > 0.5:
            diffs.append(f"Fig. 7: the motor range allowed a pull of {abs(app['pull']):.3g} deg and a push of "
                         f"{abs(app['push']):.3g} deg from rest (the paper: {req['pull']:g} and {req['push']:g}).")
    if "maze" in s:
        z = s["maze"]
        lines += ["## Maze (paper Section V-B3)", "", f"![maze]({pictures.get('maze', 'maze.png')})", "",
                  _table([("segments", z["segments"]), ("samples", z["samples"]), ("duration [s]", z["duration_s"]),
                          ("foam: impossible segments", z["foam_impossible_segments"] or "none"),
                          ("silicone: impossible segments", _silicone_cell(z["silicone_impossible_segments"])),
                          ("motor angles [deg]", f"{z['motor_min_deg']:.3g} to {z['motor_max_deg']:.3g}"),
                          ("within motor limits", z["within_motor_limits"]),
                          ("replay tracking error, max [mm]", z["max_track_mm"]),
                          ("replay tracking error, max [deg]", z["max_track_deg"]),
                          *_maze_strain_rows(z)]), ""]
        section, found = _reduced("maze", z)
        lines += section
        diffs += found
        if z["foam_impossible_segments"]:
            diffs.append(f"Maze: segments {z['foam_impossible_segments']} are infeasible even with the foam "
                         "(the paper solved its maze).")
        if z.get("samples_beyond_strain"):
            diffs.append(f"Maze: {z['samples_beyond_strain']} of {z['samples']} foam samples strain the sheets beyond "
                         f"{z['strain_limit']:g}, where the homogenised constants no longer hold.")
        if z["silicone_impossible_segments"] == []:
            diffs.append("Maze: silicone sheets solved every segment; the paper could not solve its maze with them.")
    dyn_lines, dyn_diffs = dynamics_section(s.get("dynamics") or {}, pictures)
    lines += source_lines(beside.get("dynamics"), "robot")[0] + dyn_lines
    lines += missing_lines(beside.get("dynamics"), DYNAMICS_HEADING)
    diffs += dyn_diffs
    standin = [k for k in ("workspace", "ranges", "anisotropy", "maze") if k in s and s[k].get("model") == "standin"]
    if standin:
        diffs.append(f"{', '.join(standin)}: computed on the analytic stand-in robot (model = 'standin'), "
                     "not the FEM robot: these numbers test the study logic, not the physics.")
    lines += ["## Differences from the paper", ""]
    lines += [f"- {d}" for d in diffs] or ["- none found by the automatic checks."]
    lines.append("")
    return "\n".join(lines)
