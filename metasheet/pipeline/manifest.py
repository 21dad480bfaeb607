"""Hashes, cache keys and ``manifest.json``: what a stage read, with which parameters, what it wrote.

A stage's cache key hashes its name, its parameters, the contents of any file a
parameter names (a cell design, say), the hashes of its upstream stages' outputs
and the metasheet version. Equal key and intact outputs mean the stage is skipped.
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
from importlib import metadata
from pathlib import Path
from typing import Any

from .. import __version__

MANIFEST = "manifest.json"

#: Packages whose versions every manifest records.
TRACKED = (
    "numpy", "scipy", "scikit-fem", "gmsh", "meshio", "pyvista", "vtk", "trimesh",
    "manifold3d", "scikit-image", "pyamg", "numba", "qpsolvers", "daqp", "pydantic",
    "matplotlib", "distributed",
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
    """Every file under ``directory`` except the manifest -> {sha256, bytes}."""
    out = {}
    for p in sorted(directory.rglob("*")):
        if p.is_file() and p.name != MANIFEST:
            rel = p.relative_to(directory).as_posix()
            out[rel] = {"sha256": sha256_file(p), "bytes": p.stat().st_size}
    return out


def versions() -> dict[str, str]:
    """Python, metasheet and dependency versions."""
    v = {"python": platform.python_version(), "metasheet": __version__, "platform": platform.platform()}
    for name in TRACKED:
        try:
            v[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            pass
    return v


def cache_key(stage: str, params: dict, files: dict[str, str], inputs: dict[str, dict]) -> str:
    """The key that decides whether a stage must run again."""
    return sha256_json(
        {"stage": stage, "params": params, "files": files, "inputs": inputs, "version": __version__}
    )


def read_manifest(directory: Path) -> dict | None:
    """The manifest of an output directory, or None if absent or unreadable."""
    try:
        return json.loads((directory / MANIFEST).read_text())
    except (OSError, ValueError):
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
    """Write JSON to a temporary name, then rename it into place."""
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    tmp.write_text(json.dumps(obj, indent=2, sort_keys=False, default=_json_default) + "\n")
    os.replace(tmp, path)


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
