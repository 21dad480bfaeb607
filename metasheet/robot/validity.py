"""The strain-validity check of a robot state, away from the grips' clamped edges.

The homogenised foam is a model for moderate strains: a state whose largest principal
Green-Lagrange strain exceeds a limit (0.3 by default) is outside its domain. Taken over
every element, that maximum does not converge under mesh refinement: where a sheet meets a
rigid grip (the clamped edge of a servo horn's tab or of the centre ring) the elastic field is
singular, and the finer the mesh at the grips the larger the strain of the elements that touch
them. A real clamp is not rigid and spreads that load over about a sheet thickness (Saint-Venant).

So the check counts the elements whose centroid lies farther than ``band_mm`` from every node
held by a grip (default :data:`GRIP_BAND_MM`, the authors' sheet thickness); the sharp concave
corners of the sheet itself stay in the check (the printed part has them). ``band_mm = 0``
counts every element (the raw maximum).
"""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError, check_range

#: width of the band along the grips left out of the validity check [mm] (the sheet thickness)
GRIP_BAND_MM = 5.0


def grip_distance(robot) -> np.ndarray:
    """(m,) distance [mm] from each element's centroid (corner nodes, at rest) to the nearest
    node a grip holds (the effector's and every servo's nodes)."""
    from scipy.spatial import cKDTree

    c, body = robot.coupling, robot.body
    held = np.unique(np.concatenate([np.asarray(c.effector_nodes)] + [np.asarray(s.nodes) for s in c.servos]))
    centroids = body.rest[body.tets[:, :4]].mean(axis=1)
    return cKDTree(body.rest[held]).query(centroids)[0]


def validity_elements(robot, band_mm: float = GRIP_BAND_MM) -> np.ndarray:
    """(m,) bool: the elements the check counts (centroid farther than ``band_mm`` [mm] from
    the grips); every element for ``band_mm = 0``."""
    check_range("strain_band_mm", band_mm, 0.0, 1000.0)
    if band_mm == 0:
        return np.ones(len(robot.body.tets), bool)
    keep = grip_distance(robot) > band_mm
    if not keep.any():
        raise ConfigError(f"strain_band_mm: {band_mm:g} mm leaves no element of the sheets to check: "
                          "use a narrower band")
    return keep


def validity_strain(body, x, elements: np.ndarray) -> float:
    """Largest principal Green-Lagrange strain [-] over the ``elements`` (m,) bool of ``body``
    (:meth:`~.body.ElasticBody.max_principal_strain`) at node positions ``x`` (n, 3) [mm]."""
    return float(body.max_principal_strain(x, elements).max())
