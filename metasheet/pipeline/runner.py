"""Run a pipeline's stages in dependency order, skipping those whose inputs did not change.

What a run guarantees (tested in ``tests/test_reliability_*.py``):

- **Nothing half-written.** Each stage writes into a fresh temporary directory
  ``.<stage>.tmp-<pid>`` next to its final one; only a stage that succeeded is renamed into
  place (the old outputs are kept until then), so a failing or killed stage never leaves
  files that a later run would trust. A run first removes the temporary directories of
  processes that are gone (a SIGKILL leaves them); ``metasheet clean`` does too.
- **One run per output folder at a time.** A run holds a lock (:func:`output_lock`, the
  ``filelock`` library: an OS lock the kernel drops when its process dies) on
  ``<out>/.<pipeline>.lock`` for its whole duration, and writes who holds it (pid, host,
  start, command) to ``<out>/.<pipeline>.lock.json``. A second run waits, saying who it
  waits for, or with ``wait=False`` raises :class:`~metasheet.errors.LockedError`. A lock
  left by a dead process is free and taken over, with a note. Only the process that called
  :func:`run_pipeline` takes it: the work units a stage hands to its executor (process
  pool or dask workers) never do.
- **Named faults.** An output folder that cannot be written (permissions, read-only, disk
  full) is an :class:`~metasheet.errors.OutputError` naming the path and the cause.
- **Same bytes.** Wall-clock times go to the manifest only (``started``, ``wall_time_s``,
  ``cpu_s``, ``timings_s``); see :mod:`.manifest` for the cache key's canonical hashes.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import re
import shutil
import socket
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from datetime import datetime, timezone
from pathlib import Path

from ..errors import ConfigError, LockedError, MetasheetError, OutputError, StageError, output_error
from ..executor import CpuMeter, Executor
from . import manifest as mf
from .config import Pipeline, upstream
from .registry import StageContext, stages
from .schedule import run_graph

#: errno values of a write that failed because of the output folder, not of the stage's logic.
WRITE_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EACCES, errno.EPERM, errno.EROFS}

#: A run's temporary directories: ``.<stage>.tmp-<pid>`` (being written) and
#: ``.<stage>.old-<pid>`` (the previous outputs during the swap).
DEBRIS = re.compile(r"^\.(?P<stage>.+)\.(?P<kind>tmp|old)-(?P<pid>\d+)$")


@dataclass(frozen=True)
class StageOutcome:
    """What happened to one stage in a run."""

    name: str
    status: str  # "ran" or "cached"
    directory: Path
    wall_time: float
    summary: dict = field(default_factory=dict)
    cpu_time: float | None = None  # [s]: the stage's thread and its units in local workers; None: cached


Reporter = Callable[[str, str], None]  # (stage, message)


def _quiet(stage: str, message: str) -> None:
    pass


def plan(pipeline: Pipeline, only: str | None) -> tuple[str, ...]:
    """Stages to visit: all, or ``only`` and everything upstream of it."""
    if only is None:
        return pipeline.order
    if only not in pipeline.params:
        raise ConfigError(
            f"--stage: {only!r}: not a stage of {pipeline.path}; its stages: {', '.join(pipeline.order)}"
        )
    needed: set[str] = set()

    def visit(n: str) -> None:
        if n not in needed:
            needed.add(n)
            for u in upstream(pipeline, n):
                visit(u)

    visit(only)
    return tuple(n for n in pipeline.order if n in needed)


# ------------------------------------------------------------------------------ processes


def pid_alive(pid: int) -> bool:
    """True when process ``pid`` exists on this host and is not a zombie."""
    if pid <= 0:
        return False
    if os.name == "nt":  # pragma: no cover  (os.kill would terminate it)
        import ctypes

        handle = ctypes.windll.kernel32.OpenProcess(0x1000, False, pid)  # QUERY_LIMITED_INFORMATION
        if not handle:
            return False
        code = ctypes.c_ulong()
        ctypes.windll.kernel32.GetExitCodeProcess(handle, ctypes.byref(code))
        ctypes.windll.kernel32.CloseHandle(handle)
        return code.value == 259  # STILL_ACTIVE
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    except OSError:
        return False
    try:  # a killed child its parent has not reaped yet is gone for our purposes
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] not in ("Z", "X")
    except (OSError, IndexError):
        return True


# ---------------------------------------------------------------------------------- lock


def lock_paths(out_root: Path, name: str) -> tuple[Path, Path]:
    """The lock file of output folder ``out_root/name`` and the side file naming its holder."""
    return out_root / f".{name}.lock", out_root / f".{name}.lock.json"


def read_holder(info_file: Path) -> dict | None:
    """The holder recorded in a lock's side file (pid, host, started, command), or None."""
    try:
        data = json.loads(info_file.read_text())
        return data if isinstance(data, dict) and isinstance(data.get("pid"), int) else None
    except (OSError, ValueError):
        return None


