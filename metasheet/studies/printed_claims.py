"""The paper's physical robot, claim by claim, against the printed robot's model (issue 62,
item 5): each print's :class:`~.printed_adapter.PrintedRobot`, within its walls' limits
(:mod:`.printed_limits`).

The paper's robot (Section V-B): all six motors pulled by 15 deg or pushed by 35 deg rolled the
rod one way and the other (Fig. 7); at rest and around it the effector turned by 10 deg about
each axis with the other DOF held (Fig. 5: full six-DOF control). Per print this module computes

* ``roll``: the rod's rotation with all motors turned from rest, pulled to ``pull_deg`` and
  pushed to ``push_deg`` (1 deg steps, each equilibrium from the last), and at the travel where
  the walls first touch, when that comes first;
* ``rotations``: the inverse model's reach of the rest pose turned by ``rot_deg`` about each
  axis both ways, once without the walls' box (the motor travel it takes) and once within it;
* the rest Jacobian's singular values (its smallest: the weakest of the six DOF) and the rod's
  roll per degree of all six motors (the sheet stage's linear rest model's, to round-off).

A claim is "predicted" when the print's model meets it within its walls' limits, "predicted up
to the walls' limit" when it meets it on the way but the walls touch before the paper's travel,
"not predicted" otherwise, with the limit that stops it. Every word is computed from numbers.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .printed_adapter import PrintedRobot, PrintedSpec

#: [deg] the least rod rotation that counts as rolled (the paper's rolls were tens of degrees)
ROLL_MIN_DEG = 1.0


def _rod_deg(model: PrintedRobot, pose) -> float:
    return float(np.degrees(pose[3 + model.rod_axis]))


def roll_path(model: PrintedRobot, sign: float, travel_deg: float, step_deg: float = 1.0) -> list[list[float]]:
    """[[travel [deg], rod rotation [deg]], ...] with every motor turned by ``sign`` x travel
    from rest, in steps of at most ``step_deg``, each equilibrium from the last."""
    rest = model.rest_motors()
    n = max(1, int(np.ceil(travel_deg / step_deg - 1e-9)))
    state, rows = None, [[0.0, 0.0]]
    for t in np.linspace(travel_deg / n, travel_deg, n):
        pose, state = model.equilibrium(rest + sign * t, state=state)
        rows.append([float(t), _rod_deg(model, pose)])
    return rows


def roll_claim(spec: PrintedSpec, pull_deg: float, push_deg: float, limits: dict) -> dict:
    """The rod's roll pulled and pushed (module docstring), with the walls' ``limits``
    (:func:`.printed_limits.combine`: ``roll up`` is pulling when the model's ``pull_sign`` is +1)."""
    model = PrintedSpec.build(replace(spec, valid_deg=None))
    out = {}
    for name, sign, travel in (("pull", model.pull_sign, pull_deg), ("push", -model.pull_sign, push_deg)):
        direction = "roll up" if sign > 0 else "roll down"
        contact = (limits.get("directions", {}).get(direction) or {}).get("contact_deg")
        path = roll_path(model, sign, travel)
        row = {"travel_deg": travel, "rod_rotation_deg": path[-1][1], "contact_deg": contact,
               "path": [[round(t, 6), round(r, 6)] for t, r in path]}
        if contact is not None and contact < travel:
            pose, _ = model.equilibrium(model.rest_motors() + sign * contact)
            row["rod_rotation_at_contact_deg"] = _rod_deg(model, pose)
        out[name] = row
    reach = {k: out[k].get("rod_rotation_at_contact_deg", out[k]["rod_rotation_deg"]) for k in ("pull", "push")}
    rolled = reach["pull"] * reach["push"] < 0 and min(abs(v) for v in reach.values()) >= ROLL_MIN_DEG
    full = all(out[k]["contact_deg"] is None or out[k]["contact_deg"] >= out[k]["travel_deg"] for k in out)
    out["status"] = ("predicted" if rolled and full else "predicted up to the walls' limit" if rolled
                     else "not predicted")
    out["rod_rotation_within_limits_deg"] = reach
    return out


def rotation_claim(spec: PrintedSpec, rot_deg: float, tol_mm: float, tol_deg: float, max_steps: int = 60) -> dict:
    """The rest pose turned by ``rot_deg`` about each axis both ways (module docstring)."""
    free = PrintedSpec.build(replace(spec, valid_deg=None))
    boxed = PrintedSpec.build(spec)
    rest = free.rest_pose()
    rows = {}
    for ax, name in enumerate("xyz"):
        for sign, word in ((1.0, "+"), (-1.0, "-")):
            goal = rest.copy()
            goal[3 + ax] = sign * np.radians(rot_deg)
            a = free.reach(goal, tol_mm=tol_mm, tol_deg=tol_deg, max_steps=max_steps)
            b = boxed.reach(goal, tol_mm=tol_mm, tol_deg=tol_deg, max_steps=max_steps)
            rows[word + name] = {
                "travel_needed_deg": float(np.abs(a.motors_deg - free.rest_motors()).max()) if a.reached else None,
                "reached_without_limits": bool(a.reached), "reached": bool(b.reached),
                "stopped_by_walls": bool(b.left_domain), "error_mm": float(b.error_mm), "error_deg": float(b.error_deg)}
    ok = all(r["reached"] for r in rows.values())
    free_ok = all(r["reached_without_limits"] for r in rows.values())
    walls = any(r["stopped_by_walls"] for r in rows.values())
    _, st = free.equilibrium(free.rest_motors())
    scale = np.array([1.0, 1.0, 1.0, 50.0, 50.0, 50.0])
    J = free.jacobian(st)
    sv = np.linalg.svd(scale[:, None] * J, compute_uv=False)
    status = ("predicted" if ok else "predicted up to the walls' limit" if free_ok and walls else "not predicted")
    return {"rot_deg": rot_deg, "tol_mm": tol_mm, "tol_deg": tol_deg, "goals": rows, "status": status,
            "rest_singular_values_mm_per_rad": sv.tolist(),
            "rest_rod_roll_deg_per_deg": float(J[3 + free.rod_axis].sum())}

