"""The largest principal strain of a design at a stated set of motor goals (issue 45, item 1).

Measure: the **linearised small-strain** tensor ``eps = sym(grad u)`` of the linear rest problem
(:mod:`.adjoint`), not the Green-Lagrange strain of the nonlinear robot the studies check: for a
goal q_a (na,) [rad] the motors turn by q_a, the effector follows to its equilibrium (q_e =
J q_a) and the free nodes settle, so the displacement is ``u = E (J q_a, q_a)`` and, per element
and quadrature point, ``eps = B u`` (Voigt, engineering shear). Its largest eigenvalue is the
largest principal strain [-]; it is linear in the goal (twice the angle, twice the strain), and
agrees with the Green strain to first order (the difference is O(|grad u|^2): ~10 % at 0.3).
The limit is the studies' validity limit of the homogenised foam, :data:`STRAIN_LIMIT` = 0.3
(``strain_limit`` of the workspace and reduce studies).

Elements within :data:`metasheet.robot.validity.GRIP_BAND_MM` of a grip are left out, as the
studies' check does (the clamped edges are singular: their strain grows with refinement).

Goals (:func:`goals`): all motors at +N and at -N deg together (the roll's motion), and motor 0
alone at +N and -N deg (a single-motor move); N = ``goal_deg``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, check_range
from ..homogenize.localisation import voigt_to_tensor

#: [-] validity limit of the homogenised foam's constants (the studies' ``strain_limit``)
STRAIN_LIMIT = 0.3
#: [deg] default goal amplitude
GOAL_DEG = 10.0


@dataclass(frozen=True)
class Goal:
    """A motor goal: ``name`` and ``motors_deg`` (na,) [deg] from rest."""

    name: str
    motors_deg: tuple[float, ...]


@dataclass(frozen=True)
class GoalStrain:
    """The largest principal small strain [-] at each goal, over the checked elements.

    Attributes
    ----------
    goals : the goals, in order; strain : (len(goals),) [-]; limit : [-] the validity limit;
    goal_deg : [deg] the goals' amplitude; elements : how many elements were checked.
    """

    goals: tuple[Goal, ...]
    strain: tuple[float, ...]
    limit: float
    goal_deg: float
    elements: int

    @property
    def worst(self) -> float:
        """The largest of :attr:`strain` [-]."""
        return max(self.strain)

    @property
    def within_limit(self) -> bool:
        return self.worst <= self.limit


def goals(na: int, goal_deg: float = GOAL_DEG) -> tuple[Goal, ...]:
    """The stated goals for ``na`` motors at amplitude ``goal_deg`` [deg] (module docstring)."""
    check_range("goal_deg", goal_deg, 0.0, 90.0, lo_open=True)
    if na < 1:
        raise ConfigError(f"na: {na!r}: expected at least one motor")
    n = float(goal_deg)
    one = tuple([n] + [0.0] * (na - 1))
    return (Goal(f"all +{n:g} deg", (n,) * na), Goal(f"all -{n:g} deg", (-n,) * na),
            Goal(f"motor 0 +{n:g} deg", one), Goal(f"motor 0 -{n:g} deg", tuple([-n] + [0.0] * (na - 1))))


def principal_strains(eps: np.ndarray) -> np.ndarray:
    """(..., 3) eigenvalues [-], ascending, of Voigt small strains ``eps`` (..., 6) (engineering
    shear: 11, 22, 33, 2*23, 2*13, 2*12)."""
    e = np.asarray(eps, float)
    if e.shape[-1] != 6:
        raise ConfigError(f"eps: shape {e.shape}: expected (..., 6) Voigt strains")
    return np.linalg.eigvalsh(voigt_to_tensor(e))


def element_strains(B: np.ndarray, dofs: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(m, nq, 6) Voigt small strains [-] ``B u`` of displacement ``u`` (3 n,) [mm]; ``B``
    (m, nq, 6, 3 nen) [1/mm], ``dofs`` (m, 3 nen) each element's dof numbers."""
    return np.einsum("mqia,ma->mqi", B, np.asarray(u, float)[dofs])


def max_principal_strain(B: np.ndarray, dofs: np.ndarray, u: np.ndarray, elements: np.ndarray) -> float:
    """Largest principal small strain [-] of ``u`` over the ``elements`` (m,) bool and their
    quadrature points."""
    eps = element_strains(B[elements], dofs[elements], u)
    return float(principal_strains(eps)[..., -1].max())


def goal_strain(problem, sol, goal_deg: float = GOAL_DEG, band_mm: float | None = None) -> GoalStrain:
    """The largest principal small strain of the design ``sol`` (:class:`.adjoint.RestSolution`)
    of ``problem`` at :func:`goals` (``goal_deg`` [deg]), elements beyond ``band_mm`` [mm] of the
    grips (None: :data:`~metasheet.robot.validity.GRIP_BAND_MM`)."""
    from ..robot.validity import GRIP_BAND_MM, validity_elements
    from .adjoint import _field

    keep = validity_elements(problem.robot, GRIP_BAND_MM if band_mm is None else band_mm)
    dofs = problem.robot.body.pattern.dofs
    gs = goals(sol.J.shape[1], goal_deg)
    out = []
    for g in gs:
        qa = np.radians(np.asarray(g.motors_deg, float))
        u = _field(problem, sol, np.concatenate([sol.J @ qa, qa]))
        out.append(max_principal_strain(problem.B, dofs, u, keep))
    return GoalStrain(gs, tuple(out), STRAIN_LIMIT, float(goal_deg), int(keep.sum()))
