"""Fibre streaks: short integral curves of an axis field, seeded evenly, drawn as one line
collection.

matplotlib's ``streamplot`` spaces its lines evenly by growing them one at a time in Python
(1 to 3 s a panel on a sheet), and it reads the field as vectors; a fibre field is an axis
field (f and -f are the same fibre), whose sign a sampled grid may flip from node to node.
Here every seed of a staggered grid is integrated at once (numpy, vectorised over the seeds)
a fixed length each way, the direction's sign taken at each step to continue the previous one:
each corner's sign is matched to the streak's direction before it is interpolated. The same
picture of where the fibres run, in milliseconds.
"""

from __future__ import annotations

import numpy as np


def _sample(xs, ys, U, V, P, ref):
    """Bilinear unit direction at points P (m, 2) of the grid's axis field, each corner's sign
    taken to agree with ``ref`` (m, 2) before the weights (averaging f and -f would cancel);
    NaN where a corner is NaN or P is outside the grid."""
    fx = (P[:, 0] - xs[0]) / (xs[1] - xs[0])
    fy = (P[:, 1] - ys[0]) / (ys[1] - ys[0])
    ok = (fx >= 0) & (fy >= 0) & (fx <= len(xs) - 1) & (fy <= len(ys) - 1)  # False at NaN too
    fx, fy = np.where(ok, fx, 0.0), np.where(ok, fy, 0.0)
    i = np.clip(np.floor(fx).astype(int), 0, len(xs) - 2)
    j = np.clip(np.floor(fy).astype(int), 0, len(ys) - 2)
    tx, ty = np.clip(fx - i, 0, 1), np.clip(fy - j, 0, 1)
    out = np.zeros((len(P), 2))
    for jj, ii, w in ((j, i, (1 - tx) * (1 - ty)), (j, i + 1, tx * (1 - ty)), (j + 1, i, (1 - tx) * ty),
                      (j + 1, i + 1, tx * ty)):
        c = np.stack([U[jj, ii], V[jj, ii]], axis=1)
        c = np.where((np.sum(c * ref, axis=1) < 0)[:, None], -c, c)
        out += w[:, None] * c
    out[~ok] = np.nan
    with np.errstate(invalid="ignore", divide="ignore"):  # a zero average: NaN, the streak ends
        return out / np.linalg.norm(out, axis=1, keepdims=True)


def streak_lines(xs, ys, U, V, spacing: float, length: float, steps: int = 8) -> list[np.ndarray]:
    """Streaks of the axis field (U, V) (ny, nx) on the grid ``xs`` (nx,), ``ys`` (ny,) [mm]
    (NaN outside the domain), seeded on a staggered grid of ``spacing`` [mm], each integrated
    ``length`` [mm] each way by the midpoint rule in ``steps`` steps. Returns polylines (k, 2)
    [mm], one per seed inside, ending where the field ends."""
    ex, ey = np.arange(xs[0], xs[-1], spacing), np.arange(ys[0], ys[-1], spacing * np.sqrt(3) / 2)
    X, Y = np.meshgrid(ex, ey)
    X = X + (np.arange(len(ey)) % 2)[:, None] * spacing / 2  # staggered rows: an even cover
    seeds = np.stack([X.ravel(), Y.ravel()], axis=1)
    i = np.clip(np.rint((seeds[:, 0] - xs[0]) / (xs[1] - xs[0])).astype(int), 0, len(xs) - 1)
    j = np.clip(np.rint((seeds[:, 1] - ys[0]) / (ys[1] - ys[0])).astype(int), 0, len(ys) - 1)
    d0 = _sample(xs, ys, U, V, seeds, np.stack([U[j, i], V[j, i]], axis=1))  # the nearest texel's sign
    keep = np.all(np.isfinite(d0), axis=1)
    seeds, d0 = seeds[keep], d0[keep]
    h = length / steps
    halves = []
    for sign in (1.0, -1.0):
        p, prev = seeds.copy(), sign * d0
        pts = [p.copy()]
        for _ in range(steps):
            mid = p + 0.5 * h * _sample(xs, ys, U, V, p, prev)
            d = _sample(xs, ys, U, V, mid, prev)
            p = p + h * d
            prev = np.where(np.isfinite(d), d, prev)
            pts.append(p.copy())  # NaN from the first step that leaves the field on
        halves.append(np.stack(pts, axis=1))  # (m, steps + 1, 2)
    lines = []
    for fwd, bwd in zip(*halves):
        line = np.concatenate([bwd[::-1], fwd[1:]])
        ok = np.all(np.isfinite(line), axis=1)  # the finite stretch through the seed (index steps)
        lo, hi = steps, steps
        while lo > 0 and ok[lo - 1]:
            lo -= 1
        while hi < len(line) - 1 and ok[hi + 1]:
            hi += 1
        if hi > lo:
            lines.append(line[lo:hi + 1])
    return lines
