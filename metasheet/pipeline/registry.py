"""The stage registry: what each stage reads, which parameters it takes, what it writes.

A stage is a plain function ``run(ctx: StageContext) -> dict`` plus its declaration.
It reads its upstream stages' artefacts from ``ctx.inputs[name]`` (their output
directories), writes every file into ``ctx.workdir`` (a fresh temporary directory)
and returns a small JSON-able summary for the manifest. The runner moves the
whole directory into place only when the stage succeeded, so a failing or killed
stage never leaves a half-written output.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict

from ..runtime.executor import Executor


class Params(BaseModel):
    """Base of every stage's parameter model: unknown keys are errors, models are frozen, and
    every float, nested ones too (lists, tuples, tables), is finite: TOML's ``nan`` and ``inf``
    would pass every bound check of a field without one and reach the artefacts
    (``Infinity`` is not JSON).

    A string parameter that names a project file says so in its description with the
    words "relative to the project root" (``cell.design``, ``chart.design``): loading the
    pipeline (``metasheet validate`` too) then checks the file exists.

    Checks across fields belong in a ``model_validator(mode="after")`` raising
    :class:`~metasheet.errors.ConfigError` ``"field: value: what is allowed"`` (the loader adds
    the file and the table); checks against other stages' tables in :meth:`check_pipeline`.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    def check_pipeline(self, table: str, params: dict[str, Params]) -> None:
        """Check this table (the stage ``table``) against the pipeline's others (``params``: stage
        -> its parameters) when a pipeline is loaded; raise :class:`~metasheet.errors.ConfigError`
        ``"table.field: value: what is allowed"`` (the loader adds the file). Nothing by default."""

    def check_files(self, table: str, params: dict[str, Params], root: Path) -> None:
        """Read and check the files this table names (a cell design) and what the stage will
        check against them, when a pipeline is loaded (``metasheet validate`` too): an error
        then costs no upstream stage. Raise :class:`~metasheet.errors.ConfigError` like
        :meth:`check_pipeline`; ``root`` is the project root. Nothing by default."""


@dataclass
class StageContext:
    """What a running stage gets.

    Attributes
    ----------
    name : the stage's name.
    params : the validated parameter model of the stage.
    workdir : temporary directory to write every output into.
    inputs : upstream stage name -> that stage's (finished) output directory.
    root : directory of the pipeline file; relative paths in params resolve here.
    executor : where to run independent work units.
    progress : ``progress(description, done, total)`` reports progress to the user.
    timings : phase -> wall-clock seconds the stage may fill; the runner records them in
        the manifest (``timings_s``). Wall-clock times never go into an artefact: the same
        config gives the same bytes.
    column : which column of the paper a study computes ("prediction": the printed foam's
        constants; "reproduction": the paper's own model), :mod:`metasheet.pipeline.column`.
    subdir : folder of ``workdir`` the files go to ("": the stage's own folder; a study's
        second column writes into ``<column>/``).
    siblings : ``"<pipeline>/<stage>"`` -> that folder, for each of the stage's
        :attr:`Stage.siblings` that has outputs beside this pipeline's (same output root).
    """

    name: str
    params: Any
    workdir: Path
    inputs: dict[str, Path]
    root: Path
    executor: Executor = field(default_factory=Executor)
    progress: Callable[[str, int, int], None] = lambda desc, done, total: None
    timings: dict[str, float] = field(default_factory=dict)
    column: str = "prediction"
    subdir: str = ""
    siblings: dict[str, Path] = field(default_factory=dict)

    def path(self, filename: str) -> Path:
        """Where to write the output file ``filename``."""
        folder = self.workdir / self.subdir if self.subdir else self.workdir
        folder.mkdir(parents=True, exist_ok=True)
        return folder / filename


@dataclass(frozen=True)
class Stage:
    """Declaration of one stage.

    Attributes
    ----------
    name : stage name, the ``[NAME]`` table of a pipeline file.
    params : pydantic model of that table.
    run : the stage function.
    requires : upstream stages whose outputs it reads (must be in the pipeline).
    optional : upstream stages it reads when they are in the pipeline.
    reads : params -> the ``optional`` stages it reads with these parameters (None: all of them):
        a stage that does not read one does not wait for it, and runs beside it.
    siblings : params -> other pipelines' stage folders it reads when they have outputs,
        ``"<pipeline name>/<stage>"`` under the same output root (None: none). Their outputs'
        hashes join its cache key, so a rerun of that pipeline makes this stage stale; it
        never waits for them, nor runs them.
    outputs : files it writes (documentation and a post-run check).
    doc : one line for ``metasheet stages``.
    """

    name: str
    params: type[Params]
    run: Callable[[StageContext], dict]
    requires: tuple[str, ...] = ()
    optional: tuple[str, ...] = ()
    reads: Callable[[Params], tuple[str, ...]] | None = None
    siblings: Callable[[Params], tuple[str, ...]] | None = None
    outputs: tuple[str, ...] = ()
    doc: str = ""


_REGISTRY: dict[str, Stage] = {}


def register(stage: Stage) -> Stage:
    """Add a stage to the registry (stage modules call this at import)."""
    _REGISTRY[stage.name] = stage
    return stage


def stages() -> dict[str, Stage]:
    """All registered stages, by name, in registration (pipeline) order."""
    from . import stages as _  # noqa: F401  (imports register every stage)

    return dict(_REGISTRY)
