"""The density solve: strut radius / wall thickness for a relative density (issue 3, item 4)."""

import numpy as np
import pytest

from metasheet.cells.foam import Foam, voxelize
from metasheet.cells.metrics import PolyhedralMetric, StretchedMetric
from metasheet.cells.seeds import poisson_disk_seeds
from metasheet.cells.thickness import solve_thickness
from metasheet.errors import ConfigError, InfeasibleError

CUBE = np.array([6.0, 6.0, 6.0])


@pytest.mark.parametrize("topology,target", [("open", 0.15), ("closed", 0.35)])
def test_density_solver_hits_its_target(topology, target):
    seeds = poisson_disk_seeds(16, CUBE, 1)
    n = 48
    sol = solve_thickness(seeds, CUBE, StretchedMetric(), topology, target, n)
    assert abs(sol.relative_density - target) < 1.0 / n**3 + 1e-12
    foam = Foam(seeds, CUBE, StretchedMetric(), topology, sol.thickness)
    assert voxelize(foam, n).mean() == pytest.approx(sol.relative_density, abs=1e-12)
    # the sub-voxel volume estimate agrees with the voxel count
    assert sol.volume_estimate == pytest.approx(target, rel=0.03)


def test_unreachable_density_names_the_field_and_the_range():
    seeds = poisson_disk_seeds(64, CUBE, 1)
    with pytest.raises(InfeasibleError, match=r"relative_density: 0.01: .*reachable range is \[0\.\d+, "):
        solve_thickness(seeds, CUBE, StretchedMetric(), "open", 0.01, 24)
    with pytest.raises(ConfigError, match="relative_density"):
        solve_thickness(seeds, CUBE, StretchedMetric(), "open", 1.2, 24)


def test_polyhedral_foam_solves_and_matches_its_voxelisation():
    size = np.array([8.0, 8.0, 8.0])
    m = PolyhedralMetric(k=5, height=1.5, x_shrink=0.8)
    seeds = poisson_disk_seeds(16, size, 4, scale=m.scale)
    sol = solve_thickness(seeds, size, m, "open", 0.2, 32)
    assert abs(sol.relative_density - 0.2) < 1e-4
    phases = voxelize(Foam(seeds, size, m, "open", sol.thickness), 32)
    assert phases.mean() == pytest.approx(sol.relative_density, abs=1e-12)
