"""A hyperelastic voxel body with prescribed displacements, solved by Newton's method with the
linear multigrid as the preconditioner of each step's CG.

The body is the solid voxels of a phase grid, one neo-Hookean law
(:class:`~.hyperelastic.NeoHookean`) for every solid phase, no body forces. Dofs named in
``prescribed`` take the given displacements; the others are found where the internal forces
vanish, which for a hyperelastic body is where the strain energy is stationary over them:

1. **Predictor.** From the current state, the prescribed dofs move by their increment and the
   free dofs by the tangent's answer to it (``K_ff du_f = -K_fp du_p``), the consistent linear
   prediction. Where a Gauss point would invert (det F <= 0) the increment is halved and the
   load taken in more steps (at most ``max_substeps``).
2. **Newton in a trust region.** Each step minimises the tangent's quadratic model within a
   radius [mm] by Steihaug's truncated CG (:mod:`.trust_region`), to a relative tolerance that
   tightens with the residual (``min(0.1, sqrt(|r| / |f|))``, down to ``rtol / 10``: Eisenstat
   and Walker's superlinear choice; the linear multigrid preconditions the deformed tangent
   poorly, and CG iterations are what a step costs), preconditioned
   by the split multigrid of the *linear* elastic body (:func:`~.multigrid.build_hierarchy`,
   built once): at rest the tangent is that operator, away from it a fixed, well-conditioned
   approximation of it. Once the steps' CG has taken more than :data:`REBUILD_ITERATIONS` on the
   multigrid in use, the next step's is rebuilt on the current tangent (:mod:`.tangent_multigrid`;
   back to the rest one where that is not positive definite, and the count doubled before the
   next try). The step is kept where the energy falls by at least a tenth of the model's
   prediction, and the radius follows that ratio. Thin walls that buckle make the tangent
   indefinite; the trust region then follows the falling directions instead of
   solving an indefinite system (a line search did not: it stalled on the printed sheet).
3. **Stable, not only balanced.** A Newton method converges to saddles too: a perfect column
   pressed past its buckling load balances straight. At the end the tangent is probed once
   for negative curvature (truncated CG from a fixed pseudo-random right-hand side, at most
   100 iterations: CG is Lanczos, and the extreme eigenvalues come first); along one found,
   the state moves to a lower energy and Newton resumes (at most three times).
4. **Stop** when the free dofs' residual is at most ``rtol`` times the internal forces' norm on
   the prescribed dofs (the reactions), or raise :class:`~metasheet.errors.ConvergenceError`
   with the history.

The result holds the displacements and internal forces of the body's nodes (reactions at the
prescribed dofs). Everything runs sequentially over fixed orders (the kernels, the CG's
fixed-order reductions): the same bits on any thread count.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from threadpoolctl import threadpool_limits

from ...errors import ConfigError, ConvergenceError, check_range
from ..hex8 import HEX8_CORNERS
from .contact import Contact, SurfacePairs, surface_areas
from .element import validate_grid
from .hyperelastic import (NeoHookean, colour_order, gauss_gradients, internal_forces, max_principal_strain,
                           tangent_apply)
from .multigrid import Hierarchy, build_hierarchy
from .operator import VoxelOperator, node_shape, touched_nodes
from .pcg import pcg
from .tangent_multigrid import tangent_hierarchy, tangent_table
from .trust_region import steihaug, update_radius


@dataclass(frozen=True)
class NonlinearSolution:
    """The equilibrium of a hyperelastic voxel body.

    nodes : (n,) int64 flat grid nodes ``(i Ny + j) Nz + k`` of the body (those its solid voxels
        touch), increasing; u : (n, 3) [mm] their displacements; forces : (n, 3) [N] the internal
        forces there (the reactions at the prescribed dofs, ~0 at the free ones).
    energy : the strain energy [mJ = N mm]; residual : the free dofs' final residual over the
        reactions' norm (or over the forces' round-off / rtol where they vanish) [-]; newton : Newton iterations (all load steps); cg : CG iterations of each
        solve; steps : load steps taken; node_shape : (Nx, Ny, Nz); h : (3,) voxel edges [mm];
        strain : (nx, ny, nz) each solid voxel's largest principal Green-Lagrange strain over its
        Gauss points [-], NaN in the void; stable : the stability probe found no negative
        curvature (True), still found one after three escapes (False), or did not run (None).
    contact : with a penalty (:mod:`.contact`), its pairs at the solution: ``pairs``,
        ``min_distance_mm``, ``force_N`` (the pair forces' sum); None without one.
    """

    nodes: np.ndarray
    u: np.ndarray
    forces: np.ndarray
    energy: float
    residual: float
    newton: int
    cg: tuple
    steps: int
    node_shape: tuple
    h: np.ndarray
    strain: np.ndarray | None = None
    stable: bool | None = None
    contact: dict | None = None

    def full(self, a: np.ndarray) -> np.ndarray:
        """(n, 3) node values -> (Nx, Ny, Nz, 3), zero off the body."""
        out = np.zeros((int(np.prod(self.node_shape)), 3))
        out[self.nodes] = a
        return out.reshape(tuple(self.node_shape) + (3,))


class _Body:
    """The solid voxels in the body's node numbering, and their kernels' arguments."""

    def __init__(self, index: np.ndarray, h: np.ndarray, law: NeoHookean):
        N = node_shape(index.shape, False)
        self.N = N
        self.nodes = np.flatnonzero(touched_nodes(index, False).ravel())
        node_map = np.full(int(np.prod(N)), -1, np.int64)
        node_map[self.nodes] = np.arange(len(self.nodes))
        ijk = np.argwhere(index >= 0)
        corners = ijk[:, None, :] + HEX8_CORNERS[None]
        flat = (corners[..., 0] * N[1] + corners[..., 1]) * N[2] + corners[..., 2]
        self.voxels = np.ascontiguousarray(node_map[flat])
        self.order, self.starts, self.colours = colour_order(ijk)
        self.node_map = node_map
        self.dN, self.w = gauss_gradients(h)
        self.mu, self.lam = float(law.mu), float(law.lam)
        self.F = np.empty((len(self.voxels), 8, 3, 3))
        self.Finv = np.empty((len(self.voxels), 8, 3, 3))
        self.c = np.empty((len(self.voxels), 8))
        self.contact: SurfacePairs | None = None  # the walls' penalty contact, when asked

    def forces(self, u: np.ndarray) -> tuple[np.ndarray, float, int]:
        f = np.zeros_like(u)
        energy, bad = internal_forces(u, self.voxels, self.order, self.starts, self.colours, self.dN, self.w, self.mu,
                                      self.lam, self.F, self.Finv, self.c, f)
        if self.contact is not None:
            fc, ec, crossed = self.contact.forces(u)
            f += fc
            energy += ec
            bad += crossed  # walls passed through each other: refused as an inverted element is
        return f, energy, bad

    def tangent(self, v: np.ndarray) -> np.ndarray:
        """K_t v at the Gauss points' F of the last :meth:`forces` call."""
        y = np.zeros_like(v)
        tangent_apply(np.ascontiguousarray(v), self.voxels, self.order, self.starts, self.colours,
                      self.dN, self.w, self.mu, self.lam, self.Finv, self.c, y)
        if self.contact is not None:
            y += self.contact.tangent(v)
        return y


class HyperelasticBody:
    """The solid of ``phases`` with its prescribed dofs, prepared once (the voxels' node lists, the
    linear split multigrid) and solved for any prescribed values (:meth:`solve`): a robot's pose
    after pose, a ladder of motions.

    phases : (nx, ny, nz) int, 0 = void, k > 0 solid (every solid phase obeys ``law``).
    size : (3,) [mm] the grid's edges; node (i, j, k) sits at (i hx, j hy, k hz).
    prescribed : (nx + 1, ny + 1, nz + 1, 3) bool, the prescribed dofs (those on nodes the solid
        touches count).
    contact : None (walls pass through each other), True (:meth:`.contact.Contact.default`) or a
        :class:`~.contact.Contact`: penalty contact between wall surfaces that were apart.
    """

    def __init__(self, phases, size, law: NeoHookean, prescribed, contact: Contact | bool | None = None):
        self.law = law if isinstance(law, NeoHookean) else NeoHookean(*law)
        index, _, h, _ = validate_grid(phases, size, {p: np.eye(6) for p in _solid_phases(phases)})
        self.index, self.h = index, np.asarray(h, float)
        self.N = node_shape(index.shape, False)
        self.body = _Body(index, h, self.law)
        if contact is True:
            contact = Contact.default(h, self.law.E)
        if contact not in (None, False):
            if not isinstance(contact, Contact):
                raise ConfigError(f"contact: {contact!r}: None, True or a Contact")
            flat, areas = surface_areas(index >= 0, h)
            rest = np.stack(np.unravel_index(flat, self.N), 1) * np.asarray(h, float)
            self.body.contact = SurfacePairs(self.body.node_map[flat], rest, areas, contact)
        touched = touched_nodes(index, False)
        fixed = _dofs(prescribed, "prescribed", self.N, bool) & touched[..., None]
        if not fixed.any():
            raise ConfigError("prescribed: no prescribed dof on the solid: the body would float")
        self.free_grid, self.fixed = (touched[..., None] & ~fixed).astype(float), fixed
        op = VoxelOperator(index, law_table(self.law, h), np.ones(index.shape), False, self.free_grid, h)
        with threadpool_limits(limits=1, user_api="blas"):
            self.H = build_hierarchy(op, fixed, coarsening="split")
        self.at = self.body.node_map[self.H.fine.active]  # the hierarchy's compact nodes, body numbering
        self.free_c = self.H.fine.free  # (a, 3) their free dofs
        self.fixed_b = fixed.reshape(-1, 3)[self.body.nodes]
        self.mg = self.H  # the multigrid of the solve under way (:func:`_newton`), the rest one between solves
        self._table = None  # its tangent's element table, rewritten at each rebuild within a solve
        # the round-off of the forces: eps times the stress of the displacement gradient (|H| at
        # most max|u| / h) over a voxel face, summed over the dofs; under a large rigid motion the
        # forces are differences of O(|H|) stresses, so no residual falls below it (1e3: the sums' depth)
        self.roundoff = 1e3 * np.finfo(float).eps * self.law.E * float(np.prod(h)) ** (2 / 3) * \
            np.sqrt(3.0 * len(self.body.nodes))

    def floor(self, u: np.ndarray) -> float:
        """The forces' round-off [N] at displacements ``u`` (n, 3) [mm] (:func:`forces_floor`)."""
        return forces_floor(self.roundoff, float(self.h.min()), u)

    def tangent_hierarchy(self) -> Hierarchy | None:
        """The split multigrid of the tangent at the last :meth:`_Body.forces` call's state
        (:mod:`.tangent_multigrid`), or None where it is not positive definite. With walls'
        contact the penalty's tangent is not in it (the rest hierarchy's role then)."""
        if self.body.contact is not None:
            return None
        b = self.body
        # the last table's memory again: the caller dropped the hierarchy that held it
        self._table = tangent_table(b.dN, b.w, b.mu, b.lam, b.Finv, b.c, self._table)
        return tangent_hierarchy(self.index, self._table, self.free_grid, self.fixed, self.h)

    def on_free(self, v_b: np.ndarray) -> np.ndarray:
        """Body numbering (n, 3) -> the hierarchy's compact free dofs (a, 3)."""
        return v_b[self.at] * self.free_c

    def to_body(self, v_c: np.ndarray) -> np.ndarray:
        out = np.zeros((len(self.body.nodes), 3))
        out[self.at] = v_c * self.free_c
        return out

    def solve(self, values, initial=None, *, rtol: float = 1e-8, max_newton: int = 60, max_substeps: int = 64,
              cg_maxiter: int = 2000, probe: bool = True,
              progress: Callable[[str, int, int], None] | None = None) -> NonlinearSolution:
        """The equilibrium with the prescribed dofs at ``values`` (nx + 1, ny + 1, nz + 1, 3) [mm]
        from ``initial`` (the same shape [mm]: a nearby solution, continuation; None: rest).
        rtol : the free residual over the reactions' norm, in (0, 1e-2); max_newton : Newton
        iterations per load step; max_substeps : the most load steps the predictor may take;
        probe : check the equilibrium for stability and leave it where it is a saddle (module
        docstring, step 3; up to 100 CG iterations more)."""
        target = _dofs(values, "values", self.N, float)
        start = np.zeros(self.N + (3,)) if initial is None else _dofs(initial, "initial", self.N, float)
        check_range("rtol", rtol, 0.0, 1e-2, lo_open=True, hi_open=True)
        with threadpool_limits(limits=1, user_api="blas"):  # fixed-order sums: the same bits on any load
            return _solve(self, target, start, float(rtol), int(max_newton), int(max_substeps), int(cg_maxiter),
                          bool(probe), progress or (lambda *_: None))


def forces_floor(roundoff: float, h_min: float, u: np.ndarray) -> float:
    """The forces' round-off [N] of a body whose rest round-off is ``roundoff`` [N]
    (:attr:`HyperelasticBody.roundoff`) at displacements ``u`` [mm]: it grows with the
    displacement gradient, at most max|u| / ``h_min`` [mm]."""
    return roundoff * (1.0 + float(np.abs(u).max()) / h_min)


def solve_hyperelastic(phases, size, law: NeoHookean, *, prescribed, values, initial=None, rtol: float = 1e-8,
                       max_newton: int = 60, max_substeps: int = 64, cg_maxiter: int = 2000, probe: bool = True,
                       progress: Callable[[str, int, int], None] | None = None,
                       contact: Contact | bool | None = None) -> NonlinearSolution:
    """One equilibrium of the solid of ``phases`` under prescribed displacements (module
    docstring; the arguments are :class:`HyperelasticBody`'s and :meth:`HyperelasticBody.solve`'s)."""
    return HyperelasticBody(phases, size, law, prescribed, contact).solve(
        values, initial, rtol=rtol, max_newton=max_newton, max_substeps=max_substeps, cg_maxiter=cg_maxiter,
        probe=probe, progress=progress)


def _solid_phases(phases) -> list[int]:
    ph = np.asarray(phases)
    if ph.ndim != 3 or not np.issubdtype(ph.dtype, np.integer):
        raise ConfigError(f"phases: shape {ph.shape}, dtype {ph.dtype}: must be a 3-D integer array (0 = void)")
    return [int(p) for p in np.unique(ph) if p > 0]


def _dofs(a, name: str, N, dtype) -> np.ndarray:
    arr = np.asarray(a)
    if arr.shape != tuple(N) + (3,):
        raise ConfigError(f"{name}: shape {arr.shape}: must be {tuple(N) + (3,)} (one value per node and dof)")
    if dtype is bool:
        if arr.dtype != bool:
            raise ConfigError(f"{name}: dtype {arr.dtype}: must be bool")
        return arr
    if not np.all(np.isfinite(arr)):
        raise ConfigError(f"{name}: non-finite displacements")
    return arr.astype(float)


def _solve(hb: HyperelasticBody, target, start, rtol, max_newton, max_substeps, cg_maxiter, probe, say):
    body, fixed_b = hb.body, hb.fixed_b
    u = start.reshape(-1, 3)[body.nodes].copy()
    goal = target.reshape(-1, 3)[body.nodes]
    cgs = []

    def apply(v):  # (a, 3, m) -> (a, 3, m): the tangent on the free dofs
        out = np.empty_like(v)
        for k in range(v.shape[2]):
            out[..., k] = hb.on_free(body.tangent(hb.to_body(v[..., k])))
        return out

    def cg(b, tol):
        res = pcg(apply, b, hb.H.precondition, rtol=tol, maxiter=cg_maxiter, flexible=hb.H.flexible)
        cgs.append(int(res.iterations[0]))
        if not res.converged[0]:
            raise ConvergenceError(f"hyperelastic: a Newton step's CG reached {res.residual[0]:.2e} after "
                                   f"{res.iterations[0]} iterations, asked {tol:g}", history=res.history[:, 0].tolist())
        return hb.to_body(res.x[..., 0])

    if body.contact is not None:
        body.contact.reset()
    f, energy, bad = body.forces(u)
    if bad:
        raise ConfigError(f"initial: {bad} Gauss points inverted (det F <= 0) in the starting state")
    newton, steps, tries = 0, 0, 0
    done, frac = 0.0, 1.0  # the share of the prescribed increment reached, the next step's share
    u0p = u[fixed_b].copy()
    radius = None  # the trust region's radius [mm], carried over the load steps
    hb.mg = hb.H  # the Newton steps' multigrid: the rest one, or one rebuilt on a tangent, carried on
    while done < 1.0:
        tries += 1
        if steps >= max_substeps or tries > 4 * max_substeps:
            raise ConvergenceError(f"hyperelastic: the prescribed motion needed more than {max_substeps} load steps "
                                   f"(reached {100 * done:.1f} %): it inverts elements near the prescribed dofs")
        step = min(frac, 1.0 - done)
        dp = np.zeros_like(u)
        dp[fixed_b] = (goal[fixed_b] - u0p) * step
        trial = u + dp + cg(-hb.on_free(body.tangent(dp))[..., None], 1e-6)  # the consistent predictor
        kept = _save_pairs(body)
        f_t, e_t, bad = body.forces(trial)
        if bad:
            frac = step / 2
            _back(body, u, kept)
            continue
        moved = float(np.linalg.norm(hb.on_free(trial - u - dp)))
        radius = max(radius or 0.0, moved, float(hb.h.min()))
        u, f, energy, steps = trial, f_t, e_t, steps + 1
        done += step
        say("hyperelastic: load steps", int(round(100 * done)), 100)
        u, f, energy, its, radius = _newton(hb, u, f, energy, rtol, max_newton, cg_maxiter, say, cgs, radius)
        newton += its
        frac = min(2 * step, 1.0)
    stable = None
    for _ in range(ESCAPES if probe else 0):
        away = _escape(hb, u, energy, min(cg_maxiter, PROBE_ITERATIONS), radius, cgs)
        if away is None:
            stable = True
            break
        u, f, energy = away
        say("hyperelastic: left a saddle along negative curvature", 0, 1)
        u, f, energy, its, radius = _newton(hb, u, f, energy, rtol, max_newton, cg_maxiter, say, cgs, radius)
        newton += its
    else:
        stable = False if probe else None
    hb.mg, hb._table = hb.H, None  # a rebuilt multigrid's memory back
    ref = float(np.linalg.norm(f[fixed_b]))
    # over the reactions, or over the round-off's scale where they vanish (a rigid motion)
    resid = float(np.linalg.norm(hb.on_free(f))) / max(ref, hb.floor(u) / rtol)
    per_voxel = np.empty(len(body.voxels))
    max_principal_strain(body.F, per_voxel)
    strain = np.full(hb.index.shape, np.nan)
    strain[hb.index >= 0] = per_voxel  # argwhere's order, as the body's voxels
    contact = None if body.contact is None else body.contact.summary()
    return NonlinearSolution(body.nodes, u, f, float(energy), resid, newton, tuple(cgs), steps, tuple(body.N),
                             hb.h, strain, stable, contact)


#: the stability probe: CG iterations at most, and saddles left at most, per solve
PROBE_ITERATIONS, ESCAPES = 100, 3
#: once the Newton steps' CG has taken more iterations on the multigrid in use, the next step's is
#: rebuilt on the tangent (:mod:`.tangent_multigrid`): a rebuild costs about 20 iterations' time on
#: the paper's sheet, and the steps after it took 5 to 10 iterations where the rest multigrid took
#: 50 to 180 (so a rebuild comes once about twice its cost has gone into the multigrid in use)
REBUILD_ITERATIONS = 40


def _escape(hb, u, energy, maxiter, radius, cgs):
    """A converged state checked for stability: truncated CG on the tangent from a fixed
    pseudo-random right-hand side meets a direction of negative curvature if the tangent has
    one it can see (CG is Lanczos: the extreme eigenvalues appear first). Returns (u, f,
    energy) moved along it to a lower energy, or None when none is found (the tangent then
    holds the state's). Preconditioned by the rest multigrid, which is positive definite
    whatever the state (a tangent's multigrid, :mod:`.tangent_multigrid`, took all 100 iterations
    too, at 1.8 times the cost of each, on the paper's sheet)."""
    body, to_body = hb.body, hb.to_body
    v = hb.on_free(np.random.default_rng(0).standard_normal((len(body.nodes), 3)))
    step = steihaug(lambda w: hb.on_free(body.tangent(to_body(w))), v,
                    lambda r: hb.H.precondition(r[..., None])[..., 0], np.inf,
                    rtol=1e-3, maxiter=maxiter, flexible=hb.H.flexible)
    cgs.append(step.iterations)
    if step.direction is None:
        return None
    d = to_body(step.direction)
    # curvature per unit length^2 against a voxel's stiffness E h: a null direction's round-off
    # (a rigid motion the grips leave free, a loose voxel) is not a buckling mode
    if float(np.sum(d * body.tangent(d))) > -1e-6 * hb.law.E * float(hb.h.min()) * float(np.sum(d * d)):
        return None
    d *= max(radius, float(hb.h.min())) / float(np.linalg.norm(d))
    for _ in range(20):
        for sign in (1.0, -1.0):
            f_t, e_t, bad = body.forces(u + sign * d)
            if not bad and e_t < energy:
                return u + sign * d, f_t, e_t
        d *= 0.5
    body.forces(u)
    return None


def _newton(hb, u, f, energy, rtol, max_newton, cg_maxiter, say, cgs, radius):
    """Trust-region Newton iterations on the free dofs from ``u`` (forces ``f``, ``energy``)
    until the free residual is at most ``rtol`` times the reactions' norm, or the forces'
    round-off [N]. Each step is Steihaug's truncated CG on the tangent (:mod:`.trust_region`)
    within ``radius`` [mm] (Euclidean over the free dofs), accepted where the energy falls by at
    least a tenth of the model's prediction; the radius follows the model's quality. Returns
    (u, f, energy, iterations, the last radius)."""
    body, on_free, to_body = hb.body, hb.on_free, hb.to_body
    hist = []

    def apply(v):  # (a, 3) -> (a, 3): the tangent on the free dofs
        return on_free(body.tangent(to_body(v)))

    spent, threshold = 0, REBUILD_ITERATIONS  # CG iterations on the multigrid in use, and when to rebuild

    def precondition(r):
        return hb.mg.precondition(r[..., None])[..., 0]

    smallest = 1e-9 * float(hb.h.min())
    for it in range(max_newton + 1):
        g = on_free(f)
        gn = float(np.linalg.norm(g))
        ref = max(float(np.linalg.norm(f[hb.fixed_b])), 1e-300)
        hist.append(gn / ref)
        pairs = "" if body.contact is None else f", {len(body.contact.pairs)} wall pairs pushing"
        say(f"hyperelastic: Newton, residual {gn / ref:.1e}, radius {radius or 0.0:.2g} mm (CG {sum(cgs)} iterations so "
            f"far{pairs})", it, max_newton)
        if gn <= max(rtol * ref, hb.floor(u)):
            return u, f, energy, it, radius
        if it == max_newton:
            break
        if spent > threshold:  # the multigrid in use has cost a rebuild's time twice (a count: deterministic)
            hb.mg = None  # the old one's memory first
            hb.mg, spent = hb.tangent_hierarchy() or hb.H, 0
            if hb.mg is hb.H:  # refused (not positive definite): try again only after twice as many
                threshold *= 2
        tol = max(min(0.1, np.sqrt(gn / ref)), rtol / 10)
        step = steihaug(apply, g, precondition, radius, rtol=tol, maxiter=cg_maxiter, flexible=hb.mg.flexible)
        if step.ended == "indefinite":  # the tangent's multigrid of a state that buckles: the rest one
            cgs.append(step.iterations)
            hb.mg, threshold = hb.H, 2 * threshold
            step = steihaug(apply, g, precondition, radius, rtol=tol, maxiter=cg_maxiter, flexible=hb.mg.flexible)
        cgs.append(step.iterations)
        spent += step.iterations
        trial = u + to_body(step.p)
        kept = _save_pairs(body)
        f_t, e_t, bad = body.forces(trial)
        rho = -np.inf
        if not bad and step.model < 0:
            actual = energy - e_t
            # below the energy's round-off (a sum of O(|H|^2) terms per Gauss point; the forces'
            # round-off times the motion's scale bounds it): the trapezoid rule on the forces
            noise = 10.0 * hb.floor(u) * max(float(np.abs(u).max()), float(hb.h.min()))
            if -step.model < max(1e-8 * abs(energy), noise):
                actual = -0.5 * float(np.sum((g + on_free(f_t)) * step.p))
            rho = actual / -step.model
        norm = float(np.linalg.norm(step.p))
        radius = update_radius(radius, rho, norm, step.ended in ("boundary", "curvature"), np.inf)
        if rho > 0.1:
            u, f, energy = trial, f_t, e_t
        else:
            _back(body, u, kept)
        if radius < smallest:
            raise ConvergenceError(f"hyperelastic: the trust region shrank below {smallest:.1e} mm at residual "
                                   f"{gn / ref:.2e}: no step lowers the energy", history=hist)
    raise ConvergenceError(f"hyperelastic: Newton reached {hist[-1]:.2e} after {max_newton} iterations, asked "
                           f"{rtol:g}", history=hist)


def _save_pairs(body):
    """The contact pairs' directions before a trial state (None without contact)."""
    return None if body.contact is None else body.contact.save()


def _back(body, u, kept) -> None:
    """Back to the kept state ``u`` after a refused trial: the pairs the trial met forgotten
    (``kept``, :func:`_save_pairs`), the tangent evaluated at ``u`` again."""
    if kept is not None:
        body.contact.restore(kept)
    body.forces(u)


def law_table(law: NeoHookean, h) -> np.ndarray:
    """(1, 24, 24) [N/mm] the linear voxel element of the law's small-strain tangent (the
    preconditioner's operator, and the law's rest tangent)."""
    from ...mechanics.material import Isotropic
    from .element import phase_table

    return phase_table(Isotropic(law.E, law.nu).stiffness(), h).K
