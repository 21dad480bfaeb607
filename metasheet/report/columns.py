"""The report's side-by-side section: each of the paper's claims, its reproduction and the
printed foam's prediction (:mod:`metasheet.pipeline.column`), with a verdict.

A verdict is computed from the numbers, never written by hand: "reproduced" when the
reproduction column's figure meets the paper's statement as the row's test reads it,
"not reproduced" with the figure that misses otherwise.
"""

from __future__ import annotations

from collections.abc import Mapping

#: The paper's statement behind each figure (paper-6dof-anisotropic-soft-robot.md).
STATEMENTS = {
    "workspace": "Fig. 5 / IV-B: \"at the initial position (center of workspace) and in a whole area around it, "
                 "we have a full 6 DOF control\" (+-10 deg about x, y, z within 2 deg)",
    "ranges": "Fig. 6: narrower motor ranges give nested, smaller workspaces",
    "anisotropy": "Fig. 7: the rod rotation appears progressively with alpha (none when isotropic), pulling all "
                  "motors 15 deg or pushing them 35 deg",
    "maze": "V-B3: the foam robot guides the marble along the whole maze; silicone sheets cannot",
}


#: The share of the reachable points near rest with full control that reads as "a whole area
#: around it": most of them, so that one grid point next to rest does not decide the verdict.
NEAR_REST_SHARE = 0.5


def _workspace(w: Mapping) -> tuple[str, bool]:
    full = w["counts"].get("3 rotations", 0)
    text = f"{full} of {w['reachable']} reachable points pass all three rotations"
    rest = (w.get("rest_rotations") or {}).get("ok")
    if rest is not None:
        text += f"; at rest {sum(rest.values())}/3 axes"
    near = w.get("near_rest")
    if near:
        text += (f"; within {near['radius_mm']:g} mm of rest {near['full_control']} of {near['reachable']} "
                 "reachable points do")
    share = (near or {}).get("share")
    ok = bool(rest and all(rest.values()) and share is not None and share > NEAR_REST_SHARE)
    return text, ok


def _ranges(r: Mapping) -> tuple[str, bool]:
    via = r.get("via_narrower", {})
    counts = ", ".join(f"{k}: {v}" + (f" ({via[k]} by a narrower range's path)" if via.get(k) else "")
                       for k, v in r["reachable"].items())
    n = list(r["reachable"].values())
    lims = r.get("ranges_deg") or [[-i, i] for i in range(len(n), 0, -1)]  # without them: widest first
    shrinking = all(n[a] > n[b] for a in range(len(n)) for b in range(len(n))  # each strictly smaller than
                    if a != b and lims[a][0] <= lims[b][0] and lims[b][1] <= lims[a][1])  # those containing it
    return f"reachable {counts}; nested: {r['nested']}", bool(r["nested"] and shrinking)


def _anisotropy(a: Mapping) -> tuple[str, bool]:
    rot = a["rod_rotation_deg"]
    ends = [abs(v) for v in (rot["pull"][-1], rot["push"][-1]) if v is not None]
    starts = [abs(v) for v in (rot["pull"][0], rot["push"][0]) if v is not None]
    if not ends or not starts:
        return "not converged at the sweep's ends", False
    grows = max(starts) <= 0.05 * max(ends)
    app = a["applied_deg"]
    text = (f"rod rotation {max(starts):.3g} deg isotropic, pull {_deg(rot['pull'][-1])} / push "
            f"{_deg(rot['push'][-1])} at alpha {a['alpha_percent'][-1]:.3g} % (motors {abs(app['pull']):.3g} / "
            f"{abs(app['push']):.3g} deg)")
    req = a["requested_deg"]
    full_stroke = abs(abs(app["pull"]) - req["pull"]) <= 0.5 and abs(abs(app["push"]) - req["push"]) <= 0.5
    return text, bool(grows and full_stroke)


def _maze(z: Mapping) -> tuple[str, bool]:
    foam, sil = z["foam_impossible_segments"], z["silicone_impossible_segments"]
    sil_text = "not run (silicone = false)" if sil is None else f"{len(sil)} impossible"
    text = (f"foam: {len(foam)} of {z['segments']} segments impossible; silicone: {sil_text} "
            f"(tilt {z.get('tilt_deg', 'n/a')} deg)")
    return text, not foam and (sil is None or bool(sil))


def _deg(v) -> str:
    return "n/a" if v is None else f"{v:.3g}"


ROWS = {"workspace": _workspace, "ranges": _ranges, "anisotropy": _anisotropy, "maze": _maze}


def study_verdict(study: str, summary: Mapping) -> tuple[str, bool]:
    """(text, met) of the paper's statement for ``study`` (a key of :data:`STATEMENTS`) on a
    column's ``summary`` (the study stage's JSON, or the printed stage's per-print summary in
    the same keys)."""
    return ROWS[study](summary)


