"""Periodic seed points for Voronoi foams.

Every sampler returns ``seeds : (N, 3) float [mm]`` inside the box ``[0, size)`` and takes
an explicit RNG seed, so the same arguments give the same bytes. The box is a period
of the foam: :func:`periodic_images` tiles the seeds with their 26 neighbouring images
so that every Voronoi cell of a seed in the box is complete (its neighbours across the
periodic boundary are present).

``scale`` (3,) lets a sampler work in the space where a stretched metric is Euclidean
(``x * scale``, see :attr:`metasheet.cells.metrics.StretchedMetric.scale`): a jittered grid
is then regular and a Poisson-disk sampler keeps its minimum distance *under the metric*,
so cells come out equally regular whatever the stretch.
"""

from __future__ import annotations

import itertools

import numpy as np

from ..errors import ConfigError, InfeasibleError, check_range

SAMPLERS = ("uniform", "jittered", "poisson")

#: The 27 integer shifts (-1, 0, 1)^3 of the periodic images; row 13 is (0, 0, 0).
IMAGE_SHIFTS = np.array(list(itertools.product((-1, 0, 1), repeat=3)), dtype=float)


def _box(size) -> np.ndarray:
    size = np.asarray(size, dtype=float)
    if size.shape != (3,):
        raise ConfigError(f"size: shape is {size.shape} and should be (3,) [mm]")
    if not np.all(np.isfinite(size)) or np.any(size <= 0):
        raise ConfigError(f"size: {size.tolist()!r}: every side must be a finite number > 0 [mm]")
    return size


def _scale(scale) -> np.ndarray:
    s = np.ones(3) if scale is None else np.asarray(scale, dtype=float)
    if s.shape != (3,) or np.any(~np.isfinite(s)) or np.any(s <= 0):
        raise ConfigError(f"scale: {np.asarray(scale).tolist()!r}: expected 3 finite numbers > 0")
    return s


def _count(count) -> int:
    if int(count) != count or int(count) < 1:
        raise ConfigError(f"seeds.count: {count!r}: expected an integer >= 1")
    return int(count)


def wrap(points: np.ndarray, size) -> np.ndarray:
    """Points folded into the box ``[0, size)`` (periodic), (n, 3) [mm]."""
    size = np.asarray(size, dtype=float)
    p = np.mod(np.asarray(points, dtype=float), size)
    # np.mod can return ``size`` itself for tiny negative inputs.
    return np.where(p >= size, p - size, p)


def uniform_seeds(count: int, size, rng_seed: int) -> np.ndarray:
    """``count`` independent uniform points in the box.

    Parameters
    ----------
    count : number of seeds N.
    size : (3,) box [mm].
    rng_seed : seed of :func:`numpy.random.default_rng`.

    Returns
    -------
    seeds : (N, 3) float [mm]
    """
    size = _box(size)
    rng = np.random.default_rng(rng_seed)
    return wrap(rng.random((_count(count), 3)) * size, size)


