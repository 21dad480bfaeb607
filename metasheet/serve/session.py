"""The shared robot of ``metasheet serve``: its state and the solver thread that moves it.

Independent of the web page (unit-tested without one): the page posts commands and draws
the :class:`Snapshot` s the session publishes; every tab of the page sees the same session.

* Commands return at once (:meth:`Session.set_goal`, :meth:`~Session.set_motors`,
  :meth:`~Session.set_material`, :meth:`~Session.play_maze`, :meth:`~Session.reset`); one
  worker thread runs them, off the web server's event loop, so a slow solve never freezes
  the page.
* The latest motion wins: a goal, a motor command, a playback or a reset replaces whatever
  motion was pending or running, so a goal dragged faster than the solver follows is never
  queued behind stale ones. The worker looks for newer commands after every control step.
* A goal is driven by :class:`.tracking.GoalRun` (``goto``'s loop, one control step of
  eq. 8 at a time, each published): it ends "reached", or "unreachable" on the certified
  closest pose (goto's "stalled" or "max_steps"); never an exception. A pose near the goal
  is certified only once the goal has stayed :data:`SETTLE` s: while a drag streams goals
  the loop only steps, and every new goal gets at least one control step
  (:meth:`.tracking.GoalRun.track`), even one already within the tolerances of the pose:
  the robot follows the pointer at the drag's event rate instead of in jumps of the
  tolerance (0.1 mm, 0.2 deg), which a slow drag would otherwise show a few times a second.
* Motor commands are the forward model: :func:`~metasheet.robot.equilibrium.solve_equilibrium`
  from the current state; when no newer command waits, a fresh linearisation then updates
  the Jacobian's singular values.
* A solver error (no equilibrium at these motor angles) is published as status "error" with
  its message; the robot keeps its last good state and the worker keeps running.
* On the reduced model (``--model reduced``) every solve stays in its training box: outside
  it the full model solves and the snapshot says so (:mod:`.models`: a control step leaving
  the box is undone and the goal driven on by the full model; a forward solve outside it
  runs on the full model); silicone runs on the full model (the basis is the foam's).

Live settings (:data:`LIVE_SETTINGS`): ``drift_tol`` 10 instead of 0.5. While a goal moves,
every control step leaves a pending equilibrium correction of a few tenths of a mm, and at
the default the kept tangent is refreshed more often (~210 ms each on the quick pipeline's
robot against ~15 ms for a chord step): 6.0 / 16.8 / 6.1 updates/s against 5.0 / 14.4 / 4.6
on the three drags of benchmarks/bench_serve.py. The QP already compensates the pending
correction, and a reached goal is still certified as an equilibrium within ``eq_tol``, as
``goto`` certifies it, and with the default ``drift_tol``: certifying a closest pose with the
loose one took 37 s instead of 0.8 s on that robot (the chord corrections stall and the full
Newton solve has to start from far).
"""

from __future__ import annotations

import reprlib
import threading
import time
import traceback
from dataclasses import dataclass, replace

import numpy as np

from ..errors import ConfigError, MetasheetError
from ..robot.inverse_settings import InverseSettings
from ..robot.qp import pose_error
from ..mechanics.rotations import rotation_matrix
from .models import RobotModels
from .tracking import GoalRun, check_goal, pose_of

#: the inverse loop's settings on the page (see the module docstring for drift_tol)
LIVE_SETTINGS = InverseSettings(drift_tol=10.0)
#: a goal must stay this long before the pose reached is certified [s]: a drag streams goals
#: (~60 per second), and certifying each one it already is near would cost more than stepping
SETTLE = 0.15
#: rotations count as arc lengths at this radius in the singular values [mm/rad], as in
#: :func:`metasheet.robot.kinematics.kinematics`
LENGTH_SCALE = 50.0


