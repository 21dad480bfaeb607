"""Run a pipeline's stages in dependency order, skipping those whose inputs did not change.

What a run guarantees (tested in ``tests/test_reliability_*.py``):

- **Nothing half-written.** Each stage writes into a fresh temporary directory
  ``.<stage>.tmp-<pid>`` next to its final one; only a stage that succeeded is renamed into
  place (the old outputs are kept until then), so a failing or killed stage never leaves
  files that a later run would trust. A run first removes the temporary directories of
  processes that are gone (a SIGKILL leaves them); ``metasheet clean`` does too
  (:mod:`.debris`). Nothing outside the pipeline's own folder is written or removed
  (:func:`~.debris.output_folder`).
- **Interrupted means stopped.** An interrupt (Ctrl-C, SIGTERM, SIGHUP through the CLI)
  kills the pool's workers, stops the stages under way at their next progress report,
  removes this run's temporary folders and re-raises; the workers of a SIGKILLed run exit
  by themselves (:mod:`metasheet.runtime.executor`).
- **One run per output folder at a time**, first come first served (:mod:`.lock`). Only the
  process that called :func:`run_pipeline` takes the lock: the work units a stage hands to
  its executor (process pool or dask workers) never do.
- **Named faults.** An output folder that cannot be written (permissions, read-only, disk
  full) is an :class:`~metasheet.errors.OutputError` naming the path and the cause.
- **Same bytes.** The run computes with one BLAS / OpenMP thread in this process and in each
  worker (:data:`~metasheet.runtime.executor.UNIT_THREADS`), whatever ``OPENBLAS_NUM_THREADS`` says:
  no result depends on how a library splits a sum. Measured times go to the manifest only
  (``started``, ``wall_time_s``, ``cpu_s``, ``timings_s``); see :mod:`.manifest` for the
  cache key's canonical hashes.
"""

from __future__ import annotations

import errno
import os
import shutil
import threading
import time
from collections.abc import Callable
from concurrent.futures import BrokenExecutor
from dataclasses import dataclass, field, replace
from datetime import datetime, timezone
from pathlib import Path

from ..errors import ConfigError, Interrupted, MetasheetError, OutputError, StageError, output_error
from ..runtime.cpu import code_paths
from ..runtime.executor import CpuMeter, Executor, own_threads
from ..runtime.memory import keep_freed_memory
from ..supervise import tell as tell_supervisor
from . import manifest as mf
from .config import Pipeline, upstream
from .debris import output_folder, remove_debris, remove_own_debris, remove_path, remove_unit_caches
from .lock import Reporter, _quiet, output_lock, pid_alive  # noqa: F401 - pid_alive: the runner's API
from .ownership import check_replaceable, name_files, not_ours
from .registry import StageContext, stages
from .schedule import run_graph
from .staleness import closure, stage_key
from .warmup import Warmer, downstream_closure

#: errno values of a write that failed because of the output folder, not of the stage's logic.
WRITE_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EACCES, errno.EPERM, errno.EROFS, errno.EFBIG}

@dataclass(frozen=True)
class StageOutcome:
    """What happened to one stage in a run."""

    name: str
    status: str  # "ran" or "cached"
    directory: Path
    wall_time: float
    summary: dict = field(default_factory=dict)
    cpu_time: float | None = None  # [s]: the stage's thread and its units in local workers; None: cached


def plan(pipeline: Pipeline, only: str | None) -> tuple[str, ...]:
    """Stages to visit: all, or ``only`` and everything upstream of it."""
    if only is None:
        return pipeline.order
    if only not in pipeline.params:
        raise ConfigError(
            f"--stage: {only!r}: not a stage of {pipeline.path}; its stages: {', '.join(pipeline.order)}"
        )
    return closure(pipeline, [only])