def describe_holder(holder: dict | None) -> str:
    """``run pid 123 on host since 2026-01-01T10:00:00+00:00 (metasheet run ...)``."""
    if not holder:
        return "another run (no holder recorded)"
    text = f"run pid {holder['pid']}"
    if holder.get("host") and holder["host"] != socket.gethostname():
        text += f" on {holder['host']}"
    if holder.get("started"):
        text += f" since {holder['started']}"
    if holder.get("command"):
        text += f" ({holder['command']})"
    return text


@contextlib.contextmanager
def output_lock(out_root: Path, name: str, *, wait: bool = True, report: Reporter | None = None,
                poll: float = 0.2) -> Iterator[Path]:
    """Hold the lock of output folder ``out_root/name`` for the ``with`` block.

    ``wait``: when another run holds it, report who (pid, since when) and wait; else raise
    :class:`~metasheet.errors.LockedError` at once. A lock whose holder died is free (the
    kernel drops it) and is taken over with a note naming the dead pid. Yields the lock file.
    """
    from filelock import FileLock, Timeout

    report = report or _quiet
    out_root = Path(out_root)
    base = out_root / name
    lock_file, info_file = lock_paths(out_root, name)
    try:
        out_root.mkdir(parents=True, exist_ok=True)
        lock = FileLock(str(lock_file))
        try:
            lock.acquire(timeout=0)
        except Timeout:
            holder = read_holder(info_file)
            if not wait:
                raise LockedError(
                    f"{base}: in use by {describe_holder(holder)}; wait for it to finish "
                    "(run without --no-wait to wait) or stop it"
                ) from None
            report("lock", f"{base}: in use by {describe_holder(holder)}; waiting for it to finish")
            lock.acquire(timeout=-1, poll_interval=poll)
            report("lock", f"{base}: free, going on")
        else:
            holder = read_holder(info_file)
            if holder and holder["pid"] != os.getpid() and not pid_alive(holder["pid"]):
                report("lock", f"{base}: taking over the lock left by {describe_holder(holder)}: "
                       "that process is gone")
    except OSError as exc:
        raise output_error(exc, str(base)) from exc
    try:
        try:
            mf.write_json_atomic(info_file, {
                "pid": os.getpid(), "host": socket.gethostname(),
                "started": datetime.now(timezone.utc).isoformat(timespec="seconds"),
                "command": " ".join([Path(sys.argv[0]).name, *sys.argv[1:]]) if sys.argv and sys.argv[0] else "",
            })
        except OSError as exc:
            raise output_error(exc, str(base)) from exc
        yield lock_file
    finally:
        with contextlib.suppress(OSError):
            if (read_holder(info_file) or {}).get("pid") == os.getpid():
                info_file.unlink()
        lock.release()


# -------------------------------------------------------------------------------- debris


def find_debris(base: Path) -> list[tuple[Path, int]]:
    """Temporary directories (and files) of runs under ``base``: (path, pid), sorted."""
    if not base.is_dir():
        return []
    found = []
    for p in sorted(base.iterdir()):
        m = DEBRIS.match(p.name)
        if m:
            found.append((p, int(m["pid"])))
    return found


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    else:
        path.unlink(missing_ok=True)


