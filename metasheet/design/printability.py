"""Printability of a fibre design (issue 45, item 1): IceSL's ranges and the angle's round trip.

Two checks, on what the design changes (the foam's in-plane axis) and what it is printed with:

1. **settings in range** (:func:`check_settings`): every IceSL setting of the design within
   the range IceSL's 8-bit textures can hold (:data:`metasheet.sheet.icesl.FIELD_SCALE`:
   ``infill_angle`` [0, 360] deg, ``infill_percentage`` [0, 100] %, ``kgon_x_shrink``
   [0, 1]); a value outside is refused with a :class:`~metasheet.errors.ConfigError` naming the
   setting. The design's own setting is ``infill_angle``, the fibre axis as the printmap writes
   it (:mod:`metasheet.sheet.angles`); the foam's other settings are the caller's (the design
   stage's ``print_settings``).
2. **angle round trip** (:func:`angle_round_trip`): sheet A's fibre field sampled on the
   printmap's 64^3 grid (:func:`metasheet.sheet.icesl.print_fields`), quantised to 8 bits,
   read back at each foam element's centroid as the slicer interpolates it, and compared with
   the design's axis there (the angle between the two lines) against the printmap's
   ``angle_tolerance_deg`` (2 deg). Elements whose stencil straddles the angle field's seam are
   counted and left out, as the printmap does. The constants' round trip needs a print source
   (a cell or chart stage: :mod:`metasheet.pipeline.printsource`) and is not checked here: a
   pipeline with published constants has none; sheet B, the mirror, is not sampled.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..sheet import angles, icesl
from ..sheet.consistency import axis_difference_deg

#: [deg] the printmap stage's default ``angle_tolerance_deg``
ANGLE_TOLERANCE_DEG = 2.0


def check_settings(settings: Mapping[str, object]) -> dict[str, tuple[float, float]]:
    """Check every IceSL setting ``name -> value or array`` (IceSL units) lies in IceSL's range;
    return ``name -> (min, max)`` of each. Raises ConfigError naming the first setting outside
    (or with no known range)."""
    out = {}
    for name, v in settings.items():
        if name not in icesl.FIELD_SCALE:
            raise ConfigError(f"print_settings.{name}: no IceSL range known; known settings are "
                              f"{sorted(icesl.FIELD_SCALE)}")
        a = np.atleast_1d(np.asarray(v, float))
        try:
            icesl.to_texture(name, a)
        except ConfigError as err:
            raise ConfigError(f"print_settings.{err}") from None
        out[name] = (float(a.min()), float(a.max()))
    return out


@dataclass(frozen=True)
class AngleRoundTrip:
    """The printed axis against the design's, at sheet A's foam element centroids.

    Attributes
    ----------
    max_deg : largest axis difference [deg] off the seam; p99_deg : its 99th percentile [deg];
    tolerance_deg : [deg]; compared : elements compared; seam : elements on the seam (left out);
    infill_angle_range_deg : (lo, hi) of the written infill_angle texture [deg].
    """

    max_deg: float
    p99_deg: float
    tolerance_deg: float
    compared: int
    seam: int
    infill_angle_range_deg: tuple[float, float]

    @property
    def ok(self) -> bool:
        return self.max_deg <= self.tolerance_deg


def angle_round_trip(points: np.ndarray, tets: np.ndarray, params, fiber_fn: Callable[[np.ndarray], np.ndarray],
                     tolerance_deg: float = ANGLE_TOLERANCE_DEG) -> AngleRoundTrip:
    """The round trip of ``fiber_fn`` (points (q, 3) [mm] -> unit fibres (q, 3)) printed on the
    sheet ``points`` (k, 3) [mm], ``tets`` (m, 4) of geometry ``params``
    (:class:`~metasheet.sheet.geometry.SheetParams`). The ``infill_angle`` texture is checked
    against IceSL's range on the way (:func:`check_settings`)."""
    pts, tets = np.asarray(points, float), np.asarray(tets)
    pf = icesl.print_fields(pts, tets, element_settings={}, fiber_fn=fiber_fn, params=params)
    tex = icesl.quantise(pf.textures[icesl.ANGLE])
    check_settings({icesl.ANGLE: tex * icesl.FIELD_SCALE[icesl.ANGLE]})
    cent = pts[tets[:, :4]].mean(axis=1)
    foam = ~icesl.solid_mask(cent, params)
    c = cent[foam]
    angle = icesl.FIELD_SCALE[icesl.ANGLE] * icesl.sample(tex, pf.box, c)
    diff = axis_difference_deg(angle, fiber_fn(c))
    seam = icesl.FIELD_SCALE[icesl.ANGLE] * icesl.stencil_span(tex, pf.box, c) > angles.SEAM_JUMP
    d = diff[~seam]
    if len(d) == 0:
        raise ConfigError("fiber_fn: every foam element is on the angle field's seam: nothing to compare")
    s = icesl.FIELD_SCALE[icesl.ANGLE]
    return AngleRoundTrip(float(d.max()), float(np.percentile(d, 99)), float(tolerance_deg), len(d),
                          int(seam.sum()), (float(tex.min() * s), float(tex.max() * s)))
