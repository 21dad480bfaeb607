"""Which stages' outputs a pipeline file no longer matches: their cache keys, recomputed.

``metasheet run`` skips a stage whose manifest records the key the pipeline computes now
(:func:`stage_key`, the runner's own computation). Readers of outputs written earlier
(``metasheet serve``, ``robot goto --pipeline``) ask :func:`stale_stages` the same question,
so a pipeline file edited since its run (another scene, another mesh, under the same
``name``) is never answered from the old outputs.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..errors import StageError
from . import manifest as mf
from .config import Pipeline, siblings, upstream


@dataclass(frozen=True)
class StageKey:
    """What a stage's cache key hashes and the key itself (recorded in its manifest);
    ``siblings``: those of the stage's sibling folders that have outputs (their hashes are in
    ``input_hashes`` under ``"<pipeline>/<stage>"``)."""

    key: str
    params: dict
    files: dict[str, str]
    input_hashes: dict[str, dict[str, str]]
    siblings: tuple[str, ...] = ()


def stage_key(pipeline: Pipeline, name: str, base: Path) -> StageKey:
    """The cache key of stage ``name`` of ``pipeline`` with its upstream outputs under
    ``base`` (``<out root>/<pipeline name>``): its parameters, the files they name, the
    content hashes its upstream stages' manifests record and those of its sibling folders
    (other pipelines' stages under the same root) that have a manifest: a sibling without
    one is left out, so the stage is stale once it appears. StageError when an upstream
    stage has no manifest (no outputs)."""
    params = pipeline.params[name].model_dump(mode="json")
    input_hashes = {}
    for u in upstream(pipeline, name):
        m = mf.read_manifest(base / u)
        if m is None:
            raise StageError(f"stage {name!r}: upstream stage {u!r} has no outputs in {base / u}")
        input_hashes[u] = {k: mf.content_hash(v) for k, v in m["outputs"].items()}
    found = []
    for rel in siblings(pipeline, name):  # "<pipeline>/<stage>": a slash, never a stage name
        m = mf.read_manifest(base.parent / rel)
        if m is not None:
            input_hashes[rel] = {k: mf.content_hash(v) for k, v in m["outputs"].items()}
            found.append(rel)
    files = mf.param_files(params, pipeline.root)
    return StageKey(mf.cache_key(name, params, files, input_hashes), params, files, input_hashes, tuple(found))


def closure(pipeline: Pipeline, names) -> tuple[str, ...]:
    """``names`` (those the pipeline has) and every stage upstream of them, in run order."""
    needed: set[str] = set()

    def visit(n: str) -> None:
        if n not in needed:
            needed.add(n)
            for u in upstream(pipeline, n):
                visit(u)

    for n in names:
        if n in pipeline.params:
            visit(n)
    return tuple(n for n in pipeline.order if n in needed)


def stale_stages(pipeline: Pipeline, base: Path, names=None) -> tuple[str, ...]:
    """The stages among ``names`` (default: all; their upstream stages too) whose manifest
    under ``base`` records another key than ``pipeline`` computes now, in run order.

    A stage without a manifest is not judged here (outputs written by hand, or none: the
    reader's own check names a missing file); nor is one whose upstream has none. A stage
    whose manifest is damaged (:func:`~.manifest.damage`) is stale.
    """
    stale = []
    for name in closure(pipeline, pipeline.order if names is None else names):
        if mf.damage(base / name):
            stale.append(name)
            continue
        recorded = mf.read_manifest(base / name)
        if recorded is None:
            continue
        try:
            key = stage_key(pipeline, name, base).key
        except StageError:
            continue
        if recorded.get("key") != key:
            stale.append(name)
    return tuple(stale)
