"""The robot's time series for ParaView (metasheet.export.series, issue 65 item 3): each array
against an answer computed another way (the sheets' own fibre field, the state's positions,
a rigid motion, the horn formula of metasheet.robot.robots)."""

import re
from types import SimpleNamespace

import meshio
import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.export.series import PARTS, MazePlate, read_series, write_robot_series
from metasheet.robot.robots import Q_A, Q_B
from metasheet.robot.statics import RobotState

pv = pytest.importorskip("pyvista")


@pytest.fixture(scope="module")
def pair14():
    """The 14 mm P1 foam robot (as tests/conftest.py's foam_robot_14) and its sheets."""
    from metasheet.published import paper
    from metasheet.robot.builder import SheetPair, six_dof_robot
    from metasheet.sheet.geometry import SheetParams

    sheets = SheetPair.spiral(SheetParams(mesh_size=14))
    return sheets, six_dof_robot(sheets, paper.PAPER_FOAM, density=paper.FOAM_DENSITY)


@pytest.fixture(scope="module")
def path3(pair14):
    """Rest equilibrium, then all motors +3 and +6 deg: three states."""
    from metasheet.robot.equilibrium import solve_equilibrium

    robot = pair14[1]
    th0 = robot.coupling.rest_angles
    rest = solve_equilibrium(robot, th0, tol=1e-10).state
    s1 = solve_equilibrium(robot, th0 + np.radians(3.0), state=rest).state
    s2 = solve_equilibrium(robot, th0 + np.radians(6.0), state=s1).state
    return [rest, s1, s2]


def world_fibers(sheets):
    """(m, 3) the sheets' fibres in the world frame (sheet A's elements first)."""
    f = np.vstack([sheets.fibers @ Q_A.T, sheets.fibers_mirrored @ Q_B.T])
    return f / np.linalg.norm(f, axis=1, keepdims=True)


def same_axes(f, g):
    """Largest difference between axes f and g (m, 3), each up to its sign."""
    s = np.sign(np.einsum("ij,ij->i", f, g))
    return float(np.abs(f - s[:, None] * g).max())


def test_pvd_holds_the_steps_and_positions(pair14, path3, tmp_path):
    robot = pair14[1]
    times = [0.0, 0.1, 0.30000000000000004]
    pvd = write_robot_series(robot, path3, times, tmp_path)
    assert pvd == tmp_path / "path.pvd"
    steps = read_series(pvd)
    assert [t for t, _ in steps] == times  # repr-exact time steps
    assert all(sorted(parts) == [0, 1, 2, 3] for _, parts in steps)
    assert pv.PVDReader(str(pvd)).time_values == times
    for (_, parts), st in zip(steps, path3):
        m = meshio.read(parts[0])
        assert np.array_equal(m.points, st.x)
        assert np.array_equal(m.point_data["displacement"], st.x - robot.coupling.rest)
        assert np.array_equal(m.cells_dict["tetra"], robot.body.tets)
        n_a = robot.info["n_tets_per_sheet"][0]
        assert np.array_equal(m.cell_data["sheet"][0], np.repeat([0, 1], [n_a, len(robot.body.tets) - n_a]))
    # the strain grows with the stroke; the same inputs give the same bytes
    strain = [meshio.read(p[0]).cell_data["max_principal_strain"][0].max() for _, p in steps]
    assert 0 < strain[1] < strain[2]
    again = write_robot_series(robot, path3, times, tmp_path / "again")
    files = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*") if p.is_file() and "again" not in p.parts)
    assert len(files) == 1 + 3 * len(PARTS)
    assert all((tmp_path / f).read_bytes() == (again.parent / f).read_bytes() for f in files)


def test_rest_fibers_strain_and_horns(pair14, tmp_path):
    sheets, robot = pair14
    c = robot.coupling
    angles = c.rest_angles + np.radians(np.array([3.0, -4.0, 5.0, 0.0, 7.0, -2.0]))
    moved = RobotState(c.origin.copy(), np.eye(3), angles, c.rest.copy())  # horns only: not an equilibrium
    (_, rest), (_, turned) = read_series(write_robot_series(robot, [robot.rest_state(), moved], [0.0, 1.0], tmp_path))
    m = meshio.read(rest[0])
    fib = m.cell_data["fiber"][0]
    assert same_axes(fib, world_fibers(sheets)) < 1e-12
    assert np.abs(m.cell_data["max_principal_strain"][0]).max() < 1e-12
    # horn tip = pivot + horn h(theta), h = -cos(theta) u_k + sin(theta) n (robots.py's convention)
    h = meshio.read(turned[3])
    tips = h.points[1::2]
    for k, s in enumerate(c.servos):
        Q, sheet = (Q_A, sheets.sheet) if k < 3 else (Q_B, sheets.mirrored)
        phi = sheet.arm_angles[k % 3]
        u, n = Q @ [np.cos(phi), np.sin(phi), 0.0], Q[:, 2]
        assert np.allclose(h.points[2 * k], s.pivot, atol=1e-12)
        assert np.allclose(tips[k], s.pivot + s.horn_length * (-np.cos(angles[k]) * u + np.sin(angles[k]) * n),
                           atol=1e-9)
    assert np.allclose(h.cell_data["angle_deg"][0], np.degrees(angles))


