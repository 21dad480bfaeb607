"""Study logic on the analytic stand-in robot (fast): grid, classes, ranges, anisotropy, maze, resume."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from metasheet.errors import ConfigError
from metasheet.runtime.executor import Executor
from metasheet.studies.anisotropy import anisotropy_sweep, anisotropy_sweeps
from metasheet.studies.grid import star_grid
from metasheet.studies.maze import MazeSettings, maze_commands, solve_maze, solve_mazes
from metasheet.studies.model import MODELS, ModelCache, RobotModel, pose_errors
from metasheet.studies.ranges import motor_range_study
from metasheet.studies.resume import UnitCache, unit_key
from metasheet.studies.standin import StandInSpec
from metasheet.studies.workspace import WorkspaceSettings, classify, explore_workspace

SMALL = dict(n_azimuth=6, n_elevation=3, n_steps=8, extent_axial=40.0, extent_lateral=50.0)


@pytest.fixture(scope="module")
def ws():
    return explore_workspace(StandInSpec(), star_grid(**SMALL), WorkspaceSettings(substeps=2))


def test_default_grid_is_the_papers_size_and_thinned():
    g = star_grid()
    assert 1700 <= len(g) <= 1900
    t = np.linalg.norm(g.points / np.array([20.0, 20.0, 20.0]), axis=1)  # ellipsoidal radius in [0, 1]
    inner, outer = (t < 0.35).sum(), (t >= 0.35).sum()
    # per ray: 12 of 37 steps lie below 0.35 and every third is kept (4); 25 lie above
    assert inner == 62 * 4 and outer == 62 * 25
    assert np.allclose(np.linalg.norm(g.directions, axis=1), 1.0)
    # every ray is collinear with its direction
    for r in range(len(g.directions)):
        p = g.points[g.ray_points(r)]
        assert np.allclose(np.cross(p / np.array([20.0, 20.0, 20.0]), g.directions[r]), 0.0, atol=1e-12)


def test_grid_rejects_bad_input():
    with pytest.raises(ConfigError, match="n_steps"):
        star_grid(n_steps=0)
    with pytest.raises(ConfigError, match="thin_below"):
        star_grid(thin_below=1.5)


def test_standin_satisfies_protocol_and_has_five_dof_when_isotropic():
    m = MODELS.get(StandInSpec())
    assert isinstance(m, RobotModel)
    sv = np.linalg.svd(MODELS.get(StandInSpec(alpha=0.0)).J, compute_uv=False)
    assert sv[-1] < 1e-12 * sv[0] and np.linalg.svd(m.J, compute_uv=False)[-1] > 1e-3


def test_model_cache_builds_once_per_spec_and_is_bounded():
    cache = ModelCache(max_size=2)
    specs = [StandInSpec(alpha=a) for a in (0.0, 10.0, 20.0)]
    m0 = cache.get(specs[0])
    assert cache.get(StandInSpec(alpha=0.0)) is m0 and len(cache) == 1  # equal key: no rebuild
    cache.get(specs[1])
    cache.get(specs[2])  # full: the least recently used is dropped
    assert len(cache) == 2 and specs[0] not in cache and specs[1] in cache and specs[2] in cache
    m0 = cache.get(specs[0])  # rebuilt: drops specs[1]
    assert specs[1] not in cache
    cache.get(specs[2])  # used again, so the next new spec drops specs[0], built after it
    cache.get(specs[1])
    assert specs[2] in cache and specs[1] in cache and specs[0] not in cache
    assert cache.get(specs[0]) is not m0
    cache.clear()
    assert len(cache) == 0
    with pytest.raises(ConfigError, match="max_size"):
        ModelCache(max_size=0)


def test_threads_asking_for_one_spec_wait_for_one_build():
    """Two stage threads of a run built the same reduced model side by side (8 CPU s twice):
    now the second waits for the first's build, while another spec builds meanwhile."""
    import threading
    import time

    builds, started = [], threading.Barrier(4)

    class SlowSpec:
        def __init__(self, key):
            self.key = key

        def build(self):
            builds.append(self.key)
            time.sleep(0.5)
            return object()

    cache, got = ModelCache(max_size=4), {}

    def ask(i, key):
        started.wait()
        got[i] = cache.get(SlowSpec(key))

    threads = [threading.Thread(target=ask, args=(i, "a" if i < 3 else "b")) for i in range(4)]
    t0 = time.monotonic()
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert sorted(builds) == ["a", "b"]  # one build per spec
    assert got[0] is got[1] is got[2] and got[3] is not got[0]
    assert time.monotonic() - t0 < 0.9  # "b" built beside "a" (0.5 s), not after it (1 s)


