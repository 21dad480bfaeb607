"""What metasheet can prove it wrote in an output folder, before it removes or replaces it.

The proof is a stage folder's ``manifest.json``: it lists every file the stage wrote
(:func:`~.manifest.output_hashes`). A folder whose manifest is missing or unreadable, or that
holds a file the manifest does not list (a user's ``notes.txt`` in ``material/``), is not
replaced (``metasheet run``) unless the user says so (``--overwrite``), and ``metasheet clean
--all`` keeps such files and the folders holding them: the rule of DVC, ``git clean`` and
cargo, a tool removes only what it wrote.
"""

from __future__ import annotations

from pathlib import Path

from ..errors import OutputError
from . import manifest as mf

#: At most this many foreign files are named in a message (then "and N more").
NAMED = 5


def foreign_files(stage_dir: Path, stage: str | None = None) -> list[str] | None:
    """Files under ``stage_dir`` (relative POSIX paths, sorted) that its manifest does not list;
    None when there is no readable manifest of stage ``stage`` (when given) to tell."""
    m = mf.read_manifest(stage_dir)
    if not isinstance(m, dict) or not isinstance(m.get("outputs"), dict):
        return None
    if stage is not None and m.get("stage") != stage:
        return None
    listed = set(m["outputs"]) | {mf.MANIFEST}
    return sorted(rel for p in stage_dir.rglob("*")
                  if not p.is_dir() and (rel := p.relative_to(stage_dir).as_posix()) not in listed)


def check_replaceable(stage_dir: Path, stage: str, overwrite: bool = False) -> None:
    """Raise :class:`~metasheet.errors.OutputError` unless ``stage_dir`` is absent, empty, or
    holds only what stage ``stage`` wrote there (or ``overwrite``)."""
    if overwrite or not stage_dir.exists() or (stage_dir.is_dir() and not any(stage_dir.iterdir())):
        return
    why = not_ours(stage_dir, stage)
    if why:
        raise OutputError(f"{stage_dir}: not replacing it: {why}. Move them away, or pass --overwrite "
                          "to replace the folder anyway")


def not_ours(stage_dir: Path, stage: str) -> str | None:
    """Why ``stage_dir`` is not provably stage ``stage``'s outputs (None: it is)."""
    if stage_dir.is_symlink() or not stage_dir.is_dir():
        return "it is a link or a file, not a folder metasheet wrote"
    foreign = foreign_files(stage_dir, stage)
    if foreign is None:
        return (f"it has no readable {mf.MANIFEST} of stage {stage!r} (missing or damaged), so metasheet "
                "cannot tell which of its files it wrote")
    if foreign:
        return f"it holds {name_files(foreign)}, which metasheet did not write"
    return None


def name_files(files: list[str]) -> str:
    """``a, b and c`` (at most :data:`NAMED` names, then "and N more")."""
    shown = files[:NAMED]
    more = len(files) - len(shown)
    if more:
        return f"{', '.join(shown)} and {more} more"
    return shown[0] if len(shown) == 1 else f"{', '.join(shown[:-1])} and {shown[-1]}"
