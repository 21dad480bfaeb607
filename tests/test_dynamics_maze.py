"""The maze's corridor and walls (metasheet.dynamics.maze_geometry) and its picture
(metasheet.viz.marble): exact walls of an L, inside/outside, progress along the centre line,
a revisiting path, the JSON round trip, validation."""

import json

import numpy as np
import pytest

from metasheet.dynamics.maze_geometry import (MazeGeometry, centerline_progress, from_json, inside_corridor,
                                              maze_from_path, plate_bounds, to_json)
from metasheet.errors import ConfigError
from metasheet.pipeline.stages.maze import DEFAULT_PATH
from metasheet.viz.marble import maze_picture

L_PATH = [(0.0, 0.0), (40.0, 0.0), (40.0, 30.0)]
TOL = 1e-6  # [mm] Clipper2 rounds to 1e-8 mm


@pytest.fixture(scope="module")
def ell():
    return maze_from_path(L_PATH, width=20.0, wall_height=6.0, margin=5.0)


def _undirected(segments):
    return sorted(tuple(sorted(map(tuple, np.round(s, 6).tolist()))) for s in segments)


def test_l_walls_are_the_corridor_outline(ell):
    # the outline of the two extended rectangles: the outer corner square, the end caps
    corners = [(50, -10), (50, 40), (30, 40), (30, 10), (-10, 10), (-10, -10)]
    expected = [(corners[i], corners[(i + 1) % 6]) for i in range(6)]
    assert len(ell.walls) == 6
    assert _undirected(ell.walls) == _undirected(np.array(expected, float))
    np.testing.assert_allclose(ell.plate, [70.0, 60.0], atol=TOL)  # (60, 50) bbox + 2 x 5
    np.testing.assert_allclose(plate_bounds(ell), [[-15, -15], [55, 45]], atol=TOL)


def test_l_walls_at_half_width_and_corridor_on_their_left(ell):
    from metasheet.dynamics.maze_geometry import segment_distances

    # every point of the centre line away from the corner is 10 mm from the nearest wall
    for p in [(10.0, 0.0), (25.0, 0.0), (40.0, 15.0), (40.0, 25.0)]:
        assert segment_distances(np.array([p]), ell.walls)[0].min() == pytest.approx(10.0, abs=TOL)
    a, b = ell.walls[:, 0], ell.walls[:, 1]
    d = (b - a) / np.linalg.norm(b - a, axis=1)[:, None]
    left = (a + b) / 2 + 0.1 * np.column_stack([-d[:, 1], d[:, 0]])
    assert inside_corridor(ell, left).all()


def test_inside_corridor(ell):
    pts = [(20, 0), (40, 20), (45, -5), (-5, 5), (20, 15), (60, 0), (35, 35), (-11, 0)]
    np.testing.assert_array_equal(inside_corridor(ell, pts), [1, 1, 1, 1, 0, 0, 1, 0])


def test_progress_along_an_l_is_exact(ell):
    pts = [(0, 0), (20, 0), (20, 3), (40, 0), (40, 15), (45, 25), (40, 30), (-5, 0)]
    np.testing.assert_allclose(centerline_progress(ell, pts), [0, 20, 20, 40, 55, 65, 70, 0], atol=1e-12)


def test_a_revisiting_path_gives_a_corridor_with_an_island():
    g = maze_from_path(DEFAULT_PATH)
    path = np.array(DEFAULT_PATH)
    assert inside_corridor(g, path).all()
    # the island inside the loop is no corridor; the first and last corridors overlap at the start
    assert not inside_corridor(g, [(5.0, 12.5)])[0]
    # the centre line sampled from start to end: tracked progress runs the whole length while
    # the plain closest point at the end (= the start) reads 0
    seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
    pts = np.concatenate([a + np.linspace(0, 1, 40, endpoint=False)[:, None] * (b - a)
                          for a, b in zip(path[:-1], path[1:])] + [path[-1:]])
    tracked = centerline_progress(g, pts, track=True)
    assert np.all(np.diff(tracked) > 0)
    assert tracked[-1] == pytest.approx(seg.sum(), abs=1e-9)
    assert centerline_progress(g, pts[-1:])[0] == 0.0


def test_json_round_trip(ell, tmp_path):
    f = tmp_path / "maze.json"
    f.write_text(json.dumps(to_json(ell)))
    back = from_json(json.loads(f.read_text()))
    for name in ("path", "plate", "walls"):
        np.testing.assert_array_equal(getattr(back, name), getattr(ell, name))
    assert (back.width, back.wall_height) == (ell.width, ell.wall_height)


def test_picture_is_a_png(ell, tmp_path):
    u = np.column_stack([np.linspace(0, 40, 50), np.zeros(50)])
    png = maze_picture(ell.path, ell.walls, ell.plate, u, file=tmp_path / "maze.png", times=np.linspace(0, 1, 50))
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    assert (tmp_path / "maze.png").read_bytes() == png
    assert maze_picture(ell.path, ell.walls, ell.plate)[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("kwargs, match", [
    ({"path": [(0, 0)]}, "path: shape"),
    ({"path": [(0, 0), (0, 0), (1, 0)]}, "path: segment 0 has zero length"),
    ({"path": L_PATH, "width": 0.0}, r"width: 0.0: allowed range is \(0, inf\]"),
    ({"path": L_PATH, "margin": -1.0}, r"margin: -1.0: allowed range is \[0, inf\]"),
])
def test_maze_validation(kwargs, match):
    with pytest.raises(ConfigError, match=match):
        maze_from_path(**kwargs)


def test_geometry_validation():
    with pytest.raises(ConfigError, match="maze.json: missing walls"):
        from_json({"path": L_PATH, "width": 20, "wall_height": 6, "plate": [1, 1]})
    with pytest.raises(ConfigError, match="plate"):
        MazeGeometry(np.array(L_PATH), plate=(1.0, -1.0))
