"""The paper's numbers, each with its source: foam and silicone, densities, and the robot's scene.

Vanneste, Goury, Duriez, *Enabling the control of a new degree of freedom by using
anisotropic material on a 6-DOF parallel soft robot*. Every default that stands for the
paper's robot is defined here once and imported where it is used (stage parameters, the
robot builder, the studies, the report), so changing the preset changes it everywhere.

Sources:

* Foam constants: "paramPaper" in the authors' public SOFA code, for a Voronoi foam of
  about 15 % relative density, in kPa there; here MPa. The authors' force field did not
  use mu_l; metasheet uses all five (C44 = C55 = mu_l).
* Silicone: the SOFA SoftRobots tripod tutorial, E = 250 kPa, nu = 0.45.
* Densities: NinjaFlex TPU 1.19 g/cm^3 (maker's data) times the foam's relative density
  0.15; silicone 1.07 g/cm^3 (a typical cured silicone rubber: our choice, the sources
  give the sheet's mass, 32 g, not its density).
* Scene: rod and servo geometry of metasheet's model of the 6-DOF robot (see
  :mod:`metasheet.robot.robots` for how the servos are placed from the rest angle). The
  motor stroke 0-90 deg is the paper's (Section IV-A: 0 = horizontal horn, 90 = vertical);
  rod length, rest angle and horn length are our reading of FACTS.md, not the authors'
  6-DOF scene (which puts the sheet centres 120 mm apart and the servos on a 66 mm circle):
  these are the ``metasheet`` scene preset; the ``authors`` preset is theirs
  (:mod:`metasheet.robot.scenes`, selected with ``[orient] scene``).
"""

from __future__ import annotations

from ..conventions import TPU_DENSITY
from ..mechanics.material import Isotropic, TransverseIsotropic

#: The printed foam's transverse-isotropic constants [MPa, -] (authors' "paramPaper").
PAPER_FOAM = TransverseIsotropic(E_t=1.39, E_l=0.09422, nu_t=0.26162, nu_tl=0.4161, mu_l=0.01628215)
#: Relative density of the paper's foam [-].
FOAM_RELATIVE_DENSITY = 0.15
#: Mass density of the paper's foam sheet [t/mm^3]: TPU times the relative density.
FOAM_DENSITY = TPU_DENSITY * FOAM_RELATIVE_DENSITY

#: The tutorial's isotropic silicone sheet [MPa, -].
SILICONE = Isotropic(E=0.25, nu=0.45)
#: Mass density of the silicone sheet [t/mm^3].
SILICONE_DENSITY = 1.07e-9

#: Rod joining the two sheet centres; the effector is its midpoint [mm].
ROD_LENGTH = 80.0
#: Motor angle of the undeformed rest pose; places the servo pivots [deg].
REST_ANGLE = 60.0
#: Servo horn, pivot to the arm's tip box [mm].
HORN_LENGTH = 25.0
#: Motor stroke [deg]: 0 = horizontal horn, 90 = vertical (paper Section IV-A).
ANGLE_MIN, ANGLE_MAX = 0.0, 90.0


def is_published(material: TransverseIsotropic, rtol: float = 1e-6) -> bool:
    """True when ``material`` holds the paper's published foam constants (within ``rtol``)."""
    ref = PAPER_FOAM.to_dict()
    return all(abs(v - ref[k]) <= rtol * abs(ref[k]) for k, v in material.to_dict().items() if k in ref)
