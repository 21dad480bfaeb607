"""The studies on the reduced-order robot (issue 16): a coarse robot (16 mm tets), a basis
trained on rest +-10 deg from 12 full equilibria, tiny grids.

Independent answers: the full model's own study (classes), the full model's equilibrium at the
reduced result's motor angles (the reduce stage's position target, 0.1 mm, inside the box),
and the full model itself for every call the reduced model hands over (outside the box).
"""

import logging
import pickle

import numpy as np
import pytest

from metasheet.errors import ConfigError, StageError
from metasheet.mechanics.material import Isotropic
from metasheet.studies.adapter import FemRobot, paper_robot_spec
from metasheet.studies.certify import certify_study, sample
from metasheet.studies.grid import star_grid
from metasheet.studies.reduced_adapter import ReducedFem, ReducedSpec
from metasheet.studies.workspace import WorkspaceSettings, explore_workspace

POSITION_TARGET_MM = 0.1  # the reduce stage's certificate target for positions inside the box [mm]
LOG = "metasheet.studies.reduced_adapter"


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    from metasheet.robot.equilibrium import solve_equilibrium
    from metasheet.rom.training import motor_design, train

    spec = paper_robot_spec(mesh_size=16.0)
    fem = FemRobot(spec)
    c = fem.robot.coupling
    lo, hi = c.rest_angles - np.radians(10), c.rest_angles + np.radians(10)
    snaps = [solve_equilibrium(fem.robot, a, state=fem.rest, linearizer=fem.lz).state
             for a in motor_design(lo, hi, 12, 1)]
    basis = train(fem.robot, snaps, fem.rest, box=(lo, hi), basis_tol_mm=0.005, fit_tol_mm=0.01)
    path = tmp_path_factory.mktemp("rom") / "basis.npz"
    basis.save(path)
    return spec, ReducedSpec.from_file(spec, path), basis


@pytest.mark.slow
def test_workspace_classes_agree_or_differences_are_certified(trained):
    """Default-selection sibling: test_workspace_classes_agree_on_two_rays."""
    _workspace_classes(trained, 3, 3, 4)


def test_workspace_classes_agree_on_two_rays(trained):
    """The slow test's checks on 2 rays of 2 steps (not 3 of 3)."""
    _workspace_classes(trained, 2, 2, 2)


