"""The spiral fibre field of the sheet (paper Fig. 3).

Each element's longitudinal axis l (local axis 3 of ``TransverseIsotropic``, the soft
direction of the paper's foam) follows a spiral about the sheet centre. At a point of
polar angle t and radius r in the sheet plane the in-plane direction is

    l = cos(beta) e_t + sin(beta) e_r,

with e_t, e_r the circumferential and radial unit vectors and beta the spiral's pitch
angle (the angle between the fibre and the circle through the point). beta = 0 gives
circles, beta = 90 deg radial lines; a constant beta is the logarithmic spiral
r = r0 exp(t tan(beta)) (the default law). Positive beta turns counter-clockwise when
seen from +z while moving outwards. An optional tilt lifts l out of the plane:
l = cos(tilt) l_plane + sin(tilt) e_z.

The mirrored field of the second tripod is the reflection ``M = diag(1, -1, 1)``
(y -> -y, the plane that contains arm 0 and maps the Y sheet onto itself): at a point p,
``l_mirrored(p) = M l(M p)``. It is a reflection, not a rotation: the spiral turns the
other way.

Laws are pluggable: a law maps (r (m,) [mm], pitch [rad], r_ref [mm]) to beta (m,) [rad].
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..errors import ConfigError, check_range

Law = Callable[[np.ndarray, float, float], np.ndarray]

MIRROR = np.diag([1.0, -1.0, 1.0])  # y -> -y; see geometry.REFLECT


def _log(r, pitch, r_ref):
    return np.full_like(r, pitch)


def _archimedean(r, pitch, r_ref):
    # r = b t has tan(beta) = b / r; b is set so that beta = pitch at r = r_ref
    return np.arctan(np.tan(pitch) * r_ref / np.maximum(r, 1e-9))


def _circular(r, pitch, r_ref):
    return np.zeros_like(r)


def _radial(r, pitch, r_ref):
    return np.full_like(r, 0.5 * np.pi)


LAWS: dict[str, Law] = {
    "log": _log,
    "archimedean": _archimedean,
    "circular": _circular,
    "radial": _radial,
}


def register_law(name: str, law: Law) -> None:
    """Add a fibre law: ``law(r (m,) [mm], pitch [rad], r_ref [mm]) -> beta (m,) [rad]``."""
    if not callable(law):
        raise ConfigError(f"law {name!r}: {law!r} is not callable")
    LAWS[name] = law


def spiral_fibers(
    centroids: np.ndarray,
    *,
    pitch_deg: float = 45.0,
    mirrored: bool = False,
    tilt_deg: float = 0.0,
    law: str | Law = "log",
    r_ref: float = 33.0,
) -> np.ndarray:
    """Unit fibre directions l (m, 3) at points ``centroids`` (m, 3) [mm].

    Parameters
    ----------
    centroids : (m, 3) float [mm], in the sheet frame (centre at the origin, plane z = 0).
    pitch_deg : pitch angle beta of the spiral [deg], in [-90, 90] (sign = turning sense).
    mirrored : the reflected field ``M l(M p)``, M = diag(1, -1, 1).
    tilt_deg : out-of-plane tilt of l towards +z [deg], in [-90, 90].
    law : a name in :data:`LAWS` ("log", "archimedean", "circular", "radial") or a callable.
    r_ref : radius where a radius-dependent law takes the pitch ``pitch_deg`` [mm].
    """
    p = np.asarray(centroids, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ConfigError(f"centroids: shape is {p.shape} and should be (m, 3)")
    check_range("pitch_deg", pitch_deg, -90.0, 90.0)
    check_range("tilt_deg", tilt_deg, -90.0, 90.0)
    check_range("r_ref", r_ref, 0.0, None, lo_open=True)
    if isinstance(law, str):
        if law not in LAWS:
            raise ConfigError(f"law: {law!r}: allowed values are {sorted(LAWS)}")
        fn = LAWS[law]
    elif callable(law):
        fn = law
    else:
        raise ConfigError(f"law: {law!r}: expected a name in {sorted(LAWS)} or a callable")
    if mirrored:
        return _spiral(p @ MIRROR, fn, np.deg2rad(pitch_deg), np.deg2rad(tilt_deg), r_ref) @ MIRROR
    return _spiral(p, fn, np.deg2rad(pitch_deg), np.deg2rad(tilt_deg), r_ref)


def _spiral(p, fn, pitch, tilt, r_ref):
    r = np.hypot(p[:, 0], p[:, 1])
    t = np.arctan2(p[:, 1], p[:, 0])  # at r = 0 arctan2 gives 0: e_r = +x, still a unit vector
    beta = np.asarray(fn(r, pitch, r_ref), dtype=float) * np.ones_like(r)
    if not np.all(np.isfinite(beta)):
        raise ConfigError("law: returned non-finite pitch angles")
    # direction angle in the plane: e_t is at t + 90 deg, turning towards e_r by beta
    psi = t + 0.5 * np.pi - beta
    out = np.empty_like(p)
    out[:, 0] = np.cos(tilt) * np.cos(psi)
    out[:, 1] = np.cos(tilt) * np.sin(psi)
    out[:, 2] = np.sin(tilt)
    return out


def fiber_angles(fibers: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """In-plane angle theta and inclination phi [rad] of unit fibres (m, 3).

    theta = atan2(l_y, l_x) in [0, 2 pi); phi = asin(l_z) in [-pi/2, pi/2], the angle
    above the XY plane (the printer's layer plane).
    """
    f = np.asarray(fibers, dtype=float)
    theta = np.mod(np.arctan2(f[:, 1], f[:, 0]), 2 * np.pi)
    phi = np.arcsin(np.clip(f[:, 2] / np.linalg.norm(f, axis=1), -1.0, 1.0))
    return theta, phi
