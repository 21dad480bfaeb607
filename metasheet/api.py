"""The Python API: load a pipeline, run it, read its results as typed values.

Exported at the top level (``metasheet.run``, ``metasheet.read_constants``, ...) and imported
only when first used, so ``import metasheet`` stays light::

    import metasheet

    run = metasheet.run("pipelines/quick.toml", overrides=["cell.seed=7"])
    c = metasheet.read_constants(run.folder)        # E_t, E_l, nu_t, nu_tl, mu_l [MPa, -], C (6, 6)
    j = metasheet.read_jacobian(run.folder)         # J (6, 6) [mm/rad; rad/rad], singular values
    w = metasheet.read_study(run.folder, "workspace", "reproduction")   # the column's summary

A pipeline can also be given as a mapping of its tables (``{"pipeline": {...}, "cell":
{...}}``), validated as a file is. Every reader takes a run's folder (``<out>/<name>``) or the
stage's own folder and raises :class:`~metasheet.errors.OutputError` naming the missing file.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import ConfigError, OutputError
from .pipeline.config import MAX_WORKERS, Pipeline, load_pipeline
from .pipeline.manifest import write_bytes_atomic
from .pipeline.runner import StageOutcome, run_pipeline

__all__ = ["Constants", "Jacobian", "Run", "load_pipeline", "read_constants", "read_jacobian", "read_study",
           "run", "write_file"]


@dataclass(frozen=True)
class Run:
    """A finished run: its pipeline, its output folder ``<out>/<name>`` and what each stage did
    (``"ran"`` or ``"cached"``, its folder, seconds and summary)."""

    pipeline: Pipeline
    folder: Path
    stages: tuple[StageOutcome, ...]

    def stage(self, name: str) -> Path:
        """The folder of stage ``name`` of this run."""
        if name not in self.pipeline.order:
            raise ConfigError(f"stage {name!r}: not in pipeline {self.pipeline.name!r} "
                              f"(its stages: {', '.join(self.pipeline.order)})")
        return self.folder / name


def run(pipeline: Pipeline | str | Path | Mapping, *, out: str | Path | None = None, stage: str | None = None,
        force: bool = False, workers: int | None = None, overrides: Sequence[str] = (), overwrite: bool = False,
        progress: Callable[[str, str], None] | None = None) -> Run:
    """Run ``pipeline`` (a loaded one, a file's path, or its tables as a mapping), as
    ``metasheet run`` does: up-to-date stages are reused, ``stage`` runs one stage (and what it
    needs), ``force`` recomputes. ``out``: the output root (default: ``outputs/`` of the project);
    ``workers``: local worker processes (default: the file's); ``overrides``: ``TABLE.KEY=VALUE``
    as ``--set``; ``progress``: called with (stage, message) as stages start and end."""
    from .runtime.executor import Executor

    if not isinstance(pipeline, Pipeline):
        pipeline = load_pipeline(pipeline, overrides)
    elif overrides:
        raise ConfigError("overrides: give them with the pipeline's file or mapping, not a loaded Pipeline")
    executor = None
    if workers is not None:
        if not 1 <= int(workers) <= MAX_WORKERS:
            raise ConfigError(f"workers: {workers!r}: allowed 1 to {MAX_WORKERS}")
        executor = Executor(int(workers), pipeline.section.scheduler)
    out_root = Path(out) if out is not None else pipeline.root / "outputs"
    kw = {"report": progress} if progress is not None else {}
    outcomes = run_pipeline(pipeline, out_root=out_root, only=stage, force=force, executor=executor,
                            overwrite=overwrite, **kw)
    return Run(pipeline, out_root / pipeline.name, tuple(outcomes))


@dataclass(frozen=True)
class Constants:
    """The homogenised transverse-isotropic constants of a ``homogenize`` stage.

    ``E_t``, ``E_l``, ``mu_l`` [MPa]; ``nu_t``, ``nu_tl`` [-]; ``C`` (6, 6) [MPa] the effective
    stiffness (Voigt order ``voigt_order``); ``axis`` (3,) the longitudinal axis l;
    ``relative_density`` [-]; ``ci95`` the 95 % intervals' half-widths by constant (several
    realisations) or None; ``data`` the whole ``constants.json``.
    """

    E_t: float
    E_l: float
    nu_t: float
    nu_tl: float
    mu_l: float
    C: np.ndarray
    axis: np.ndarray
    relative_density: float
    ci95: dict | None
    data: dict = field(repr=False)

    def to_dict(self) -> dict[str, float]:
        """The five constants by name (``metasheet.mechanics.material.TransverseIsotropic(**...)``)."""
        return {k: getattr(self, k) for k in ("E_t", "E_l", "nu_t", "nu_tl", "mu_l")}


@dataclass(frozen=True)
class Jacobian:
    """The robot's direct Jacobian at rest for one material case of a ``robot`` stage.

    ``J`` (6, n_motors): rows x, y, z [mm/rad], rx, ry, rz [rad/rad]; ``singular_values`` (6,)
    of ``diag(1, 1, 1, L, L, L) J`` with ``L = length_scale_mm``; ``rod_rotation_deg_per_deg``
    the rod's roll per degree of all motors; ``material`` the case (``"foam"``: the pipeline's
    material; ``"published"``, ``"silicone"``...: the comparisons); ``data`` the case's entry.
    """

    material: str
    J: np.ndarray
    singular_values: np.ndarray
    length_scale_mm: float
    rod_rotation_deg_per_deg: float
    data: dict = field(repr=False)


def _stage_file(folder: str | Path, stage: str, name: str) -> Path:
    """``folder/name`` when ``folder`` is the stage's own, else ``folder/stage/name``."""
    folder = Path(folder)
    for f in (folder / name, folder / stage / name):
        if f.is_file():
            return f
    raise OutputError(f"{folder}: no {stage} outputs ({stage}/{name}): run the pipeline's {stage} stage first")