def test_classes_consistent_with_recorded_errors(ws):
    r, s = ws.records, ws.settings
    reached = r.error_mm <= s.tol_mm
    assert np.array_equal(r.reached, np.nan_to_num(reached, nan=0).astype(bool) & r.tried & r.converged)
    ok = (r.rot_error_mm <= s.tol_mm) & (r.rot_error_deg <= s.tol_rot_deg)
    axes_ok = ok.reshape(-1, 3, 2).all(axis=2)
    expect = np.where(r.reached, axes_ok.sum(axis=1), -1)
    assert np.array_equal(ws.cls, expect)
    assert np.array_equal(classify(r.reached, axes_ok), ws.cls)
    # every class occurs on this grid, and the centre keeps all three rotations
    assert set(np.unique(ws.cls)) >= {3, 0, -1}
    centre = np.argmin(np.linalg.norm(ws.goals, axis=1))
    assert ws.cls[centre] == 3
    # the recorded motor angles really put the effector within tolerance (forward check)
    m = MODELS.get(StandInSpec())
    for i in np.flatnonzero(r.reached)[:20]:
        pose, _ = m.equilibrium(r.motors_deg[i])
        assert pose_errors(np.concatenate([ws.goals[i], np.zeros(3)]), pose)[0] <= s.tol_mm + 1e-9


def test_validity_and_loss_of_control_recorded(ws):
    r = ws.records
    assert np.all(np.isfinite(r.strain[r.reached])) and np.all(np.isnan(r.strain[~r.reached]))
    assert np.array_equal(ws.valid, r.reached & (r.strain <= ws.settings.strain_limit))
    # the stand-in's strain is 0.004 per degree of the largest motor offset
    i = np.flatnonzero(r.reached)[5]
    assert r.strain[i] == pytest.approx(0.004 * np.abs(r.motors_deg[i] - 30.0).max(), rel=1e-12)
    # saturation: control authority falls towards the rim
    radius = np.linalg.norm(ws.goals, axis=1)
    inner = r.reached & (radius < 20)
    outer = r.reached & (radius > 30)
    assert np.nanmean(r.sigma_min[outer]) < np.nanmean(r.sigma_min[inner])


def test_continuity_components(ws):
    assert ws.edges_tested > 0 and ws.edges_passed <= ws.edges_tested
    assert ws.n_components == 1  # the stand-in's workspace is star-convex around rest
    assert np.all(ws.component[ws.records.reached] == 0) and np.all(ws.component[~ws.records.reached] == -1)


def test_motor_range_workspaces_nest():
    res = motor_range_study(StandInSpec(), star_grid(**SMALL), [(0, 90), (10, 80), (20, 70)])
    counts = res.counts()
    assert counts[0] > counts[1] > counts[2] > 0
    assert res.nested and not res.violations
    assert np.all(res.reached[2] <= res.reached[1]) and np.all(res.reached[1] <= res.reached[0])
    # the stand-in's rays never stall short of a bound: each range's own search finds its whole set
    assert np.array_equal(res.found, res.reached) and np.all((res.via >= 0) == res.reached)


def test_range_excluding_rest_starts_inside_it():
    res = motor_range_study(StandInSpec(), star_grid(**SMALL), [(0, 90), (35, 90)])  # rest is 30 deg
    assert 0 < res.counts()[1] < res.counts()[0] and res.nested


def test_anisotropy_sweep_zero_at_isotropic_and_growing():
    spec = StandInSpec()
    res = anisotropy_sweep(spec, np.linspace(0, spec.design_alpha, 5))
    rot = res.rod_rotation_deg
    assert np.all(np.abs(rot[0]) < 1e-9)  # alpha = 0: no rod rotation
    assert np.all(np.diff(np.abs(rot[:, 1])) > 0) and np.all(np.diff(np.abs(rot[:, 0])) > 0)
    assert np.sign(rot[-1, 0]) == -np.sign(rot[-1, 1])  # pull and push turn the rod opposite ways
    assert res.lateral_mm[0, 1] > 1.0 and res.lateral_mm[-1, 1] < 1e-9  # isotropic sheets buckle sideways
    # analytic check at small amplitude: all motors together give c_rod * alpha/alpha_max * 6 rad/deg
    small = anisotropy_sweep(spec, [spec.design_alpha / 2], pull_deg=0.01, push_deg=0.01)
    assert small.rod_rotation_deg[0, 1] == pytest.approx(np.degrees(6 * 0.01 * 0.5 * 0.01), rel=1e-3)
    with pytest.raises(ConfigError, match="alphas"):
        anisotropy_sweep(spec, [120.0])


