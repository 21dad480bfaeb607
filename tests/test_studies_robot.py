"""The studies on a coarse real FEM robot (metasheet.robot) through the adapter."""

import pickle

import numpy as np
import pytest

from metasheet.mechanics.material import Isotropic
from metasheet.studies.anisotropy import anisotropy_sweep
from metasheet.studies.grid import star_grid
from metasheet.studies.maze import MazeSettings, solve_maze
from metasheet.studies.model import MODELS, RobotModel, pose_errors
from metasheet.studies.workspace import WorkspaceSettings, explore_workspace

pytest.importorskip("metasheet.robot.inverse")


def coarse_spec(mesh_size: float = 14.0):
    """The 6-DOF robot on ~850 tets per sheet, motors at rest at the default 60 deg
    (the paper's pull 15 / push 35 both fit inside 0-90 deg)."""
    from metasheet.studies.adapter import paper_robot_spec

    return paper_robot_spec(mesh_size=mesh_size)


@pytest.fixture(scope="module")
def spec():
    return coarse_spec()


def test_adapter_is_a_robot_model_and_pickles(spec):
    m = MODELS.get(spec)
    assert isinstance(m, RobotModel)
    assert m.rod_axis == 0 and np.allclose(m.rest_motors(), 60.0, rtol=0, atol=1e-9)
    back = pickle.loads(pickle.dumps(spec))
    assert back.key == spec.key and back.with_alpha(0.0).key != spec.key
    # forward/inverse round trip: motors that reach a goal put the effector there at equilibrium
    r = m.reach(m.rest_pose() + np.array([0, 3.0, 0, 0, 0, 0]), tol_mm=0.5, rot_weight=0.0)
    assert r.reached
    pose, _ = m.equilibrium(r.motors_deg)
    assert pose_errors(r.pose, pose)[0] < 0.05
    # rest is undeformed up to gravity sag: tiny strain; full control authority
    assert 0 <= m.max_principal_strain(m.rest) < 0.02
    assert m.min_singular_value(m.rest) > 0


def test_anisotropy_sweep_on_fem(spec):
    res = anisotropy_sweep(spec, [0.0, spec.design_alpha / 2, spec.design_alpha])
    rot = np.abs(res.rod_rotation_deg)
    assert np.allclose(np.abs(res.applied_deg), [15.0, 35.0], atol=1.0)
    # isotropic sheets: the mirror symmetry forbids a rod rotation (mesh asymmetry only)
    assert np.all(rot[0] < 0.03 * rot[-1])
    assert np.all(np.diff(rot, axis=0) > 0)  # grows with alpha
    assert rot[-1, 1] > 3.0  # a visible rotation with the paper's foam, pushing 35 deg


@pytest.mark.slow
def test_workspace_on_fem_classes_consistent(spec):
    """Default-selection sibling: test_workspace_on_fem_classes_consistent_on_one_step_a_ray."""
    _workspace_classes(spec, 2, 4)


def test_workspace_on_fem_classes_consistent_on_one_step_a_ray(spec):
    """The slow test's checks on the nearest point of each ray (2 points, not 4)."""
    _workspace_classes(spec, 1, 2)


def _workspace_classes(spec, n_steps, least_reached):
    grid = star_grid(n_azimuth=2, n_elevation=1, n_steps=n_steps, extent_axial=6.0, extent_lateral=8.0,
                     thin_below=0.0)
    s = WorkspaceSettings(max_steps=30, substeps=1)
    ws = explore_workspace(spec, grid, s)
    r = ws.records
    assert np.array_equal(r.reached, r.tried & r.converged & (np.nan_to_num(r.error_mm, nan=np.inf) <= s.tol_mm))
    ok = ((r.rot_error_mm <= s.tol_mm) & (r.rot_error_deg <= s.tol_rot_deg)).reshape(-1, 3, 2).all(axis=2)
    assert np.array_equal(ws.cls, np.where(r.reached, ok.sum(axis=1), -1))
    assert r.reached.sum() >= least_reached  # the nearest points (3-4 mm) are reachable
    m = MODELS.get(spec)
    lo, hi = m.motor_range
    reached = r.reached
    assert np.all((r.motors_deg[reached] >= lo - 1e-9) & (r.motors_deg[reached] <= hi + 1e-9))
    assert np.all(r.strain[reached] > 0) and np.all(r.sigma_min[reached] > 0)
    assert ws.component[reached].min() == 0


def test_maze_on_fem_tracks_and_needs_the_foam(spec):
    path = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]]  # along the rod, then across it
    s = MazeSettings(tilt_deg=5.0, dt=0.5, ramp_s=0.5, speed=10.0)
    foam = solve_maze(spec, path, s)
    lo, hi = foam.motor_range
    assert foam.motors_deg.min() >= lo and foam.motors_deg.max() <= hi
    assert foam.segment_ok.all()
    assert np.nanmax(foam.track_mm) <= s.tol_mm and np.nanmax(foam.track_deg) <= s.tol_deg
    # the recorded strain is the equilibrium's at the sample's motors, solved again from rest
    model, i = MODELS.get(spec), int(np.argmax(foam.strain))
    _, st = model.equilibrium(foam.motors_deg[i])
    assert foam.strain[i] > 0 and abs(model.max_principal_strain(st) - foam.strain[i]) < 1e-6 * foam.strain[i]
    # a held sample's replay is the one before it: an equilibrium solved again at its own motors
    # from itself does not move (bit for bit), so the replay takes it as it is
    again, _ = model.equilibrium(foam.motors_deg[i], state=st)
    assert np.array_equal(again, model.equilibrium(foam.motors_deg[i])[0])
    sil = solve_maze(spec.with_material(Isotropic(0.25, 0.45)), path, s)
    # silicone: tilting across the rod needs the rod rotation, which isotropic sheets lack
    assert sil.segment_ok.tolist() == [True, False]


@pytest.mark.slow
def test_full_default_grid_on_paper_mesh_anisotropy_and_standin_workspace():
    """Full-size cases (CI skips them): the paper's mesh for the sweep, the default 1,798-point grid."""
    spec = coarse_spec(mesh_size=5.0)
    res = anisotropy_sweep(spec, np.linspace(0.0, spec.design_alpha, 6))
    rot = np.abs(res.rod_rotation_deg)
    assert np.all(rot[0] < 0.03 * rot[-1]) and np.all(np.diff(rot, axis=0) > 0)
    from metasheet.studies.standin import StandInSpec

    ws = explore_workspace(StandInSpec(), star_grid(), WorkspaceSettings(substeps=2))
    assert len(ws.goals) == 1798 and (ws.cls == 3).sum() > 100 and ws.n_components >= 1