def grid_shape(count: int, size, scale=None) -> tuple[int, int, int]:
    """The grid (a, b, c), a*b*c = count, whose spacing in scaled space is most nearly cubic.

    Raises :class:`ConfigError` when no factorisation gives spacings within a factor 2
    of each other (a prime count, say).
    """
    count = _count(count)
    ext = _box(size) * _scale(scale)
    best, best_ratio = None, np.inf
    for a in range(1, count + 1):
        if count % a:
            continue
        for b in range(1, count // a + 1):
            if (count // a) % b:
                continue
            shape = np.array([a, b, count // (a * b)])
            spacing = ext / shape
            ratio = spacing.max() / spacing.min()
            if ratio < best_ratio - 1e-12:
                best, best_ratio = shape, ratio
    if best_ratio > 2.0:
        raise ConfigError(
            f"seeds.count: {count}: a jittered grid needs a count that factors into a near-cubic "
            f"grid for this box (best {tuple(int(v) for v in best)} has spacings a factor "
            f"{best_ratio:.2g} apart); try e.g. 27, 64 or 125, or sampler = 'poisson'"
        )
    return tuple(int(v) for v in best)


def grid_seeds(shape, size) -> np.ndarray:
    """Seeds at the centres of a regular ``shape`` grid of the box: (prod(shape), 3) [mm].

    One seed per site of a cubic grid gives the simple cubic Voronoi lattice (cubes).
    """
    size = _box(size)
    shape = tuple(int(v) for v in shape)
    if len(shape) != 3 or min(shape) < 1:
        raise ConfigError(f"shape: {shape!r}: expected 3 integers >= 1")
    axes = [(np.arange(m) + 0.5) * (L / m) for m, L in zip(shape, size)]
    g = np.meshgrid(*axes, indexing="ij")
    return np.stack([c.ravel() for c in g], axis=1)


def jittered_grid_seeds(count: int, size, rng_seed: int, *, jitter: float = 0.5, scale=None) -> np.ndarray:
    """One seed per site of a near-cubic grid, each moved uniformly within its site.

    Parameters
    ----------
    count : N, must factor into a near-cubic grid (see :func:`grid_shape`).
    size : (3,) box [mm].
    rng_seed : RNG seed.
    jitter : [-], in [0, 1]: each seed moves by up to ``jitter/2`` of the site spacing on
        each side of the site centre (0: the regular lattice; 1: anywhere in its site).
    scale : (3,) optional scale of the space where the grid should be cubic.

    Returns
    -------
    seeds : (N, 3) float [mm]
    """
    size = _box(size)
    check_range("seeds.jitter", jitter, 0.0, 1.0)
    shape = grid_shape(count, size, scale)
    base = grid_seeds(shape, size)
    rng = np.random.default_rng(rng_seed)
    spacing = size / np.array(shape)
    return wrap(base + (rng.random(base.shape) - 0.5) * float(jitter) * spacing, size)


def default_min_distance(count: int, size, scale=None, packing: float = 0.25) -> float:
    """Minimum distance (in scaled space) at which ``count`` disks fill ``packing`` of the box.

    Random sequential addition of hard spheres jams at a packing fraction of about 0.38;
    0.25 is reached quickly and leaves the seeds visibly random.
    """
    volume = float(np.prod(_box(size) * _scale(scale)))
    return float((6.0 * packing * volume / (np.pi * _count(count))) ** (1.0 / 3.0))


def poisson_disk_seeds(
    count: int,
    size,
    rng_seed: int,
    *,
    min_distance: float | None = None,
    scale=None,
    max_attempts: int | None = None,
) -> np.ndarray:
    """Periodic Poisson-disk seeds: uniform darts, rejected closer than ``min_distance``.

    Parameters
    ----------
    count : N.
    size : (3,) box [mm].
    rng_seed : RNG seed.
    min_distance : smallest allowed periodic distance between two seeds, measured in
        scaled space ``x * scale`` [mm]; default :func:`default_min_distance`.
    scale : (3,) optional, see the module docstring.
    max_attempts : darts thrown before giving up; default ``2000 * N``.

    Returns
    -------
    seeds : (N, 3) float [mm]

    Raises
    ------
    InfeasibleError : when N seeds cannot be placed (``min_distance`` too large).
    """
    size = _box(size)
    scale = _scale(scale)
    count = _count(count)
    if min_distance is None:
        min_distance = default_min_distance(count, size, scale)
    check_range("seeds.min_distance", min_distance, 0.0, None, lo_open=True)
    d2 = float(min_distance) ** 2
    period = size * scale
    rng = np.random.default_rng(rng_seed)
    max_attempts = 2000 * count if max_attempts is None else int(max_attempts)
    accepted = np.empty((count, 3))
    n = 0
    attempts = 0
    while n < count:
        batch = rng.random((256, 3)) * period
        for q in batch:
            attempts += 1
            if attempts > max_attempts:
                limit = default_min_distance(count, size, scale, packing=0.38)
                raise InfeasibleError(
                    f"seeds.min_distance: {min_distance:g}: placed only {n} of {count} seeds in "
                    f"{max_attempts} attempts; random packing jams near {limit:.3g} for this count "
                    "and box: lower min_distance or the count"
                )
            if n:
                d = q - accepted[:n]
                d -= period * np.round(d / period)
                if np.min(np.einsum("ij,ij->i", d, d)) < d2:
                    continue
            accepted[n] = q
            n += 1
            if n == count:
                break
    return wrap(accepted / scale, size)


def make_seeds(sampler: str, count: int, size, rng_seed: int, *, scale=None, jitter: float = 0.5,
               min_distance: float | None = None) -> np.ndarray:
    """Dispatch to a sampler by name: ``'uniform'``, ``'jittered'`` or ``'poisson'``."""
    if sampler == "uniform":
        return uniform_seeds(count, size, rng_seed)
    if sampler == "jittered":
        return jittered_grid_seeds(count, size, rng_seed, jitter=jitter, scale=scale)
    if sampler == "poisson":
        return poisson_disk_seeds(count, size, rng_seed, min_distance=min_distance, scale=scale)
    raise ConfigError(f"seeds.sampler: {sampler!r}: expected one of {', '.join(SAMPLERS)}")


def periodic_images(seeds: np.ndarray, size) -> tuple[np.ndarray, np.ndarray]:
    """The seeds and their 26 periodic images around the box.

    Returns
    -------
    points : (27 N, 3) float [mm], image ``i`` of seed ``j`` at row ``i * N + j``,
        ``points = seeds + IMAGE_SHIFTS[i] * size``; image 13 is the box itself.
    owner : (27 N,) int, the seed each image belongs to.
    """
    seeds = np.asarray(seeds, dtype=float)
    size = _box(size)
    if seeds.ndim != 2 or seeds.shape[1] != 3:
        raise ConfigError(f"seeds: shape is {seeds.shape} and should be (N, 3) [mm]")
    pts = (seeds[None, :, :] + IMAGE_SHIFTS[:, None, :] * size).reshape(-1, 3)
    owner = np.tile(np.arange(len(seeds)), len(IMAGE_SHIFTS))
    return pts, owner
