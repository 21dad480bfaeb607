"""Byte-stable ``.npz`` files: the same arrays give the same bytes.

``numpy.savez`` stamps each member with the current time, so two runs of a stage would write
different bytes for the same voxels. :func:`npz_bytes` writes an uncompressed zip with fixed
member timestamps and modes; :func:`write_npz` writes it to a temporary name and renames it,
so a killed run never leaves half a file.
"""

from __future__ import annotations

import io
import os
import zipfile
from pathlib import Path

import numpy as np


def npz_bytes(**arrays: np.ndarray) -> bytes:
    """An uncompressed ``.npz`` of ``arrays`` (name -> array), same arrays, same bytes."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_STORED) as zf:
        for name, arr in arrays.items():
            member = io.BytesIO()
            np.lib.format.write_array(member, np.ascontiguousarray(arr), allow_pickle=False)
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.external_attr = 0o644 << 16
            zf.writestr(info, member.getvalue())
    return buf.getvalue()


def write_npz(path: Path, **arrays: np.ndarray) -> None:
    """:func:`npz_bytes` written to ``path`` atomically (a temporary name, then a rename)."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    tmp.write_bytes(npz_bytes(**arrays))
    os.replace(tmp, path)
