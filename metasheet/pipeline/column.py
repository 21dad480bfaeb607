"""The study column: the paper reproduced, or the printed foam predicted. One module holds
what a column is and builds its robot; the study stages, ``robot goto`` and ``serve`` call it.

The paper's figures (Fig. 5-8, the maze) came from the authors' model: the published
transverse-isotropic constants (:data:`metasheet.published.paper.PAPER_FOAM`) under the authors' SOFA
force field (shear moduli from E_t and nu_t, mu_l unused: :mod:`metasheet.mechanics.material_model`),
and no strain limit. metasheet's own answer is another robot: the printed foam's homogenised
constants, all five of them, within the strain range the homogenisation holds in. A study
computes either or both:

``reproduction``
    the published constants, the authors' force field (the studies' ``reproduction_model``),
    the authors' kind of mesh (uniform linear tetrahedra, 5 mm: their ``tripod_coarse_04.vtk``
    has 2,711), no strain stop, the paper's goto tolerances (1 mm, 2 deg: Section IV-B): the
    paper's model and protocol, so its counts can be compared with the paper's own. (Its coarse
    linear sheets are stiffer than the converged ones: the report's "Mesh convergence" says by
    how much; the paper's facts hold on both under this force field, docs/paper.md.)
``prediction``
    the material stage's constants, density and model, the study's own mesh, the strain-validity
    limit where the study has one: what the printed robot should do.

Both columns share the orient stage's geometry and fibre law and the robot stage's scene.
Every study's JSON carries ``"column"``; the first column of a study writes into its stage's
folder, a second into ``<stage>/<column>/`` (:func:`column_folder`); the report sets them side
by side.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path

from ..errors import ConfigError

COLUMNS = ("prediction", "reproduction")

#: The reproduction's sheets: the authors' kind of mesh (see the module docstring).
REPRODUCTION_MESH = {"element": "p1", "mesh_size": 5.0, "grip_size": 0.0}


@dataclass(frozen=True)
class Column:
    """What a column fixes.

    Attributes
    ----------
    name : "prediction" or "reproduction".
    material : the sheets' :class:`~metasheet.mechanics.material.TransverseIsotropic`; None: the
        material stage's (and its density) with the orient sheets' per-element constants.
    model : the material model, "ours" / "authors"; None: the material stage's.
    mesh : the sheet keys (``element``, ``mesh_size`` [mm], ``grip_size`` [mm]) the column
        re-meshes with unless a study sets them; {}: the study's own.
    study_defaults : the study-table keys the column changes unless the table's
        ``reproduction`` sub-table says otherwise (its mesh, and no strain stop).
    tolerances : ``robot goto``'s default position [mm] and rotation [deg] tolerances.
    keeps_units : whether a finished study keeps its work units for the next run (its robot
        does not depend on the pipeline's cell, so a rerun after another cell reuses them).
    """

    name: str
    material: object | None
    model: str | None
    mesh: dict
    study_defaults: dict
    tolerances: tuple[float, float]
    keeps_units: bool

    @property
    def fixes_material(self) -> bool:
        return self.material is not None


def column(name: str, reproduction_model: str = "authors", field: str = "column") -> Column:
    """The :class:`Column` called ``name``; the reproduction's material model is
    ``reproduction_model``. A :class:`ConfigError` naming ``field`` for an unknown name."""
    if name == "prediction":
        return Column(name, None, None, {}, {}, (0.1, 0.2), False)
    if name == "reproduction":
        from ..published import paper

        return Column(name, paper.PAPER_FOAM, reproduction_model, dict(REPRODUCTION_MESH),
                      {"stop_beyond_strain": False, **REPRODUCTION_MESH}, (1.0, 2.0), True)
    raise ConfigError(f"{field}: {name!r}: allowed values are {', '.join(COLUMNS)}")


def column_folder(stage_dir, name: str, stage: str) -> Path:
    """The folder of column ``name``'s outputs of the stage ``stage`` in ``stage_dir``: the
    stage's own folder when its ``<stage>.json`` names that column (a summary without
    ``"column"`` is the prediction's), else ``<stage_dir>/<name>`` (which may not exist)."""
    stage_dir = Path(stage_dir)
    own = stage_dir / f"{stage}.json"
    first = json.loads(own.read_text()).get("column", "prediction") if own.is_file() else "prediction"
    return stage_dir if name == first else stage_dir / name


def column_sheets(orient, col: Column, mesh_size: float | None = None, layers: int | None = None,
                  element: str | None = None, grip_size: float | None = None):
    """The :class:`~metasheet.robot.builder.SheetPair` of ``col``'s robot from the orient stage's
    :class:`~metasheet.pipeline.artefacts.OrientFile`: orient's own, or re-meshed
    (:func:`metasheet.pipeline.remesh.remesh`) when any of ``mesh_size`` [mm], ``layers``,
    ``element``, ``grip_size`` [mm] is given, the column's mesh filling those left None; with
    per-element constants only when the orient sheets are graded and the column does not fix the
    material."""
    from .remesh import remesh

    given = {"mesh_size": mesh_size, "layers": layers, "element": element, "grip_size": grip_size}
    keys = {**col.mesh, **{k: v for k, v in given.items() if v is not None}}
    if keys:
        sheets = remesh(orient, keys.pop("mesh_size", orient.sheet_params.mesh_size), **keys)
    else:
        sheets = orient.sheets(need_constants=orient.graded)
    if col.fixes_material or not (orient.graded and sheets.has_constants):
        sheets = replace(sheets, constants=None, constants_mirrored=None)
    return sheets


@dataclass(frozen=True)
class ColumnRobot:
    """The parts of a column's 6-DOF robot: its ``sheets``
    (:class:`~metasheet.robot.builder.SheetPair`, with per-element constants when graded),
    the design ``material`` (:class:`~metasheet.mechanics.material.TransverseIsotropic`: everywhere unless
    the sheets carry constants), the material ``model`` and the sheets' ``density`` [t/mm^3]."""

    column: Column
    sheets: object
    material: object
    model: str
    density: float

    def robot(self, **scene):
        """The :class:`~metasheet.robot.robots.Robot` (``scene``: ``rod_length`` [mm],
        ``geometry``, ``gravity`` of :func:`~metasheet.robot.builder.six_dof_robot`)."""
        from ..robot.builder import six_dof_robot

        material = None if self.sheets.has_constants else self.material
        return six_dof_robot(self.sheets, material, density=self.density, model=self.model, **scene)

    def spec(self, **kw):
        """The picklable :class:`~metasheet.studies.adapter.RobotSpec` a study runs on (``kw``:
        its scene and inverse-model settings)."""
        from ..studies.adapter import RobotSpec

        return RobotSpec.from_sheets(self.sheets, self.material, density=self.density, model=self.model, **kw)


def column_robot(orient, material_file, col: Column, sheet_mass_g: float | None = None, **mesh) -> ColumnRobot:
    """The one builder of a column's robot: the orient stage's sheets (:func:`column_sheets`,
    ``mesh``: its keys), the column's material or else the material stage's
    (:class:`~metasheet.pipeline.artefacts.MaterialFile` ``material_file``), and the density:
    ``sheet_mass_g`` [g] over the sheet's volume when the scene gives a sheet mass, else the
    column's foam (the paper's density for the published constants) or the material stage's."""
    from ..published import paper
    from ..robot.builder import resolve_density

    sheets = column_sheets(orient, col, **mesh)
    if col.fixes_material:
        material, model, density = col.material, col.model, paper.FOAM_DENSITY
    else:
        material, model, density = material_file.material, material_file.model, material_file.density
    density = resolve_density(sheets.sheet, None if sheet_mass_g else density, sheet_mass_g or None)
    return ColumnRobot(col, sheets, material, model, density)
