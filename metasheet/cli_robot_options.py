"""The options that choose the robot a command drives, shared by ``robot goto`` and ``robot path``
(:func:`metasheet.goto.command_robot` resolves them)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

PipelineOption = Annotated[Optional[Path], typer.Option(
    "--pipeline", help="pipeline TOML file whose robot to drive (its robot stage's scene, material stage's density "
    "and model; run it first)")]
OutOption = Annotated[Optional[Path], typer.Option(
    "--out", help="output root the pipeline ran with (default: outputs/ of the project)")]
OrientOption = Annotated[Optional[Path], typer.Option(
    "--orient", help="without --pipeline: an orient stage's output directory (the paper's scene and foam density)")]
MeshSizeOption = Annotated[float, typer.Option(
    "--mesh-size", min=2.0, max=20.0, help="sheet mesh size [mm] when no --pipeline or --orient")]
MaterialModelOption = Annotated[Optional[str], typer.Option(
    "--material-model", help="material model 'ours' or 'authors' (default: the material stage's, else 'ours')")]
ColumnOption = Annotated[str, typer.Option(
    "--column", help="with --pipeline: 'prediction' (the material stage's constants) or 'reproduction' (the "
    "published constants under the authors' force field, on the same mesh and scene)")]