def _workspace_classes(trained, n_azimuth, n_steps, least_reached):
    spec, rspec, _ = trained
    grid = star_grid(n_azimuth=n_azimuth, n_elevation=1, n_steps=n_steps, extent_axial=4.0, extent_lateral=7.0,
                     thin_below=0.0)
    s = WorkspaceSettings(max_steps=30, rotations=False, continuity=False)
    full = explore_workspace(spec, grid, s)
    red = explore_workspace(rspec, grid, s)
    assert full.records.reached.sum() >= least_reached  # the test says something: points reached on both models
    differ = np.flatnonzero(full.cls != red.cls)
    assert len(differ) <= 1, (full.cls, red.cls)
    # every point the reduced model reached, re-solved by the full model at its motor angles
    ids = np.flatnonzero(red.records.reached)
    rest = rspec.build().rest_pose()
    goals = np.column_stack([red.goals[ids], np.tile(rest[3:], (len(ids), 1))])
    # every point twice (as two motor ranges that both hold its path report it): one full solve each
    motors = red.records.motors_deg[ids]
    cert = certify_study(rspec, np.vstack([goals, goals]), np.vstack([motors, motors]), tol_mm=s.tol_mm,
                         labels=ids.tolist() * 2)
    assert cert.certified == cert.reachable == 2 * len(ids) and cert.solves == len(ids)
    bad = [p["point"] for p in cert.points]
    assert bad[:len(bad) // 2] == bad[len(bad) // 2:] and len(bad) % 2 == 0  # a twin shares its verdict
    # a point the models classify differently and the reduced one reached is among those certified
    assert set(differ[red.records.reached[differ]].tolist()) <= set(ids.tolist())
    model = rspec.build()
    for g, q in zip(goals, red.records.motors_deg[ids]):
        c = model.certify(g, q, tol_mm=s.tol_mm)
        assert c.full_converged
        if c.in_box:  # the reduced and full equilibria at the same motors: the reduce stage's target
            assert abs(c.full_error_mm - c.reduced_error_mm) <= POSITION_TARGET_MM
    assert all(p["full_error_mm"] is None or p["full_error_mm"] > s.tol_mm for p in cert.points)
    assert cert.disagree == len(cert.points) and cert.rate == cert.disagree / cert.certified


def test_only_bit_identical_points_share_a_solve():
    from metasheet.studies.certify import _distinct

    g = np.zeros((4, 6))
    m = np.array([[1.0] * 6, [1.0] * 6, [1.0 + 1e-15] * 6, [1.0] * 6])
    g[3, 0] = 1e-12
    rows, which = _distinct(g, m)
    assert rows.tolist() == [0, 2, 3] and which.tolist() == [0, 0, 1, 2]


def test_certified_sample_is_seeded_and_sized():
    a, b = sample(50, 7, 3), sample(50, 7, 3)
    assert np.array_equal(a, b) and len(a) == 7 and len(set(a.tolist())) == 7 and a.max() < 50
    assert not np.array_equal(a, sample(50, 7, 4))
    assert np.array_equal(sample(5, 0, 0), np.arange(5)) and np.array_equal(sample(5, 9, 0), np.arange(5))
    with pytest.raises(ConfigError, match="certify"):
        sample(5, -1, 0)


def test_outside_the_box_warns_once_and_is_the_full_model(trained, caplog):
    spec, rspec, basis = trained
    model, ref = ReducedFem(rspec), FemRobot(spec)
    q = model.rest_motors() + np.array([15.0, 0, 0, 0, 0, -12.0])  # beyond rest +-10 deg
    assert not model.in_box(q) and model.in_box(model.rest_motors())
    with caplog.at_level(logging.WARNING, logger=LOG):
        pose, st = model.equilibrium(q)
        pose2, _ = model.equilibrium(q + 1.0)
    warned = [r for r in caplog.records if r.name == LOG and "training box" in r.getMessage()]
    assert len(warned) == 1 and model.fallbacks == 2
    pose_ref, st_ref = ref.equilibrium(q)
    assert hasattr(st, "x")  # a full RobotState
    assert np.abs(pose - pose_ref).max() < 1e-9
    assert np.abs(st.x - st_ref.x).max() < 1e-9
    # strains of a fallback state are the full model's
    assert model.max_principal_strain(st) == pytest.approx(ref.max_principal_strain(st_ref), abs=1e-12)


def test_a_point_outside_the_box_is_certified_from_the_box_edge(trained):
    """Outside the box the certificate's full solve starts from the reduced equilibrium at the
    box's edge, not from the extrapolation at the point; its answer is the full model's own."""
    spec, rspec, basis = trained
    model, ref = ReducedFem(rspec), FemRobot(spec)
    q = model.rest_motors() + np.array([16.0, 0, 0, 0, 0, -14.0])  # beyond rest +-10 deg
    pose_ref, _ = ref.equilibrium(q)
    c = model.certify(pose_ref, q, tol_mm=0.5, tol_deg=0.5)
    assert not c.in_box and c.full_converged and c.agree
    # the full equilibrium at q itself (the angle's arccos rounds at ~1e-6 deg)
    assert c.full_error_mm < 1e-6 and c.full_error_deg < 1e-4
    assert c.reduced_error_mm > 10 * c.full_error_mm  # the extrapolation, reported, is not the answer


def test_a_stop_ends_the_controller_before_the_step_that_fires_it(trained):
    spec, _, _ = trained
    ref = FemRobot(spec)
    goal = ref.rest_pose() + np.array([0.0, 9.0, 0.0, 0, 0, 0])
    free = ref.reach(goal, tol_mm=0.5, rot_weight=0.0)
    q0 = ref.rest_motors()
    far = np.abs(free.motors_deg - q0).max()
    assert far > 6.0 and not free.stopped  # the free reach moves a motor further than the stop allows
    r = ref.reach(goal, tol_mm=0.5, rot_weight=0.0, stop=lambda st: np.abs(np.degrees(st.angles) - q0).max() > 3.0)
    assert r.stopped and not r.reached and r.steps >= 1 and np.abs(r.motors_deg - q0).max() <= 3.0
    pose, _ = ref.equilibrium(r.motors_deg)  # the stopped state is an equilibrium (certified)
    assert np.abs(pose - r.pose).max() < 1e-6
    # not certified: the same run's last control state (one Newton step from that equilibrium),
    # and no certification run
    stop = lambda st: np.abs(np.degrees(st.angles) - q0).max() > 3.0  # noqa: E731
    before = dict(ref.ctrl.certified)
    u = ref.reach(goal, tol_mm=0.5, rot_weight=0.0, stop=stop, certify_stop=False)
    assert ref.ctrl.certified == before
    assert u.stopped and u.steps == r.steps and np.array_equal(u.motors_deg, r.motors_deg)
    assert np.abs(u.pose - r.pose).max() < 0.05


def test_a_reach_leaving_the_box_is_carried_on_by_the_full_model_from_the_edge(trained, caplog):
    spec, rspec, basis = trained
    model, ref = ReducedFem(rspec), FemRobot(spec)
    goal = model.rest_pose() + np.array([0.0, 9.0, 0.0, 0, 0, 0])  # needs more than +-10 deg
    with caplog.at_level(logging.WARNING, logger=LOG):
        r = model.reach(goal, tol_mm=0.5, rot_weight=0.0)
    assert model.fallbacks == 1 and any("training box" in x.getMessage() for x in caplog.records)
    rf = ref.reach(goal, tol_mm=0.5, rot_weight=0.0)  # the full model's own reach from rest
    assert r.reached and rf.reached and hasattr(r.state, "x") and not model.in_box(r.motors_deg)
    pose, _ = ref.equilibrium(r.motors_deg)  # independent: the full model at the answer's motors
    # two equilibria, each certified to eq_tol (1e-5 of the force scale): 1.2e-6 apart measured
    assert np.abs(pose - r.pose).max() < 1e-5 and r.error_mm <= 0.5
    assert np.abs(r.motors_deg - rf.motors_deg).max() < 2.0  # another path, the same neighbourhood
    # from that full state outside the box, the next goal is the full model's alone
    r3 = model.reach(goal + np.array([0.0, 0.5, 0.0, 0, 0, 0]), state=r.state, tol_mm=0.5, rot_weight=0.0)
    assert r3.reached and hasattr(r3.state, "x") and model.fallbacks == 1
    # a reach inside the box stays reduced and lands where the full model does at its motors
    g2 = model.rest_pose() + np.array([0.0, 2.0, 1.0, 0, 0, 0])
    fresh = ReducedFem(rspec)
    r2 = fresh.reach(g2, tol_mm=0.5, rot_weight=0.0)
    assert fresh.fallbacks == 0 and r2.reached and not hasattr(r2.state, "x")
    pose_full, _ = ref.equilibrium(r2.motors_deg)
    assert np.linalg.norm(pose_full[:3] - r2.pose[:3]) <= POSITION_TARGET_MM


def test_a_reach_leaving_the_box_stops_where_the_strain_passes_the_domain_limit(trained):
    """Beyond at the box's edge: the reduced edge state, its strain the full model's at the same
    angles (within the basis's error). Between the edge and the answer: the full continuation
    stops past the box, at a full equilibrium beyond the limit. Above the answer's strain: the
    full model's answer, as without a domain strain."""
    spec, rspec, basis = trained
    ref = FemRobot(spec)
    goal = ref.rest_pose() + np.array([0.0, 9.0, 0.0, 0, 0, 0])  # needs more than +-10 deg
    low = ReducedFem(rspec.with_domain_strain(1e-4, "full"))  # every edge is beyond
    r = low.reach(goal, tol_mm=0.5, rot_weight=0.0)
    assert r.left_domain and not r.reached and low.fallbacks == 0 and low.edge_stops == 1
    assert not hasattr(r.state, "x") and low.in_box(r.motors_deg)
    q = np.radians(r.motors_deg)  # within one control step (max_step_deg) of the box's boundary
    margin = np.radians(spec.max_step_deg)
    assert (np.minimum(q - basis.box_lo, basis.box_hi - q) <= margin).any()
    pose_full, st_full = ref.equilibrium(r.motors_deg)
    s_edge, s_edge_full = low.max_principal_strain(r.state), ref.max_principal_strain(st_full)
    assert np.linalg.norm(pose_full[:3] - r.pose[:3]) <= 1.0
    # a strain is a gradient of the displacements the basis fits to 0.005 mm: 5.6 % apart measured
    assert s_edge > 1e-4 and s_edge == pytest.approx(s_edge_full, rel=0.1)
    high = ReducedFem(rspec.with_domain_strain(10.0, "full"))  # nothing is beyond: the full model's answer
    rh = high.reach(goal, tol_mm=0.5, rot_weight=0.0)
    assert rh.reached and not rh.left_domain and high.edge_stops == high.strain_stops == 0 and high.fallbacks == 1
    s_end = ref.max_principal_strain(rh.state)
    assert s_end > 1.2 * s_edge_full  # the strain grows past the box: a limit fits between
    limit = 0.5 * (s_edge_full + s_end)
    mid = ReducedFem(rspec.with_domain_strain(limit, "full"))
    rm = mid.reach(goal, tol_mm=0.5, rot_weight=0.0)
    assert rm.left_domain and not rm.reached and hasattr(rm.state, "x") and not mid.in_box(rm.motors_deg)
    assert mid.strain_stops == 1 and mid.edge_stops == 0
    assert ref.max_principal_strain(rm.state) > limit  # the control step that passed the limit
    pose_at, st_at = ref.equilibrium(rm.motors_deg)  # independent: the equilibrium there, beyond it too
    assert ref.max_principal_strain(st_at) > limit and np.abs(pose_at - rm.pose).max() < 0.1  # one Newton step off
    assert rm.steps < rh.steps  # it stopped on the way
    assert rspec.with_domain_strain(0.3).key not in (rspec.key, rspec.with_domain_strain(0.2).key,
                                                     rspec.with_domain_strain(0.3, "full").key)
    assert rspec.with_domain_strain(None).key == rspec.key


def test_past_the_box_the_reduced_model_stops_at_the_strain_limit_and_hands_far_reaches_over(trained):
    """past_box "reduced": a reach whose first step past the box passes the limit stops there
    on the reduced model alone (no full solve), its strain the full model's at the same angles
    (within the basis's error); a reach going further than one control step past the box is
    redone the "full" way and gives the full mode's answer."""
    spec, rspec, basis = trained
    ref = FemRobot(spec)
    goal = ref.rest_pose() + np.array([0.0, 9.0, 0.0, 0, 0, 0])  # needs ~17 deg past the +-10 deg box
    low = ReducedFem(rspec.with_domain_strain(0.05))
    assert low.spec.past_box == "reduced"
    r = low.reach(goal, tol_mm=0.5, rot_weight=0.0)
    assert r.left_domain and not r.reached and not hasattr(r.state, "x")
    assert low.fallbacks == 0 and low.strain_stops == 1 and low.past_box_reaches == 1 and low.redone == 0
    out = low.degrees_outside(np.radians(r.motors_deg))
    assert 0.0 < out <= spec.max_step_deg + 1e-9  # the first control step past the box
    s_red = low.max_principal_strain(r.state)
    _, st_full = ref.equilibrium(r.motors_deg)  # independent: the full model at those angles
    assert s_red > 0.05 and ref.max_principal_strain(st_full) > 0.05
    assert s_red == pytest.approx(ref.max_principal_strain(st_full), rel=0.15)  # 5 deg extrapolated
    for limit in (10.0, 0.3):  # nothing is beyond / beyond only far out: both go too far, redone
        red = ReducedFem(rspec.with_domain_strain(limit))
        full = ReducedFem(rspec.with_domain_strain(limit, "full"))
        a, b = red.reach(goal, tol_mm=0.5, rot_weight=0.0), full.reach(goal, tol_mm=0.5, rot_weight=0.0)
        assert red.redone == 1 and full.redone == 0
        assert (a.reached, a.left_domain) == (b.reached, b.left_domain)
        # the redo starts with the tangent the first try left the controller: another path to
        # the same answer (2.5e-4 mm apart measured)
        assert np.abs(a.pose - b.pose).max() < 0.01 and np.abs(a.motors_deg - b.motors_deg).max() < 0.1


def test_a_reach_reached_past_the_box_is_confirmed_by_the_full_model(trained):
    """A goal the reduced model reaches within one control step past its box: the answer is the
    full equilibrium at the same motor angles (independent: the full model's own solve there)."""
    spec, rspec, basis = trained
    ref = FemRobot(spec)
    model = ReducedFem(rspec.with_domain_strain(10.0))
    hi = np.degrees(basis.box_hi)
    q = ref.rest_motors().copy()
    q[1::2] = hi[1::2] + 2.0  # 2 deg past the box's top on every other motor
    goal, _ = ref.equilibrium(q)
    r = model.reach(goal, tol_mm=0.5, tol_deg=2.0)
    assert r.reached and hasattr(r.state, "x") and model.past_box_reaches == 1 and model.redone == 0
    assert 0.0 < model.degrees_outside(np.radians(r.motors_deg)) <= spec.max_step_deg
    pose, _ = ref.equilibrium(r.motors_deg)
    assert np.abs(pose - r.pose).max() < 1e-5 and r.error_mm <= 0.5


def test_a_ray_stopping_beyond_the_strain_limit_ends_at_the_edge_of_the_reduced_models_domain(trained):
    spec, rspec, _ = trained
    grid = star_grid(n_azimuth=2, n_elevation=1, n_steps=4, extent_axial=4.0, extent_lateral=14.0, thin_below=0.0)
    free = explore_workspace(rspec, grid, WorkspaceSettings(max_steps=30, rotations=False, continuity=False))
    model = ReducedFem(rspec)
    inside = np.array([t and model.in_box(q) for t, q in zip(free.records.reached, free.records.motors_deg)])
    assert inside.any() and (free.records.tried & ~inside).any()  # both kinds of point on this grid
    # a limit above every point reached inside the box: the rays leave the box beyond it
    s = WorkspaceSettings(max_steps=30, rotations=False, continuity=False, stop_beyond_strain=True,
                          strain_limit=float(free.records.strain[inside].max()) + 0.005)
    red = explore_workspace(rspec, grid, s)
    rec = red.records
    assert rec.left_domain.any()
    assert (rec.strain[rec.left_domain] > s.strain_limit).all() and (red.cls[rec.left_domain] == -1).all()
    assert rec.reached[inside].all()  # the points inside the box: reached as without the stop
    for r in range(len(grid.directions)):
        ids = grid.ray_points(r)
        tried = ids[rec.tried[ids]]
        # the ray ends at its first point beyond the limit: left the domain at the box's edge, or
        # (the edge still within the limit) reached beyond it by the full model
        beyond = tried[rec.strain[tried] > s.strain_limit]
        assert len(beyond) <= 1 and (len(beyond) == 0 or beyond[0] == tried[-1])
        assert not (rec.reached & rec.left_domain)[ids].any()


def test_spec_key_follows_the_basis_and_material_changes_use_the_full_model(trained, tmp_path, caplog):
    from dataclasses import replace

    spec, rspec, basis = trained
    same = ReducedSpec.from_file(spec, rspec.basis_path)
    assert same.key == rspec.key and pickle.loads(pickle.dumps(rspec)).key == rspec.key
    other = tmp_path / "other.npz"
    replace(basis, box_hi=basis.box_hi + 0.01).save(other)
    assert ReducedSpec.from_file(spec, other).key != rspec.key
    assert rspec.key != spec.key and rspec.key.startswith("rom-")
    narrow = rspec.with_motor_range(20, 70)
    assert isinstance(narrow, ReducedSpec) and narrow.key != rspec.key and narrow.basis_hash == rspec.basis_hash
    with caplog.at_level(logging.WARNING, logger=LOG):
        sil = rspec.with_material(Isotropic(0.25, 0.45))
        soft = rspec.with_alpha(0.0)
    assert not isinstance(sil, ReducedSpec) and sil.key == spec.with_material(Isotropic(0.25, 0.45)).key
    assert soft.key == spec.with_alpha(0.0).key
    assert any("invalidates the basis" in x.getMessage() for x in caplog.records)
    # a basis file changed after the spec was made, or trained on another mesh: clear errors
    moved = ReducedSpec.from_file(spec, other)
    replace(basis, box_hi=basis.box_hi + 0.02).save(other)
    with pytest.raises(ConfigError, match="changed since"):
        moved.build()
    with pytest.raises(ConfigError, match=r"same mesh settings \(mesh_size"):
        ReducedSpec.from_file(paper_robot_spec(mesh_size=20.0), rspec.basis_path).build()
    with pytest.raises(ConfigError, match="run the 'reduce' stage"):
        ReducedSpec.from_file(spec, tmp_path / "missing.npz")


def test_reduced_model_needs_the_reduce_stage(tmp_path):
    from metasheet.pipeline.config import load_pipeline
    from metasheet.pipeline.runner import run_pipeline

    (tmp_path / "pipelines").mkdir()
    p = tmp_path / "pipelines" / "bad.toml"
    p.write_text('[pipeline]\nname = "bad"\nstages = ["workspace"]\n[workspace]\nmodel = "reduced"\n')
    with pytest.raises(StageError, match=r"workspace\.model: 'reduced': the 'reduce' stage must be in the pipeline"):
        run_pipeline(load_pipeline(p))


PIPELINE = """[pipeline]
name = "rq"
stages = ["material", "orient", "reduce", "ranges", "report"]
[material]
source = "config"
[orient]
mesh_size = 16
picture = false
[reduce]
snapshots = 6
box_deg = 10
held_out = 1
adapt_rounds = 1  # the studies on a basis, not its certificate (tests/test_reduce_adapt.py)
surface_box_deg = 7
surface_check = 20
[ranges]
model = "reduced"
certify = 0
ranges = [[0, 90], [55, 65]]
n_azimuth = 2
n_elevation = 1
n_steps = 2
extent_axial = 3
extent_lateral = 4
thin_below = 0
max_steps = 30
"""


@pytest.mark.slow
def test_ranges_stage_on_the_reduced_model_records_and_certifies(tmp_path):
    """Default-selection sibling: test_ranges_stage_on_a_coarser_reduced_model."""
    _ranges_stage(tmp_path, PIPELINE, 20)


def test_ranges_stage_on_a_coarser_reduced_model(tmp_path):
    """The slow test's pipeline and checks on 20 mm P1 sheets (not P2: a sixth of the dofs; the
    reduce stage's code does not depend on the element), 4 snapshots, 8 surface checks. On P2
    the reduced model's inverse stalled at the box's mixed corners (35 steps each): 45 CPU s,
    against 16 on P1, of which the orient stage's sheet.png is 5."""
    text = PIPELINE.replace("mesh_size = 16", 'mesh_size = 20\nelement = "p1"').replace(
        "snapshots = 6", "snapshots = 4").replace("surface_check = 20", "surface_check = 8")
    _ranges_stage(tmp_path, text, 8)


def _ranges_stage(tmp_path, text, surface_check):
    import json

    from metasheet.pipeline.config import load_pipeline
    from metasheet.pipeline.runner import run_pipeline

    (tmp_path / "cells").mkdir()
    (tmp_path / "pipelines").mkdir()
    p = tmp_path / "pipelines" / "rq.toml"
    p.write_text(text)
    run_pipeline(load_pipeline(p))
    out = tmp_path / "outputs" / "rq"
    r = json.loads((out / "ranges" / "ranges.json").read_text())
    red = json.loads((out / "reduce" / "reduce.json").read_text())
    info, cert = r["model_info"], r["certification"]
    assert info["model"] == "reduced" and info["k"] == red["k"] and info["elements"] == red["elements"]
    assert info["robot_key"] == red["robot_key"] and info["box_deg"] == red["box_deg"]
    manifest = json.loads((out / "ranges" / "manifest.json").read_text())
    assert manifest["summary"]["model_info"]["basis_key"] == info["basis_key"]
    # the same config trains the same basis, byte for byte (the studies' model key is its hash):
    # tests/test_reduce_adapt.py::test_the_training_rounds_give_the_same_bytes_twice
    assert "training_ecsw_rows" in json.loads((out / "reduce" / "manifest.json").read_text())["timings_s"]
    # certify = 0: every point reached in any range re-solved by the full model
    assert cert["reachable"] == sum(r["reachable"].values()) == cert["certified"] > 0
    assert cert["disagree"] == len(cert["points"]) and cert["rate"] == cert["disagree"] / cert["certified"]
    text = (out / "report" / "report.md").read_text()
    # the three ranges share most paths: a point reached with the same motors in two is solved once
    assert 0 < cert["solves"] < cert["certified"]
    assert (f"{cert['certified']} of {cert['reachable']} re-solved ({cert['certified'] - cert['solves']} of "
            f"them the same goal and motors as another: {cert['solves']} full solves), {cert['disagree']} "
            "disagree") in text
    assert f"k = {red['k']} modes" in text
    # the surface in its own box (rest +- 7 deg), checked on 20 reduced-model equilibria beside the held-out poses
    surf = red["surface"]
    lo, hi = (np.array(b) for b in surf["box_deg"])
    assert np.allclose(hi - lo, 14.0) and surf["check"]["equilibria"] == surface_check
    assert surf["certified"] == (surf["check"]["met"] and (surf["certificate"]["poses"] == 0
                                                          or surf["certificate"]["met"]))
    assert surf["certificate"]["poses"] + surf["certificate"].get("poses_beyond_strain", 0) \
        + surf["held_out_outside_box"] == red["certificate"]["poses"] + red["certificate"].get("poses_beyond_strain", 0)
    assert f"further equilibria within the strain limit (of {surface_check};" in text


def test_the_surface_box_must_lie_in_the_training_box():
    from metasheet.pipeline.stages.reduce import ReduceParams, surface_box

    lo, hi = np.full(6, 0.9), np.full(6, 1.5)
    rest = np.full(6, 1.2)
    assert surface_box(lo, hi, rest, ReduceParams(box_deg=10.0)) == (lo, hi)
    slo, shi = surface_box(lo, hi, rest, ReduceParams(box_deg=10.0, surface_box_deg=5.0))
    assert np.allclose(slo, 1.2 - np.radians(5)) and np.allclose(shi, 1.2 + np.radians(5))
    with pytest.raises(ConfigError, match=r"reduce.surface_box_deg: 12.0: allowed range \(0, box_deg = 10.0\]"):
        surface_box(lo, hi, rest, ReduceParams(box_deg=10.0, surface_box_deg=12.0))


def test_report_lists_points_the_full_model_misses():
    from metasheet.report.build import build_report

    cert = {"reachable": 40, "requested": 10, "seed": 0, "certified": 10, "disagree": 1, "rate": 0.1,
            "points": [{"point": 7, "goal": [0] * 6, "motors_deg": [60] * 6, "reduced_error_mm": 0.9,
                        "reduced_error_deg": 0.0, "full_error_mm": 1.2, "full_error_deg": 0.0,
                        "full_converged": True, "in_box": True}]}
    ranges = {"reachable": {"0-90": 40}, "nested": True, "violations": [], "model": "reduced",
              "model_info": {"model": "reduced", "k": 9, "elements": 50, "basis_key": "abc",
                             "box_deg": [[50.0] * 6, [70.0] * 6]}, "certification": cert}
    text = build_report({"ranges": ranges}, {})
    assert "a random sample (seed 0)): 10 of 40 re-solved, 1 disagree (rate 0.1)" in text
    assert "point 7: reduced error 0.9 mm, full error 1.2 mm" in text
    assert "50 to 70 deg (every motor)" in text
    diffs = text.split("## Differences from the paper")[1]
    assert "ranges: 1 of 10 points the reduced model reached are missed by the full model" in diffs
