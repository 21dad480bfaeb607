"""``metasheet status``: each stage of a pipeline, whether its outputs are up to date, and why not.

The answer is the runner's own (:func:`~.staleness.stage_key` against the manifest, then the
outputs' hashes: :func:`~.manifest.is_fresh`), broken down into what changed since the stage
ran: its parameters (the keys named), the files they name, an upstream stage's outputs, the
sibling pipelines' outputs it reads, metasheet's code. A stage whose upstream has no outputs
waits for it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..errors import StageError
from ..runtime.provenance import code_digest
from . import manifest as mf
from .config import Pipeline
from .staleness import stage_key

#: At most this many changed parameter keys are named.
NAMED = 6


@dataclass(frozen=True)
class StageStatus:
    """One stage: ``state`` "up to date", "stale", "not run" or "waits"; ``why`` its reasons."""

    name: str
    state: str
    why: tuple[str, ...] = ()


def pipeline_status(pipeline: Pipeline, base: Path) -> list[StageStatus]:
    """The status of every stage of ``pipeline`` with its outputs under ``base``
    (``<out root>/<pipeline name>``), in run order."""
    return [stage_status(pipeline, name, base) for name in pipeline.order]


def stage_status(pipeline: Pipeline, name: str, base: Path) -> StageStatus:
    final = base / name
    if not final.exists():
        return StageStatus(name, "not run", (f"no outputs in {final}",))
    damage = mf.damage(final)
    if damage:
        return StageStatus(name, "stale", (f"manifest damaged: {damage}",))
    recorded = mf.read_manifest(final)
    if recorded is None:
        return StageStatus(name, "stale", (f"no manifest in {final}: metasheet cannot tell what it holds",))
    try:
        sk = stage_key(pipeline, name, base)
    except StageError as err:
        return StageStatus(name, "waits", (str(err).split(": ", 1)[-1],))
    if recorded.get("key") == sk.key:
        if mf.is_fresh(final, sk.key):
            return StageStatus(name, "up to date")
        return StageStatus(name, "stale", ("outputs changed since they were written (their hashes differ)",))
    return StageStatus(name, "stale", reasons(recorded, sk) or ("its cache key differs",))


def reasons(recorded: dict, sk) -> tuple[str, ...]:
    """What differs between a manifest ``recorded`` and the key ``sk`` computed now."""
    out = []
    changed = changed_keys(recorded.get("params", {}), sk.params)
    if changed:
        shown = ", ".join(changed[:NAMED]) + (f" and {len(changed) - NAMED} more" if len(changed) > NAMED else "")
        out.append(f"parameters changed: {shown}")
    files = recorded.get("param_files", {})
    for f in sorted(set(files) | set(sk.files)):
        if files.get(f) != sk.files.get(f):
            out.append(f"file {f} changed" if f in files and f in sk.files else f"file {f} added or removed")
    inputs = recorded.get("inputs", {})
    for u in sorted(set(inputs) | set(sk.input_hashes)):
        if inputs.get(u) != sk.input_hashes.get(u):
            out.append(f"the outputs of {u} changed" if u in inputs and u in sk.input_hashes
                       else f"{u}'s outputs appeared or went")
    if recorded.get("versions", {}).get("metasheet_code") not in (None, code_digest()):
        out.append("metasheet's code changed")
    return tuple(out)


def changed_keys(a, b, prefix: str = "") -> list[str]:
    """Dotted paths where the parameter trees ``a`` and ``b`` differ, sorted."""
    if isinstance(a, dict) and isinstance(b, dict):
        return sorted(k for key in set(a) | set(b)
                      for k in changed_keys(a.get(key), b.get(key), f"{prefix}{key}."))
    return [] if a == b else [prefix.rstrip(".")]