def test_rigid_motion(pair14, tmp_path):
    robot = pair14[1]
    c = robot.coupling
    Q = _rotation([0.3, -0.5, 0.8], 0.4)
    t = np.array([5.0, -3.0, 2.0])
    state = RobotState(Q @ c.origin + t, Q, c.rest_angles.copy(), c.rest @ Q.T + t)
    maze = MazePlate(path=((0.0, 0.0), (30.0, 0.0), (30.0, 25.0)))
    (_, rest), (_, moved) = read_series(write_robot_series(robot, [robot.rest_state(), state], [0.0, 0.5], tmp_path,
                                                           "rigid", maze=maze))
    m0, m1 = meshio.read(rest[0]), meshio.read(moved[0])
    assert np.abs(m1.cell_data["max_principal_strain"][0]).max() < 1e-12
    assert np.abs(m1.cell_data["fiber"][0] - m0.cell_data["fiber"][0] @ Q.T).max() < 1e-12
    for k in (1, 2):  # the rod and the maze
        a, b = meshio.read(rest[k]).points, meshio.read(moved[k]).points
        assert np.abs(b - (a @ Q.T + t)).max() < 1e-12
    rod = meshio.read(rest[1]).points
    centres = np.asarray(robot.info["sheet_centres_mm"])
    assert np.array_equal(rod[:2], centres)
    assert np.linalg.norm(rod[1] - rod[0]) == pytest.approx(robot.info["rod_length_mm"])
    plate = meshio.read(rest[2])
    assert np.ptp(plate.points[:8], axis=0) == pytest.approx(maze.size)
    assert np.allclose(plate.points[8:, :2], np.array(maze.path) + maze.centre[:2])  # the path in the x-y plane
    assert len(plate.cells_dict["line"]) == 2


def _rotation(axis, angle):
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def test_p2_written_as_tetra10(tmp_path):
    from metasheet.published import paper
    from metasheet.robot.builder import SheetPair, six_dof_robot
    from metasheet.sheet.geometry import SheetParams

    sheets = SheetPair.spiral(SheetParams(mesh_size=16), element="p2")
    robot = six_dof_robot(sheets, paper.PAPER_FOAM, density=paper.FOAM_DENSITY)
    (_, parts), = read_series(write_robot_series(robot, [robot.rest_state()], [0.0], tmp_path))
    m = meshio.read(parts[0])
    cells = m.cells_dict["tetra10"]
    assert np.array_equal(np.sort(cells, axis=1), np.sort(robot.body.tets, axis=1))
    assert np.array_equal(cells[:, :4], robot.body.tets[:, :4])
    x = m.points  # VTK's midpoint order: edges 01, 12, 20, 03, 13, 23
    for k, (i, j) in enumerate([(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]):
        assert np.allclose(x[cells[:, 4 + k]], 0.5 * (x[cells[:, i]] + x[cells[:, j]]), atol=1e-9)
    grid = pv.read(parts[0])
    assert set(np.unique(grid.celltypes)) == {pv.CellType.QUADRATIC_TETRA}
    assert same_axes(m.cell_data["fiber"][0], world_fibers(sheets)) < 1e-12


def test_reduced_state_uses_the_robots_positions(pair14, path3, tmp_path):
    """A reduced robot's states have no ``x``: the series takes the robot's positions."""
    robot = pair14[1]
    st = path3[1]
    reduced = SimpleNamespace(body=robot.body, coupling=robot.coupling, info=robot.info, name="r", full=robot,
                              basis=None, positions=lambda s: st.x)
    state = SimpleNamespace(p=st.p, R=st.R, angles=st.angles, a=np.zeros(3))
    (_, parts), = read_series(write_robot_series(reduced, [state], [2.0], tmp_path))
    assert np.array_equal(meshio.read(parts[0]).points, st.x)


@pytest.mark.parametrize("change, field", [
    (dict(states=[]), "states"),
    (dict(times=[0.0, 1.0]), "times"),
    (dict(times=[0.0, 1.0, 1.0]), "times[2]"),
    (dict(times=[0.0, np.nan, 2.0]), "times[1]"),
    (dict(bad_state=True), "states[1]"),
    (dict(name="a/b"), "name"),
    (dict(maze="plate"), "maze"),
])
def test_bad_inputs(pair14, path3, tmp_path, change, field):
    robot = pair14[1]
    states = list(change.get("states", path3))
    if change.get("bad_state"):
        s = states[1]
        states[1] = RobotState(s.p, s.R, s.angles, s.x[:-1])
    with pytest.raises(ConfigError, match="^" + re.escape(field)):
        write_robot_series(robot, states, change.get("times", [0.0, 1.0, 2.0]), tmp_path,
                           change.get("name", "path"), maze=change.get("maze"))
    assert not any(tmp_path.iterdir())


def test_rewrite_replaces_the_series(pair14, path3, tmp_path, monkeypatch):
    robot = pair14[1]
    write_robot_series(robot, path3, [0.0, 1.0, 2.0], tmp_path)
    write_robot_series(robot, path3[:2], [0.0, 1.0], tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["path", "path.pvd"]  # no temporary folder
    assert len(list((tmp_path / "path").iterdir())) == 2 * len(PARTS)  # no step of the first series
    before = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    calls = []

    def failing(*args, **kw):  # a run cut short at its sixth file
        calls.append(1)
        if len(calls) == 6:
            raise KeyboardInterrupt
        return write(*args, **kw)

    write = meshio.write
    monkeypatch.setattr(meshio, "write", failing)
    with pytest.raises(KeyboardInterrupt):
        write_robot_series(robot, path3, [0.0, 1.0, 2.0], tmp_path)
    assert {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["path", "path.pvd"]
