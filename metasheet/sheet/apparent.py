"""Apparent constants: the transverse-isotropic material that makes the homogenised sheet FEM
best reproduce a target grip stiffness (issue 44, item 4; the target is the printed foam's DNS).

The model is the sheet FEM of :func:`.grips.fem_condensed`: same mesh, fibre field, element
and material model (:mod:`metasheet.mechanics.material_model`), one material everywhere. The misfit is
scale-free: the residual is ``log`` of the 18 generalised eigenvalues of (target, model)
relative stiffnesses (:func:`.grips.eigen_pairs`), the objective its squared 2-norm (the
affine-invariant distance of the two 18 x 18 matrices: units and coordinate scaling drop out).

Why it is cheap: a transverse-isotropic tensor about its axis 3 is linear in five components
``c = (C11, C12, C13, C33, C44)`` (C22 = C11, C23 = C13, C55 = C44, C66 = (C11 - C12) / 2),
for both material models, and rotating it to each element's fibre is linear too, so the
assembled stiffness is ``K(c) = sum_j c_j K_j`` with five matrices assembled once
(:class:`SheetBasis`). One evaluation is one sparse factorisation of the free block; its
displacement fields U of the unit grip motions give the exact derivative
``dS / dc_j = U^T K_j U``, hence an analytic Jacobian of the residual
(``d log lambda_i / dc_j = -w_i^T K_j w_i``, ``w_i`` the displacement field of mode i).

The fit runs in ``p = (log E_t, log E_l, atanh nu_t, atanh(nu_tl / b), log mu_l)`` with
``b = sqrt((1 - nu_t) E_t / (2 E_l))``: every p is a positive-definite material of ours
(:class:`~metasheet.mechanics.material.TransverseIsotropic`'s conditions); ``dc / dp`` comes from central
differences of that closed-form map. The authors' model ignores mu_l (its C44 is
``(C11 - C12) / 2``): then only the first four are fitted and mu_l stays at its start
(:attr:`ApparentFit.fitted` says which); a p whose authors' tensor is indefinite gets a
non-finite residual, which the trust region answers by shrinking its step.

Measured on the paper's 5 mm sheet in P2 (``SheetPair.spiral(SheetParams(), element="p2")``:
3,586 tets, 19,974 dofs, pitch 45 deg), model "ours", start PAPER_FOAM, SuperLU, one of two
shared cores (OPENBLAS_NUM_THREADS=1: with OpenBLAS's default threads on the busy machine the
small dense products of a condensation took 0.1-0.2 s each):

* the five K_j: 1.3 s; one condensation 0.3-0.4 s; one evaluation with its Jacobian 0.5 s.
* its own FEM target at E_t x1.3, E_l x0.6, nu_t 0.2, nu_tl 0.5, mu_l x1.5: 9 evaluations,
  4.4 s, converged, rms log ratio 2e-11 (from 0.20). The Jacobian's singular values there,
  (2.5, 1.0, 0.87, 0.29, 0.0096): the smallest is almost purely nu_t, which a plate hardly
  sees (only through the transverse shear mu_t), so a noisy target leaves nu_t loose.
* unreachable targets stop at ``max_evaluations`` (60) without converging, in ~30 s: the FEM
  of fibres at pitch 30 deg (rms 0.72 -> 0.17), nu_tl running to its limit (pd_margin
  0.003); the authors' model on ours' PAPER_FOAM target (rms 1.27 -> 0.37), nu_t -> 0.93.
  The best TI material then lies on the positive-definiteness limit: read ``pd_margin``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.optimize import least_squares

from ..errors import ConfigError
from ..mechanics.material import CONSTANT_NAMES, TransverseIsotropic
from ..mechanics.material_model import check_model, model_stiffness
from ..mechanics.voigt import stiffness_along
from .elements import as_element
from .grips import (
    GripCondensation,
    check_references,
    check_stiffness,
    eigen_pairs,
    grip_references,
    linear_stiffness,
    relative_stiffness,
)

#: the five components a transverse-isotropic tensor about axis 3 is linear in [MPa]
COMPONENT_NAMES = ("C11", "C12", "C13", "C33", "C44")
#: Voigt entries (row, col) read off a tensor for each component
_ENTRIES = ((0, 0), (0, 1), (0, 2), (2, 2), (3, 3))
#: step of the central differences of c(p) (p is O(1): logs and atanh)
_STEP = 1e-6


def component_basis() -> np.ndarray:
    """(5, 6, 6) Voigt tensors E_j with ``C = sum_j c_j E_j`` for every transverse-isotropic
    C about axis 3 (engineering shear: C66 = (C11 - C12) / 2)."""
    E = np.zeros((5, 6, 6))
    E[0][[0, 1], [0, 1]] = 1.0
    E[0, 5, 5] = 0.5
    E[1, 0, 1] = E[1, 1, 0] = 1.0
    E[1, 5, 5] = -0.5
    E[2][[0, 2, 1, 2], [2, 0, 2, 1]] = 1.0
    E[3, 2, 2] = 1.0
    E[4][[3, 4], [3, 4]] = 1.0
    return E


def model_components(constants, model: str = "ours") -> np.ndarray:
    """(5,) c [MPa] of the tensor ``model`` makes of ``constants`` (5,) in CONSTANT_NAMES order;
    ConfigError (naming the constant) when they make no positive-definite tensor."""
    C = model_stiffness(TransverseIsotropic(*(float(v) for v in constants)), model)
    return np.array([C[i, j] for i, j in _ENTRIES])


def to_params(constants) -> np.ndarray:
    """(5,) p of (5,) constants (module docstring): unbounded, every p a valid material."""
    E_t, E_l, nu_t, nu_tl, mu_l = (float(v) for v in constants)
    b = np.sqrt((1.0 - nu_t) * E_t / (2.0 * E_l))
    return np.array([np.log(E_t), np.log(E_l), np.arctanh(nu_t), np.arctanh(nu_tl / b), np.log(mu_l)])


def from_params(p) -> np.ndarray:
    """(5,) constants [MPa, -] of (5,) p, the inverse of :func:`to_params`."""
    E_t, E_l, nu_t = np.exp(p[0]), np.exp(p[1]), np.tanh(p[2])
    b = np.sqrt((1.0 - nu_t) * E_t / (2.0 * E_l))
    return np.array([E_t, E_l, nu_t, b * np.tanh(p[3]), np.exp(p[4])])


def pd_margin(constants) -> float:
    """min(1 - |nu_t|, 1 - |nu_tl| / b) of (5,) constants, b of :func:`to_params` [-]: 0 on
    the limit of positive definiteness, 1 at nu_t = nu_tl = 0."""
    E_t, E_l, nu_t, nu_tl, _ = (float(v) for v in constants)
    b = np.sqrt((1.0 - nu_t) * E_t / (2.0 * E_l))
    return float(min(1.0 - abs(nu_t), 1.0 - abs(nu_tl) / b))


def _check_constants(constants, name: str, model: str) -> np.ndarray:
    """(5,) constants of a TransverseIsotropic, a dict or a (5,) sequence that make a
    positive-definite tensor of ``model``, else ConfigError naming ``name``."""
    if isinstance(constants, TransverseIsotropic):
        x = np.array(constants.as_tuple())
    elif isinstance(constants, dict):
        x = np.array(TransverseIsotropic.from_mapping(constants, where=name).as_tuple())
    else:
        x = np.asarray(constants, float)
        if x.shape != (5,) or not np.all(np.isfinite(x)):
            raise ConfigError(f"{name}: shape is {x.shape} and should be finite (5,): {', '.join(CONSTANT_NAMES)}")
    try:
        model_components(x, model)
    except ConfigError as err:
        raise ConfigError(f"{name}: {err}") from None
    return x


def _named(x) -> dict:
    return {k: float(v) for k, v in zip(CONSTANT_NAMES, x)}


@dataclass(frozen=True, eq=False)
class SheetBasis:
    """The sheet FEM as a linear function of c: ``K(c) = sum_j c_j K_j``.

    Attributes
    ----------
    pattern : (3n, 3n) CSR whose indices all the K_j share (its data is K_0's).
    data : (5, nnz) the K_j's data [N/mm per MPa], component order :data:`COMPONENT_NAMES`.
    condensation : the grips' :class:`~.grips.GripCondensation` of this pattern.
    references : (4, 3) [mm]; element : "p1" or "p2"; seconds : assembly time [s].
    """

    pattern: sp.csr_matrix
    data: np.ndarray
    condensation: GripCondensation
    references: np.ndarray
    element: str
    seconds: float

    def matrix(self, weights) -> sp.csr_matrix:
        """(3n, 3n) CSR ``sum_j weights_j K_j``: K(c) for weights = c (5,) [MPa]."""
        w = np.asarray(weights, float)
        if w.shape != (5,) or not np.all(np.isfinite(w)):
            raise ConfigError(f"c: shape is {w.shape} and should be finite (5,): {', '.join(COMPONENT_NAMES)}")
        return sp.csr_matrix((w @ self.data, self.pattern.indices, self.pattern.indptr), shape=self.pattern.shape)

    def condensed(self, c, *, fields: bool = False, solver: str = "superlu"):
        """(24, 24) grip stiffness at components ``c`` (5,); with ``fields`` also U (3n, 24)
        (:meth:`.grips.GripCondensation.condense`)."""
        K = self.matrix(c)
        return self.condensation.condense(K, solver, fields=fields)


def sheet_basis(sheet, fibers, element: str = "p2", *, references=None) -> SheetBasis:
    """Assemble the five K_j of ``sheet`` (a linear SheetMesh) with its fibre field ``fibers``
    (m, 3) (axis 3 = l along each), in ``element`` ("p1", "p2")."""
    t0 = time.perf_counter()
    m = len(sheet.tets)
    if np.shape(fibers) != (m, 3):
        raise ConfigError(f"fibers: shape is {np.shape(fibers)} and should be ({m}, 3)")
    refs = grip_references(sheet.params) if references is None else check_references(references)
    mesh = as_element(sheet, element)
    pts = np.asarray(mesh.points, float)
    mats = [linear_stiffness(pts, mesh.tets, stiffness_along(E, fibers)) for E in component_basis()]
    # one assembly pattern (SparsityPattern.from_elements of the same tets): data can be combined
    if any(not np.array_equal(A.indices, mats[0].indices) or not np.array_equal(A.indptr, mats[0].indptr)
           for A in mats[1:]):
        raise RuntimeError("sheet_basis: the five assemblies differ in pattern")
    cond = GripCondensation.of(mats[0], pts, mesh.attach, refs)
    return SheetBasis(mats[0], np.stack([A.data for A in mats]), cond, refs, element, time.perf_counter() - t0)


@dataclass(frozen=True, eq=False)
class ApparentFit:
    """The apparent constants of a target grip stiffness (:func:`fit_apparent`).

    constants : {name: value} [MPa, -] in CONSTANT_NAMES order; start : the same at the start.
    fitted : the names that were fitted (the authors' model: mu_l is not, it stays at start).
    model : "ours" or "authors"; element : "p1" or "p2"; components : (5,) c of the fitted tensor [MPa].
    rms_log, max_log : rms and max |log ratio| of the 18 eigen-ratios at the fit [-].
    ratios_start, ratios_fit : (18,) ascending eigen-ratios target / model [-].
    singular_values : (len(fitted),) of the residual's Jacobian by p at the fit [-] (p: log
        moduli, atanh of the bounded ratios): a small one is a combination the target leaves
        undetermined (a flat valley: the constants along it are not to be trusted).
    pd_margin : min(1 - |nu_t|, 1 - |nu_tl| / b) at the fit [-], the distance of the bounded
        Poisson ratios to the positive-definite limit (module docstring): near 0, the best
        fit lies on that limit, p runs off to infinity and the fit stops without converging.
    evaluations : model evaluations (sparse factorisations); seconds : fit wall time [s].
    converged : the optimiser met a tolerance (False: it ran out of evaluations or failed);
    message : the optimiser's word.
    """

    constants: dict
    start: dict
    fitted: tuple
    model: str
    element: str
    components: np.ndarray
    rms_log: float
    max_log: float
    ratios_start: np.ndarray
    ratios_fit: np.ndarray
    singular_values: np.ndarray
    pd_margin: float
    evaluations: int
    seconds: float
    converged: bool
    message: str

    @property
    def material(self) -> TransverseIsotropic:
        return TransverseIsotropic.from_mapping(self.constants, where="constants")


def log_ratios(basis: SheetBasis, K_target, c, *, jacobian: bool = False):
    """(18,) log eigen-ratios of target over model at components ``c`` (5,), ascending; with
    ``jacobian`` also (18, 5) their derivatives by c [1/MPa] (exact, from U^T K_j U)."""
    S, U = basis.condensed(c, fields=True)
    pairs = eigen_pairs(K_target, S, basis.references)
    r = np.log(pairs.ratios)
    if not jacobian:
        return r
    W = U[:, 6:] @ pairs.modes  # (3n, 18) each mode's field; modes are v^T S_rel v = 1
    J = np.empty((18, 5))
    for j in range(5):  # K_t v = lam S v: d lam = -lam v^T dS v, so d log lam = -w^T K_j w
        Kj = sp.csr_matrix((basis.data[j], basis.pattern.indices, basis.pattern.indptr), shape=basis.pattern.shape)
        J[:, j] = -np.einsum("ni,ni->i", W, np.asarray(Kj @ W))
    return r, J


def _components_jacobian(p, model: str, free) -> np.ndarray:
    """(5, len(free)) dc/dp by central differences (one-sided where a side is no material)."""
    D = np.empty((5, len(free)))
    for k, i in enumerate(free):
        side = []
        for s in (1.0, -1.0):
            q = p.copy()
            q[i] += s * _STEP
            try:
                side.append((s, model_components(from_params(q), model)))
            except ConfigError:  # the authors' tensor can turn indefinite within the step
                pass
        if not side:
            raise ConfigError(f"start: no positive-definite {model!r} tensor near p = {p.tolist()}")
        c0 = model_components(from_params(p), model) if len(side) == 1 else None
        D[:, k] = ((side[0][1] - side[1][1]) / (2 * _STEP) if len(side) == 2
                   else side[0][0] * (side[0][1] - c0) / _STEP)
    return D


def fit_apparent(basis, K_target, start, *, model: str = "ours", tol: float = 1e-10,
                 max_evaluations: int = 60) -> ApparentFit:
    """The constants whose sheet FEM (``basis``) best matches ``K_target`` (24, 24) [N/mm, N,
    N mm] in the log eigen-ratio norm, from ``start`` (TransverseIsotropic, dict or (5,)).

    Several sheets of one material (the robot's two: normal and mirrored) are fitted at once
    with ``basis`` and ``K_target`` sequences of equal length: their residuals are stacked
    (18 per sheet, ``ratios_start``/``ratios_fit`` in that order).

    ``model``: "ours" fits all five; "authors" fits E_t, E_l, nu_t, nu_tl (mu_l unused).
    ``tol``: least_squares' xtol, ftol and gtol; ``max_evaluations``: its max_nfev.
    """
    t0 = time.perf_counter()
    check_model(model, "model")
    bases = tuple(basis) if isinstance(basis, (tuple, list)) else (basis,)
    targets = tuple(K_target) if isinstance(K_target, (tuple, list)) else (K_target,)
    if len(bases) != len(targets) or not bases:
        raise ConfigError(f"basis, K_target: {len(bases)} bases for {len(targets)} targets: give one target per basis")
    targets = tuple(check_stiffness(K, "K_target") for K in targets)
    for K, b in zip(targets, bases):
        if np.linalg.eigvalsh(relative_stiffness(0.5 * (K + K.T), b.references))[0] <= 0:
            raise ConfigError("K_target: its arms' block (centre held) is not positive definite: "
                              "allowed only a sheet held by its centre")
    if not (0.0 < float(tol) < 1.0):
        raise ConfigError(f"tol: {tol!r}: allowed range (0, 1)")
    if int(max_evaluations) < 1:
        raise ConfigError(f"max_evaluations: {max_evaluations!r}: allowed >= 1")
    x0 = _check_constants(start, "start", model)
    p0 = to_params(x0)
    free = list(range(5 if model == "ours" else 4))
    cache, count = {}, [0]

    def full(q):
        p = p0.copy()
        p[free] = q
        return p

    def evaluate(q):
        key = tuple(np.asarray(q, float))
        if key not in cache:
            p = full(q)
            try:
                c = model_components(from_params(p), model)
            except ConfigError:  # no tensor there (authors' model): the trust region steps back
                return np.full(18 * len(bases), np.nan), None
            count[0] += 1
            parts = [log_ratios(b, K, c, jacobian=True) for b, K in zip(bases, targets)]
            r, Jc = np.concatenate([q[0] for q in parts]), np.vstack([q[1] for q in parts])
            cache.clear()  # least_squares asks for the Jacobian at the last accepted point only
            cache[key] = (r, Jc @ _components_jacobian(p, model, free))
        return cache[key]

    r0 = evaluate(p0[free])[0]
    res = least_squares(lambda q: evaluate(q)[0], p0[free], jac=lambda q: evaluate(q)[1], method="trf",
                        xtol=tol, ftol=tol, gtol=tol, max_nfev=int(max_evaluations))
    x = from_params(full(res.x))
    x[len(free):] = x0[len(free):]  # the unfitted mu_l exactly as given (exp(log) rounds)
    r = np.asarray(res.fun, float)  # at the last accepted point
    return ApparentFit(
        constants=_named(x), start=_named(x0), fitted=tuple(CONSTANT_NAMES[i] for i in free), model=model,
        element=bases[0].element, components=model_components(x, model), rms_log=float(np.sqrt(np.mean(r**2))),
        max_log=float(np.abs(r).max()), ratios_start=np.exp(r0), ratios_fit=np.exp(r),
        singular_values=np.linalg.svd(np.atleast_2d(res.jac), compute_uv=False), pd_margin=pd_margin(x),
        evaluations=count[0],
        seconds=time.perf_counter() - t0, converged=bool(res.status > 0), message=str(res.message))