def test_sweeps_in_one_map_equal_the_sweeps_one_by_one():
    spec = StandInSpec()
    alphas = [np.linspace(0, spec.design_alpha, 3), [spec.design_alpha / 2]]
    specs = [spec, spec.with_alpha(spec.design_alpha / 2)]
    both = anisotropy_sweeps(list(zip(specs, alphas)), pull_deg=10.0)
    for res, sp, a in zip(both, specs, alphas):
        one = anisotropy_sweep(sp, a, pull_deg=10.0)
        for f in ("alpha", "delta", "rod_rotation_deg", "lateral_mm", "axial_mm", "applied_deg"):
            assert np.array_equal(getattr(res, f), getattr(one, f)), f
    assert len(both[1].alpha) == 1 and np.abs(both[0].rod_rotation_deg[-1]).min() > 0


def test_mazes_in_one_map_equal_the_mazes_one_by_one():
    path = [[0, 0], [20, 0], [20, 15]]
    spec, s = StandInSpec(), MazeSettings(dt=0.25)
    sil, foam = solve_mazes([spec.with_alpha(0.0), spec], path, s)
    for res, sp in ((sil, spec.with_alpha(0.0)), (foam, spec)):
        one = solve_maze(sp, path, s)
        for f in ("motors_deg", "error_mm", "track_mm", "reached", "segment_ok", "strain"):
            np.testing.assert_array_equal(getattr(res, f), getattr(one, f), err_msg=f)
    assert foam.segment_ok.all() and not sil.segment_ok.all()


def test_maze_commands_tilt_the_segment_downhill():
    cmd = maze_commands([[0, 0], [10, 0], [10, 10], [0, 0]], np.zeros(6), MazeSettings(tilt_deg=8.0))
    for i, d in enumerate(cmd.directions):
        w = cmd.poses[(cmd.segment == i) & cmd.hold][0, 3:]
        down = Rotation.from_rotvec(w).apply(d)
        assert down[2] == pytest.approx(-np.sin(np.radians(8.0)), abs=1e-12)  # rolls downhill along d
        assert np.linalg.norm(w) == pytest.approx(np.radians(8.0))
    assert abs(cmd.directions[1] @ [0, 1, 0]) == pytest.approx(1.0)
    w1 = cmd.poses[(cmd.segment == 1) & cmd.hold][0, 3:]
    assert abs(w1[0]) == pytest.approx(np.radians(8.0))  # across the rod: a rotation about the rod
    assert np.allclose(cmd.poses[-1, 3:], 0.0)  # back to level
    assert np.all(np.diff(cmd.time) > 0)
    with pytest.raises(ConfigError, match="path"):
        maze_commands([[0, 0]], np.zeros(6))


def test_maze_respects_limits_tracks_and_fails_with_silicone():
    path = [[0, 0], [20, 0], [20, 15], [-10, 15]]
    spec = StandInSpec()
    s = MazeSettings(dt=0.2)
    foam = solve_maze(spec, path, s)
    lo, hi = foam.motor_range
    assert foam.motors_deg.min() >= lo and foam.motors_deg.max() <= hi
    assert foam.segment_ok.all()
    assert np.nanmax(foam.track_mm) <= s.tol_mm and np.nanmax(foam.track_deg) <= s.tol_deg
    # the strain along the path is the replayed equilibrium's: the stand-in's law at its motors
    rest = MODELS.get(spec).rest_motors()
    law = spec.strain_per_deg * np.abs(foam.motors_deg - rest).max(axis=1)
    assert foam.strain.shape == (len(foam.commands.time),) and np.allclose(foam.strain, law, rtol=1e-9)
    assert foam.strain.max() > 0
    sil = solve_maze(spec.with_alpha(0.0), path, s)
    # only the segment across the rod needs the rod rotation
    assert sil.segment_ok.tolist() == [True, False, True]
    # while a command holds the motors hold, on a reached segment and on the impossible one
    for res in (foam, sil):
        for i in range(3):
            held = res.motors_deg[(res.commands.segment == i) & res.commands.hold]
            assert len(held) >= 2 and np.array_equal(held, np.broadcast_to(held[0], held.shape))


