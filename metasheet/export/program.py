"""A motor program: a path of effector poses (:mod:`.path`), sampled at a rate and solved by
the inverse model (paper eq. 8) into the six motor angles the real servos follow.

:func:`solve_program` solves the samples by continuation, as the robot moves: the first from
rest, each next one from the state the previous one reached (its kept tangent too), so a
sample costs a few control steps. A sample not reached (stalled, out of control steps) is
flagged with the primary cause (:func:`metasheet.goto.stall_text`) and the program goes on from
its closest state; one whose equilibrium fails ("failed") holds the previous sample's motors.
A sample whose goal equals the previous one's holds its motors too (the maze's held tilts):
solving it again would only let the motors wander about an unreachable goal. On a reduced
model a goal that leaves the training box is driven by the full model, as on the page
(:class:`metasheet.serve.models.RobotModels`); each sample records which model solved it.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import ConfigError, ConvergenceError, check_range
from .path import csv_rows, rotations

# -- the solve ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class MotorProgram:
    """A solved motor program of T samples.

    times : (T,) [s]. goals : (T, 6) the sampled path [mm, deg]. angles_deg : (T, 6) motor
    angles [deg] (0 = horizontal horn reaching inwards, 90 = vertical). poses : (T, 6) the
    poses reached [mm, deg]. error_mm, error_deg : (T,) their distance to the goals.
    status : per sample "reached", "stalled", "max_steps" or "failed" (equilibrium not found:
    the previous motors held). reason : why a sample was not reached ("" when it was).
    model : per sample "full" / "reduced", the model that solved it. rest : (6,) the rest
    pose [mm, deg]. states : the solved states (the inverse model's own), for a ParaView series.
    """

    times: np.ndarray
    goals: np.ndarray
    angles_deg: np.ndarray
    poses: np.ndarray
    error_mm: np.ndarray
    error_deg: np.ndarray
    status: tuple
    reason: tuple
    model: tuple
    rest: np.ndarray
    states: tuple = field(default=(), repr=False, compare=False)

    @property
    def reached(self) -> np.ndarray:
        """(T,) bool."""
        return np.array([s == "reached" for s in self.status], bool)

    def summary(self) -> dict:
        r = self.reached
        worst = int(np.argmax(self.error_mm))
        return {"samples": int(len(self.times)), "reached": int(r.sum()), "not_reached": int((~r).sum()),
                "duration_s": float(self.times[-1] - self.times[0]), "max_error_mm": float(self.error_mm.max()),
                "max_error_deg": float(self.error_deg.max()), "worst_sample": worst,
                "models": sorted(set(self.model)),
                "first_not_reached": int(np.flatnonzero(~r)[0]) if (~r).any() else None}


def rest_pose(state) -> np.ndarray:
    """(6,) [mm, deg] the effector pose of a state (full or reduced)."""
    from ..mechanics.rotations import rotation_vector

    return np.concatenate([state.p, np.degrees(rotation_vector(state.R))])


def _errors(goal, pose) -> tuple[float, float]:
    rel = rotations(np.asarray(pose)[None]).inv() * rotations(np.asarray(goal)[None])
    return float(np.linalg.norm(goal[:3] - pose[:3])), float(np.degrees(np.linalg.norm(rel.as_rotvec())))


def _solve_one(models, goal, settings):
    """One goal from the current state: the reduced model while inside its box, else the full."""
    if models.may_return():
        models.enter("reduced")
    if models.active == "reduced":
        box = models.reduced
        res = models.ctrl.goto(goal, settings=settings, stop=lambda st: not box.in_box(st.angles))
        if res.status != "stopped":
            return res
        models.enter("full")  # the goal leaves the training box: the full model drives on
    return models.ctrl.goto(goal, settings=settings)


def _sample(models, goal, settings, prev: tuple) -> tuple:
    """(angles (6,) [deg], pose (6,) [mm, deg], (error [mm], [deg]), status, reason, model, state)
    of ``goal`` solved from the current state; ``prev``: the previous sample's, held on a failure."""
    from ..goto import stall_text

    try:
        res = _solve_one(models, goal, settings)
    except ConvergenceError as exc:  # no equilibrium: the motors hold the previous sample's angles
        models.restore(prev[6])
        return prev[0], prev[1], _errors(goal, prev[1]), "failed", f"equilibrium solver: {exc}", prev[5], prev[6]
    why = "" if res.reached else stall_text(models.robot, res).splitlines()[0].removeprefix("limited by: ")
    return res.angles_deg, res.pose, (res.pos_error, res.rot_error), res.status, why, models.active, res.state


def solve_program(robot, times, goals, settings, *, models=None, progress=None) -> MotorProgram:
    """Solve ``goals`` (T, 6) [mm, deg] at ``times`` (T,) [s] on ``robot`` (full or reduced) by
    continuation from rest (see the module docstring); ``settings``: the
    :class:`metasheet.robot.inverse_settings.InverseSettings` of every solve; ``models``: a
    :class:`metasheet.serve.models.RobotModels` already at rest (built here when None);
    ``progress(done, total)`` after each sample."""
    from ..serve.models import RobotModels

    models = models if models is not None else RobotModels(robot, None, settings)
    goals = np.asarray(goals, float)
    if goals.ndim != 2 or goals.shape[1] != 6 or len(goals) == 0 or np.shape(times) != (len(goals),):
        raise ConfigError(f"goals: shape is {goals.shape} and should be (T, 6) with T >= 1, times (T,)")
    rest = rest_pose(models.rest)
    rows = [(np.degrees(models.rest.angles), rest, (0.0, 0.0), "reached", "", models.active, models.rest)]
    for i, goal in enumerate(goals):
        held = i and np.array_equal(goal, goals[i - 1])  # a held goal holds the motors
        rows.append(rows[-1] if held else _sample(models, goal, settings, rows[-1]))
        if progress is not None:
            progress(i + 1, len(goals))
    q, X, err, status, reason, used, states = zip(*rows[1:])
    err = np.array(err, float)
    return MotorProgram(np.asarray(times, float), goals, np.array(q, float), np.array(X, float), err[:, 0],
                        err[:, 1], status, reason, used, rest, states)


# -- the files -----------------------------------------------------------------------------------
#: What a motor angle means, for program.json (see :mod:`metasheet.robot.robots`).
ZERO_CONVENTION = ("0 deg: the horn horizontal, reaching inwards (towards its sheet's centre); 90 deg: the horn "
                   "vertical, along the sheet's normal (away from the servo base); the angle turns about the servo "
                   "axis a = n x u (n the sheet normal, u the arm's outward direction)")
STATUS_TEXT = "reached | stalled | max_steps (the inverse loop's end) | failed (no equilibrium: previous motors held)"
_POSE = ("x_mm", "y_mm", "z_mm", "rx_deg", "ry_deg", "rz_deg")
HEADER = (["time_s"] + [f"motor{k}_deg" for k in range(6)] + [f"pulse{k}_us" for k in range(6)]
          + [f"goal_{c}" for c in _POSE] + [f"reached_{c}" for c in _POSE]
          + ["error_mm", "error_deg", "status", "model", "reason"])


def units() -> dict:
    """The unit (or the values) of every program.csv column."""
    out = {"time_s": "s", "error_mm": "mm", "error_deg": "deg", "status": STATUS_TEXT,
           "model": "full | reduced: the model that solved the sample",
           "reason": "the primary cause when not reached (robot goto's 'limited by'), else empty"}
    for k in range(6):
        out[f"motor{k}_deg"] = "deg (0 = horizontal horn, 90 = vertical: servo_zero)"
        out[f"pulse{k}_us"] = "us, the hobby-servo pulse width (pulse)"
    for c in ("goal", "reached"):
        for a in "xyz":
            out[f"{c}_{a}_mm"] = "mm (world frame, the rod centre)"
            out[f"{c}_r{a}_deg"] = "deg (rotation vector, world frame)"
    return out


def program_csv(program: MotorProgram, pulses) -> bytes:
    """program.csv: one row a sample, :data:`HEADER`'s columns, fixed decimals (same program, same bytes)."""
    import io

    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(HEADER)
    for i, t in enumerate(program.times):
        w.writerow([f"{t:.6f}", *(f"{v:.4f}" for v in program.angles_deg[i]), *(f"{v:.2f}" for v in pulses[i]),
                    *(f"{v:.4f}" for v in program.goals[i]), *(f"{v:.4f}" for v in program.poses[i]),
                    f"{program.error_mm[i]:.5f}", f"{program.error_deg[i]:.5f}", program.status[i],
                    program.model[i], program.reason[i]])
    return buf.getvalue().encode()


def read_program_csv(file) -> tuple[np.ndarray, np.ndarray]:
    """(times (T,) [s], angles (T, 6) [deg]) of a program.csv (its time_s and motor columns)."""
    rows = csv_rows(file)
    need = HEADER[:7]
    if not rows or any(c not in rows[0] for c in need):
        missing = [c for c in need if not rows or c not in rows[0]]
        raise ConfigError(f"{file}: missing column(s) {', '.join(missing)}: expected a program.csv "
                          "(metasheet robot path)")
    if len(rows) < 2:
        raise ConfigError(f"{file}: empty program: no sample under the header")
    idx = [rows[0].index(c) for c in need]
    vals = np.array([[check_range(f"{file}: sample {i}, {c}", r[j].strip() if j < len(r) else "")
                      for c, j in zip(need, idx)] for i, r in enumerate(rows[1:])], float)
    return vals[:, 0], vals[:, 1:]


def program_json(program: MotorProgram, record: dict) -> bytes:
    """program.json: ``record`` (what made the program: inputs, rate, model, tolerances, pulse
    map, check) with the columns' units, the zero convention and the summary; keys sorted."""
    import json

    from ..version import __version__

    out = {**record, "columns": units(), "servo_zero": ZERO_CONVENTION, "summary": program.summary(),
           "rest_pose": {"position_mm": program.rest[:3].tolist(), "rotation_vector_deg": program.rest[3:].tolist()},
           "metasheet_version": __version__}
    return (json.dumps(out, indent=2, sort_keys=True, default=_plain) + "\n").encode()


def _plain(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    raise TypeError(f"{type(o).__name__} is not JSON serialisable")


def program_picture(program: MotorProgram, stroke, *, title: str = "", tolerances=None) -> bytes:
    """PNG: the six motor angles over time with the stroke's ends, samples not reached marked;
    below, the pose error of each sample (and the tolerances [mm], [deg] when given)."""
    from ..viz import figure_png, one_at_a_time

    @one_at_a_time
    def draw() -> bytes:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        t, q, miss = program.times, program.angles_deg, ~program.reached
        fig, (ax, ax2) = plt.subplots(2, 1, figsize=(10, 7), sharex=True, height_ratios=(2, 1))
        for k in range(q.shape[1]):
            ax.plot(t, q[:, k], lw=1.4, label=f"motor {k} (sheet {'AB'[k // 3]})")
        for lim in sorted(set(np.round(np.concatenate(stroke), 6))):
            ax.axhline(lim, color="k", ls="--", lw=0.8)
        ax.plot([], [], "k--", lw=0.8, label="stroke")
        if miss.any():
            ax.plot(np.repeat(t[miss], q.shape[1]), q[miss].ravel(), "x", color="#d62728", ms=6,
                    label=f"not reached ({int(miss.sum())} samples)")
        ax.set_ylabel("motor angle [deg]  (0 horizontal, 90 vertical)")
        ax.set_title(title or "motor program")
        ax.legend(fontsize=8, ncol=4, loc="upper center", bbox_to_anchor=(0.5, -0.02))
        ax.grid(alpha=0.3)
        ax2.plot(t, program.error_mm, label="position error [mm]")
        ax2.plot(t, program.error_deg, label="rotation error [deg]")
        for tol, c in zip(tolerances or (), ("C0", "C1")):
            ax2.axhline(tol, color=c, ls=":", lw=0.8)
        ax2.set_xlabel("time [s]")
        ax2.set_ylabel("pose error")
        ax2.legend(fontsize=8)
        ax2.grid(alpha=0.3)
        return figure_png(fig)

    return draw()


def write_files(folder, files: dict) -> list[Path]:
    """Write ``files`` (name -> bytes) into ``folder``: all to temporary names first, flushed,
    then each renamed into place, so a failed write (a full disk) leaves the folder as it was;
    a folder made here and left empty is removed. Returns the paths written."""
    import os

    folder = Path(folder)
    made = not folder.exists()
    folder.mkdir(parents=True, exist_ok=True)
    tmps = [folder / f".{name}.tmp-{os.getpid()}" for name in files]
    try:
        for tmp, data in zip(tmps, files.values()):
            with open(tmp, "wb") as fh:
                fh.write(data)
                fh.flush()
                os.fsync(fh.fileno())
        for tmp, name in zip(tmps, files):
            os.replace(tmp, folder / name)
    except BaseException:
        for tmp in tmps:
            tmp.unlink(missing_ok=True)
        if made and not any(folder.iterdir()):
            folder.rmdir()
        raise
    return [folder / name for name in files]
