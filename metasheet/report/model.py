"""Report section: which of the paper's claims depend on the shear modulus mu_l.

The authors' SOFA force field built its tensor with the longitudinal shear modulus
E_t / (2 (1 + nu_t)) and never used mu_l (:mod:`metasheet.mechanics.material_model`). The robot stage
evaluates the foam robot under both material models (cases ``foam`` and ``foam_<other>``,
and the same for ``published``), the anisotropy stage the Fig. 7 end point
(``model_end_points``); this section puts the claims side by side:

1. 5 vs 6 controllable DOF (Jacobian singular values, isotropic vs anisotropic sheets);
2. the rod turns when all motors move together (Fig. 8) [deg per motor deg];
3. the Fig. 7 end point (rod rotation at the design anisotropy) [deg].
"""

from __future__ import annotations

from collections.abc import Mapping

from ..mechanics.material_model import MATERIAL_MODELS

LABELS = {"ours": "ours (all five constants)", "authors": "authors' force field (mu_l unused)"}

#: A singular value counts as a controllable direction above this fraction of the largest [-].
DOF_FRACTION = 0.05


def _columns(robot: Mapping) -> list[tuple[str, str, str]]:
    """(constants label, model, robot case) for every case the robot stage computed."""
    run = robot.get("material_model", "ours")
    cols = []
    for base, label in (("foam", "pipeline"), ("published", "published")):
        if base not in robot:
            continue
        for m in MATERIAL_MODELS:
            case = base if m == run else f"{base}_{m}"
            cols.append((label, m, case))
    return cols


def _end_point(anisotropy: Mapping | None, base: str, model: str, run: str) -> dict | None:
    """The Fig. 7 end point {"pull": deg, "push": deg} of ``base`` under ``model``, or None."""
    if not anisotropy:
        return None
    if model == run:
        if base == "foam":
            rot = anisotropy["rod_rotation_deg"]
            return {"pull": rot["pull"][-1], "push": rot["push"][-1]}
        e = anisotropy.get("published_end_point")
    else:
        e = anisotropy.get("model_end_points", {}).get(model if base == "foam" else f"published_{model}")
    if not e or "skipped" in e:
        return None
    return e["rod_rotation_deg"]


def _num(v, fmt="{:.3g}") -> str:
    return "not converged" if v is None else fmt.format(v)


def model_section(robot: Mapping | None, anisotropy: Mapping | None) -> tuple[list[str], list[str]]:
    """(Markdown lines, differences found) of the mu_l table; empty when the robot stage did
    not evaluate the other material model."""
    if not robot or not robot.get("other_model"):
        return [], []
    run = robot.get("material_model", "ours")
    cols = [c for c in _columns(robot) if c[2] in robot]
    if len({m for _, m, _ in cols}) < 2:
        skipped = "; ".join(f"{k}: {v}" for k, v in robot.get("model_skipped", {}).items())
        return ["## Which results depend on the shear modulus mu_l", "",
                f"Not compared: the other material model could not be built ({skipped or 'no case'}).", ""], []
    head = "| claim | " + " | ".join(f"{lab}, {LABELS[m]}" for lab, m, _ in cols) + " |"
    intro = (f"The robot runs on model **{run}**. The authors' force field (TetrahedronAnisotropicForceField) "
             "sets c44 = c55 = E_t / (2 (1 + nu_t)) and never reads mu_l; its c13 differs too "
             "(see `metasheet.mechanics.material_model`), so a column pair measures both differences together. "
             "Silicone (isotropic) is the same under both.")
    lines = ["## Which results depend on the shear modulus mu_l", "", intro, "", head, "|---" * (len(cols) + 1) + "|"]
    sil = robot.get("silicone", {}).get("singular_values")

    def row(label, values):
        lines.append(f"| {label} | " + " | ".join(values) + " |")

    sv = {c: robot[c]["singular_values"] for _, _, c in cols}
    row("Jacobian singular values", [", ".join(f"{x:.3g}" for x in sv[c]) for _, _, c in cols])
    sil_txt = f" (silicone: {sil[-1] / sil[0]:.3g})" if sil else ""
    row(f"5 vs 6 DOF: smallest / largest singular value{sil_txt}", [f"{sv[c][-1] / sv[c][0]:.3g}" for _, _, c in cols])
    sil_dof = f" (silicone: {sum(x > DOF_FRACTION * sil[0] for x in sil)})" if sil else ""
    row(f"controllable DOF (singular value > {DOF_FRACTION:g} x largest){sil_dof}",
        [str(sum(x > DOF_FRACTION * sv[c][0] for x in sv[c])) for _, _, c in cols])
    sil_rot = robot.get("silicone", {})
    for key, label in (("rod_rotation_deg_per_deg", "Fig. 8: rod rotation per motor degree, all together, from J"),
                       ("rod_rotation_finite_deg_per_deg", "Fig. 8: the same from a finite move")):
        ref = f" (silicone: {sil_rot[key]:.3g})" if key in sil_rot else ""
        row(f"{label} [deg/deg]{ref}", [_num(robot[c].get(key), "{:.4g}") for _, _, c in cols])
    ends = {(lab, m): _end_point(anisotropy, "foam" if lab == "pipeline" else "published", m, run)
            for lab, m, _ in cols}
    if any(v is not None for v in ends.values()):
        for case in ("pull", "push"):
            row(f"Fig. 7 end point: rod rotation, {case} [deg]",
                ["-" if ends[(lab, m)] is None else _num(ends[(lab, m)][case]) for lab, m, _ in cols])
    lines.append("")
    return lines, _differences(robot, cols, ends)


def _differences(robot: Mapping, cols, ends) -> list[str]:
    """Sentences for the claims whose number moves by more than 20 % between the two models."""
    out = []
    for lab in dict.fromkeys(lab for lab, _, _ in cols):
        pair = {m: c for lb, m, c in cols if lb == lab}
        if len(pair) < 2:
            continue
        a, b = robot[pair["ours"]], robot[pair["authors"]]
        for key, what in (("rod_rotation_deg_per_deg", "Fig. 8 rod rotation per motor degree"),):
            x, y = a.get(key), b.get(key)
            if x is not None and y is not None and abs(x - y) > 0.2 * max(abs(x), abs(y), 1e-12):
                out.append(f"Material model matters ({lab} constants): {what} is {x:.3g} deg/deg with all five "
                           f"constants and {y:.3g} deg/deg with the authors' force field (shear from E_t, nu_t "
                           "instead of mu_l, and their c13).")
        s_a, s_b = a["singular_values"][-1] / a["singular_values"][0], b["singular_values"][-1] / b["singular_values"][0]
        if abs(s_a - s_b) > 0.2 * max(s_a, s_b):
            out.append(f"Material model matters ({lab} constants): the smallest / largest Jacobian singular value is "
                       f"{s_a:.3g} with all five constants and {s_b:.3g} with the authors' force field.")
        e_a, e_b = ends.get((lab, "ours")), ends.get((lab, "authors"))
        if e_a and e_b:
            for case in ("pull", "push"):
                x, y = e_a[case], e_b[case]
                if x is not None and y is not None and abs(x - y) > 0.2 * max(abs(x), abs(y), 1e-12):
                    out.append(f"Material model matters ({lab} constants): the Fig. 7 end point ({case}) turns the rod by "
                               f"{x:.3g} deg with all five constants and {y:.3g} deg with the authors' force field.")
    return out
