"""The tripod sheet: geometry and tet mesh, spiral fibre field, grading, IceSL export."""

from .fibers import spiral_fibers
from .geometry import SheetMesh, mirror_sheet, tripod_sheet
from .grading import Grading, grade
from .outline import SheetParams

__all__ = ["Grading", "SheetMesh", "SheetParams", "grade", "mirror_sheet", "spiral_fibers", "tripod_sheet"]