def clean(pipeline: Pipeline, *, out_root: Path | None = None, everything: bool = False, wait: bool = True,
          report: Reporter = _quiet) -> list[Path]:
    """Remove what killed runs left in ``pipeline``'s output folder (their temporary folders,
    and resume caches that hold no unit); ``everything``: also every stage folder metasheet can
    prove it wrote (:mod:`.ownership`) and the resume caches, then the folder itself when nothing
    else is left in it. Files metasheet did not write, and the folders holding them, are kept and
    named. Holds the folder's lock, so it never races a run; touches nothing outside
    :func:`output_folder`."""
    out_root = Path(out_root) if out_root else pipeline.root / "outputs"
    base = output_folder(out_root, pipeline.name)
    if not base.exists():
        return []
    with output_lock(out_root, pipeline.name, wait=wait, report=report):
        removed = remove_debris(base, report)
        for cache in sorted(base.glob(".*.units")):
            units = sum(1 for _ in cache.glob("*.pkl"))
            if units and not everything:
                report("clean", f"kept {cache}: {units} finished unit(s) a rerun resumes from (--all removes it)")
                continue
            _remove(cache, removed)
            report("clean", f"removed {cache}" + ("" if units else " (an empty resume cache)"))
        if everything:
            _remove_stage_folders(base, removed, report)
    return removed


def _remove_stage_folders(base: Path, removed: list[Path], report: Reporter) -> None:
    """Remove the stage folders under ``base`` that metasheet wrote, then ``base`` when empty."""
    kept = []
    for entry in sorted(base.iterdir()):
        why = not_ours(entry, entry.name) if entry.is_dir() and not entry.is_symlink() else "not a stage folder"
        if why:
            kept.append(entry.name)
            report("clean", f"kept {entry}: {why}")
            continue
        _remove(entry, removed)
        report("clean", f"removed {entry}")
    if kept:
        report("clean", f"kept {base}: it holds {name_files(kept)}, which metasheet did not write")
        return
    _remove(base, removed)
    report("clean", f"removed {base}")


def _remove(path: Path, removed: list[Path]) -> None:
    try:
        remove_path(path)
    except OSError as exc:
        raise output_error(exc, str(path)) from exc
    removed.append(path)


# ----------------------------------------------------------------------------------- run


def _os_failure(exc: OSError, name: str, roots: tuple[Path, ...]) -> MetasheetError:
    """A write failure in the outputs -> OutputError; any other OSError -> StageError."""
    target = Path(exc.filename).resolve() if isinstance(exc.filename, (str, os.PathLike)) else None
    in_outputs = target is None or any(target.is_relative_to(r.resolve()) for r in roots)
    if exc.errno in WRITE_ERRNOS and (in_outputs or exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)):
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
    overwrite: bool = False,
) -> list[StageOutcome]:
    """Run ``pipeline``; return one :class:`StageOutcome` per visited stage.

    Stages whose upstream stages are done run at once, up to ``[pipeline] stages_at_once``
    (:mod:`.schedule`).

    ``only`` runs one stage (and what it needs, from cache when fresh); ``force``
    reruns the selected stage (or every stage when ``only`` is None). The output folder's
    lock is held for the whole run; ``wait=False`` raises :class:`~metasheet.errors.LockedError`
    instead of waiting for another run (see the module docstring). A stage folder that holds
    files metasheet did not write is not replaced unless ``overwrite`` (:mod:`.ownership`).
    """
    registry = stages()
    out_root = Path(out_root) if out_root else pipeline.root / "outputs"
    base = output_folder(out_root, pipeline.name)
    names = plan(pipeline, only)
    keep_freed_memory()  # before the workers start: they take it from the environment
    executor = executor or Executor(pipeline.section.workers, pipeline.section.scheduler)
    cancel = threading.Event()
    with output_lock(out_root, pipeline.name, wait=wait, report=report):
        try:
            base.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise output_error(exc, str(base)) from exc
        remove_debris(base, report)
        tell_supervisor(out_root, pipeline.name)
        try:
            # one pool of workers for the whole run; this process computes with a unit's threads
            with own_threads(executor.threads), executor.session() as ex:
                warmer = Warmer(ex.pool, downstream_closure(names, lambda n: upstream(pipeline, n)))
                done = run_graph(names, {n: upstream(pipeline, n) for n in names},
                                 lambda name: _run_stage(pipeline, registry[name], base,
                                                         force and (only is None or only == name),
                                                         replace(ex, priority=names.index(name)), report,
                                                         progress_factory, cancel, overwrite, warmer),
                                 at_once=pipeline.section.stages_at_once,
                                 on_interrupt=lambda: _stop(cancel, ex))
        except BaseException as exc:
            if not isinstance(exc, Exception):  # interrupted: nothing of this run stays behind
                cancel.set()
                remove_own_debris(base)
            raise
        return [done[n] for n in names]


