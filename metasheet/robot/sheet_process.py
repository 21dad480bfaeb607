"""One printed sheet's finite-strain solves in a process of its own: the printed robot's two sheets
at once, one per core.

At a given rod pose the robot's two sheets are independent solves (:mod:`.voxel_robot`). Their
kernels gain only 1.2 to 1.5 times on a second thread (memory-bound products, serial sparse
factors: ``docs/performance.md``), so two sheets side by side, one thread each, take about the
time of the slower one on one thread, where one after the other on two threads they take the sum
over 1.35. A :class:`SheetProcess` builds its sheet's :class:`~.voxel_grips_nonlinear.GripBody`
in a child process (the parent holds no copy) and answers solve requests over a pipe.

The child computes with one thread (numba and BLAS): every kernel sums in a fixed order, so its
answers are the in-process ones bit for bit. It dies with its parent (``PR_SET_PDEATHSIG``: a
parent killed even by SIGKILL takes it along) and is stopped when the parent closes it or exits.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import weakref

import numpy as np

from ..errors import ConfigError


def _die_with_parent(parent: int) -> None:
    """SIGKILL this process when its parent dies (Linux; elsewhere the pipe's end stops it)."""
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL))  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass
    if os.getppid() != parent:  # the parent died before the call
        os._exit(1)


def _serve(conn, sheet, contact, parent: int) -> None:
    """The child: build the sheet's body, then solve each request until told to stop."""
    _die_with_parent(parent)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent's Ctrl-C is the parent's to handle
    try:
        import numba
        from threadpoolctl import threadpool_limits

        from ..sheet.voxel_grips_nonlinear import GripBody

        numba.set_num_threads(1)
        threadpool_limits(limits=1)
        body = GripBody(sheet.phases, sheet.size, sheet.law, bodies=sheet.bodies,
                        references=sheet.references - sheet.origin, contact=contact)
        conn.send(("ready", body.hyper.roundoff, float(body.hyper.h.min())))
    except BaseException as exc:  # noqa: BLE001 - sent back whole, raised in the parent
        conn.send(("error", exc))
        return
    while True:
        try:
            msg = conn.recv()
        except EOFError:
            return
        if msg[0] == "stop":
            return
        _, rot, trans, initial, rtol, probe = msg
        try:
            conn.send(("done", body.wrenches(rot, trans, initial, rtol, probe=probe)))
        except BaseException as exc:  # noqa: BLE001
            conn.send(("error", exc))


class SheetProcess:
    """A :class:`~metasheet.robot.voxel_robot.VoxelSheet` held by a child process: :meth:`submit`
    a grip pose, then :meth:`result` its :class:`~metasheet.sheet.voxel_grips_nonlinear.GripWrenches`
    (what :meth:`GripBody.wrenches` returns in this process, bit for bit)."""

    def __init__(self, sheet, contact=None):
        ctx = multiprocessing.get_context("spawn")  # a fork would copy numba's and BLAS's threads
        self._conn, child = ctx.Pipe()
        self._proc = ctx.Process(target=_serve, args=(child, sheet, contact, os.getpid()), daemon=True,
                                 name="metasheet-sheet")
        self._proc.start()
        child.close()
        self._stop = weakref.finalize(self, _stop, self._conn, self._proc)
        self._pending = False
        self._roundoff = None  # the child's first answer (its body built): asked for when first needed,
        # so that two sheets' processes build their bodies at once

    def _ready(self) -> None:
        if self._roundoff is None:
            msg = self._receive()
            self._roundoff, self._hmin = msg[1], msg[2]

    def submit(self, rotations, translations, initial=None, rtol: float = 1e-8, probe: bool = True,
               progress=None) -> None:
        """Start the solve at the grips' poses (:meth:`GripBody.wrenches`' arguments; ``progress`` is
        not forwarded)."""
        if self._pending:
            raise ConfigError("submit: the last solve's result was not collected (call result() first)")
        self._ready()
        self._conn.send(("solve", np.asarray(rotations, float), np.asarray(translations, float), initial, rtol,
                         bool(probe)))
        self._pending = True

    def result(self):
        """The submitted solve's GripWrenches; its error raised here."""
        if not self._pending:
            raise ConfigError("result: no solve was submitted")
        self._pending = False
        return self._receive()[1]

    def wrenches(self, rotations, translations, initial=None, rtol: float = 1e-8, progress=None, probe: bool = True):
        """:meth:`GripBody.wrenches` in the child (``progress`` is not forwarded)."""
        self.submit(rotations, translations, initial, rtol, probe)
        return self.result()

    def floor(self, u: np.ndarray) -> float:
        """The forces' round-off [N] at displacements ``u`` (as :meth:`HyperelasticBody.floor`)."""
        from ..fem.voxel.nonlinear import forces_floor

        self._ready()
        return forces_floor(self._roundoff, self._hmin, u)

    def close(self) -> None:
        """Stop the child (also at exit and when this object is collected)."""
        self._stop()

    def _receive(self):
        try:
            msg = self._conn.recv()
        except EOFError:
            self.close()
            raise ConfigError(f"sheet process: the child ended (exit code {self._proc.exitcode}) without an "
                              "answer: out of memory?") from None
        if msg[0] == "error":
            raise msg[1]
        return msg


def _stop(conn, proc) -> None:
    try:
        conn.send(("stop",))
    except (OSError, ValueError):
        pass
    proc.join(timeout=5)
    if proc.is_alive():
        proc.kill()
        proc.join()
    conn.close()
