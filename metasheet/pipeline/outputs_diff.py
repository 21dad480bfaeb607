"""Compare two output trees file by file: identical bytes, equal numbers, or different.

``metasheet diff A B`` answers "did this change alter any result?" for two runs of a
pipeline (two versions of the code, two machines, two thread counts). Files whose bytes
match are "identical". Otherwise the numbers inside are compared where the format is known
(JSON, VTU, NPZ, CSV and text), quantity by quantity (a JSON key, a mesh array, a CSV
column), and the largest normwise relative difference ``max|a - b| / max(|a|, |b|)`` over
the quantities is reported; anything else (pictures, STL) is just "different". Wall-clock fields (``timings_s``, ``wall_s``, ...) and manifests are skipped:
they differ between any two runs. A file no reader can parse (a corrupt mesh) is a
"different" row saying so, never a crash.

Tolerance: a quantity agrees when

    max|a - b| <= atol + rtol * max(max|a|, max|b|)

normwise over the quantity and symmetric in a and b (numpy.isclose's rule with the scale of
the whole quantity instead of each b). ``atol`` is the floor for quantities that are zero up
to round-off (a moment zero by symmetry: 3.3e-16 against 4.1e-16 is a 180 % relative
difference); it is in the quantity's own unit, so it has no default but 0 (see ``metasheet
diff --atol``).
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import MetasheetError
from .manifest import MANIFEST, damage, sha256_file

#: JSON keys holding wall-clock times: never compared.
TIME_KEYS = ("timings_s", "wall_s", "s_per_point", "time_s", "seconds", "median_step_ms")
_NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?|nan|inf", re.IGNORECASE)


@dataclass(frozen=True)
class FileDiff:
    """One file's comparison: ``status`` "identical", "numbers", "different", "missing in a"
    or "missing in b"; ``max_rel`` the largest relative difference of its numbers and
    ``max_abs`` the largest absolute one (nan when not compared numerically); ``within``:
    identical, or every quantity within the tolerance it was compared with (module
    docstring); ``note`` what did not line up (shapes, keys, text, an unreadable file)."""

    path: str
    status: str
    max_rel: float = float("nan")
    note: str = ""
    max_abs: float = float("nan")
    within: bool = False


def _json_numbers(obj, groups: dict, keys: list, prefix: str = "") -> None:
    if isinstance(obj, dict):
        for k in sorted(obj):
            if k not in TIME_KEYS:
                _json_numbers(obj[k], groups, keys, f"{prefix}.{k}")
    elif isinstance(obj, (list, tuple)):
        for v in obj:
            _json_numbers(v, groups, keys, f"{prefix}[]")
    elif isinstance(obj, bool) or obj is None or isinstance(obj, str):
        keys.append(f"{prefix}={obj!r}")  # compared exactly, as structure
    elif isinstance(obj, (int, float)):
        groups.setdefault(prefix, []).append(float(obj))
        keys.append(prefix)


def _csv_columns(text: str) -> tuple[dict, list]:
    lines = [ln.split(",") for ln in text.strip().splitlines()]
    groups, keys = {}, [",".join(lines[0])]
    for row in lines[1:]:
        for name, cell in zip(lines[0], row):
            try:
                groups.setdefault(name, []).append(float(cell))
            except ValueError:
                keys.append(f"{name}={cell}")
    return groups, keys


def _quantities(path: Path) -> tuple[dict[str, np.ndarray], list]:
    """The numbers of a file grouped by quantity (a JSON key path, a VTU array, a CSV column),
    and the non-numeric structure they sit in."""
    suffix = path.suffix.lower()
    if suffix == ".json":
        groups, keys = {}, []
        _json_numbers(json.loads(path.read_text()), groups, keys)
    elif suffix == ".vtu":
        from .artefacts import read_mesh

        m = read_mesh(path)
        groups = {"points": m.points, **{f"cells:{c.type}": c.data for c in m.cells}}
        groups |= {f"point:{k}": v for k, v in m.point_data.items()}
        groups |= {f"cell:{k}": np.concatenate([np.ravel(b) for b in v]) for k, v in m.cell_data.items()}
        keys = sorted(f"{k}{np.shape(v)}" for k, v in groups.items())
    elif suffix == ".npz":
        with np.load(path) as z:
            groups = {k: z[k] for k in z.files}
        keys = sorted(f"{k}{np.shape(v)}" for k, v in groups.items())
    elif suffix == ".csv":
        groups, keys = _csv_columns(path.read_text())
    else:
        text = path.read_text()
        groups, keys = {"numbers": [float(t) for t in _NUMBER.findall(text)]}, [_NUMBER.sub("#", text)]
    return {k: np.ravel(np.asarray(v, float)) for k, v in groups.items()}, keys


@dataclass(frozen=True)
class _Gap:
    """How far apart one quantity is: ``diff`` max|a - b|, ``scale`` max(max|a|, max|b|)."""

    diff: float
    scale: float

    @property
    def rel(self) -> float:
        """diff / scale; 0 for equal quantities, inf when a zero scale has a difference."""
        return 0.0 if self.diff == 0.0 else (np.inf if self.scale == 0.0 else self.diff / self.scale)

    def within(self, rtol: float, atol: float) -> bool:
        return self.diff <= atol + rtol * self.scale


def _gap(a: np.ndarray, b: np.ndarray) -> _Gap:
    """The :class:`_Gap` of one quantity (NaN where both are NaN, and equal infinities, count as
    equal; NaN against a number, or an infinite difference, is an infinite one)."""
    same = (a == b) | (np.isnan(a) & np.isnan(b))
    with np.errstate(invalid="ignore"):  # inf - inf where they are equal: masked by ``same``
        d = np.where(same, 0.0, np.abs(a - b))
    d = np.where(np.isnan(d), np.inf, d)
    # the scale of the finite values: an infinity elsewhere in the file must not make every
    # difference relatively zero (and within any rtol)
    scale = max(float(np.max(np.abs(x[np.isfinite(x)]), initial=0.0)) for x in (a, b))
    worst = float(np.max(d, initial=0.0))
    return _Gap(worst if np.isfinite(worst) else np.inf, scale)


def compare_file(a: Path, b: Path, *, rtol: float = 0.0, atol: float = 0.0) -> FileDiff:
    """Compare two files of the same relative path (see the module docstring); ``within``
    with tolerances ``rtol`` [-] and ``atol`` (the quantities' units)."""
    rel = a.name
    if sha256_file(a) == sha256_file(b):
        return FileDiff(rel, "identical", 0.0, max_abs=0.0, within=True)
    if a.suffix.lower() not in (".json", ".vtu", ".npz", ".csv", ".txt", ".lua", ".md"):
        return FileDiff(rel, "different", note="binary content differs")
    try:
        ga, ka = _quantities(a)
    except Exception as exc:  # noqa: BLE001  (whatever a reader raises on corrupt bytes, a row says so)
        return FileDiff(rel, "different", note=f"unreadable in a: {_why(exc)}")
    try:
        gb, kb = _quantities(b)
    except Exception as exc:  # noqa: BLE001
        return FileDiff(rel, "different", note=f"unreadable in b: {_why(exc)}")
    if ka != kb or ga.keys() != gb.keys() or any(ga[k].shape != gb[k].shape for k in ga):
        return FileDiff(rel, "different", note="structure differs (keys, shapes or text)")
    gaps = {k: _gap(ga[k], gb[k]) for k in ga}
    name = max(gaps, key=lambda k: gaps[k].rel, default="")
    worst = gaps[name].rel if name else 0.0
    return FileDiff(rel, "numbers", worst, f"largest in {name}" if worst else "",
                    max_abs=max((g.diff for g in gaps.values()), default=0.0),
                    within=all(g.within(rtol, atol) for g in gaps.values()))


def _why(exc: Exception) -> str:
    return str(exc) if isinstance(exc, MetasheetError) else f"{type(exc).__name__}: {exc}"


def compare_trees(a: Path, b: Path, *, rtol: float = 0.0, atol: float = 0.0,
                  skip_manifests: bool = True) -> list[FileDiff]:
    """:class:`FileDiff` for every file under either tree (relative paths, sorted); ``rtol``,
    ``atol``: the tolerance of each file's ``within`` (module docstring)."""
    def files(root: Path) -> set[str]:
        return {p.relative_to(root).as_posix() for p in root.rglob("*")
                if p.is_file() and not (skip_manifests and p.name == MANIFEST)}

    fa, fb = files(a), files(b)
    out = [_damaged(rel, a, b) for rel in sorted(_manifests(a) | _manifests(b))] if skip_manifests else []
    out = [d for d in out if d is not None]
    for rel in sorted(fa | fb):
        if rel not in fa or rel not in fb:
            out.append(FileDiff(rel, "missing in a" if rel not in fa else "missing in b"))
            continue
        d = compare_file(a / rel, b / rel, rtol=rtol, atol=atol)
        out.append(replace(d, path=rel))
    return sorted(out, key=lambda d: d.path)


def _manifests(root: Path) -> set[str]:
    return {p.relative_to(root).as_posix() for p in root.rglob(MANIFEST) if p.is_file()}


def _damaged(rel: str, a: Path, b: Path) -> FileDiff | None:
    """A manifest is skipped (it holds times), unless it is damaged in either tree: then the
    trees differ, since nothing says what that stage wrote."""
    for side, root in (("a", a), ("b", b)):
        why = damage((root / rel).parent)
        if why:
            return FileDiff(rel, "different", note=f"damaged manifest in {side}: {why.split(': ', 1)[1]}")
    return None