@dataclass(frozen=True)
class Snapshot:
    """The robot as the page draws it, after one solver step.

    Attributes
    ----------
    version : increases with every snapshot.
    material : "foam" or "silicone". description : what that robot is made of.
    mode : "inverse" (following the goal), "forward" (motor commands), "maze" (playback).
    status : "moving", "reached", "unreachable", "holding" (forward: at
        equilibrium at the commanded angles), "playing", "error".
    message : a sentence for the page (what happened, the error's message).
    state : the state drawn: a :class:`~metasheet.robot.statics.RobotState`, or a
        :class:`~metasheet.rom.coordinates.ReducedState` on the reduced model.
    x : (n, 3) [mm] the full mesh's nodes at ``state`` (what the page draws).
    model : "full" / "reduced": the model ``state`` is on. note : why it is not the model
        asked for (outside the reduced model's training box, silicone), else "".
    goal : (6,) the goal (x, y, z [mm], rotation vector [deg]).
    goal_version : increases when the session moved the goal itself (forward, material,
        playback, reset): the page then moves its goal gizmo there.
    pose : (6,) effector pose [mm, deg]. angles_deg : (na,) motor angles [deg].
    angle_min_deg, angle_max_deg : (na,) the stroke [deg].
    pos_error : [mm], rot_error : [deg]: pose to goal.
    singular_values : (min(6, na),) of diag(1, 1, 1, L, L, L) J at the last fresh
        linearisation [mm/rad] (L = :data:`LENGTH_SCALE`); empty before the first.
    step_ms : the last solver step (a control step or a forward solve) [ms].
    maze : (sample, samples) of a playback, else None.
    """

    version: int
    material: str
    description: str
    mode: str
    status: str
    message: str
    state: object
    goal: np.ndarray
    goal_version: int
    pose: np.ndarray
    angles_deg: np.ndarray
    angle_min_deg: np.ndarray
    angle_max_deg: np.ndarray
    pos_error: float
    rot_error: float
    singular_values: np.ndarray
    step_ms: float
    maze: tuple | None = None
    x: np.ndarray | None = None
    model: str = "full"
    note: str = ""


def singular_values(J, length_scale: float = LENGTH_SCALE) -> np.ndarray:
    """Singular values [mm/rad] of diag(1, 1, 1, L, L, L) J for J (6, na) [mm/rad, rad/rad]."""
    if J is None:
        return np.zeros(0)
    scale = np.array([1.0, 1.0, 1.0, length_scale, length_scale, length_scale])
    return np.linalg.svd(scale[:, None] * np.asarray(J), compute_uv=False)