def remove_debris(base: Path, report: Reporter | None = None) -> list[Path]:
    """Remove the temporary directories under ``base`` whose process is gone (a killed run's);
    those of live processes stay. Returns what was removed. Call it holding the lock."""
    report = report or _quiet
    removed = []
    for path, pid in find_debris(base):
        if pid == os.getpid() or pid_alive(pid):
            report("clean", f"kept {path}: process {pid} is alive")
            continue
        try:
            _remove(path)
        except OSError as exc:
            raise output_error(exc, str(path)) from exc
        removed.append(path)
        report("clean", f"removed {path} (left by process {pid}, which is gone)")
    return removed


def clean(pipeline: Pipeline, *, out_root: Path | None = None, everything: bool = False, wait: bool = True,
          report: Reporter = _quiet) -> list[Path]:
    """Remove what killed runs left in ``pipeline``'s output folder; ``everything``: the whole
    folder (every stage's outputs). Holds the folder's lock, so it never races a run."""
    out_root = Path(out_root) if out_root else pipeline.root / "outputs"
    base = out_root / pipeline.name
    if not base.exists():
        return []
    with output_lock(out_root, pipeline.name, wait=wait, report=report):
        removed = remove_debris(base, report)
        if everything and base.exists():
            try:
                shutil.rmtree(base)
            except OSError as exc:
                raise output_error(exc, str(base)) from exc
            removed.append(base)
            report("clean", f"removed {base}")
    return removed


# ----------------------------------------------------------------------------------- run


def _os_failure(exc: OSError, name: str, roots: tuple[Path, ...]) -> MetasheetError:
    """A write failure in the outputs -> OutputError; any other OSError -> StageError."""
    target = Path(exc.filename).resolve() if isinstance(exc.filename, (str, os.PathLike)) else None
    in_outputs = target is None or any(target.is_relative_to(r.resolve()) for r in roots)
    if exc.errno in WRITE_ERRNOS and (in_outputs or exc.errno in (errno.ENOSPC, errno.EDQUOT)):
        return output_error(exc, f"stage {name!r}")
    return StageError(f"stage {name!r} failed: {type(exc).__name__}: {exc}")


def run_pipeline(
    pipeline: Pipeline,
    *,
    out_root: Path | None = None,
    only: str | None = None,
    force: bool = False,
    executor: Executor | None = None,
    report: Reporter = _quiet,
    progress_factory: Callable[[str], Callable[[str, int, int], None]] | None = None,
    wait: bool = True,
) -> list[StageOutcome]:
    """Run ``pipeline``; return one :class:`StageOutcome` per visited stage.

    Stages whose upstream stages are done run at once, up to ``[pipeline] stages_at_once``
    (:mod:`.schedule`).

    ``only`` runs one stage (and what it needs, from cache when fresh); ``force``
    reruns the selected stage (or every stage when ``only`` is None). The output folder's
    lock is held for the whole run; ``wait=False`` raises :class:`~metasheet.errors.LockedError`
    instead of waiting for another run (see the module docstring).
    """
    registry = stages()
    out_root = Path(out_root) if out_root else pipeline.root / "outputs"
    base = out_root / pipeline.name
    names = plan(pipeline, only)
    executor = executor or Executor(pipeline.section.workers, pipeline.section.scheduler)
    with output_lock(out_root, pipeline.name, wait=wait, report=report):
        try:
            base.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise output_error(exc, str(base)) from exc
        remove_debris(base, report)
        with executor.session() as ex:  # one pool of workers for the whole run
            done = run_graph(names, {n: upstream(pipeline, n) for n in names},
                             lambda name: _run_stage(pipeline, registry[name], base,
                                                     force and (only is None or only == name),
                                                     replace(ex, priority=names.index(name)), report,
                                                     progress_factory),
                             at_once=pipeline.section.stages_at_once)
        return [done[n] for n in names]


