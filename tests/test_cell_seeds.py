"""Periodic seed samplers and their images (issue 3, item 1)."""

import numpy as np
import pytest

from metasheet.cells.foam import Foam, foam_field
from metasheet.cells.metrics import StretchedMetric
from metasheet.cells.seeds import (
    IMAGE_SHIFTS,
    default_min_distance,
    grid_seeds,
    grid_shape,
    jittered_grid_seeds,
    make_seeds,
    periodic_images,
    poisson_disk_seeds,
    uniform_seeds,
)
from metasheet.errors import ConfigError, InfeasibleError

SIZE = np.array([4.0, 5.0, 6.0])


@pytest.mark.parametrize("sampler", ["uniform", "jittered", "poisson"])
def test_samplers_are_in_the_box_and_reproducible(sampler):
    a = make_seeds(sampler, 27, SIZE, 7)
    b = make_seeds(sampler, 27, SIZE, 7)
    c = make_seeds(sampler, 27, SIZE, 8)
    assert a.shape == (27, 3)
    assert np.all(a >= 0) and np.all(a < SIZE)
    assert a.tobytes() == b.tobytes()
    assert not np.array_equal(a, c)


def test_images_tile_the_seeds_periodically():
    s = uniform_seeds(5, SIZE, 0)
    pts, owner = periodic_images(s, SIZE)
    assert pts.shape == (27 * 5, 3)
    assert np.array_equal(pts[13 * 5 : 14 * 5], s)  # image 13 is the box itself
    shifts = (pts - s[owner]) / SIZE
    assert np.allclose(shifts, np.round(shifts), atol=1e-12)
    assert {tuple(r) for r in np.round(shifts).astype(int)} == {tuple(r) for r in IMAGE_SHIFTS.astype(int)}


def test_field_of_tiled_seeds_is_periodic():
    # Every Voronoi cell is complete: the foam repeats with the box, shifted by any period.
    foam = Foam(uniform_seeds(12, SIZE, 3), SIZE, StretchedMetric(2.0, 2, "transverse"), "open", 0.2)
    f = foam_field(foam)
    p = np.random.default_rng(0).random((2000, 3)) * SIZE
    for k in ([1, 0, 0], [0, -1, 0], [2, 3, -4]):
        assert np.allclose(f(p + np.array(k) * SIZE), f(p), atol=1e-9)


def test_jittered_grid_without_jitter_is_the_grid():
    s = jittered_grid_seeds(8, [2.0, 2.0, 2.0], 0, jitter=0.0)
    assert np.allclose(np.sort(s, axis=0), np.sort(grid_seeds((2, 2, 2), [2.0, 2.0, 2.0]), axis=0))
    assert np.allclose(np.unique(s), [0.5, 1.5])


def test_grid_shape_follows_the_scaled_box():
    assert grid_shape(64, [10, 10, 10]) == (4, 4, 4)
    assert grid_shape(16, [20, 10, 10]) == (4, 2, 2)
    # cells flattened along z (scale 1 / 2 across): the grid has more layers along z
    a, b, c = grid_shape(32, [10, 10, 10], scale=[0.5, 0.5, 1.0])
    assert c > a and c > b


def test_prime_count_on_a_jittered_grid_names_the_field():
    with pytest.raises(ConfigError, match="seeds.count"):
        jittered_grid_seeds(61, [10, 10, 10], 0)


def test_poisson_disk_keeps_its_periodic_minimum_distance():
    scale = np.array([1.0, 1.0, 0.5])
    d = default_min_distance(40, SIZE, scale)
    s = poisson_disk_seeds(40, SIZE, 1, scale=scale)
    period = SIZE * scale
    u = s * scale
    diff = u[:, None, :] - u[None, :, :]
    diff -= period * np.round(diff / period)
    dist = np.linalg.norm(diff, axis=2) + np.eye(len(s)) * 1e9
    assert dist.min() >= d * (1 - 1e-12)


def test_poisson_disk_too_dense_is_infeasible():
    with pytest.raises(InfeasibleError, match="seeds.min_distance"):
        poisson_disk_seeds(50, [1.0, 1.0, 1.0], 0, min_distance=0.5, max_attempts=5000)


def test_bad_sampler_and_size_name_the_field():
    with pytest.raises(ConfigError, match="seeds.sampler"):
        make_seeds("halton", 8, SIZE, 0)
    with pytest.raises(ConfigError, match="size"):
        uniform_seeds(8, [1.0, -1.0, 1.0], 0)
