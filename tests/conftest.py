import pytest
"""Shared pytest options. Keep this file small and general."""


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
