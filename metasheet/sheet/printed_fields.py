"""The foam brush's settings as fields in the print frame, as the slicer reads them.

Each of ``infill_percentage`` [%], ``kgon_x_shrink`` [-] and ``infill_angle`` [deg] is a number,
a callable ``(n, 3) [mm] -> (n,)`` or a print-map texture (:class:`TextureField`: 8-bit,
trilinear between texel centres, clamped at the box faces, :func:`metasheet.sheet.icesl.sample`);
:func:`printmap_fields` reads them from a ``printmap`` stage's ``printmap.json`` and field
files (given as text: this module reads no file).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, check_range
from . import icesl
from .grid import GridBox

FIELDS = ("infill_percentage", "kgon_x_shrink", "infill_angle")


@dataclass(frozen=True)
class TextureField:
    """A print-map texture as the slicer reads it: ``scale * trilinear(texture)`` at points (n, 3)
    [mm], clamped at the box faces (:func:`metasheet.sheet.icesl.sample`). ``texture`` (n, n, n)
    in [0, 1], quantised to 8 bits if it came from a field file (:func:`printmap_fields`)."""

    box: GridBox
    texture: np.ndarray
    scale: float

    def __call__(self, points: np.ndarray) -> np.ndarray:
        return self.scale * icesl.sample(self.texture, self.box, points)


FieldLike = float | Callable[[np.ndarray], np.ndarray] | TextureField


def _evaluate(name: str, f: FieldLike, points: np.ndarray) -> np.ndarray:
    if callable(f):
        v = np.asarray(f(points), dtype=float)
        if v.shape != (len(points),):
            raise ConfigError(f"{name}: the field returned shape {v.shape} for {len(points)} points; "
                              f"expected ({len(points)},)")
        return v
    return np.full(len(points), float(check_range(name, f)))


@dataclass(frozen=True)
class FoamFields:
    """The foam brush's Polyfoam settings in the print frame, each a number, a callable
    ``(n, 3) [mm] -> (n,)`` or a :class:`TextureField`: ``infill_percentage`` [%] in [1, 90],
    ``kgon_x_shrink`` [-] in (0, 1], ``infill_angle`` [deg] (the soft axis' angle from +x).
    Callables are evaluated in the padded box around the sheet too (seeds outside the sheet
    shape the cells cut by its faces)."""

    infill_percentage: FieldLike = 20.0
    kgon_x_shrink: FieldLike = 1.0
    infill_angle: FieldLike = 0.0

    def __call__(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        p = np.asarray(points, dtype=float)
        return tuple(_evaluate(n, getattr(self, n), p) for n in FIELDS)

    @property
    def uniform(self) -> bool:
        return not any(callable(getattr(self, n)) for n in FIELDS)

    def describe(self) -> dict:
        return {n: (float(v) if not callable(v) else type(v).__name__) for n in FIELDS
                for v in (getattr(self, n),)}


def printmap_fields(info: Mapping, label: str, texts: Mapping[str, str]) -> FoamFields:
    """The foam brush's fields of one sheet of a print map, as IceSL holds them.

    Parameters
    ----------
    info : ``printmap.json`` (the printmap stage's), as a dict.
    label : the sheet, ``"normal"`` or ``"mirrored"``.
    texts : file name -> text of the field files of that sheet (``infill_angle.txt``, ...).

    A setting written as a value is that value; one written as a field is its texture,
    quantised to 8 bits; one not written is IceSL's default.
    """
    brush = info["brushes"][str(icesl.FOAM)]
    sheet = info["sheets"][label]
    box = GridBox(np.asarray(sheet["box_lo_mm"], float), np.asarray(sheet["box_hi_mm"], float),
                  int(info.get("grid", [icesl.N])[0]))
    out = {}
    for name in FIELDS:
        key = f"{name}_{icesl.FOAM}"
        if key in brush.get("fields", {}):
            fname = brush["fields"][key]
            if fname not in texts:
                raise ConfigError(f"texts: {fname!r} (the {label} sheet's {name} field) is missing")
            tex = icesl.quantise(icesl.parse_field_text(texts[fname], box.n))
            out[name] = TextureField(box, tex, icesl.FIELD_SCALE[name])
        else:
            out[name] = float(brush["settings"].get(key, icesl.POLYFOAM_DEFAULTS[name]))
    return FoamFields(**out)
