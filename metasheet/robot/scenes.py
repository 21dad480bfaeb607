"""Named scene presets of the 6-DOF robot: the sheet, its fibres, the servos, the rod, the mass.

A preset is one :class:`ScenePreset`: every number the orient stage (sheet geometry, fibre
law), the robot stage and the study stages (rod, servo placement, stroke, sheet mass,
gravity) take by default, each with its source. The pipeline selects one with
``[orient] scene = "authors" | "metasheet"``; the orient stage records it in ``sheet.json``
and the robot and study stages read it from there, so one key changes it everywhere, and
every stage key given explicitly still overrides its own number.

Frames: the sheet's local frame is :mod:`metasheet.sheet.geometry`'s (centre at the origin,
mid-plane z = 0, arm k along 120 k deg from +x); the world frame is
:mod:`metasheet.robot.robots`' (rod along x, sheet A at x = -rod/2, gravity (0, 0, -g)).

``authors``: the authors' public SOFA scene of the paper's 6-DOF robot (VannesteFelix/
anisotropy, ``examples/Tripod/inverse_simu``: ``inverse_simu.pyscn``, ``utility/tripod.py``
and its mesh ``examples/Tripod/mesh/tripod_coarse_04.vtk``, 2,711 tetrahedra), translated to
metasheet's frames. Their rod is world y, gravity world -z (in the sheet planes, along arm 0,
which hangs down: the servo frames of arm 0 are at z = -66); metasheet's rod is x, gravity
-z along arm 0 of both sheets too, so gravity keeps its place relative to the rod and arms.
Their fibre of an element at polar angle a (from world z towards x) is at a + offset
(``inverse_simu.pyscn:280,284``), offset = 60 deg for both tripods (``:357-358``): 60 deg to
the radius, so pitch 90 - 60 = +30 deg in metasheet's convention (the angle to the circle;
checked element by element on their mesh: 30.00 +- 0.01 deg, same turning sense as ours).
Their direct scene (``examples/Tripod/direct_simu/direct_simu.py:97,101,287-289``, offset
-150 deg on another mesh) has the fibres at 30 deg to the radius, i.e. pitch -60: set
``[orient] pitch_deg = -60`` for it. Both scenes give the second tripod the same world-frame
rule as the first (its angle list recomputed for its own placement: ``direct_simu.py:93-95``
lists a and 360 - a), so its fibre field is the reflection of the first through the plane
across the rod, as metasheet's mirrored sheet is (:mod:`metasheet.sheet.fibers`).

``metasheet``: metasheet's own choices, and why they differ:

* rod 80 mm (not 120): FACTS.md's "tripods at +-90 mm, rod 80 mm" read as servo bases at
  +-90 mm (:mod:`metasheet.robot.robots`); the authors' scene was not at hand then.
* servos placed from a rest angle of 60 deg with a 25 mm horn (the servo circle, ~71.5 mm, is
  derived): the same rest angle on every mesh (a fixed servo circle makes it depend on the
  tip box's centroid), and 60 deg keeps all six +-10 deg rotations at rest on the 6-DOF robot,
  where 45-55 deg lose most of them (measured, see :mod:`metasheet.robot.robots`).
* 5 mm fillets in the concave corners: a sharp re-entrant corner concentrates strain in a few
  elements and degrades the mesh; the authors' corners are sharp.
* 45 deg log spiral: the pitch was not known from the sources then (see above: the authors'
  is 30 deg).
* no sheet mass: the density is the foam's, TPU x relative density
  (:data:`metasheet.published.paper.FOAM_DENSITY`); the authors give every sheet 32 g, which on their
  mesh (27,365 mm^3) is 1.17 g/cm^3, nearly solid TPU (the tutorial's silicone sheet's mass).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields

from ..published import paper
from ..conventions import GRAVITY
from ..errors import ConfigError, check_range
from ..sheet.outline import SheetParams
from .robots import ServoGeometry

_AUTHORS = "VannesteFelix/anisotropy examples/Tripod/"
_INV = _AUTHORS + "inverse_simu/"
_MESH = _AUTHORS + "mesh/tripod_coarse_04.vtk"


@dataclass(frozen=True)
class ScenePreset:
    """The numbers of one scene, each with its source (``sources[field]``).

    Attributes
    ----------
    name : the preset's name.
    arm_width, reach, thickness, hole_radius, fillet_radius : sheet geometry [mm]
        (:class:`~metasheet.sheet.outline.SheetParams`; fillet 0 = sharp corners).
    tip_box : (along the arm, across, z) box of the nodes each horn holds [mm].
    centre_radius : cylinder (r_xy) of the centre nodes tied to the rod [mm].
    law, pitch_deg : fibre law and pitch [deg] (angle between fibre and circle,
        :mod:`metasheet.sheet.fibers`); the second sheet's field is the reflection.
    rod_length : distance between the two sheets' centres [mm].
    rest_angle, horn_length : servo placement from a rest angle [deg] and horn [mm], or
    servo_radius, servo_depth : pivots on a circle of this radius [mm], this far behind the
        sheet's mid-plane [mm] (rest angle and horn then derived per servo); see
        :class:`~metasheet.robot.robots.ServoGeometry`.
    angle_min, angle_max : motor stroke [deg] (0 = horizontal horn, 90 = vertical).
    sheet_mass_g : mass of each sheet [g] (density = mass / sheet volume) or None (the
        material's density).
    gravity : (3,) world-frame gravity [mm/s^2] (rod along x).
    sources : field -> where the number comes from.
    """

    name: str
    arm_width: float
    reach: float
    thickness: float
    hole_radius: float
    fillet_radius: float
    tip_box: tuple[float, float, float]
    centre_radius: float
    law: str
    pitch_deg: float
    rod_length: float
    rest_angle: float | None
    horn_length: float
    servo_radius: float | None
    servo_depth: float | None
    angle_min: float
    angle_max: float
    sheet_mass_g: float | None
    gravity: tuple[float, float, float]
    sources: dict = field(default_factory=dict, compare=False)

    def __post_init__(self):
        missing = [f.name for f in fields(self) if f.name not in ("name", "sources") and f.name not in self.sources]
        if missing:
            raise ConfigError(f"scene {self.name!r}: sources: no source for {missing}")
        if self.sheet_mass_g is not None:
            check_range("sheet_mass_g", self.sheet_mass_g, 0.0, 1e4, lo_open=True)
        self.sheet_params()  # validates the geometry
        self.servo_geometry()  # validates the servo placement

    def sheet_params(self, mesh_size: float = 5.0) -> SheetParams:
        """The sheet geometry, meshed at ``mesh_size`` [mm]."""
        return SheetParams(arm_width=self.arm_width, reach=self.reach, thickness=self.thickness,
                           hole_radius=self.hole_radius, fillet_radius=self.fillet_radius, mesh_size=mesh_size,
                           tip_box=self.tip_box, centre_radius=self.centre_radius)

    def fiber_settings(self) -> dict:
        """Keywords of :func:`metasheet.sheet.fibers.spiral_fibers` (law, pitch_deg)."""
        return {"law": self.law, "pitch_deg": self.pitch_deg}

    def servo_geometry(self) -> ServoGeometry:
        return ServoGeometry(self.rest_angle, self.horn_length, self.angle_min, self.angle_max,
                             servo_radius=self.servo_radius, servo_depth=self.servo_depth)

    def to_dict(self) -> dict:
        """JSON-able ``{"name", "values": {field: number}, "sources": {field: text}}``."""
        d = asdict(self)
        sources = d.pop("sources")
        name = d.pop("name")
        d["tip_box"], d["gravity"] = list(self.tip_box), list(self.gravity)
        return {"name": name, "values": d, "sources": dict(sources)}


def sheet_density(sheet_mass_g: float, volume_mm3: float) -> float:
    """Mass density [t/mm^3] of a sheet of ``sheet_mass_g`` [g] and ``volume_mm3`` [mm^3]."""
    check_range("sheet_mass_g", sheet_mass_g, 0.0, 1e4, lo_open=True)
    check_range("sheet volume", volume_mm3, 0.0, None, lo_open=True)
    return float(sheet_mass_g) * 1e-6 / float(volume_mm3)  # 1 g = 1e-6 t


METASHEET = ScenePreset(
    name="metasheet", arm_width=30.0, reach=66.0, thickness=5.0, hole_radius=5.0, fillet_radius=5.0,
    tip_box=(15.0, 45.0, 30.0), centre_radius=7.5, law="log", pitch_deg=45.0,
    rod_length=paper.ROD_LENGTH, rest_angle=paper.REST_ANGLE, horn_length=paper.HORN_LENGTH,
    servo_radius=None, servo_depth=None, angle_min=paper.ANGLE_MIN, angle_max=paper.ANGLE_MAX,
    sheet_mass_g=None, gravity=(0.0, 0.0, -GRAVITY),
    sources={
        "arm_width": "FACTS.md:41 (three arms 30 mm wide)",
        "reach": "FACTS.md:42 (66 mm in the 6-DOF scene)",
        "thickness": "FACTS.md:41 (5 mm thick)",
        "hole_radius": "FACTS.md:42 (central hole radius 5 mm)",
        "fillet_radius": "metasheet's choice: smooth concave corners (module docstring)",
        "tip_box": "FACTS.md:47 (a box about 45 x 15 x 30 mm around the tip)",
        "centre_radius": "FACTS.md:48 (a sphere of radius 7.5 mm there; here the cylinder of that radius the mesh conforms to, metasheet/sheet/geometry.py)",
        "law": "paper Fig. 3 (a spiral); log = constant angle to the circle",
        "pitch_deg": "metasheet's choice (module docstring)",
        "rod_length": "metasheet.published.paper.ROD_LENGTH (robot/robots.py docstring)",
        "rest_angle": "metasheet.published.paper.REST_ANGLE (robot/robots.py docstring: keeps the +-10 deg rotations)",
        "horn_length": "FACTS.md:46 (horn about 25 mm)",
        "servo_radius": "derived from rest_angle and horn_length",
        "servo_depth": "derived from rest_angle and horn_length",
        "angle_min": "paper Section IV-A (0 = horizontal horn)",
        "angle_max": "paper Section IV-A (90 = vertical horn)",
        "sheet_mass_g": "none: density = TPU 1.19 g/cm^3 x relative density 0.15 (metasheet.published.paper)",
        "gravity": "metasheet.robot.robots: rod along x, gravity -z",
    })

AUTHORS = ScenePreset(
    name="authors", arm_width=30.0, reach=66.0, thickness=5.0, hole_radius=5.0, fillet_radius=0.0,
    tip_box=(36.0, 45.0, 30.0), centre_radius=7.5, law="log", pitch_deg=30.0,
    rod_length=120.0, rest_angle=None, horn_length=paper.HORN_LENGTH, servo_radius=66.0, servo_depth=30.0,
    angle_min=paper.ANGLE_MIN, angle_max=paper.ANGLE_MAX, sheet_mass_g=32.0, gravity=(0.0, 0.0, -GRAVITY),
    sources={
        "arm_width": _MESH + ": arm end face from x = -15 to 15 (and FACTS.md:41)",
        "reach": _MESH + ": arm end face at y = -66 (and FACTS.md:42)",
        "thickness": _MESH + ": z from 0 to 5",
        "hole_radius": _MESH + ": smallest node radius 5.0",
        "fillet_radius": _MESH + " and mesh/tripod.geo_unrolled:6-8,26-29: the arm edges meet in sharp "
                         "concave corners at r = 17.32 = 15 / sin 60 deg",
        "tip_box": _INV + "utility/tripod.py:151: the rigidified arm-tip node groups span the last "
                   "18 mm of each arm (r 48 to 66, centroid r = 58.0): a box 36 mm long centred on the "
                   "arm end; across and z: the whole arm section",
        "centre_radius": _INV + "utility/tripod.py:151 (4th group: nodes r 5 to 7.2) and "
                         "direct_simu/utility/tripod_HighOrder.py:184 (radii=[7.5])",
        "law": _INV + "inverse_simu.pyscn:280,284: angle = polar angle + offset (constant to the radius)",
        "pitch_deg": _INV + "inverse_simu.pyscn:357-358: offset = 60 deg to the radius -> 90 - 60 = 30 deg "
                     "to the circle (the direct scene, direct_simu.py:287-289, has -150: pitch -60)",
        "rod_length": _INV + "utility/tripod.py:139,146: sheet-centre frames at y = 30 - 90 = -60 and "
                      "-30 + 90 = +60 (FACTS.md:50-51)",
        "rest_angle": "derived per servo from servo_radius, servo_depth and the tip box (73.3 deg: the "
                      "stress-free horn, their displacement 0); their 'rest angle ~ 44degree' (utility/tripod.py:36) "
                      "and initDisplacement 48.15 / 45 deg (:143,:147, commented out at :193,:197,:201) are a home "
                      "~45 deg into their stroke on their displacement scale, not a stress-free angle; this preset "
                      "meets the paper's facts (90 deg stroke, pull 15 / push 35, +-10 deg tilts within 2 deg) under "
                      "the authors' force field, measured: docs/paper.md, metasheet/studies/scene_facts.py",
        "horn_length": "not used (the pivots are placed); derived per servo (~31 mm): their arm-tip frames "
                       "sit on the pivots (utility/tripod.py:139,146); FACTS.md:46 gives 25 mm",
        "servo_radius": _INV + "utility/tripod.py:32 (radius=66), :139,:146 (frames at r = 66)",
        "servo_depth": _INV + "utility/tripod.py:139,146: servo frames at y = -91.35 and +88.65 (mean +-90.0) "
                       "behind sheet centres at +-60",
        "angle_min": "paper Section IV-A (0 = horizontal horn)",
        "angle_max": "paper Section IV-A (90 = vertical horn); their stroke is 90 deg from rest "
                     "(utility/tripod.py:37-38)",
        "sheet_mass_g": _INV + "inverse_simu.pyscn:253 (totalMass=0.032 kg) and FACTS.md:52",
        "gravity": _INV + "inverse_simu.pyscn:220 (gravity [0, 0, -9810] mm/s^2, rod along y): across the "
                   "rod, along arm 0 (servo of arm 0 at z = -66, utility/tripod.py:139)",
    })

@dataclass(frozen=True)
class RobotScene:
    """The robot's scene as the robot and study stages need it: rod [mm], rest angle [deg] and
    horn [mm] or the servos' circle radius and depth [mm] (then rest_angle None), motor
    stroke [deg], sheet mass [g] (None: the material's density), gravity (3,) [mm/s^2] and the
    preset's name (:mod:`metasheet.robot.scenes`)."""

    rod_length: float
    rest_angle: float | None
    horn_length: float
    angle_min: float
    angle_max: float
    servo_radius: float | None = None
    servo_depth: float | None = None
    sheet_mass_g: float | None = None
    gravity: tuple = (0.0, 0.0, -GRAVITY)
    scene: str = "metasheet"

    def with_overrides(self, **kw) -> "RobotScene":
        """This scene with the keys given (not None) replaced. An explicit ``rest_angle``
        places the servos from it (dropping the scene's circle); an explicit ``servo_radius``
        or ``servo_depth`` places them on a circle (dropping the scene's rest angle)."""
        from dataclasses import replace

        kw = {k: v for k, v in kw.items() if v is not None}
        if "rest_angle" in kw and not ({"servo_radius", "servo_depth"} & kw.keys()):
            kw.update(servo_radius=None, servo_depth=None)
        elif {"servo_radius", "servo_depth"} & kw.keys() and "rest_angle" not in kw:
            kw["rest_angle"] = None
        return replace(self, **kw)

    def servo_geometry(self, angle_min: float | None = None, angle_max: float | None = None):
        """The :class:`~metasheet.robot.robots.ServoGeometry` (stroke overridable) [deg]."""
        return ServoGeometry(self.rest_angle, self.horn_length,
                             self.angle_min if angle_min is None else angle_min,
                             self.angle_max if angle_max is None else angle_max,
                             servo_radius=self.servo_radius, servo_depth=self.servo_depth)


#: The named presets.
PRESETS: dict[str, ScenePreset] = {p.name: p for p in (METASHEET, AUTHORS)}


def get_preset(name: str, *, key: str = "scene") -> ScenePreset:
    """The preset called ``name``; a :class:`ConfigError` naming ``key`` and the allowed values otherwise."""
    if name not in PRESETS:
        raise ConfigError(f"{key}: {name!r}: allowed values are {sorted(PRESETS)}")
    return PRESETS[name]