def _json(path: Path) -> dict:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise OutputError(f"{path}: not a readable JSON file ({exc}): run the stage again") from None
    if not isinstance(data, dict):
        raise OutputError(f"{path}: not a JSON object: run the stage again")
    return data


def read_constants(folder: str | Path) -> Constants:
    """The constants of a run's (or a ``homogenize`` folder's) ``constants.json``."""
    d = _json(_stage_file(folder, "homogenize", "constants.json"))
    ci = d.get("ci95")
    return Constants(*(float(d[k]) for k in ("E_t", "E_l", "nu_t", "nu_tl", "mu_l")),
                     C=np.asarray(d["C"], float), axis=np.asarray(d["axis"], float),
                     relative_density=float(d["relative_density"]),
                     ci95=dict(ci["halfwidth"]) if isinstance(ci, dict) and "halfwidth" in ci else None, data=d)


def read_jacobian(folder: str | Path, material: str = "foam") -> Jacobian:
    """The Jacobian of material case ``material`` in a run's (or a ``robot`` folder's)
    ``jacobian.json``."""
    path = _stage_file(folder, "robot", "jacobian.json")
    cases = _json(path).get("materials", {})
    if material not in cases:
        raise ConfigError(f"material: {material!r}: not a case of {path} (its cases: {', '.join(cases)})")
    c = cases[material]
    return Jacobian(material, np.asarray(c["J_mm_per_rad_and_rad_per_rad"], float),
                    np.asarray(c["singular_values"], float), float(c["singular_values_length_scale_mm"]),
                    float(c["rod_rotation_deg_per_deg"]), c)


def read_study(folder: str | Path, stage: str, column: str | None = None) -> dict:
    """The summary of study ``stage`` (``workspace``, ``ranges``, ``anisotropy``, ``maze``...)
    from its manifest: the counts and figures the report quotes. ``column``
    (``"prediction"`` / ``"reproduction"``) picks one column's; None: the stage's first."""
    man = _json(_stage_file(folder, stage, "manifest.json"))
    summary = man.get("summary") or {}
    if column is None:
        return summary
    columns = summary.get("columns", {summary.get("column"): summary} if summary.get("column") else {})
    if column not in columns:
        raise ConfigError(f"column: {column!r}: not a column of stage {stage} (its columns: "
                          f"{', '.join(map(str, columns)) or 'none'})")
    return columns[column]


def write_file(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary name and a rename (never half a file:
    an interrupted write leaves the old file or none), its folders made; returns the path."""
    path = Path(path)
    write_bytes_atomic(path, data)
    return path
