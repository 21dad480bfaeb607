"""The design stage's parametric search: its Optuna journal, study name and trial evaluation.

The journal lives in ``<outputs>/.design.units/`` while the stage runs (outside the temporary
workdir, so a killed run keeps its finished trials); a rerun starts from it, or else from the
last finished run's ``design/study.journal``, when its study is the same: the study's name
hashes the input files and the search settings (the strain limit too when the search is
constrained), not ``n_trials``, so more trials resume the same study.
"""

from __future__ import annotations

import hashlib
import json
import shutil

import numpy as np

from ..design import search as ds
from .artefacts import SHEET_FILES
from .manifest import sha256_file
from .registry import StageContext

JOURNAL = "study.journal"


def cache_dir(ctx: StageContext):
    """Where the journal lives while the stage runs."""
    return ctx.workdir.parent / f".{ctx.name}.units"


def study_name(ctx: StageContext) -> str:
    """The study's name: a hash of what a trial's value depends on (the input files and the
    search settings), not of ``n_trials``: more trials resume the same study."""
    p = ctx.params
    h = hashlib.sha256()
    for d, f in ((ctx.inputs["orient"], SHEET_FILES["normal"]), (ctx.inputs["orient"], SHEET_FILES["mirrored"]),
                 (ctx.inputs["orient"], "sheet.json"), (ctx.inputs["material"], "material.json")):
        h.update(sha256_file(d / f).encode())
    keys = ("sampler", "seed", "batch", "population", "pitch_deg", "n_radial", "radial_deg", "length_scale", "goal_deg")
    settings = {k: getattr(p, k) for k in keys}
    if p.constrain_strain:  # a constrained search samples other trials: another study (unconstrained: as before)
        settings["strain_limit"] = p.strain_limit
    h.update(json.dumps(settings, sort_keys=True).encode())
    return "design-" + h.hexdigest()[:16]


def search(ctx: StageContext, space, problem, cent, spiral_kw):
    """Run or resume the stage's search (:func:`metasheet.design.search.run_search`) in its journal;
    returns (:class:`~metasheet.design.search.SearchRecord`, the study's name)."""
    import optuna
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend

    p = ctx.params
    name, cache = study_name(ctx), cache_dir(ctx)
    cache.mkdir(parents=True, exist_ok=True)
    journal, previous = cache / JOURNAL, ctx.workdir.parent / ctx.name / JOURNAL
    if not journal.exists() and previous.is_file():
        shutil.copyfile(previous, journal)  # the last finished run's trials

    def storage():
        return JournalStorage(JournalFileBackend(str(journal)))

    st = storage()
    if journal.exists() and name not in optuna.get_all_study_names(st):
        journal.unlink()  # another study (other inputs or settings): start afresh
        st = storage()
    record = ds.run_search(st, name, space, n_trials=p.n_trials, batch=p.batch, sampler=p.sampler, seed=p.seed,
                           population=p.population,
                           evaluate=lambda v: evaluate_designs(ctx, problem, cent, spiral_kw, v, goal_deg=p.goal_deg),
                           progress=lambda d, n: ctx.progress("search trials", d, n),
                           strain_limit=p.strain_limit if p.constrain_strain else None)
    shutil.copyfile(journal, ctx.path(JOURNAL))
    return record, name


def evaluate_designs(ctx: StageContext, problem, cent, spiral_kw, values: list, label: str = "",
                     goal_deg: float | None = None) -> list:
    """The :class:`~metasheet.design.search.Scores` of search designs ``values`` (variables
    [deg]), in order (with the strain at the goals of ``goal_deg`` [deg] when given): one work
    unit per worker (the problem travels once per unit)."""
    workers = max(1, int(getattr(ctx.executor, "workers", 1)))
    chunks = [c for c in np.array_split(np.arange(len(values)), min(workers, len(values))) if len(c)]
    units = [ds.Trials(problem, cent, spiral_kw, tuple(tuple(float(x) for x in values[i]) for i in c), goal_deg)
             for c in chunks]
    kw = {"progress": lambda d, n: ctx.progress(label, d, n)} if label else {}
    return [s for r in ctx.executor.map(ds.evaluate_trials, units, **kw) for s in r]