class Session:
    """The robot every tab drives, and the thread that solves for it.

    Parameters
    ----------
    build : ``build(material) -> (robot, info)`` (:func:`.loading.load_robot` bound to an
        output folder); ``info.description`` is shown on the page.
    material : the material to start with. settings : the inverse loop's settings.
    """

    def __init__(self, build, *, material: str = "foam", settings: InverseSettings = LIVE_SETTINGS):
        self._build = build
        self.settings = settings
        self._robots: dict[str, RobotModels] = {}
        self._material = material
        self._cond = threading.Condition()
        self._pending: dict[str, tuple] = {}  # "motion" / "material" -> the latest command
        self.dropped = 0  # commands a newer one replaced before they ran
        self._job = None  # the running motion: a generator, one solver step per next()
        self._busy = False
        self._stopping = False
        self._snap: Snapshot | None = None
        self._goal = None
        self._goal_version = 0
        self._thread: threading.Thread | None = None

    # -- life ---------------------------------------------------------------------------
    def start(self) -> Snapshot:
        """Build the first robot and its rest equilibrium here (errors surface to the caller),
        publish it, then start the worker thread."""
        self._entry(self._material)
        self._goal = pose_of(self.current.ctrl.state)
        self._publish("inverse", "reached", "at rest (equilibrium under gravity)", step_ms=0.0)
        self._thread = threading.Thread(target=self._run, name="metasheet-serve-solver", daemon=True)
        self._thread.start()
        return self._snap

    def stop(self, timeout: float = 10.0) -> None:
        with self._cond:
            self._stopping = True
            self._cond.notify_all()
        if self._thread is not None:
            self._thread.join(timeout)

    @property
    def current(self) -> RobotModels:
        return self._robots[self._material]

    def robot_of(self, material: str):
        """(robot, info) of a material built so far (any thread: built robots are never replaced)."""
        r = self._robots[material]
        return (r.reduced if r.reduced is not None else r.full), r.info

    # -- commands (any thread) ----------------------------------------------------------
    def _post(self, key: str, command: tuple) -> None:
        with self._cond:
            self.dropped += self._pending.pop(key, None) is not None  # the latest wins, at the end of the line
            self._pending[key] = command
            self._busy = True
            self._cond.notify_all()

    # Every value from the page is checked here, before it is posted: a bad one is a
    # ConfigError (the page shows it) and never reaches the worker or the state.
    def set_goal(self, pose) -> None:
        """Drive the effector to ``pose`` (6,) = (x, y, z [mm], rotation vector [deg]), each
        component within :data:`.tracking.GOAL_LIMITS`."""
        self._post("motion", ("goal", check_goal(pose)))

    def set_motors(self, angles_deg) -> None:
        """Move the motors to ``angles_deg`` (na,) [deg] (clipped to the stroke): forward model."""
        built = self._robots.get(self._material)
        count = len(built.full.angle_min) if built is not None else None  # None: before start()
        try:
            a = np.asarray(angles_deg, dtype=float).reshape(-1)
        except (TypeError, ValueError):  # text, None, ragged lists: a malformed message
            a = np.zeros(0)
        if a.size == 0 or (count is not None and a.size != count) or not np.all(np.isfinite(a)):
            many = f"{count} " if count else ""
            raise ConfigError(f"motor angles: {reprlib.repr(angles_deg)}: expected {many}finite numbers [deg]")
        self._post("motion", ("motors", a))

    def set_material(self, material: str) -> None:
        """Switch the sheets' material ("foam" / "silicone") at the current motor angles."""
        from .loading import MATERIALS

        if not isinstance(material, str) or material not in MATERIALS:
            raise ConfigError(f"material: {reprlib.repr(material)}: allowed values are {', '.join(MATERIALS)}")
        self._post("material", ("material", material))

    def play_maze(self, playback) -> None:
        """Replay a :class:`.maze.MazePlayback` through the forward model, in its own time."""
        if playback is None or len(playback) == 0:
            raise ConfigError("maze: nothing to play: the maze stage's outputs are missing")
        self._post("motion", ("maze", playback))

    def reset(self) -> None:
        """Back to the rest angles (forward model)."""
        self._post("motion", ("reset", None))

    # -- snapshots (any thread) ---------------------------------------------------------
    def snapshot(self) -> Snapshot:
        with self._cond:
            return self._snap

    def wait(self, after: int, timeout: float | None = None) -> Snapshot | None:
        """The first snapshot newer than version ``after``, or None after ``timeout`` [s]."""
        with self._cond:
            self._cond.wait_for(lambda: self._snap.version > after or self._stopping, timeout)
            return self._snap if self._snap.version > after else None

    def wait_idle(self, timeout: float | None = None) -> Snapshot:
        """The snapshot once every command has been run to its end (for scripts and tests);
        ConfigError after ``timeout`` [s]."""
        with self._cond:
            if not self._cond.wait_for(lambda: not self._busy, timeout):
                raise ConfigError(f"session: still busy after {timeout} s")
            return self._snap

    # -- the worker ---------------------------------------------------------------------
    def _run(self) -> None:
        while True:
            with self._cond:
                self._cond.wait_for(lambda: self._pending or self._job is not None or self._stopping)
                if self._stopping:
                    return
                commands = list(self._pending.values())
                self._pending.clear()
            for cmd in commands:
                self._safely(self._apply, cmd)
            if self._job is not None:
                self._safely(self._advance)
            with self._cond:
                if not self._pending and self._job is None:
                    self._busy = False
                    self._cond.notify_all()

    def _safely(self, fn, *args) -> None:
        """Run ``fn``; an error becomes status "error" on the last good state, never a dead worker."""
        try:
            fn(*args)
        except MetasheetError as exc:
            self._fail(str(exc))
        except Exception as exc:  # a bug: keep serving, say so on the page, log the traceback
            traceback.print_exc()
            self._fail(f"internal error ({type(exc).__name__}: {exc}); see the server's log")

    def _fail(self, message: str) -> None:
        self._job = None
        good = self._snap.state if self._snap is not None and self._snap.material == self._material else None
        if good is not None:
            self.current.restore(good)
        self._publish(self._snap.mode if self._snap else "inverse", "error", message)

    def _advance(self) -> None:
        try:
            next(self._job)
        except StopIteration:
            self._job = None

    def _apply(self, cmd: tuple) -> None:
        kind, arg = cmd
        if kind == "material":
            if arg != self._material:
                angles = self.current.ctrl.state.angles
                self._publish("forward", "moving", f"building the {arg} robot ...")
                self._entry(arg)
                self._material = arg
                self._job = self._forward(angles, f"switched to {arg}")
            return
        if kind == "goal":
            self._goal = arg
            self._job = self._drive(arg)
        elif kind == "motors":
            self._job = self._forward(np.radians(arg), "motors set (forward model)")
        elif kind == "reset":
            self._job = self._forward(self.current.robot.coupling.rest_angles, "back at the rest angles")
        elif kind == "maze":
            self._job = self._maze(arg)

    def _entry(self, material: str) -> RobotModels:
        if material not in self._robots:
            self._robots[material] = RobotModels(*self._build(material), self.settings)  # the rest equilibrium
        return self._robots[material]

    # -- the motions (generators: one solver step per next()) -----------------------------
    def _drive(self, goal):
        certify = replace(self.settings, drift_tol=InverseSettings.drift_tol)  # see the module docstring
        models = self.current
        if models.may_return():
            models.enter("reduced")  # back from the full model, well inside the training box
        run = GoalRun(models.ctrl, goal, self.settings, certify)
        born = time.perf_counter()
        track = run.near()  # already within the tolerances: one step follows the drag all the same
        while True:
            before = models.ctrl.state
            if track:
                track = False
                p = run.track()
                if p is None:
                    continue
            else:
                wait = SETTLE - (time.perf_counter() - born)
                if wait > 0 and run.near():  # certify only once the drag pauses here
                    with self._cond:
                        self._cond.wait_for(lambda: self._pending or self._stopping, wait)
                    if self._pending or self._stopping:
                        return  # a newer goal: this one is dropped uncertified
                p = run.advance()
            if not p.done and models.step_left_box(before):  # undone: the full model drives on
                run = GoalRun(models.ctrl, goal, self.settings, certify)
                self._publish("inverse", "moving", "the goal leaves the reduced model's training box: "
                              "the full model drives on")
                yield
                continue
            if not p.done:
                self._publish("inverse", "moving", f"control step {run.steps}", step_ms=1e3 * p.step_time)
                yield
                continue
            if p.status == "reached":
                self._publish("inverse", "reached", f"reached in {run.steps} control steps")
            else:
                self._publish("inverse", "unreachable", f"unreachable ({p.status} after {run.steps} control "
                              f"steps): closest pose shown, {p.pos_error:.2f} mm and {p.rot_error:.2f} deg away; "
                              f"limited by {self._why(run)}")
            return

    def _why(self, run) -> str:
        """The primary cause of ``run``'s stall (:mod:`metasheet.robot.stall`), one line."""
        from ..robot.stall import diagnose_state

        return diagnose_state(run.ctrl.robot, run.ctrl.state).text().splitlines()[0]

    def _solve(self, angles) -> float:
        """Forward model: the equilibrium at ``angles`` (na,) [rad] from the current state; [ms]."""
        return self.current.solve(angles)

    def _set_goal_here(self) -> None:
        self._goal = pose_of(self.current.ctrl.state)
        self._goal_version += 1

    def _forward(self, angles, message: str):
        ms = self._solve(angles)
        self._set_goal_here()
        self._publish("forward", "holding", message, step_ms=ms)
        yield  # a newer command may take over here, before the Jacobian is refreshed
        self.current.ctrl.refresh()  # singular values at the new state
        self._publish("forward", "holding", message + "; Jacobian updated")

    def _maze(self, playback):
        rest_p = self.current.rest.p
        t0 = time.perf_counter() - playback.time[0]
        for i in range(len(playback)):
            with self._cond:  # wait for the sample's time; a new command ends the wait
                self._cond.wait_for(lambda: self._pending or self._stopping,
                                    max(0.0, playback.time[i] - (time.perf_counter() - t0)))
            if self._pending or self._stopping:
                return
            ms = self._solve(np.radians(playback.motors_deg[i]))
            self._goal = np.concatenate([rest_p, playback.command_deg[i]])
            self._goal_version += 1
            late = (time.perf_counter() - t0) - playback.time[i]
            self._publish("maze", "playing", f"maze {playback.source.name}: t = {playback.time[i]:.1f} s"
                          + (f" ({late:.1f} s behind real time)" if late > 0.5 else ""),
                          step_ms=ms, maze=(i + 1, len(playback)))
            yield
        self._publish("maze", "holding", f"maze {playback.source.name}: played {len(playback)} samples")

    def _publish(self, mode: str, status: str, message: str, *, step_ms: float | None = None, maze=None) -> None:
        r = self.current
        st = r.ctrl.state
        goal = self._goal if self._goal is not None else pose_of(st)
        pose = pose_of(st)
        e = pose_error(st.p, st.R, goal[:3], rotation_matrix(np.radians(goal[3:])))
        prev = self._snap
        snap = Snapshot(
            version=(prev.version + 1) if prev else 0, material=self._material, description=r.info.description,
            mode=mode, status=status, message=message, state=st, goal=np.array(goal, float),
            goal_version=self._goal_version, pose=pose, angles_deg=np.degrees(st.angles),
            angle_min_deg=np.degrees(r.full.angle_min), angle_max_deg=np.degrees(r.full.angle_max),
            pos_error=float(np.linalg.norm(e[:3])), rot_error=float(np.degrees(np.linalg.norm(e[3:]))),
            singular_values=singular_values(r.ctrl.tangent.J),
            step_ms=(prev.step_ms if prev and step_ms is None else (step_ms or 0.0)), maze=maze,
            x=r.positions(st), model=r.active, note=r.note or r.info.note)
        with self._cond:
            self._snap = snap
            self._cond.notify_all()
