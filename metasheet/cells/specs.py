"""The sub-tables of a cell design (``cells/*.toml``): ``[material]``, ``[seeds]``, ``[metric]``.

Frozen pydantic models shared by the design kinds (:mod:`metasheet.cells.catalogue`,
:mod:`metasheet.cells.polyfoam`); unknown keys are refused. Units: moduli in MPa,
lengths in mm, angles in degrees; ``axis`` a 0-based index (0, 1, 2 = x, y, z).
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from ..mechanics.material import Isotropic
from .metrics import PolyhedralMetric, StretchedMetric


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class MaterialSpec(_Model):
    """An isotropic base material. ``E`` [MPa] > 0, ``nu`` [-] in (-1, 0.5)."""

    name: str = "TPU NinjaFlex"
    E: float = Field(12.0, gt=0)
    nu: float = Field(0.3, gt=-1.0, lt=0.5)

    def material(self) -> Isotropic:
        return Isotropic(self.E, self.nu)


class SeedSpec(_Model):
    """Seed points: ``sampler`` uniform | jittered | poisson, ``count`` N, RNG ``seed``,
    ``jitter`` [-] (jittered grid), ``min_distance`` [mm in the metric's scaled space]
    (Poisson disk; default fills a quarter of the box with disks)."""

    sampler: Literal["uniform", "jittered", "poisson"] = "poisson"
    count: int = Field(64, ge=1, le=4096)
    seed: int = Field(0, ge=0)
    jitter: float = Field(0.5, ge=0.0, le=1.0)
    min_distance: float | None = Field(None, gt=0)


class StretchedSpec(_Model):
    """:class:`~metasheet.cells.metrics.StretchedMetric`: ``stretch`` s >= 1 [-] and ``mode``
    axial (cells elongated along the axis) | transverse (elongated across it)."""

    kind: Literal["stretched"] = "stretched"
    stretch: float = Field(1.0, ge=1.0, le=1000.0)
    mode: Literal["axial", "transverse"] = "axial"

    def build(self, axis: int) -> StretchedMetric:
        return StretchedMetric(self.stretch, axis, self.mode)


class PolyhedralSpec(_Model):
    """:class:`~metasheet.cells.metrics.PolyhedralMetric`: ``k`` [-], ``height`` [-],
    ``x_shrink`` [-], ``angle`` [deg]."""

    kind: Literal["polyhedral"]
    k: int = Field(6, ge=3, le=64)
    height: float = Field(1.0, gt=0.0, le=1000.0)
    x_shrink: float = Field(1.0, gt=0.0, le=1.0)
    angle: float = Field(0.0, ge=-360.0, le=360.0)

    def build(self, axis: int) -> PolyhedralMetric:
        return PolyhedralMetric(self.k, self.height, self.x_shrink, self.angle, axis)
