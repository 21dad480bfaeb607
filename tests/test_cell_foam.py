"""Voronoi foams as distance fields: exactness, slope, continuity, stretched and polyhedral cells
(issue 3, items 2-4). The density solve is tested in ``test_cell_thickness.py``, the
polyhedral gauge itself in ``test_cell_metrics.py``.
"""

import numpy as np
import pytest

from metasheet.cells.foam import Foam, cell_labels, foam_field, voxel_centres, voxelize
from metasheet.cells.measure import mean_chord_lengths
from metasheet.cells.metrics import PolyhedralMetric, StretchedMetric
from metasheet.cells.seeds import grid_seeds, poisson_disk_seeds, uniform_seeds
from metasheet.cells.skeleton import SkeletonIndex
from metasheet.cells.thickness import solve_thickness
from metasheet.errors import ConfigError

CUBE = np.array([6.0, 6.0, 6.0])


def _lattice_distances(p, spacing):
    """Distances to the faces and edges of the simple cubic Voronoi lattice (cubes of side h
    with faces at multiples of h)."""
    q = np.mod(p, spacing)
    q = np.sort(np.minimum(q, spacing - q), axis=1)  # per-axis distance to the nearest face plane
    return q[:, 0], np.hypot(q[:, 0], q[:, 1])


@pytest.mark.parametrize("topology", ["open", "closed"])
def test_one_seed_per_cubic_site_gives_the_simple_cubic_lattice_exactly(topology):
    h = 2.0
    seeds = grid_seeds((3, 3, 3), CUBE)  # centres of 2 mm cubes: Voronoi cells are those cubes
    foam = Foam(seeds, CUBE, StretchedMetric(), topology, 0.3)
    p = np.random.default_rng(1).random((5000, 3)) * CUBE
    wall, strut = _lattice_distances(p, h)
    expected = strut - 0.3 if topology == "open" else wall - 0.15
    assert np.allclose(foam_field(foam)(p), expected, atol=1e-12)
    # struts run along the axes: the voxel solid is exactly the analytic one
    n = 30
    c = voxel_centres(CUBE, n)
    wall, strut = _lattice_distances(c, h)
    analytic = (strut < 0.3) if topology == "open" else (wall < 0.15)
    assert np.array_equal(voxelize(foam, n).ravel().astype(bool), analytic)


def test_one_seed_lattice_with_images_only():
    # a single seed: all its neighbours are its own periodic images
    foam = Foam(np.array([[1.0, 1.0, 1.0]]), [2.0, 2.0, 2.0], StretchedMetric(), "open", 0.2)
    p = np.random.default_rng(2).random((2000, 3)) * 2.0
    _, strut = _lattice_distances(p, 2.0)  # the cell is the box: faces at multiples of 2
    assert np.allclose(foam_field(foam)(p), strut - 0.2, atol=1e-12)


def test_field_has_unit_slope_near_the_solid():
    foam = Foam(uniform_seeds(20, CUBE, 4), CUBE, StretchedMetric(1.5, 2, "axial"), "open", 0.3)
    f = foam_field(foam)
    rng = np.random.default_rng(3)
    p = rng.random((20000, 3)) * CUBE
    v = f(p)
    band = p[np.abs(v) < 0.15][:500]
    eps = 1e-5
    grad = np.stack([(f(band + eps * e) - f(band - eps * e)) / (2 * eps) for e in np.eye(3)], axis=1)
    slope = np.linalg.norm(grad, axis=1)
    assert np.median(np.abs(slope - 1.0)) < 1e-6
    assert np.mean(np.abs(slope - 1.0) < 1e-3) > 0.97


@pytest.mark.parametrize("topology", ["open", "closed"])
def test_field_is_continuous_where_it_decides_the_solid(topology):
    seeds = uniform_seeds(20, CUBE, 5)
    foam = Foam(seeds, CUBE, StretchedMetric(2.0, 2, "transverse"), topology, 0.3)
    f = foam_field(foam)
    rng = np.random.default_rng(6)
    p = rng.random((50000, 3)) * CUBE
    d = rng.normal(size=p.shape)
    d /= np.linalg.norm(d, axis=1)[:, None]
    step = 5e-3
    a, b = f(p), f(p + step * d)
    slope = np.abs(a - b) / step
    cells = SkeletonIndex(seeds, CUBE, foam.metric).distances(np.vstack([p, p + step * d])).cell
    crossing = cells[: len(p)] != cells[len(p):]
    near = np.minimum(a, b) < 0.0  # one end in the solid
    assert (crossing & near).sum() > 20  # the pairs do cross cell walls there
    assert slope[crossing & near].max() <= 1.0 + 1e-6  # across walls: 1-Lipschitz
    inside = np.maximum(a, b) < 0.0
    assert slope[inside].max() <= 1.0 + 1e-6  # within the solid
    # the field never jumps across its zero level: the surface has no cracks
    assert not np.any((np.sign(a) != np.sign(b)) & (slope > 1.0 + 1e-6))