def columns_section(columns: Mapping[str, Mapping[str, dict]], pictures: Mapping[str, str],
                    printed: Mapping[str, str] | None = None, printed_note: list[str] | None = None) -> list[str]:
    """Markdown lines: per study that ran a reproduction column, the paper's statement, the
    reproduction, the prediction and the verdict; ``columns`` is study -> column -> summary,
    ``pictures`` "<study>/<column>" -> picture path. ``printed``: study -> the printed robot's
    cell (:func:`metasheet.report.printed.printed_column`), a third column when given, with
    ``printed_note`` (lines: where it came from) under the table. Empty when no study ran a
    reproduction."""
    studies = [k for k in ROWS if "reproduction" in columns.get(k, {})]
    if not studies:
        return []
    third = bool(printed)
    out = ["## The paper, reproduced and predicted", "",
           "The **reproduction** runs each study as the paper's figures were made: the published constants under "
           "the authors' force field, no strain stop, on the authors' kind of mesh (uniform P1, 5 mm; "
           "`metasheet/pipeline/column.py`). Its counts are that mesh's: how far it is from the converged mesh "
           "(the Jacobian, the rod's compliance) is in the section \"Mesh convergence of the robot\" when "
           "`pipelines/convergence.toml` ran beside this pipeline, and docs/paper.md (\"Which results rest on "
           "the coarse mesh\") gives the rest-pose test on the converged mesh. The **prediction** runs it "
           "on the printed foam's homogenised constants, within the homogenisation's strain limit."
           + (" The **printed robot** runs it on each print's own sheets (their voxel DNS, the rod's motion "
              "within the walls' first self-contact; the section \"The printed robot against the paper's robot\" "
              "of that pipeline's report): the claim's status over the prints, then each print's figure."
              if third else ""), "",
           "| figure | the paper | reproduction | prediction |" + (" printed robot |" if third else "")
           + " verdict |", "|---|---|---|---|" + ("---|" if third else "") + "---|"]
    for k in studies:
        rep_text, ok = ROWS[k](columns[k]["reproduction"])
        pred = columns[k].get("prediction")
        pred_text = ROWS[k](pred)[0] if pred else "not run"
        verdict = "reproduced" if ok else "not reproduced"
        cell = f" {printed.get(k, 'not run')} |" if third else ""
        out.append(f"| {k} | {STATEMENTS[k]} | {rep_text} | {pred_text} |{cell} {verdict} |")
    out += ["", *(printed_note or [])] if third else [""]
    for k in studies:
        pics = [f"![{k}, {c}]({pictures[f'{k}/{c}']})" for c in ("reproduction", "prediction") if f"{k}/{c}" in pictures]
        if pics:
            out += [f"{k}: reproduction (left) and prediction (right)", "", " ".join(pics), ""]
    return out


def _rest_test(w: Mapping | None) -> tuple[str, bool | None]:
    t = (w or {}).get("rest_rotations")
    if not t:
        return "not run", None
    turned = " ".join(f"{k} {_deg(v)}" for k, v in t["error_deg"].items())
    return f"errors [deg] {turned}; axes passed: {sum(t['ok'].values())}/3", all(t["ok"].values())


def scene_facts_section(scene: Mapping | None, robot: Mapping | None, columns: Mapping[str, Mapping]) -> list[str]:
    """Markdown lines: the paper's stated facts about the motors and the rest pose (issue 41:
    i-v) on the pipeline's robot, from its own artefacts: the scene's stroke, the robot stage's
    rest angles, the workspace's test at rest, the ranges' nesting, the maze."""
    if not scene or not robot or "rest_angles_deg" not in robot:
        return []
    v = scene["values"]
    lo, hi, rest = v["angle_min"], v["angle_max"], robot["rest_angles_deg"]
    pull, push = hi - max(rest), min(rest) - lo
    rows = [("(i) a 90 deg stroke, 0 = horizontal horn, 90 = vertical (IV-A)", f"[{lo:g}, {hi:g}] deg",
             f"[{lo:g}, {hi:g}] deg", lo == 0 and hi == 90),
            ("(ii) all motors pull 15 deg or push 35 deg from rest (Fig. 7)", f"room {pull:.3g} / {push:.3g} deg",
             f"room {pull:.3g} / {push:.3g} deg", pull >= 15 and push >= 35)]
    get = {c: {k: columns.get(k, {}).get(c) for k in ROWS} for c in ("reproduction", "prediction")}
    rep_text, ok = _rest_test(get["reproduction"]["workspace"])
    rows.append(("(iii) +-10 deg about x, y, z from rest, within 2 deg and 1 mm (IV-B)", rep_text,
                 _rest_test(get["prediction"]["workspace"])[0], ok))
    for k, fact in (("ranges", "(iv) Fig. 6's ranges give nested workspaces"),
                    ("maze", "(v) the maze solved at a tilt that rolls a marble (V-B3)")):
        rep, pred = get["reproduction"][k], get["prediction"][k]
        rows.append((fact, ROWS[k](rep)[0] if rep else "not run", ROWS[k](pred)[0] if pred else "not run",
                     ROWS[k](rep)[1] if rep else None))
    out = [f"## The scene against the paper's facts ({scene.get('name', '')} scene)", "",
           "Each fact on this pipeline's robot, computed from its artefacts (the reproduction column: published "
           "constants, the authors' force field, no strain stop). How the candidates of the scene compare: "
           "docs/paper.md, `python -m metasheet.studies.scene_facts`.", "",
           "| fact | reproduction | prediction | holds (reproduction) |", "|---|---|---|---|"]
    out += [f"| {f} | {r} | {p} | {'-' if h is None else 'yes' if h else 'no'} |" for f, r, p, h in rows]
    return [*out, ""]
