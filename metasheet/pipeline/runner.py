"""Run a pipeline's stages in dependency order, skipping those whose inputs did not change.

Each stage writes into a fresh temporary directory next to its final one; only a
stage that succeeded is renamed into place (the old outputs are kept until then),
so a failing or killed stage never leaves half-written files that a later run would
trust.
"""

from __future__ import annotations

import os
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

from ..errors import ConfigError, MetasheetError, StageError
from ..executor import Executor
from . import manifest as mf
from .config import Pipeline, upstream
from .registry import StageContext, stages


@dataclass(frozen=True)
class StageOutcome:
    """What happened to one stage in a run."""

    name: str
    status: str  # "ran" or "cached"
    directory: Path
    wall_time: float
    summary: dict = field(default_factory=dict)


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


def run_pipeline(
    pipeline: Pipeline,
    *,
    out_root: Path | None = None,
    only: str | None = None,
    force: bool = False,
    executor: Executor | None = None,
    report: Reporter = _quiet,
    progress_factory: Callable[[str], Callable[[str, int, int], None]] | None = None,
) -> list[StageOutcome]:
    """Run ``pipeline``; return one :class:`StageOutcome` per visited stage.

    ``only`` runs one stage (and what it needs, from cache when fresh); ``force``
    reruns the selected stage (or every stage when ``only`` is None).
    """
    registry = stages()
    out_root = Path(out_root) if out_root else pipeline.root / "outputs"
    base = out_root / pipeline.name
    base.mkdir(parents=True, exist_ok=True)
    executor = executor or Executor(pipeline.section.workers, pipeline.section.scheduler)
    outcomes: list[StageOutcome] = []
    for name in plan(pipeline, only):
        stage = registry[name]
        params = pipeline.params[name].model_dump(mode="json")
        ups = upstream(pipeline, name)
        inputs = {u: base / u for u in ups}
        input_hashes = {}
        for u in ups:
            m = mf.read_manifest(inputs[u])
            if m is None:
                raise StageError(f"stage {name!r}: upstream stage {u!r} has no outputs in {inputs[u]}")
            input_hashes[u] = {k: v["sha256"] for k, v in m["outputs"].items()}
        files = mf.param_files(params, pipeline.root)
        key = mf.cache_key(name, params, files, input_hashes)
        final = base / name
        forced = force and (only is None or only == name)
        if not forced and mf.is_fresh(final, key):
            report(name, "up to date, skipped")
            outcomes.append(StageOutcome(name, "cached", final, 0.0, mf.read_manifest(final).get("summary", {})))
            continue
        report(name, "running")
        progress = progress_factory(name) if progress_factory else (lambda d, i, n: None)
        t0 = time.perf_counter()
        started = datetime.now(timezone.utc).isoformat(timespec="seconds")
        work = base / f".{name}.tmp-{os.getpid()}"
        shutil.rmtree(work, ignore_errors=True)
        work.mkdir(parents=True)
        ctx = StageContext(name, pipeline.params[name], work, inputs, pipeline.root, executor, progress)
        try:
            summary = stage.run(ctx) or {}
            missing = [f for f in stage.outputs if not any(work.glob(f))]
            if missing:
                raise StageError(f"stage {name!r} did not write {', '.join(missing)}")
            wall = time.perf_counter() - t0
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
                },
            )
        except MetasheetError as err:
            shutil.rmtree(work, ignore_errors=True)
            raise StageError(f"stage {name!r} failed: {err}") from err
        except Exception as err:
            shutil.rmtree(work, ignore_errors=True)
            raise StageError(f"stage {name!r} failed: {type(err).__name__}: {err}") from err
        except BaseException:  # KeyboardInterrupt: leave old outputs, drop the partial ones
            shutil.rmtree(work, ignore_errors=True)
            raise
        _swap_into_place(work, final)
        report(name, f"done in {wall:.1f} s")
        outcomes.append(StageOutcome(name, "ran", final, wall, summary))
    return outcomes


def _swap_into_place(work: Path, final: Path) -> None:
    """Replace ``final`` by ``work`` with renames, so readers see old or new, never half."""
    old = final.with_name(f".{final.name}.old-{os.getpid()}")
    if final.exists():
        os.replace(final, old)
    os.replace(work, final)
    shutil.rmtree(old, ignore_errors=True)
