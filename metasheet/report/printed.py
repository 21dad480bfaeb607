"""Report section: the printed robot against the paper's physical robot (issue 62).

Reads the ``printed`` stage's ``printed.json`` (:mod:`metasheet.studies.printed_claims`); every
sentence is computed from it. Returns Markdown lines and the differences found, as the other
sections do.
"""

from __future__ import annotations

from collections.abc import Mapping

from .columns import STATEMENTS

#: the paper's physical robot, claim by claim (Section V-B, Fig. 5 and 7)
CLAIMS = {
    "roll": "the rod rolled one way with all six motors pulled by {pull:g} deg and the other way pushed by "
            "{push:g} deg (Fig. 7)",
    "rotations": "at rest, {rot:g} deg about each axis within {tol:g} deg, the other DOF held (Fig. 5)",
}


def _f(v, fmt: str = ".3g") -> str:
    return "-" if v is None else format(v, fmt)


def _span(s: Mapping, fmt: str = ".3g") -> str:
    if not s or s.get("n", 0) == 0:
        return "-"
    if s["min"] == s["max"]:
        return _f(s["mean"], fmt)
    return f"{_f(s['mean'], fmt)} ({_f(s['min'], fmt)} to {_f(s['max'], fmt)})"


def printed_robot_section(d: Mapping | None, pictures: Mapping[str, str] | None = None) -> tuple[list[str], list[str]]:
    """(Markdown lines, differences) of the section; ([], []) without the stage's output."""
    if not d:
        return [], []
    pictures = pictures or {}
    p = d["params"]
    rows = d["realisations"]
    text = {"roll": CLAIMS["roll"].format(pull=p["pull_deg"], push=p["push_deg"]),
            "rotations": CLAIMS["rotations"].format(rot=p["rot_deg"], tol=p["tol_deg"])}
    lines = ["## The printed robot against the paper's robot (issue 62)", "",
             (f"Each print ({len(rows)}: seeds {', '.join(str(r['seed']) for r in rows)}; {d['voxel_mm']} mm voxels, "
              f"gauge `{d['gauge']}`) as a robot of two corotational superelements with its sheets' linear DNS "
              "stiffness on their grips, valid until two of its walls first touch (first order in the motion: the "
              "nonlinear DNS closes the gaps sooner, so these limits are late). docs/printed-sheet.md says what the "
              "model leaves out."), ""]
    if "printed_robot" in pictures:
        lines += [f"![The printed robot's roll and its walls' limits]({pictures['printed_robot']})", ""]
    lines += ["| the paper's robot | printed robot | per print |", "|---|---|---|"]
    for key in ("roll", "rotations"):
        per = _per_print((r["seed"], r[key]["status"]) for r in rows)
        lines.append(f"| {text[key]} | **{d['claims'][key]}** | {per} |")
    for key in ("workspace", "ranges", "maze"):
        if key in d["claims"]:
            per = _per_print((r["seed"], r["studies"][key]["verdict"]["text"]) for r in rows)
            lines.append(f"| {STATEMENTS[key]} | **{d['claims'][key]}** | {per} |")
    lines.append("")
    spr = d["spread"]
    lines += [f"- Walls' first contact (the model's limit): {_span(spr['valid_deg'])} deg of motor travel "
              f"(mean, min to max over the prints); searched to {p['search_deg']:g} deg.",
              f"- Rod rotation pulled by {p['pull_deg']:g} deg: {_span(spr['rod_rotation_pull_deg'])} deg; pushed by "
              f"{p['push_deg']:g} deg: {_span(spr['rod_rotation_push_deg'])} deg (the model, walls ignored).",
              f"- Smallest singular value at rest: {_span(spr['smallest_singular_value'])} mm/rad "
              "(diag(1, 1, 1, 50 mm) J)."]
    for r in rows:
        lim = r["limits"]
        if not lim:
            continue
        at = r["roll"]["rod_rotation_within_limits_deg"]
        lines.append(f"- Seed {r['seed']}: walls touch first along {_direction(r, lim['binding'])} at "
                     f"{_f(lim['valid_deg'])} deg{_touch_words(lim)}; "
                     f"the rod turns {_f(at['pull'])} deg pulled and {_f(at['push'])} deg pushed up to the walls' "
                     "limit.")
    lines.append("")
    lines += _map_lines(d)
    lines += _resolution_lines(d)
    keys = [k for k in ("roll", "rotations", "workspace", "ranges", "maze") if k in d["claims"]]
    text.update({k: STATEMENTS[k] for k in ("workspace", "ranges", "maze")})
    diffs = [f"Printed robot: {text[k]}: {d['claims'][k]}." for k in keys if d["claims"][k] != "predicted"]
    return lines, diffs


#: the paper-study rows of the report's side-by-side table (:func:`.columns.columns_section`) and
#: the printed robot's claim each is read from
COLUMN_CLAIMS = {"workspace": "workspace", "ranges": "ranges", "anisotropy": "roll", "maze": "maze"}


def printed_column(d: Mapping | None) -> dict[str, str]:
    """Study -> the printed robot's cell of the side-by-side table, from the ``printed`` stage's
    ``printed.json`` ``d`` (this pipeline's or the printed-robot pipeline's beside it): the claim's
    status over the prints (the worst print's), then each print's figure (prints with the same
    figure named together); {} without it."""
    if not d:
        return {}
    out = {}
    for study, key in COLUMN_CLAIMS.items():
        if key not in d["claims"]:
            continue
        rows = d["realisations"]
        if key == "roll":
            per = _per_print((r["seed"], "{} deg pulled, {} deg pushed".format(
                *(_f(r[key]["rod_rotation_within_limits_deg"][k]) for k in ("pull", "push")))) for r in rows)
        else:
            per = _per_print((r["seed"], r["studies"][key]["verdict"]["text"]) for r in rows)
        out[study] = f"**{d['claims'][key]}** ({per})"
    return out


