"""Shared pytest options and the expensive fixtures several test files share, each computed
once per session. Keep this file small and general."""

import pytest


def pytest_addoption(parser):
    parser.addoption(
        "--update-goldens",
        action="store_true",
        default=False,
        help="rewrite golden files under tests/golden/ instead of comparing against them",
    )


@pytest.fixture(scope="module")
def foam_robot_14():
    """The light foam robot on 14 mm P1 sheets (solver tests)."""
    from metasheet import paper
    from metasheet.robot.builder import SheetPair, six_dof_robot
    from metasheet.sheet.geometry import SheetParams

    sheets = SheetPair.spiral(SheetParams(mesh_size=14))
    return six_dof_robot(sheets, paper.PAPER_FOAM, density=paper.FOAM_DENSITY)


@pytest.fixture(scope="module")
def foam_rest_14(foam_robot_14):
    """Its rest equilibrium, to 1e-10 of the force scale."""
    from metasheet.robot.equilibrium import solve_equilibrium

    return solve_equilibrium(foam_robot_14, foam_robot_14.coupling.rest_angles, tol=1e-10)


@pytest.fixture(scope="session")
def quick_outputs(tmp_path_factory):
    """The quick pipeline run once per session through ``printmap`` (cell, homogenize, material,
    orient, printmap): its output root, holding ``quick/<stage>/``. Read it; a test that runs a
    stage again copies it first (``shutil.copytree``), and the copy's stages stay cached."""
    from pathlib import Path

    from metasheet.pipeline.config import load_pipeline
    from metasheet.pipeline.runner import run_pipeline

    root = tmp_path_factory.mktemp("quick-outputs")
    pipeline = load_pipeline(Path(__file__).resolve().parents[1] / "pipelines" / "quick.toml")
    run_pipeline(pipeline, out_root=root, only="printmap")
    return root
