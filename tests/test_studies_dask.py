"""Studies on a real dask.distributed cluster (scheduler + two worker processes) equal the serial run."""

import numpy as np
import pytest

from metasheet.runtime.executor import Executor
from metasheet.studies.anisotropy import anisotropy_sweep
from metasheet.studies.grid import star_grid
from metasheet.studies.standin import StandInSpec
from metasheet.studies.workspace import WorkspaceSettings, explore_workspace

distributed = pytest.importorskip("distributed")


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as c:
        yield c


@pytest.mark.bytes
def test_workspace_on_dask_equals_serial(cluster):
    spec, grid = StandInSpec(), star_grid(n_azimuth=6, n_elevation=3, n_steps=6, extent_axial=40, extent_lateral=50)
    s = WorkspaceSettings(substeps=2)
    serial = explore_workspace(spec, grid, s)
    dask = explore_workspace(spec, grid, s, executor=Executor(scheduler=cluster.scheduler_address))
    assert np.array_equal(serial.cls, dask.cls)
    assert np.array_equal(serial.component, dask.component)
    for f in ("error_mm", "motors_deg", "rot_error_deg", "strain", "sigma_min"):
        assert np.array_equal(getattr(serial.records, f), getattr(dask.records, f), equal_nan=True), f
    assert serial.edges_tested == dask.edges_tested > 0


def test_fem_robot_rebuilt_in_dask_workers(cluster):
    from metasheet.studies.adapter import paper_robot_spec

    spec = paper_robot_spec(mesh_size=16.0)
    alphas = [0.0, spec.design_alpha]
    serial = anisotropy_sweep(spec, alphas, ramp_deg=10.0)
    dask = anisotropy_sweep(spec, alphas, ramp_deg=10.0, executor=Executor(scheduler=cluster.scheduler_address))
    assert np.allclose(serial.delta, dask.delta, rtol=0, atol=1e-9)
    assert abs(dask.rod_rotation_deg[1, 1]) > 10 * abs(dask.rod_rotation_deg[0, 1])