def _stop(cancel: threading.Event, executor: Executor) -> None:
    """Stop a run's stages under way: each raises :class:`~metasheet.errors.Interrupted` at its
    next progress report, and the pool's workers are killed (a stage waiting on its units gets
    their failure at once)."""
    cancel.set()
    if executor.pool is not None:
        executor.pool.shutdown(kill=True)


def _run_stage(pipeline: Pipeline, stage, base: Path, forced: bool, executor: Executor, report: Reporter,
               progress_factory, cancel: threading.Event | None = None, overwrite: bool = False,
               warmer: Warmer | None = None) -> StageOutcome:
    name = stage.name
    inputs = {u: base / u for u in upstream(pipeline, name)}
    # one key computation for the runner and for readers of old outputs (serve, goto)
    sk = stage_key(pipeline, name, base)
    params, files, input_hashes, key = sk.params, sk.files, sk.input_hashes, sk.key
    final = base / name
    if not forced and mf.is_fresh(final, key):
        report(name, "up to date, skipped")
        return StageOutcome(name, "cached", final, 0.0, mf.read_manifest(final).get("summary", {}))
    check_replaceable(final, name, overwrite)  # before the work: a refusal costs nothing
    if warmer is not None:  # the workers compile what the stages after this one call
        warmer.starting(name)
    report(name, "running")
    if forced:
        remove_unit_caches(base, name)
    progress = _cancellable(progress_factory(name) if progress_factory else (lambda d, i, n: None), cancel)
    t0, cpu0, meter = time.perf_counter(), time.thread_time(), CpuMeter()
    executor = replace(executor, meter=meter)
    started = datetime.now(timezone.utc).isoformat(timespec="seconds")
    work = base / f".{name}.tmp-{os.getpid()}"
    try:
        shutil.rmtree(work, ignore_errors=True)
        work.mkdir(parents=True)
    except OSError as exc:
        raise output_error(exc, str(base)) from exc
    ctx = StageContext(name, pipeline.params[name], work, inputs, pipeline.root, executor, progress,
                       siblings={rel: base.parent / rel for rel in sk.siblings})
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
                "code_paths": code_paths(),
                "started": started,
                "wall_time_s": round(wall, 3),
                "cpu_s": cpu,
                "timings_s": dict(ctx.timings),
            },
        )
        check_replaceable(final, name, overwrite)  # a file the user put there meanwhile
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
    except BrokenExecutor as err:  # a worker died under a unit: its cause is not in this process
        shutil.rmtree(work, ignore_errors=True)
        raise StageError(f"stage {name!r} failed: a worker process died while computing a unit (killed by the "
                         "system, e.g. out of memory, or crashed in a native library); rerun it, with fewer "
                         "workers or a higher memory limit if it happens again") from err
    except MemoryError as err:  # its message is empty: say what to change
        shutil.rmtree(work, ignore_errors=True)
        raise StageError(f"stage {name!r} ran out of memory (MemoryError): lower its sizes (mesh, voxels, "
                         "realisations) or the workers, or raise the memory limit (ulimit -v)") from err
    except Exception as err:
        shutil.rmtree(work, ignore_errors=True)
        raise StageError(f"stage {name!r} failed: {type(err).__name__}: {err}") from err
    except BaseException:  # KeyboardInterrupt, SystemExit: leave old outputs, drop the partial ones
        shutil.rmtree(work, ignore_errors=True)
        raise
    report(name, f"done in {wall:.1f} s")
    return StageOutcome(name, "ran", final, wall, summary, cpu["total"])


def _cancellable(progress: Callable[[str, int, int], None], cancel: threading.Event | None):
    """``progress``, raising :class:`~metasheet.errors.Interrupted` once ``cancel`` is set."""
    if cancel is None:
        return progress

    def report(desc: str, done: int, total: int) -> None:
        if cancel.is_set():
            raise Interrupted("the run was interrupted")
        progress(desc, done, total)

    return report


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
