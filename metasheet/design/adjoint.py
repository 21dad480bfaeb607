"""The robot's linear rest problem as a function of the fibre design, and its adjoint gradient.

The model (exact for it, and only for it): small-strain linear elasticity of the two sheets
about the flat, undeformed rest configuration (motors at their rest angles, no gravity
preload), coupled to the effector and the servo horns by eq. (2). Its stiffness is

    K(theta) = sum_e P_e^T K_e(theta_e) P_e,    K_e = sum_q w_q B_q^T C_e(theta_e) B_q,

``C_e`` the foam's tensor turned to the element's fibre angle (:mod:`.tensor`) and then to
the world frame; this is the corotational body's tangent at rest with the gravity terms left
out (at rest the rotation is the identity and the geometric terms vanish). Condensing the free
nodes onto the rigid coordinates q_r = (q_e (6), q_a (na)) as the robot does
(:class:`metasheet.robot.statics.Linearizer`) gives

    S = A - B^T K_ff^-1 B,  A = J_r^T K_rr J_r,  B = K_fr J_r,  J = -S_ee^-1 S_ea = W_ea W_aa^-1

(eq. 6-7). The rest equilibrium is the undeformed state for every design, so no equilibrium
sensitivity arises; the gravity sag that :func:`metasheet.robot.compare.evaluate` solves for
is left out (on the light foam robot it moves the rod roll per degree by ~1e-5 relative:
docs/design.md).

Gradient of an objective ``g = alpha^T J beta`` (:class:`.objectives.RankOne`): with
``w = (J beta, beta)`` (the rigid motion "motors by beta, effector following") and
``mu = S_ee^-1 alpha`` (the adjoint of the effector's condensed equilibrium),

    dg = -(mu, 0)^T dS w,   and   a^T dS b = (E a)^T dK (E b),   E a = [J_r a ; -K_ff^-1 B a],

the derivative of a Schur complement of a symmetric matrix. ``E b`` is the full
displacement field of rigid motion b with the free nodes at equilibrium. The adjoint field
``lambda = E (mu, 0)`` needs ``K_ff^-1 B (mu, 0)``: one adjoint solve with K_ff (done here as
the combination ``Y (mu, 0)`` of the 6 + na columns ``Y = K_ff^-1 B`` the objective solved
already, the same numbers without a second back-substitution). Then, per element,

    dg/dtheta_e = -lambda_e^T (dK_e/dtheta_e) u_e = -sum_q w_q eps_q(lambda)^T dC_e/dtheta_e eps_q(u),

and ``dg/dc = N^T (dg/dtheta_A - dg/dtheta_B)`` (sheet B's angles are minus sheet A's,
:mod:`.fibre_field`). The cost is one objective evaluation plus element-wise products: no
solve per design variable.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..published import paper
from ..errors import ConfigError
from ..fem.assembly import submatrix_map
from ..fem.hex8 import strain_operator
from ..mechanics.material import Isotropic, TransverseIsotropic
from ..mechanics.material_model import check_model, model_stiffness
from ..robot.builder import SheetPair, six_dof_robot
from ..robot.kinematics import jacobian_from_schur
from ..robot.robots import Q_A, Q_B, ServoGeometry
from ..sheet.fibers import MIRROR
from . import objectives as obj
from ..sheet.fibre_field import FibreField, PolarBSpline
from .tensor import inplane_mandel, to_frame_mandel, to_voigt


@dataclass(frozen=True, eq=False)
class RestProblem:
    """Everything of the linear rest problem that does not depend on the design.

    Attributes
    ----------
    field : the :class:`.fibre_field.FibreField` on sheet A (m elements; B's are its mirror).
    C_local : (6, 6) the material's Voigt stiffness [MPa], axis 3 = l.
    robot : the six-DOF robot (no gravity) whose mesh, coupling and servos this model uses;
        its own element tensors are not read.
    B : (2m, nq, 6, 3 nen) strain operators [1/mm]; w : (2m, nq) quadrature weights [mm^3].
    Jr : (3 nr, 6 + na) rest Jacobian of the rigid nodes [mm per mm or rad].
    dof_r, dof_f : rigid and free dofs; maps : submatrix maps of K's rr, fr, ff blocks.
    length_scale : [mm] of the scaled singular values.
    """

    field: FibreField
    C_local: np.ndarray
    robot: object
    B: np.ndarray
    w: np.ndarray
    Jr: np.ndarray
    dof_r: np.ndarray
    dof_f: np.ndarray
    maps: dict
    length_scale: float = obj.LENGTH_SCALE

    @property
    def n_coefficients(self) -> int:
        return self.field.n_coefficients

    @property
    def n_elements(self) -> int:
        """Elements per sheet, m."""
        return len(self.field.theta0)


def rest_problem(sheets: SheetPair, material, basis: PolarBSpline | None = None, *, model: str = "ours",
                 rod_length: float = paper.ROD_LENGTH, geometry: ServoGeometry | None = None,
                 length_scale: float = obj.LENGTH_SCALE) -> RestProblem:
    """The linear rest problem of the robot of ``sheets`` made of ``material``, designed by ``basis``.

    Parameters
    ----------
    sheets : the pair; ``sheets.fibers`` (in the sheet plane) is the starting field theta0 and
        ``sheets.fibers_mirrored`` must be its mirror (``fibers @ diag(1, -1, 1)``, to 1e-9).
    material : :class:`~metasheet.mechanics.material.TransverseIsotropic` or
        :class:`~metasheet.mechanics.material.Isotropic`, the same everywhere (graded per-element
        constants are not supported here).
    basis : the design's :class:`.fibre_field.PolarBSpline` (default: 4 x 12 cubic, r_max the
        sheet's outer radius).
    model : "ours" or "authors" (:mod:`metasheet.mechanics.material_model`); rod_length [mm], geometry
        (None: the default :class:`~metasheet.robot.robots.ServoGeometry`): as
        :func:`metasheet.robot.builder.six_dof_robot`.
    length_scale : [mm] for the scaled singular values.
    """
    check_model(model, "model")
    if not isinstance(material, (Isotropic, TransverseIsotropic)):
        raise ConfigError(f"material: {type(material).__name__}: expected Isotropic or TransverseIsotropic")
    if sheets.element != "p1":
        raise ConfigError(f"element: {sheets.element!r}: the design's rest problem supports 'p1' only")
    fa, fb = np.asarray(sheets.fibers, float), np.asarray(sheets.fibers_mirrored, float)
    if np.abs(fa @ MIRROR - fb).max() > 1e-9 * max(1.0, float(np.abs(fa).max())):
        raise ConfigError("fibers_mirrored: not the mirror image of fibers (fibers @ diag(1, -1, 1)); "
                          "the design keeps sheet B the mirror of sheet A")
    if basis is None:
        r = float(np.hypot(sheets.sheet.points[:, 0], sheets.sheet.points[:, 1]).max())
        basis = PolarBSpline(r_max=r)
    field = FibreField.from_fibres(sheets.sheet.centroids(), fa, basis)
    # the density only makes gravity loads, and this model has none: any positive value will do
    robot = six_dof_robot(sheets, material, density=paper.FOAM_DENSITY, rod_length=rod_length,
                          geometry=ServoGeometry() if geometry is None else geometry, gravity=(0.0, 0.0, 0.0), model=model)
    body, c = robot.body, robot.coupling
    K0 = body.pattern.matrix(np.zeros(body.pattern.nnz))
    dof_r = (3 * c.rigid_nodes[:, None] + np.arange(3)).ravel()
    dof_f = (3 * c.free[:, None] + np.arange(3)).ravel()
    maps = {k: submatrix_map(K0, a, b) for k, (a, b) in
            {"rr": (dof_r, dof_r), "fr": (dof_f, dof_r), "ff": (dof_f, dof_f)}.items()}
    obj._scale(length_scale)  # validates it
    return RestProblem(field, model_stiffness(material, model), robot, strain_operator(body.quad_grads),
                       np.asarray(body.quad_weights, float), c.rigid_jacobian(c.rest, c.origin),
                       dof_r, dof_f, maps, float(length_scale))


@dataclass(frozen=True, eq=False)
class RestSolution:
    """The linear rest problem solved for one design.

    Attributes
    ----------
    c : (n,) the design's coefficients [rad]; theta : (m,) sheet A's fibre angles [rad].
    S : (6 + na, 6 + na) condensed stiffness (N/mm, N, N mm per mm or rad), symmetric.
    J : (6, na) direct Jacobian (mm/rad, rad/rad), ``W_ea W_aa^-1`` (eq. 7).
    Y : (3 nf, 6 + na) ``K_ff^-1 B``: free-node motion per unit rigid coordinate.
    dC : (2m, 6, 6) world-frame Voigt dC_e/dtheta_e [MPa/rad] (A's elements, then B's,
        each B element's derivative in its own angle theta_B = -theta_A).
    roll : rod roll per degree of all motors [deg/deg]; singular_values : (na,) [mm/rad].
    ff : the factorised K_ff (``solve(b)`` gives ``K_ff^-1 b``), kept for the adjoint solves of
        objectives that are not functions of J alone (the strain: :mod:`.constraints`).
    """

    c: np.ndarray
    theta: np.ndarray
    S: np.ndarray
    J: np.ndarray
    Y: np.ndarray
    dC: np.ndarray
    roll: float
    singular_values: np.ndarray
    ff: object = None


def _world_tensors(problem: RestProblem, theta: np.ndarray):
    """(2m, 6, 6) world Voigt C and dC/dtheta of both sheets' elements."""
    Ca, dCa = inplane_mandel(problem.C_local, theta)
    Cb, dCb = inplane_mandel(problem.C_local, -theta)
    C = np.concatenate([to_frame_mandel(Ca, Q_A), to_frame_mandel(Cb, Q_B)])
    dC = np.concatenate([to_frame_mandel(dCa, Q_A), to_frame_mandel(dCb, Q_B)])
    return to_voigt(C), to_voigt(dC)


def solve_rest(problem: RestProblem, c) -> RestSolution:
    """Assemble K(theta(c)), condense it, and form J and the objectives at the rest pose."""
    theta = problem.field.angles(c)
    C, dC = _world_tensors(problem, theta)
    body = problem.robot.body
    # K_e = sum_q w B^T C B: plain batched products, the same order every run (no threads)
    CB = np.einsum("mij,mqjb->mqib", C, problem.B)
    Ke = np.einsum("mq,mqia,mqib->mab", problem.w, problem.B, CB)
    Ke = 0.5 * (Ke + np.transpose(Ke, (0, 2, 1)))
    data = body.pattern.assemble_data(Ke)
    blk = {k: _block(sub, data[take]) for k, (sub, take) in problem.maps.items()}
    Bfr = np.asarray(blk["fr"] @ problem.Jr)
    A = problem.Jr.T @ np.asarray(blk["rr"] @ problem.Jr)
    ff = spla.splu(blk["ff"].tocsc())
    Y = ff.solve(Bfr)
    S = A - Bfr.T @ Y
    S = 0.5 * (S + S.T)  # symmetric in exact arithmetic; made exactly so for the adjoint identity
    _, J = jacobian_from_schur(S)
    roll = obj.rod_roll_per_degree(J, problem.robot.axis)
    sv = obj.scaled_singular_values(J, problem.length_scale)
    return RestSolution(problem.field.check(c), theta, S, J, Y, dC, roll, sv, ff)


def _block(sub, data):
    return sp.csr_matrix((data, sub.indices, sub.indptr), shape=sub.shape)


def _field(problem: RestProblem, sol: RestSolution, q: np.ndarray) -> np.ndarray:
    """(n_nodes * 3,) displacement [mm] of rigid motion ``q`` (6 + na,) with the free nodes at
    equilibrium: ``E q`` (rigid nodes ``J_r q``, free nodes ``-K_ff^-1 B q``)."""
    u = np.zeros(problem.robot.body.n_nodes * 3)
    u[problem.dof_r] = problem.Jr @ q
    u[problem.dof_f] = -(sol.Y @ q)
    return u


def angle_sensitivity(problem: RestProblem, sol: RestSolution, weights: obj.RankOne) -> np.ndarray:
    """(m,) d g / d theta_e of ``g = alpha^T J beta`` per element of sheet A [unit of g per rad],
    sheet B's (mirrored) element included through theta_B = -theta_A (module docstring)."""
    S, J, na = sol.S, sol.J, sol.J.shape[1]
    mu = np.linalg.solve(S[:6, :6].T, weights.alpha)  # the adjoint of the effector's equilibrium
    w = np.concatenate([J @ weights.beta, weights.beta])
    lam = _field(problem, sol, np.concatenate([mu, np.zeros(na)]))
    u = _field(problem, sol, w)
    return stiffness_product(problem, sol, lam, u)


def stiffness_product(problem: RestProblem, sol: RestSolution, lam: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(m,) ``-lam^T (dK/dtheta_e) u`` per element of sheet A [unit of lam x N/mm x mm per rad]
    for fields ``lam``, ``u`` (3 n,) [mm], sheet B's mirrored element folded in
    (theta_B = -theta_A): the design derivative of any objective whose adjoint field is ``lam``."""
    dofs = problem.robot.body.pattern.dofs
    eps_l = np.einsum("mqia,ma->mqi", problem.B, lam[dofs])
    eps_u = np.einsum("mqia,ma->mqi", problem.B, u[dofs])
    g = -np.einsum("mq,mqi,mij,mqj->m", problem.w, eps_l, sol.dC, eps_u)
    m = problem.n_elements
    return g[:m] - g[m:]


def gradient(problem: RestProblem, sol: RestSolution, weights: obj.RankOne) -> np.ndarray:
    """(n,) d g / d c of ``g = alpha^T J beta`` [unit of g per rad of coefficient]."""
    return problem.field.N.T @ angle_sensitivity(problem, sol, weights)


@dataclass(frozen=True)
class Sensitivity:
    """An objective at one design and its gradient.

    Attributes
    ----------
    name : "rod_roll_per_degree" [deg/deg] or "min_singular_value" [mm/rad].
    value : the objective; gradient : (n,) d value / d c [unit per rad].
    per_element : (m,) d value / d theta_e on sheet A's elements [unit per rad].
    gap : distance to non-differentiability (inf for the roll; the singular-value gap).
    """

    name: str
    value: float
    gradient: np.ndarray
    per_element: np.ndarray
    gap: float


def roll_sensitivity(problem: RestProblem, c, sol: RestSolution | None = None) -> Sensitivity:
    """Rod roll per degree of all motors [deg/deg] at design ``c`` and its adjoint gradient."""
    sol = solve_rest(problem, c) if sol is None else sol
    wts = obj.rod_roll_weights(sol.J, problem.robot.axis)
    per = angle_sensitivity(problem, sol, wts)
    return Sensitivity("rod_roll_per_degree", wts.value, problem.field.N.T @ per, per, wts.gap)


def min_singular_sensitivity(problem: RestProblem, c, sol: RestSolution | None = None) -> Sensitivity:
    """Smallest scaled singular value [mm/rad] at design ``c`` and its adjoint gradient (exact
    where it is simple: see ``gap``)."""
    sol = solve_rest(problem, c) if sol is None else sol
    wts = obj.min_singular_weights(sol.J, problem.length_scale)
    per = angle_sensitivity(problem, sol, wts)
    return Sensitivity("min_singular_value", wts.value, problem.field.N.T @ per, per, wts.gap)