def _per_print(figures) -> str:
    """"seed 1: a; seeds 2, 3: b" from (seed, figure) pairs in the prints' order: prints with
    the same figure named together."""
    texts = {}
    for seed, text in figures:
        texts.setdefault(text, []).append(str(seed))
    return "; ".join(f"seed{'s' if len(seeds) > 1 else ''} {', '.join(seeds)}: {text}" for text, seeds in texts.items())


def _touch_words(lim: Mapping) -> str:
    """Where the finite-strain robot searched the first-order box's direction again (the stage's
    ``touch``): what it found there, beside the first-order value."""
    t = lim.get("touch")
    if not t:
        return ""
    found = "no touch" if t["touch_deg"] is None else f"a touch at {_f(t['touch_deg'])} deg"
    return (f" (the finite-strain voxel robot found {found} along \"{t['direction']}\", where first order "
            f"said {_f(t['first_order_deg'])} deg; the box was {_f(lim['first_order_valid_deg'])} deg)")


def _direction(row: Mapping, name: str | None) -> str:
    """A searched direction in words: a ray of Fig. 5 by its direction, the others by name."""
    for ray in (row.get("map") or {}).get("rays", []):
        if ray["name"] == name:
            x, y, z = ray["direction"]
            return f"\"{name}\" (the rod moved along ({x:+.2f}, {y:+.2f}, {z:+.2f}), orientation held)"
    return f"\"{name}\""


def _map_lines(d: Mapping) -> list[str]:
    """The validity map from the walls, over the prints: the plane of the sheets' common modes and
    the rays of Fig. 5 (:func:`metasheet.studies.printed_limits.validity_map`)."""
    maps = [(r["seed"], r["map"]) for r in d["realisations"] if r.get("map")]
    if not maps:
        return []
    out = ["Where the walls stop the printed robot (the validity map; picture, middle and right):"]
    plane = [(s, m["plane"]) for s, m in maps if m["plane"]]
    if plane:
        per = ", ".join(f"{_f(_min(x['contact_deg'] for x in xs))} to {_f(_max(x['contact_deg'] for x in xs))} deg "
                        f"(seed {s})" for s, xs in plane)
        out.append(f"- Around the plane of the two sheets' common modes ({len(plane[0][1])} directions), the walls "
                   f"first touch after {per} of the largest motor's travel, depending on the direction.")
    rays = [(s, m["rays"]) for s, m in maps if m["rays"]]
    if rays:
        per = ", ".join(f"{_f(_min(x['contact_mm'] for x in xs))} to {_f(_max(x['contact_mm'] for x in xs))} mm "
                        f"(seed {s}, median {_f(_median(x['contact_mm'] for x in xs))})" for s, xs in rays)
        every = [x for _, xs in rays for x in xs]
        strain = sum(x["binds"] == "strain" for x in every)
        free = sum(x["binds"] is None for x in every)
        out.append(f"- Along the {len(rays[0][1])} rays of Fig. 5, orientation held, the rod moves {per} before two "
                   f"walls touch; the walls' strain limit binds first on {strain} of the {len(every)} rays over the "
                   f"prints, and neither limit within the search on {free}.")
    return out + [""]


def _values(vals) -> list[float]:
    return [v for v in vals if v is not None]


def _min(vals):
    v = _values(vals)
    return min(v) if v else None


def _max(vals):
    v = _values(vals)
    return max(v) if v else None


def _median(vals):
    v = sorted(_values(vals))
    return None if not v else (v[len(v) // 2] if len(v) % 2 else 0.5 * (v[len(v) // 2 - 1] + v[len(v) // 2]))


def _resolution_lines(d: Mapping) -> list[str]:
    """The first print's figures over the voxel sizes (with their Richardson limits) and under
    the other gauge, when the stage computed them."""
    out = []
    lad = d.get("ladder")
    if lad:
        out += [f"The first print (seed {lad['seed']}, gauge `{lad['gauge']}`) at each voxel size: printed over "
                "homogenised stiffness (geometric mean of the 18 modes), the rod's roll per motor degree, the "
                "smallest singular value.", "",
                "| voxel [mm] | geometric mean (normal, mirrored) | rod roll [deg/deg] | smallest singular value "
                "[mm/deg] |", "|---|---|---|---|"]
        for r in lad["rows"]:
            g = r["geometric_mean_ratio"]
            out.append(f"| {r['voxel_mm']:g} | {g[0]:.3f}, {g[1]:.3f} | {r['rod_roll']:+.4f} | "
                       f"{min(r['singular_values']):.3g} |")
        fits = lad.get("richardson") or {}
        for key in ("geometric mean, normal", "rod roll [deg/deg]"):
            f = fits.get(key)
            if f:
                order = "no order claimed" if f["order"] is None else f"order {f['order']:.2f}"
                out.append(f"- {key}: Richardson limit {f['limit']:.4g} ({order}); the finest size "
                           f"{100 * f['relative_errors'][-1]:+.1f} % from it.")
        out.append("")
    og = d.get("other_gauge")
    if og:
        r = og["ratio"]
        out += [f"Under the other gauge (`{og['gauge']}`, the unpublished assumption of how IceSL turns the cells), "
                f"the same print at {og['voxel_mm']:g} mm: rod roll x{r['rod_roll']:.3f}, stiffness (geometric mean) "
                f"x{r['geometric_mean'][0]:.2f} (normal) and x{r['geometric_mean'][1]:.2f} (mirrored), singular "
                f"values x{min(r['singular_values']):.2f} to x{max(r['singular_values']):.2f}: the named uncertainty "
                "of every figure above.", ""]
    return out
