"""The paper's rotation test at the rest pose itself (Section IV-B: "at the initial position
(center of workspace) ... we have a full 6 DOF control"): +-``rot_deg`` about x, y and z from
the rest pose, each within the study's tolerances, as the workspace study tests every reached
grid point (:func:`metasheet.studies.workspace._rotation_test`). The star grid starts one step
out from rest, so the rest pose needs its own test.
"""

from __future__ import annotations

import numpy as np

from .model import MODELS
from .workspace import WorkspaceSettings, _rotation_test


def rest_rotations(spec, settings: WorkspaceSettings) -> dict:
    """The rotation test at ``spec``'s rest pose: {"ok": {axis: bool}, "error_mm" and
    "error_deg": {"+x": float | None, ...} (None: not tried), "rot_deg", "tol_mm",
    "tol_rot_deg"}."""
    model = MODELS.get(spec)
    rest = model.rest_pose()
    res = model.reach(rest, state=None, tol_mm=settings.tol_mm, tol_deg=None, max_steps=settings.max_steps)
    rec = {"rot_error_mm": np.full((1, 6), np.nan), "rot_error_deg": np.full((1, 6), np.nan),
           "rot_ok": np.zeros((1, 3), bool), "rot_beyond": np.zeros((1, 6), bool), "rot_jump_mm": np.full(1, np.nan)}
    _rotation_test(model, settings, rec, 0, rest[:3], rest[3:], res)
    labels = ("+x", "-x", "+y", "-y", "+z", "-z")

    def listed(a):
        return {k: (None if not np.isfinite(v) else round(float(v), 4)) for k, v in zip(labels, a)}

    return {"ok": dict(zip("xyz", (bool(v) for v in rec["rot_ok"][0]))), "error_mm": listed(rec["rot_error_mm"][0]),
            "error_deg": listed(rec["rot_error_deg"][0]), "rot_deg": settings.rot_deg, "tol_mm": settings.tol_mm,
            "tol_rot_deg": settings.tol_rot_deg}
