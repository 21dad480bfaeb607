"""Report lines on the studies of our own model that run as pipelines of their own (issue 59).

The design chart, the cell-size study and the robot's mesh convergence are not the paper's
figures: ``pipelines/chart.toml``, ``cell-size.toml`` and ``convergence.toml`` make them,
and the paper's report reads their outputs beside its own (the same output root). A note
(:func:`metasheet.pipeline.stages.report._source`) says where a study came from, or that it
is not there; these functions turn it into Markdown: where it came from and whether it was
computed on this pipeline's own cell or robot, or the command that makes it.
"""

from __future__ import annotations

from collections.abc import Mapping


def command(note: Mapping) -> str:
    """The command that makes the study of ``note`` beside this run."""
    return f"metasheet run pipelines/{note['pipeline']}.toml"


def missing_lines(note: Mapping | None, heading: str | None = None) -> list[str]:
    """``heading`` and a paragraph naming the command that makes a study not in the output
    root; nothing when the study is there (or no sibling pipeline is named)."""
    if not note or note["found"]:
        return []
    text = (f"{note['what'].capitalize()} is not in this output root (`{note['file']}`): `{command(note)}`, with "
            "the same `--out` as this run, makes it; this pipeline's next run then reruns only its report.")
    return [*([heading, ""] if heading else []), text, ""]


def source_lines(note: Mapping | None, of: str) -> tuple[list[str], list[str]]:
    """(Markdown lines, differences) saying that a study came from the sibling pipeline of
    ``note``, and whether its ``of`` (e.g. "robot") is this pipeline's: the same upstream
    outputs (``note["differs"]`` empty), or not (the stages whose outputs differ), or not
    compared (None or absent). Nothing when the study is this pipeline's own or absent."""
    if not note or not note["found"]:
        return [], []
    differs = note.get("differs")
    line = f"From the `{note['pipeline']}` pipeline beside this one (`{note['file']}`; `{command(note)}`)"
    if differs is None:
        return [line + ".", ""], []
    if not differs:
        return [line + f", on the same {of} as this pipeline's (the same upstream outputs).", ""], []
    stages = ", ".join(differs)
    return ([line + f", on another {of}: its {stages} outputs are not this pipeline's.", ""],
            [f"{note['what'].capitalize()} (`{note['file']}`) was computed on another {of} than this pipeline's "
             f"(its {stages} outputs differ): give both pipelines the same settings up to {stages} and rerun "
             f"`{command(note)}`."])
