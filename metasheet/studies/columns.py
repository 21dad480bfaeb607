"""The two columns of every study: the paper reproduced, and the printed foam predicted.

The paper's figures (Fig. 5-8, the maze) came from the authors' model: the published
transverse-isotropic constants (:data:`metasheet.paper.PAPER_FOAM`) under the authors' SOFA
force field (shear moduli from E_t and nu_t, mu_l unused: :mod:`metasheet.material_model`),
and no strain limit. metasheet's own answer is another robot: the printed foam's homogenised
constants, all five of them, within the strain range the homogenisation holds in. A study
computes either or both:

``reproduction``
    the published constants, the authors' force field (``reproduction_model``), the authors'
    kind of mesh (uniform linear tetrahedra, 5 mm: their ``tripod_coarse_04.vtk`` has 2,711),
    no strain stop: the paper's model and protocol, so its counts can be compared with the
    paper's own. (Its coarse linear sheets are stiffer than the converged ones: the report's
    "Mesh convergence" says by how much; the paper's facts hold on both under this force
    field, docs/paper.md.)
``prediction``
    the material stage's constants and model, the strain-validity limit where the study has
    one: what the printed robot should do.

Every study's JSON carries ``"column"``, and the report sets the two side by side.
"""

from __future__ import annotations

from dataclasses import dataclass

COLUMNS = ("prediction", "reproduction")


@dataclass(frozen=True)
class ColumnMaterial:
    """The sheets' material of one column: ``material`` a
    :class:`~metasheet.material.TransverseIsotropic` (None: the material stage's) and
    ``model`` "ours" / "authors" (None: the material stage's)."""

    column: str
    material: object | None
    model: str | None


def column_material(column: str, reproduction_model: str = "authors") -> ColumnMaterial:
    """The material a column's robot is made of (see the module docstring)."""
    from .. import paper

    if column == "prediction":
        return ColumnMaterial(column, None, None)
    if column == "reproduction":
        return ColumnMaterial(column, paper.PAPER_FOAM, reproduction_model)
    from ..errors import ConfigError

    raise ConfigError(f"column: {column!r}: allowed values are {list(COLUMNS)}")


#: The reproduction's sheets: the authors' kind of mesh (see the module docstring).
REPRODUCTION_MESH = {"element": "p1", "mesh_size": 5.0, "grip_size": 0.0}
#: What the reproduction column changes in a study's parameters unless its ``reproduction``
#: table says otherwise: the paper's mesh kind, and no strain stop.
REPRODUCTION_DEFAULTS = {"stop_beyond_strain": False, **REPRODUCTION_MESH}


def column_folder(stage_dir, column: str, name: str):
    """The folder (a :class:`~pathlib.Path`) of ``column``'s outputs of the stage ``name`` in
    ``stage_dir``: the stage's own folder when its ``<name>.json`` names that column (a summary
    without ``"column"`` is the prediction's), else ``<stage_dir>/<column>`` (which may not exist)."""
    import json
    from pathlib import Path

    stage_dir = Path(stage_dir)
    own = stage_dir / f"{name}.json"
    first = json.loads(own.read_text()).get("column", "prediction") if own.is_file() else "prediction"
    return stage_dir if column == first else stage_dir / column
