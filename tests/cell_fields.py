"""Small periodic level-set fields with known solids, shared by the cell surface and tet-mesh
tests (``test_cell_surface.py``, ``test_cell_tetmesh.py``); a helper module, no tests here."""

import itertools

import numpy as np


def strut_lattice(size, r):
    """Simple cubic struts: solid where the distance to the nearest of the three axis-parallel
    lines through the cell centre is < r. Returns field(points (n, 3) [mm]) -> (n,) [mm]."""
    size = np.asarray(size, dtype=float)

    def field(p):
        d = (p - 0.5 * size + 0.5 * size) % size - 0.5 * size  # wrapped offset from the centre
        rx = np.hypot(d[:, 1], d[:, 2])
        ry = np.hypot(d[:, 0], d[:, 2])
        rz = np.hypot(d[:, 0], d[:, 1])
        return np.minimum(np.minimum(rx, ry), rz) - r

    return field


def strut_lattice_volume(L, r):
    """Exact volume [mm^3] of the simple cubic strut lattice in a cube of side L, r < L / 2:
    three cylinders minus the pairwise Steinmetz overlaps (16 r^3 / 3 each) plus the triple
    one (8 (2 - sqrt 2) r^3)."""
    return 3 * np.pi * r**2 * L - 3 * 16 / 3 * r**3 + 8 * (2 - np.sqrt(2)) * r**3


def gyroid(L):
    """Gyroid sheet-network level set in a cube of side L, scaled to ~a distance [mm]. By the
    gyroid's symmetry its solid {f < 0} is exactly half the box."""

    def field(p):
        x = 2 * np.pi * np.asarray(p) / L
        g = (
            np.sin(x[:, 0]) * np.cos(x[:, 1])
            + np.sin(x[:, 1]) * np.cos(x[:, 2])
            + np.sin(x[:, 2]) * np.cos(x[:, 0])
        )
        return g * L / (2 * np.pi)

    return field


def bcc_struts(L, r):
    """Body-centred struts: the four body diagonals through the centre and their periodic
    images, radius r [mm]. Thin r (about two grid cells) stresses the surface like a foam."""
    dirs = np.array(list(itertools.product((1.0, -1.0), (1.0, -1.0), (1.0,)))) / np.sqrt(3)
    shifts = np.array(list(itertools.product((-1, 0, 1), repeat=3)), dtype=float) * L

    def field(p):
        q = (np.asarray(p) % L) - 0.5 * L
        best = np.full(len(q), np.inf)
        for s in shifts:
            y = q + s
            for d in dirs:
                along = y @ d
                best = np.minimum(best, np.sum(y * y, axis=1) - along**2)
        return np.sqrt(np.maximum(best, 0.0)) - r

    return field


def voxel_fraction(field, size, n):
    """Solid fraction {field < 0} sampled at the n^3 voxel centres."""
    size = np.asarray(size, dtype=float)
    axes = [(np.arange(n) + 0.5) * (s / n) for s in size]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    return float(np.mean(field(pts) < 0))