def _run_stage(pipeline: Pipeline, stage, base: Path, forced: bool, executor: Executor, report: Reporter,
               progress_factory) -> StageOutcome:
    name = stage.name
    params = pipeline.params[name].model_dump(mode="json")
    ups = upstream(pipeline, name)
    inputs = {u: base / u for u in ups}
    input_hashes = {}
    for u in ups:
        m = mf.read_manifest(inputs[u])
        if m is None:
            raise StageError(f"stage {name!r}: upstream stage {u!r} has no outputs in {inputs[u]}")
        input_hashes[u] = {k: mf.content_hash(v) for k, v in m["outputs"].items()}
    files = mf.param_files(params, pipeline.root)
    key = mf.cache_key(name, params, files, input_hashes)
    final = base / name
    if not forced and mf.is_fresh(final, key):
        report(name, "up to date, skipped")
        return StageOutcome(name, "cached", final, 0.0, mf.read_manifest(final).get("summary", {}))
    report(name, "running")
    progress = progress_factory(name) if progress_factory else (lambda d, i, n: None)
    t0, cpu0, meter = time.perf_counter(), time.thread_time(), CpuMeter()
    executor = replace(executor, meter=meter)
    started = datetime.now(timezone.utc).isoformat(timespec="seconds")
    work = base / f".{name}.tmp-{os.getpid()}"
    try:
        shutil.rmtree(work, ignore_errors=True)
        work.mkdir(parents=True)
    except OSError as exc:
        raise output_error(exc, str(base)) from exc
    ctx = StageContext(name, pipeline.params[name], work, inputs, pipeline.root, executor, progress)
    try:
        summary = stage.run(ctx) or {}
        missing = [f for f in stage.outputs if not any(work.glob(f))]
        if missing:
            raise StageError(f"stage {name!r} did not write {', '.join(missing)}")
        wall = time.perf_counter() - t0
        cpu = _cpu_record(time.thread_time() - cpu0, meter, executor)
        mf.write_json_atomic(
            work / mf.MANIFEST,
            {
                "stage": name,
                "pipeline": pipeline.name,
                "pipeline_file": str(pipeline.path),
                "key": key,
                "params": params,
                "param_files": files,
                "inputs": input_hashes,
                "outputs": mf.output_hashes(work),
                "summary": summary,
                "executor": executor.kind,
                "versions": mf.versions(),
                "started": started,
                "wall_time_s": round(wall, 3),
                "cpu_s": cpu,
                "timings_s": dict(ctx.timings),
            },
        )
        _swap_into_place(work, final)
    except OutputError as err:
        shutil.rmtree(work, ignore_errors=True)
        raise OutputError(f"stage {name!r}: {err}") from err
    except MetasheetError as err:
        shutil.rmtree(work, ignore_errors=True)
        raise StageError(f"stage {name!r} failed: {err}") from err
    except OSError as err:
        shutil.rmtree(work, ignore_errors=True)
        raise _os_failure(err, name, (base,)) from err
    except Exception as err:
        shutil.rmtree(work, ignore_errors=True)
        raise StageError(f"stage {name!r} failed: {type(err).__name__}: {err}") from err
    except BaseException:  # KeyboardInterrupt, SystemExit: leave old outputs, drop the partial ones
        shutil.rmtree(work, ignore_errors=True)
        raise
    report(name, f"done in {wall:.1f} s")
    return StageOutcome(name, "ran", final, wall, summary, cpu["total"])


def _cpu_record(own: float, meter: CpuMeter, executor: Executor) -> dict:
    """A stage's CPU time [s]: its own thread in this process (concurrent stages each have one),
    its units in local worker processes (also by unit function: [seconds, units]), and their
    sum; on a dask cluster the workers' share is not measured (None) and the total is this
    thread's alone. Threads a stage starts itself (a serial executor's map in a side thread)
    are not counted."""
    workers = None if executor.kind == "dask" else round(meter.seconds, 3)
    return {"stage_thread": round(own, 3), "workers": workers, "worker_units": meter.units,
            "by_unit": {k: [round(v[0], 3), v[1]] for k, v in sorted(meter.by_function.items())},
            "total": round(own + (workers or 0.0), 3)}


def _swap_into_place(work: Path, final: Path) -> None:
    """Replace ``final`` by ``work`` with renames, so readers see old or new, never half.

    When the second rename fails, the old outputs are put back before the error propagates.
    """
    old = final.with_name(f".{final.name}.old-{os.getpid()}")
    had_old = final.exists()
    if had_old:
        os.replace(final, old)
    try:
        os.replace(work, final)
    except OSError:
        if had_old:
            os.replace(old, final)
        raise
    shutil.rmtree(old, ignore_errors=True)
