"""Hashes, cache keys and ``manifest.json``: what a stage read, with which parameters, what it wrote.

A stage's cache key hashes its name, its parameters, the contents of any file a
parameter names (a cell design, say), the content hashes of its upstream stages' outputs
and the metasheet version. Equal key and intact outputs mean the stage is skipped.

The content hash of a JSON artefact is canonical (:func:`canonical_sha256`): its numbers
rounded to :data:`SIGNIFICANT_DIGITS` significant digits, keys sorted. A last-bit change
in a fitted constant (another BLAS, another thread count) then does not rerun every stage
downstream; any other file is hashed byte for byte. Wall-clock times are never in an
artefact, only in the manifest (``started``, ``wall_time_s``, ``cpu_s``, ``timings_s``).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import platform
from importlib import metadata
from pathlib import Path
from typing import Any

from ..version import __version__
from ..runtime.provenance import code_digest

MANIFEST = "manifest.json"

#: Significant digits of the numbers in a JSON artefact's canonical hash (:func:`canonical_sha256`).
SIGNIFICANT_DIGITS = 12

#: Packages whose versions every manifest records.
TRACKED = (
    "numpy", "scipy", "scikit-fem", "gmsh", "meshio", "pyvista", "vtk", "trimesh",
    "manifold3d", "scikit-image", "pyamg", "numba", "qpsolvers", "daqp", "pydantic",
    "matplotlib", "distributed", "cupy", "cupy-cuda12x", "cupy-cuda13x",
)


def sha256_file(path: Path) -> str:
    """Hex SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def sha256_json(obj: Any) -> str:
    """Hex SHA-256 of a canonical JSON dump."""
    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()


def _canonical(obj: Any) -> Any:
    if isinstance(obj, bool) or obj is None or isinstance(obj, (int, str)):
        return obj
    if isinstance(obj, float):
        if not math.isfinite(obj):
            return repr(obj)
        v = float(f"{obj:.{SIGNIFICANT_DIGITS}g}")
        return 0.0 if v == 0.0 else v  # -0.0 and 0.0 alike
    if isinstance(obj, dict):
        return {str(k): _canonical(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_canonical(v) for v in obj]
    return str(obj)


def canonical_sha256(path: Path) -> str:
    """Hex SHA-256 of a JSON file's content: numbers rounded to :data:`SIGNIFICANT_DIGITS`
    significant digits, keys sorted, no whitespace. Equal for files that differ only in
    formatting or in the last bits of their numbers. Not JSON: the bytes' SHA-256."""
    try:
        data = json.loads(Path(path).read_text())
    except (ValueError, UnicodeDecodeError):
        return sha256_file(path)
    text = json.dumps(_canonical(data), sort_keys=True, separators=(",", ":"), allow_nan=True)
    return hashlib.sha256(text.encode()).hexdigest()


def content_hash(info: dict) -> str:
    """What a downstream cache key uses of one output entry of a manifest: its canonical
    hash when it has one (JSON), else its SHA-256."""
    return info.get("canonical", info["sha256"])


def param_files(params: dict, root: Path) -> dict[str, str]:
    """Files named by string parameters (relative to ``root``) -> their hashes."""
    found: dict[str, str] = {}

    def walk(v: Any) -> None:
        if isinstance(v, dict):
            for x in v.values():
                walk(x)
        elif isinstance(v, (list, tuple)):
            for x in v:
                walk(x)
        elif isinstance(v, str) and v and len(v) < 512:
            p = root / v
            if p.is_file():
                found[v] = sha256_file(p)

    walk(params)
    return found


def output_hashes(directory: Path) -> dict[str, dict]:
    """Every file under ``directory`` except the manifest -> {sha256, bytes}, plus
    ``canonical`` (:func:`canonical_sha256`) for a JSON file."""
    out = {}
    for p in sorted(directory.rglob("*")):
        if p.is_file() and p.name != MANIFEST:
            rel = p.relative_to(directory).as_posix()
            out[rel] = {"sha256": sha256_file(p), "bytes": p.stat().st_size}
            if p.suffix.lower() == ".json":
                out[rel]["canonical"] = canonical_sha256(p)
    return out


def versions() -> dict[str, str]:
    """Python, metasheet and dependency versions."""
    v = {"python": platform.python_version(), "metasheet": __version__, "platform": platform.platform(),
         "metasheet_code": code_digest()}
    for name in TRACKED:
        try:
            v[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            pass
    return v


def cache_key(stage: str, params: dict, files: dict[str, str], inputs: dict[str, dict]) -> str:
    """The key that decides whether a stage must run again: its parameters, the files they
    name, its inputs' keys, and the code (:func:`~metasheet.runtime.provenance.code_digest`), so an
    edited metasheet reruns a stage without ``--force``."""
    return sha256_json(
        {"stage": stage, "params": params, "files": files, "inputs": inputs, "version": __version__,
         "code": code_digest()}
    )


def read_manifest(directory: Path) -> dict | None:
    """The manifest of an output directory, or None if absent or unreadable."""
    try:
        return json.loads((directory / MANIFEST).read_text())
    except (OSError, ValueError):
        return None


def damage(directory: Path) -> str | None:
    """Why the manifest in ``directory`` cannot be read (not UTF-8 JSON, not a JSON object);
    None when it is absent or readable. A damaged manifest means "stale" to every reader: a
    run recomputes the stage, ``diff`` reports it, ``serve`` and ``goto`` refuse the outputs
    (as they do a readable one without the current key)."""
    path = directory / MANIFEST
    if not path.exists():
        return None
    try:
        m = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        return f"{path}: unreadable ({type(exc).__name__}: {exc})"
    if not isinstance(m, dict):
        return f"{path}: not a JSON object"
    return None


def is_fresh(directory: Path, key: str) -> bool:
    """True when ``directory`` holds a manifest with ``key`` and every output it lists, intact."""
    m = read_manifest(directory)
    if not m or m.get("key") != key:
        return False
    for rel, info in m.get("outputs", {}).items():
        p = directory / rel
        if not p.is_file() or p.stat().st_size != info["bytes"] or sha256_file(p) != info["sha256"]:
            return False
    return True


def write_json_atomic(path: Path, obj: Any) -> None:
    """Write JSON with :func:`write_bytes_atomic`: ``path`` holds the old content or the new
    one, never a part."""
    text = json.dumps(obj, indent=2, sort_keys=False, default=_json_default) + "\n"
    write_bytes_atomic(path, text.encode())


def write_bytes_atomic(path: Path, data: bytes) -> None:
    """Write ``data`` to a temporary name, flush it to disk, then rename it into place; the
    folder is made if missing.

    A failed write (a full disk, say) removes the temporary file and re-raises: ``path``
    holds the old content or the new one, never a part.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def _json_default(o: Any):
    try:
        import numpy as np

        if isinstance(o, np.ndarray):
            return o.tolist()
        if isinstance(o, np.generic):
            return o.item()
    except ImportError:  # pragma: no cover
        pass
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")