def test_a_held_maze_command_is_solved_once(monkeypatch):
    """The inverse model runs once per new command (plus the two moves from rest), not again
    on every held sample: an impossible segment would spend max_steps on each."""
    from metasheet.studies.standin import StandInRobot

    calls = []
    reach = StandInRobot.reach
    monkeypatch.setattr(StandInRobot, "reach", lambda self, goal, **kw: calls.append(goal) or reach(self, goal, **kw))
    path = [[0, 0], [20, 0], [20, 15]]
    res = solve_maze(StandInSpec().with_alpha(0.0), path, MazeSettings(dt=0.2))
    expected = 0
    for i in range(len(path) - 1):
        p = res.commands.poses[res.commands.segment == i]
        expected += 2 + 1 + int(np.any(p[1:] != p[:-1], axis=1).sum())  # two moves from rest, new commands
    assert res.commands.hold.sum() >= 4 and len(calls) == expected


def test_continuity_paths_from_one_point_share_its_equilibrium(monkeypatch):
    """Paths from the same start solve its equilibrium once, with the same verdicts as paths
    tested one by one."""
    from metasheet.studies.standin import StandInRobot
    from metasheet.studies.continuity import EdgeTask, test_paths

    spec, s = StandInSpec(), WorkspaceSettings(substeps=2)
    m = MODELS.get(spec)
    rest = m.rest_pose()
    motors = np.array([m.rest_motors()] * 3)
    starts = np.array([rest] * 3)
    goals = rest + np.array([[3.0, 0, 0, 0, 0, 0], [0, 4.0, 0, 0, 0, 0], [0, 0, 900.0, 0, 0, 0]])  # the last: too far
    calls = []
    eq = StandInRobot.equilibrium
    monkeypatch.setattr(StandInRobot, "equilibrium", lambda self, q, **kw: calls.append(q) or eq(self, q, **kw))
    together = test_paths(EdgeTask(spec, s, motors, starts, goals))
    assert len(calls) == 1
    one_by_one = [test_paths(EdgeTask(spec, s, motors[i:i + 1], starts[i:i + 1], goals[i:i + 1]))[0] for i in range(3)]
    assert together.tolist() == one_by_one == [True, True, False]


def test_resume_after_interruption_gives_same_result(tmp_path):
    spec, grid = StandInSpec(), star_grid(**SMALL)
    settings = WorkspaceSettings(continuity=False)
    full = explore_workspace(spec, grid, settings)

    class Stop(Exception):
        pass

    def interrupt(desc, done, total):
        if desc == "workspace rays" and done >= 6:
            raise Stop

    cache = UnitCache(tmp_path / "units")
    with pytest.raises(Stop):
        explore_workspace(spec, grid, settings, cache=cache, progress=interrupt)
    stored = len(list((tmp_path / "units").glob("*.pkl")))
    assert 0 < stored < len(grid.directions)
    seen = []
    again = explore_workspace(spec, grid, settings, cache=UnitCache(tmp_path / "units"),
                              progress=lambda d, i, n: seen.append(i))
    assert seen[0] == stored  # the finished units were not recomputed
    assert np.array_equal(again.cls, full.cls)
    assert np.array_equal(again.records.motors_deg, full.records.motors_deg, equal_nan=True)


@pytest.mark.bytes
def test_process_pool_equals_serial():
    spec, grid = StandInSpec(), star_grid(n_azimuth=4, n_elevation=1, n_steps=5)
    a = explore_workspace(spec, grid, WorkspaceSettings(substeps=1))
    b = explore_workspace(spec, grid, WorkspaceSettings(substeps=1), executor=Executor(workers=2))
    assert np.array_equal(a.cls, b.cls) and np.array_equal(a.component, b.component)
    assert np.array_equal(a.records.error_mm, b.records.error_mm, equal_nan=True)


