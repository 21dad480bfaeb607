"""What killed runs leave in an output folder, and its removal.

A stage writes into ``.<stage>.tmp-<pid>`` and swaps it into place through
``.<stage>.old-<pid>`` (:mod:`.runner`); a resumable study keeps its finished units in
``.<stage>.units`` (a reproduction column's stay after success, pruned to the run's units:
:func:`metasheet.pipeline.stages._studies.drop_cache`). A SIGKILLed run leaves them; a run (or
``metasheet clean``) removes the temporary folders of processes that are gone, and an
interrupted run removes its own. Nothing outside :func:`output_folder` is ever removed.
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
from pathlib import Path

from ..errors import ConfigError, OutputError, output_error
from .lock import Reporter, _quiet, pid_alive

#: A run's temporary directories: ``.<stage>.tmp-<pid>`` (being written) and
#: ``.<stage>.old-<pid>`` (the previous outputs during the swap).
DEBRIS = re.compile(r"^\.(?P<stage>.+)\.(?P<kind>tmp|old)-(?P<pid>\d+)$")




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


def remove_path(path: Path) -> None:
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
            gone = _restore_or_remove(base, path)
        except OSError as exc:
            raise output_error(exc, str(path)) from exc
        if gone:
            removed.append(path)
            report("clean", f"removed {path} (left by process {pid}, which is gone)")
        else:
            report("clean", f"put back {base / DEBRIS.match(path.name)['stage']} from {path.name} (a swap cut "
                            f"by process {pid}, which is gone)")
    return removed


def output_folder(out_root: Path, name: str) -> Path:
    """``out_root/name``, the only folder a run of pipeline ``name`` writes in and deletes from.

    Checked before anything is written or removed: ``name`` is one plain path component (not
    ``.`` or ``..``, no separator, no leading dot) and the folder, when it exists, is a real
    folder inside ``out_root``, not a link to elsewhere."""
    bad = (not name or name.startswith(".") or any(sep in name for sep in ("/", "\\", os.sep))
           or Path(name).name != name)
    if bad:
        raise ConfigError(f"pipeline.name: {name!r}: must be one folder name (letters, digits, _ - ., "
                          "not starting with a dot)")
    base = Path(out_root) / name
    if base.is_symlink() or (base.exists() and not base.is_dir()):
        raise OutputError(f"{base}: not a folder of this output root (a link or a file): not touching it")
    return base


def remove_unit_caches(base: Path, stage: str) -> None:
    """Remove a stage's resume caches under ``base`` (``.<stage>.units`` and its columns'
    ``.<stage>-<column>.units``): a forced run recomputes every unit."""
    for cache in [base / f".{stage}.units", *base.glob(f".{stage}-*.units")]:
        if cache.is_dir():
            shutil.rmtree(cache, ignore_errors=True)


def remove_own_debris(base: Path) -> list[Path]:
    """Remove this process's temporary folders under ``base`` (:func:`remove_debris_of`)."""
    return remove_debris_of(base, os.getpid())


def remove_debris_of(base: Path, pid: int) -> list[Path]:
    """Remove process ``pid``'s temporary folders under ``base`` and the stages' resume caches
    that hold no unit (an interrupted run's: this one's, or a crashed child's seen by its
    supervisor, :mod:`metasheet.supervise`); the previous outputs (``.old-``) are put back
    when a swap was cut between its two renames."""
    removed = []
    for path, owner in find_debris(base):
        if owner != pid:
            continue
        with contextlib.suppress(OSError):
            if _restore_or_remove(base, path):
                removed.append(path)
    for cache in base.glob(".*.units"):
        with contextlib.suppress(OSError):
            cache.rmdir()  # only when empty: the units a run finished are kept for its resume
            removed.append(cache)
    return removed


def _restore_or_remove(base: Path, path: Path) -> bool:
    """Put a swap's previous outputs (``.<stage>.old-<pid>``) back when the stage folder is
    missing (the swap was cut between its renames), else remove ``path``; True if removed."""
    final = base / DEBRIS.match(path.name)["stage"]
    if path.name.startswith(f".{final.name}.old-") and not final.exists():
        os.replace(path, final)
        return False
    remove_path(path)
    return True