def _label_chords(labels, size):
    n = np.array(labels.shape)
    return np.array([labels.size * size[a] / n[a] / (labels != np.roll(labels, 1, axis=a)).sum() for a in range(3)])


@pytest.mark.parametrize("s,mode", [(2.0, "axial"), (3.0, "axial"), (2.0, "transverse")])
def test_stretching_by_s_scales_cell_extents_by_s(s, mode):
    size = np.array([10.0, 10.0, 10.0])
    metric = StretchedMetric(s, 2, mode)
    seeds = poisson_disk_seeds(100, size, 0, scale=metric.scale)
    expected = s if mode == "axial" else 1.0 / s  # extent along z over extent across
    # cells themselves: mean intercept of the Voronoi cells along each axis
    c = _label_chords(cell_labels(seeds, size, metric, 48), size)
    assert c[2] / c[:2].mean() == pytest.approx(expected, rel=0.05)
    assert c[0] == pytest.approx(c[1], rel=0.05)
    # the foam's geometry: void chords of a thin-walled closed foam
    sol = solve_thickness(seeds, size, metric, "closed", 0.35, 48, min_voxels=1.0)
    phases = voxelize(Foam(seeds, size, metric, "closed", sol.thickness), 48)
    v = mean_chord_lengths(phases == 0, size)
    assert v[2] / v[:2].mean() == pytest.approx(expected, rel=0.12)


def test_isotropic_foam_has_equal_chords():
    size = np.array([10.0, 10.0, 10.0])
    seeds = poisson_disk_seeds(100, size, 0)
    c = _label_chords(cell_labels(seeds, size, StretchedMetric(), 48), size)
    assert c.max() / c.min() < 1.05


def test_polyhedral_walls_are_parallel_to_the_axis():
    # seeds in one z-plane and a tall prism: the foam is a k-gon Voronoi pattern extruded along z
    size = np.array([8.0, 8.0, 2.0])
    seeds = uniform_seeds(12, size, 2) * [1.0, 1.0, 0.0] + [0.0, 0.0, 1.0]
    foam = Foam(seeds, size, PolyhedralMetric(k=6, height=50.0), "closed", 0.2)
    f = foam_field(foam)
    xy = np.random.default_rng(1).random((1000, 2)) * size[:2]
    # (right above and below a seed, within height / |z - z_seed| of it, a horizontal wall
    # parts it from its own periodic image along z: leave those points out)
    d = xy[:, None, :] - seeds[None, :, :2]
    d -= size[:2] * np.round(d / size[:2])
    xy = xy[np.linalg.norm(d, axis=2).min(axis=1) > 0.1]
    values = [f(np.column_stack([xy, np.full(len(xy), z)])) for z in (0.1, 0.7, 1.3, 1.9)]
    for v in values[1:]:
        assert np.allclose(v, values[0], atol=1e-9)


def test_foam_validates_its_fields():
    with pytest.raises(ConfigError, match="topology"):
        Foam(np.zeros((1, 3)), CUBE, StretchedMetric(), "foamy", 0.1)
    with pytest.raises(ConfigError, match="thickness"):
        Foam(np.zeros((1, 3)), CUBE, StretchedMetric(), "open", -0.1)
    with pytest.raises(ConfigError, match="seeds"):
        Foam(np.zeros((4, 2)), CUBE, StretchedMetric(), "open", 0.1)
    with pytest.raises(ConfigError, match="metric.stretch"):
        StretchedMetric(0.5)
    with pytest.raises(ConfigError, match="metric.x_shrink"):
        PolyhedralMetric(x_shrink=1.5)


@pytest.mark.parametrize("metric", [StretchedMetric(2.0, 2, "transverse"), PolyhedralMetric(k=6, x_shrink=0.6)])
def test_skeleton_distances_are_the_same_bits_on_one_thread_and_two(metric):
    # the kernels run blocks of points in parallel, each with its own scratch
    import numba

    seeds = uniform_seeds(20, CUBE, 5)
    p = np.random.default_rng(8).random((9000, 3)) * CUBE  # several blocks of 2,048 points
    index = SkeletonIndex(seeds, CUBE, metric)
    before = numba.get_num_threads()
    runs = []
    try:
        for n in (1, min(2, numba.config.NUMBA_NUM_THREADS)):
            numba.set_num_threads(n)
            runs.append(index.distances(p))
    finally:
        numba.set_num_threads(before)
    for field in ("wall", "strut", "cell", "wall_nz"):
        assert np.array_equal(getattr(runs[0], field), getattr(runs[1], field))
    assert np.all(np.isfinite(runs[0].wall))
