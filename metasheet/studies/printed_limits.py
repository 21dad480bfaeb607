"""The printed robot's validity from its own walls, print by print (issue 62, item 4): one work
unit per printed sheet takes the linear voxel DNS's displacement fields the sheet stage kept
(its ``walls``; :mod:`metasheet.sheet.wall_fields`), or solves them
(:func:`metasheet.sheet.dns.dns_sheet_fields`), carries them to the robot's motors with the rod
in equilibrium (:func:`metasheet.robot.condensed.grip_motions_per_motor`) and reads off

* each motor's walls' strain rate: the largest principal strain per degree of that motor
  turned up and down alone (:func:`metasheet.sheet.wall_limits.principal_range`), which bounds
  the first-order walls' strain at any motor offset (:mod:`.printed_adapter`);
* along each of a few motor directions, the travel at which two walls first touch
  (:func:`metasheet.sheet.wall_limits.first_contact`, searched to ``search_deg``) and the travel
  at which the walls' strain reaches its limit.

Directions are motor offsets per degree of the largest motor's travel: ``"roll up"`` turns all
six motors up by the same angle (pulling, paper Fig. 7), ``"roll down"`` all six down
(pushing), ``"A up"`` / ``"A down"`` sheet A's three motors (0-2), ``"B up"`` / ``"B down"``
sheet B's (3-5), and with ``motors`` each motor alone both ways. A motor direction moves
both sheets (through the rod), so each sheet is searched along every direction.

The validity map (issue 62, item 4) adds two families: :func:`plane_directions`, evenly around
the plane of sheet A's and sheet B's common modes (it holds the six base directions), and
:func:`ray_directions`, the motor directions that move the rod along the rays of the workspace
study's grid (paper Fig. 5) with its orientation held, to first order (the rest Jacobian).
:func:`validity_map` reads both back from :func:`combine`'s limits: per direction the travel
to the walls' first contact and to their strain limit, and which binds first.

Both limits are first order in the motion, as :mod:`metasheet.sheet.wall_limits` says: the
nonlinear DNS closes the mirrored print's gaps faster than this, so the contact travels are
late estimates; :mod:`.nonlinear_touch` searches a direction again on the finite-strain robot.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, check_range

#: motor directions by name: the offsets per degree of the largest motor's travel
BASE_DIRECTIONS = {
    "roll up": (1.0,) * 6, "roll down": (-1.0,) * 6,
    "A up": (1.0, 1.0, 1.0, 0.0, 0.0, 0.0), "A down": (-1.0, -1.0, -1.0, 0.0, 0.0, 0.0),
    "B up": (0.0, 0.0, 0.0, 1.0, 1.0, 1.0), "B down": (0.0, 0.0, 0.0, -1.0, -1.0, -1.0),
}


def directions(motors: bool = False) -> dict[str, tuple[float, ...]]:
    """The searched directions (module docstring): the six base ones, and each motor alone both
    ways when ``motors``."""
    out = dict(BASE_DIRECTIONS)
    if motors:
        for k in range(6):
            for sign, word in ((1.0, "up"), (-1.0, "down")):
                d = [0.0] * 6
                d[k] = sign
                out[f"motor {k} {word}"] = tuple(d)
    return out


def _unit_offsets(d) -> tuple[float, ...]:
    d = np.asarray(d, float)
    return tuple(float(v) for v in d / np.abs(d).max())


def plane_directions(n: int) -> dict[str, tuple[float, ...]]:
    """``n`` directions at angles ``phi = 360 k / n`` deg in the plane of sheet A's common mode
    (phi = 0: ``"A up"``) and sheet B's (phi = 90: ``"B up"``; 45: ``"roll up"``), named
    ``"plane <phi>"`` or by the base direction they coincide with, each scaled to a largest motor
    offset of one."""
    check_range("n", n, 0, 360)
    out = {}
    base = {v: k for k, v in BASE_DIRECTIONS.items()}
    for k in range(int(n)):
        phi = 360.0 * k / n
        c, s = np.cos(np.radians(phi)), np.sin(np.radians(phi))
        d = _unit_offsets([c, c, c, s, s, s])
        d = tuple(round(v, 12) + 0.0 for v in d)  # so that 45 deg is (1, ..., 1) exactly
        out[base.get(d, f"plane {phi:g}")] = d
    return out


def ray_directions(J, rays) -> tuple[dict[str, tuple[float, ...]], list[float]]:
    """({"ray <r>": motor offsets per degree of the largest motor}, mm_per_deg): for each unit ray
    of ``rays`` (n, 3), the motor direction ``J^-1 (ray, 0)`` that moves the rod along it with
    its orientation held (first order), and the rod's travel along the ray per degree of that
    direction's largest motor [mm/deg]. ``J`` (6, 6): the effector's (dp [mm], dtheta [rad])
    per motor [rad] at rest (:func:`metasheet.robot.condensed.grip_motions_per_motor`)."""
    J = np.asarray(J, float)
    rays = np.asarray(rays, float).reshape(-1, 3)
    if J.shape != (6, 6) or not np.isfinite(J).all():
        raise ConfigError(f"J: shape {J.shape}: expected a finite (6, 6) rest Jacobian")
    m = np.linalg.solve(J, np.vstack([rays.T, np.zeros((3, len(rays)))])).T  # (n, 6) [rad per mm]
    scale = np.abs(m).max(axis=1)
    if not (scale > 0).all():
        raise ConfigError("rays: a zero ray direction")
    dirs = {f"ray {r}": _unit_offsets(row) for r, row in enumerate(m)}
    return dirs, [float(np.radians(1.0) / s) for s in scale]


@dataclass(frozen=True)
class WallUnit:
    """One printed sheet's walls to search: ``sheet`` its :class:`~metasheet.sheet.dns.SheetPrint`;
    ``G`` (24, 6) its grips' motion per motor [mm/rad, rad/rad] with the rod in equilibrium;
    ``dirs`` the named directions; ``search_deg`` [deg] the contact search's travel;
    ``strain_limit`` [-] the walls' strain limit; ``fields`` the sheet's
    :class:`~metasheet.sheet.wall_fields.WallFields` when the sheet stage kept them (None: the
    unit solves the DNS)."""

    sheet: object
    G: tuple
    dirs: tuple
    search_deg: float
    strain_limit: float
    fields: object = None

    def __post_init__(self):
        check_range("search_deg", self.search_deg, 0.0, 90.0, lo_open=True)
        check_range("strain_limit", self.strain_limit, 0.0, None, lo_open=True)
        if np.shape(self.G) != (24, 6):
            raise ConfigError(f"G: shape {np.shape(self.G)}: expected (24, 6) grip motions per motor")


def wall_unit(u: WallUnit) -> dict:
    """The sheet's strain rates and, per direction, its first contact and strain travel [deg]
    (None: not within the search, or the strain never reaches the limit); the kept solid share."""
    from ..sheet.dns import dns_sheet_fields
    from ..sheet.wall_limits import MotorWalls

    walls = u.fields if u.fields is not None else dns_sheet_fields(u.sheet)[1]
    motors = MotorWalls.from_fields(walls, np.asarray(u.G, float))
    deg = np.pi / 180.0
    rates = [[up * deg, down * deg] for up, down in motors.rates()]  # per degree, up and down
    out = {}
    for name, d in u.dirs:
        t, pair = motors.contact(d, np.radians(u.search_deg))
        s = motors.strain_travel(d, u.strain_limit)
        out[name] = {"contact_deg": None if not np.isfinite(t) else float(np.degrees(t)),
                     "contact_nodes": [int(v) for v in pair],
                     "strain_deg": None if not np.isfinite(s) else float(np.degrees(s))}
    return {"label": walls.meta["label"], "seed": walls.meta["seed"], "kept_share": walls.meta["kept_share"],
            "strain_per_deg": rates, "directions": out}


def combine(a: dict, b: dict) -> dict:
    """The robot's limits from its two sheets' units: per direction the first contact and the
    strain travel of either sheet (the smaller), which sheet binds, and per motor the larger
    strain rate; ``valid_deg`` the first contact over the directions searched (None: none
    within the search)."""
    dirs = {}
    for name in a["directions"]:
        da, db = a["directions"][name], b["directions"][name]
        row = {}
        for key in ("contact_deg", "strain_deg"):
            vals = [(v[key], s["label"]) for v, s in ((da, a), (db, b)) if v[key] is not None]
            row[key], row[key.replace("_deg", "_sheet")] = min(vals) if vals else (None, None)
        dirs[name] = row
    contacts = [(r["contact_deg"], n) for n, r in dirs.items() if r["contact_deg"] is not None]
    valid, binding = min(contacts) if contacts else (None, None)
    rates = np.maximum(np.asarray(a["strain_per_deg"]), np.asarray(b["strain_per_deg"]))
    return {"valid_deg": valid, "binding": binding, "directions": dirs, "strain_per_deg": rates.tolist()}


def _binds(contact, strain) -> str | None:
    c, s = (np.inf if v is None else v for v in (contact, strain))
    return None if c == s == np.inf else ("contact" if c <= s else "strain")


def validity_map(limits: dict, plane: dict, rays: list[dict]) -> dict:
    """The validity map of one robot from its :func:`combine`'d ``limits``: ``plane`` the
    :func:`plane_directions` searched (name -> offsets), ``rays`` per ray of the grid its
    ``direction`` (3,), ``name`` and ``mm_per_deg`` (:func:`ray_directions`). Per plane direction
    its angle [deg] and the travels [deg of the largest motor]; per ray the rod's travel along it
    [mm] to the walls' first contact and to their strain limit; each with the limit that binds."""
    d = limits["directions"]

    def row(name):
        r = d[name]
        return {"contact_deg": r["contact_deg"], "strain_deg": r["strain_deg"],
                "binds": _binds(r["contact_deg"], r["strain_deg"]), "sheet": r["contact_sheet"]}

    out_plane = []
    for name, off in plane.items():
        phi = float(np.degrees(np.arctan2(off[3], off[0]))) % 360.0
        out_plane.append({"name": name, "phi_deg": phi, **row(name)})
    out_rays = []
    for ray in rays:
        r, k = row(ray["name"]), ray["mm_per_deg"]
        out_rays.append({**{key: ray[key] for key in ("name", "direction", "azimuth", "elevation", "mm_per_deg")},
                         "contact_mm": None if r["contact_deg"] is None else r["contact_deg"] * k,
                         "strain_mm": None if r["strain_deg"] is None else r["strain_deg"] * k,
                         **r})
    return {"plane": out_plane, "rays": out_rays}