def test_anisotropy_point_halves_failing_steps_and_reports_lost_equilibria(monkeypatch):
    """A robot whose solver fails on steps above 3 deg converges once the ramp is halved (with
    one halving allowed); one whose equilibrium is lost beyond 20 deg reports NaN and the motor
    change it reached."""
    from dataclasses import dataclass

    from metasheet.errors import ConvergenceError
    from metasheet.studies import anisotropy as an
    from metasheet.studies.model import MODELS
    from metasheet.studies.standin import StandInSpec

    @dataclass(frozen=True)
    class Picky(StandInSpec):
        max_jump: float = 3.0
        lost_beyond: float = 20.0

        @property
        def key(self) -> str:
            return f"picky-{self.max_jump}-{self.lost_beyond}-{super().key}"

        def build(self):
            rob, spec = super().build(), self

            class Wrapped:
                def __getattr__(self, name):
                    return getattr(rob, name)

                def equilibrium(self, q, *, state=None, intermediate=False):
                    q0 = rob.rest_motors()
                    prev = q0 if state is None else state[1]
                    if np.abs(np.asarray(q) - prev).max() > spec.max_jump + 1e-9:
                        raise ConvergenceError("step too large")
                    if np.abs(np.asarray(q) - q0).max() > spec.lost_beyond + 1e-9:
                        raise ConvergenceError("equilibrium lost")
                    pose, _ = rob.equilibrium(q)
                    return pose, (None, np.asarray(q, float))
            return Wrapped()

    with pytest.raises(ConvergenceError, match="step too large"):  # the default: no halving
        an._reach(MODELS.get(Picky()), np.full(6, 60.0), np.full(6, 65.0), None)
    monkeypatch.setattr(an, "MAX_CUTS", 1)
    out = np.array([an.sweep_point(an.SweepTask(Picky(), pull_deg=10.0, push_deg=30.0, ramp_deg=5.0, case=c))
                    for c in (0, 1)])
    assert np.all(np.isfinite(out[0])) and out[0, 6] == pytest.approx(-10.0)  # pull: 5 deg steps halved
    assert np.all(np.isnan(out[1, :6])) and out[1, 6] == pytest.approx(20.0)  # push: lost beyond 20 deg
    with pytest.raises(ConvergenceError):  # 5 deg halved MAX_CUTS times is still above 2 deg
        an._reach(MODELS.get(Picky(max_jump=2.0)), np.full(6, 60.0), np.full(6, 65.0), None)


def test_rays_stop_beyond_the_strain_limit():
    """With stop_beyond_strain a ray's last tried point is its only one beyond the limit; the
    points inside the limit are the same as without the stop."""
    spec, grid = StandInSpec(), star_grid(**SMALL)
    limit = 0.5 * StandInSpec().strain_per_deg * 20.0  # half of a 20 deg motor move
    free = explore_workspace(spec, grid, WorkspaceSettings(strain_limit=limit, continuity=False, rotations=False))
    stop = explore_workspace(spec, grid, WorkspaceSettings(strain_limit=limit, continuity=False, rotations=False,
                                                           stop_beyond_strain=True))
    assert stop.records.tried.sum() < free.records.tried.sum()
    for r in range(len(grid.directions)):
        ids = grid.ray_points(r)
        tried = ids[stop.records.tried[ids]]
        over = stop.records.reached[tried] & ~(stop.records.strain[tried] <= limit)
        assert over.sum() <= 1 and (over.sum() == 0 or over[-1])  # only the last tried one is beyond
        inside = tried[~over]
        assert np.array_equal(stop.records.reached[inside], free.records.reached[inside])
        np.testing.assert_array_equal(stop.records.motors_deg[inside], free.records.motors_deg[inside])


def test_rotation_tries_beyond_the_strain_limit_fail_when_the_study_stops_there():
    """With stop_beyond_strain a rotation try that meets its tolerances counts only within the
    strain limit: the classes are those of the free study with every try whose answer's strain
    (re-reached independently on the stand-in) exceeds the limit failed."""
    from metasheet.studies.workspace import RayTask, explore_ray, rotation_goals

    spec = StandInSpec()
    model = MODELS.get(spec)
    rest = model.rest_pose()
    goals = rest[:3] + np.array([[0.0, 0.0, 0.0], [0.0, 4.0, 0.0], [0.0, 8.0, 0.0]])
    free_s = WorkspaceSettings(continuity=False, strain_limit=10.0)
    free = explore_ray(RayTask(spec, free_s, goals))
    # the answers' strains, try by try, from each point's own state
    strains = np.full((len(goals), 6), np.nan)
    for i, p in enumerate(goals):
        base = model.reach(np.concatenate([p, rest[3:]]), tol_mm=1.0, rot_weight=0.0)
        for j, g in enumerate(rotation_goals(p, base.pose[3:], free_s.rot_deg)):
            r = model.reach(g, state=base.state, tol_mm=1.0, tol_deg=free_s.tol_rot_deg, max_steps=free_s.max_steps)
            strains[i, j] = model.max_principal_strain(r.state)
    ok_free = (free.rot_error_mm <= 1.0) & (free.rot_error_deg <= free_s.tol_rot_deg)
    # a limit above every point's strain, below some passing tries' answers
    limit = float(max(np.nanmax(free.strain), np.nanmin(strains[ok_free]))) + 1e-6
    assert (ok_free & (strains > limit)).any() and (ok_free & (strains <= limit)).any()  # both kinds
    stop = explore_ray(RayTask(spec, WorkspaceSettings(continuity=False, strain_limit=limit,
                                                       stop_beyond_strain=True), goals))
    assert stop.reached.all() and (stop.strain <= limit).all()
    ok = ok_free & ~(strains > limit)
    expect = np.array([[ok[i, 2 * a] and ok[i, 2 * a + 1] for a in range(3)] for i in range(len(goals))])
    np.testing.assert_array_equal(stop.rot_ok, expect)
    np.testing.assert_array_equal(stop.rot_beyond, ok_free & (strains > limit) & ~np.isnan(stop.rot_error_mm))
    assert not free.rot_beyond.any()


