"""Continuity of the workspace (paper Fig. 5, beyond the paper): a graph whose nodes are the
reached points of the star grid and the rest pose, with an edge along each ray where the
continuation went, and an edge between points at the same step of neighbouring rays when the
inverse model walks from one to the other through ``substeps`` intermediate goals, each
reached (:func:`test_paths`, one work unit per ``edges_per_unit`` paths). Its connected
components are what :func:`metasheet.studies.workspace.explore_workspace` reports.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConvergenceError
from .model import MODELS, ModelSpec, pose_errors


@dataclass(frozen=True)
class EdgeTask:
    """Paths to test: from each start (motor angles (6,) [deg], pose (6,)) to a goal pose (6,)."""

    spec: ModelSpec
    settings: object  # metasheet.studies.workspace.WorkspaceSettings
    starts_motors: np.ndarray  # (e, n_motors)
    starts_pose: np.ndarray  # (e, 6)
    goals: np.ndarray  # (e, 6)


def test_paths(task: EdgeTask) -> np.ndarray:
    """Work unit: (e,) bool, True where the inverse model walks from start to goal through
    ``substeps`` evenly spaced goals, each reached within ``tol_mm``."""
    model = MODELS.get(task.spec)
    s = task.settings
    out = np.zeros(len(task.goals), bool)
    starts: dict[bytes, tuple | None] = {}  # a point starts ~2 paths: its equilibrium is solved once
    for e, (q, a, b) in enumerate(zip(task.starts_motors, task.starts_pose, task.goals)):
        key = np.asarray(q, float).tobytes()
        if key not in starts:
            try:
                starts[key] = model.equilibrium(q)
            except ConvergenceError:  # no equilibrium found there: the path is not proven
                starts[key] = None
        if starts[key] is None:
            continue
        pose, state = starts[key]
        if pose_errors(a, pose)[0] > s.tol_mm:  # the forward model lands elsewhere (another branch)
            continue
        ok = True
        for t in np.arange(1, s.substeps + 1) / s.substeps:
            g = a + t * (b - a)
            r = model.reach(g, state=state, tol_mm=s.tol_mm, max_steps=s.max_steps, rot_weight=s.point_rot_weight)
            if pose_errors(g, r.pose)[0] > s.tol_mm or not r.converged:
                ok = False
                break
            state = r.state
        out[e] = ok
    return out


def continuity(spec: ModelSpec, settings, grid, records, parent, goals, rest, *, executor, progress, cache,
               edges_per_unit: int = 8) -> tuple[np.ndarray, int, int, int]:
    """(component (n,), components among reached points, paths tested, paths passed): the
    connected components of the reached points of ``grid`` (module docstring); ``records`` the
    workspace's point records, ``parent`` (n,) each point's predecessor on its ray (-1: rest),
    ``goals`` (n, 3) [mm], ``rest`` the rest pose (6,). Component 0 holds the rest pose; -1:
    unreachable."""
    import networkx as nx  # here: 0.13 s of every command's start

    G = nx.Graph()
    G.add_node(-1)  # the rest pose
    reached = np.flatnonzero(records.reached)
    G.add_nodes_from(reached.tolist())
    G.add_edges_from((int(i), int(parent[i])) for i in reached)
    tested = passed = 0
    if settings.continuity:
        pairs = []
        for ra, rb in grid.neighbour_rays():
            ia, ib = grid.ray_points(ra), grid.ray_points(rb)
            common = np.intersect1d(grid.index[ia], grid.index[ib])
            for step in common:
                a = int(ia[grid.index[ia] == step][0])
                b = int(ib[grid.index[ib] == step][0])
                if records.reached[a] and records.reached[b]:
                    pairs.append((a, b))
        pairs.sort()  # the paths from one point in the same unit: its equilibrium is solved once
        pose = lambda i: np.concatenate([goals[i], rest[3:]])  # noqa: E731
        edge_tasks = [
            EdgeTask(spec, settings, records.motors_deg[[a for a, _ in ch]], np.array([pose(a) for a, _ in ch]),
                     np.array([pose(b) for _, b in ch]))
            for ch in (pairs[i:i + edges_per_unit] for i in range(0, len(pairs), edges_per_unit))
        ]
        oks = cache.map(executor, test_paths, edge_tasks, progress=lambda d, n: progress("continuity", d, n))
        flags = np.concatenate(oks) if oks else np.zeros(0, bool)
        tested, passed = len(pairs), int(flags.sum())
        G.add_edges_from(p for p, ok in zip(pairs, flags) if ok)
    comps = sorted(nx.connected_components(G), key=lambda c: (-1 not in c, -len(c), min(c)))
    component = np.full(len(grid), -1)
    for c_id, comp in enumerate(comps):
        for i in comp:
            if i >= 0:
                component[i] = c_id
    n_comp = sum(1 for c in comps if any(i >= 0 for i in c))
    return component, n_comp, tested, passed