def _square_slow_first(x):
    import time

    time.sleep(1.0 if x == 0 else 0.0)
    return x * x


def test_resumable_map_stores_each_unit_as_it_arrives_on_a_pool(tmp_path):
    """One pool for every missing unit: the fast ones finish (and are stored) while the slow
    first one runs; an interruption keeps them."""
    items = list(range(6))

    class Stop(Exception):
        pass

    def interrupt(done, total):
        if done > total - len(items) + 2:
            raise Stop

    cache = UnitCache(tmp_path / "u")
    with pytest.raises(Stop):
        cache.map(Executor(workers=2), _square_slow_first, items, progress=interrupt)
    stored = len(list((tmp_path / "u").glob("*.pkl")))
    assert stored == 3  # stored before progress is told, in arrival order: not the slow first one
    assert not cache.load(unit_key(0))[0]
    assert cache.map(Executor(workers=2), _square_slow_first, items) == [x * x for x in items]
    assert len(list((tmp_path / "u").glob("*.pkl"))) == len(items)


def test_rotation_tries_stop_after_points_without_an_axis():
    """rot_stop_after: after that many rotation-tested points in a row pass no axis, the ray's
    outer points are still reached (the same continuation, bit for bit) but not rotation-tested."""
    from dataclasses import replace

    from metasheet.studies.workspace import RayTask, explore_ray

    # 4 x 2 rays of 12 steps: the rule stops 4 of the 10 rays short of their end (4 reached
    # points left untried) and the other 6 not, both branches at a third of the 6 x 3 rays of 16
    # steps' time
    grid = star_grid(**{**SMALL, "n_azimuth": 4, "n_elevation": 2, "n_steps": 12})
    base = WorkspaceSettings(rot_deg=30.0, continuity=False)  # wide rotations: rays end with failing points
    skipped = stopped = 0
    for ray in range(len(grid.directions)):
        goals = grid.points[grid.ray_points(ray)]
        full = explore_ray(RayTask(StandInSpec(), base, goals))
        cut = explore_ray(RayTask(StandInSpec(), replace(base, rot_stop_after=2), goals))
        for f in ("tried", "reached", "error_mm", "motors_deg", "strain", "sigma_min"):
            np.testing.assert_array_equal(getattr(cut, f), getattr(full, f), err_msg=f)
        assert np.array_equal(full.rot_tried, full.reached)  # 0: every reached point tried
        tested = np.flatnonzero(full.rot_tried)
        none = ~full.rot_ok[tested].any(axis=1)
        pairs = np.flatnonzero(none[:-1] & none[1:])  # two tested points in a row without an axis
        stop = tested[pairs[0] + 1] + 1 if len(pairs) else len(goals)
        assert np.array_equal(cut.rot_tried[:stop], full.rot_tried[:stop])
        np.testing.assert_array_equal(cut.rot_error_deg[:stop], full.rot_error_deg[:stop])
        assert not cut.rot_tried[stop:].any() and np.isnan(cut.rot_error_deg[stop:]).all()
        assert not cut.rot_ok[stop:].any()
        skipped += int(full.reached[stop:].sum())
        stopped += stop < len(goals)
    assert skipped > 0  # the rule left some reached points untried on this grid
    assert 0 < stopped < len(grid.directions)  # rays the rule stopped, and rays it did not


def test_rot_stop_after_is_checked():
    with pytest.raises(ConfigError, match="rot_stop_after"):
        WorkspaceSettings(rot_stop_after=-1)
