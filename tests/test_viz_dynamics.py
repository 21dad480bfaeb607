"""Pictures of the robot in motion (metasheet/viz/dynamics.py): the maze GIF, modes, steps, tracking."""

import io

import numpy as np
import pytest
from PIL import Image

from metasheet.errors import ConfigError
from metasheet.fem.meshes import box_mesh
from metasheet.viz.dynamics import (boundary_faces, maze_animation, modes_picture, step_picture,
                                    tracking_picture)

K = 3


def _scene(k=K):
    """Two thin boxes at x = -40 and +40 as fake sheets, a rod turning about x, a marble rolling."""
    p, t = box_mesh((2.0, 60.0, 60.0), (1, 2, 2))
    a = p - [1.0, 30.0, 30.0]
    pts = np.concatenate([a - [40.0, 0, 0], a + [40.0, 0, 0]])
    tets = np.concatenate([t, t + len(p)])
    ang = np.linspace(0.0, 0.15, k)
    R = np.stack([[[1, 0, 0], [0, np.cos(q), -np.sin(q)], [0, np.sin(q), np.cos(q)]] for q in ang])
    P = np.zeros((k, 3))
    P[:, 2] = 2.0 * ang
    X = np.stack([pts + [0.0, 0.0, 2.0 * q] for q in ang])
    marble = np.stack([P[i] + R[i] @ [-10.0 + 10.0 * i, 0.0, 14.0] for i in range(k)])
    kw = dict(walls=[[[-20, -8], [10, -8]], [[-10, 8], [20, 8]]], plate_lo=[-25, -18], plate_hi=[25, 18],
              top=10.0, rod_length=100.0, marble=marble, path=[[-20, 0], [0, 0], [20, 0]])
    return (tets, X, P, R, np.linspace(0.0, 0.2, k)), kw


def test_boundary_faces_of_one_tet_are_its_four_faces_pointing_out():
    x = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    f = boundary_faces([[0, 1, 2, 3]])
    assert sorted(map(tuple, np.sort(f, axis=1))) == [(0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)]
    n = np.cross(x[f[:, 1]] - x[f[:, 0]], x[f[:, 2]] - x[f[:, 0]])
    assert np.all(np.sum(n * (x[f].mean(axis=1) - x.mean(axis=0)), axis=1) > 0)


def test_boundary_faces_of_a_box_are_only_the_outer_triangles():
    """2 x 1 x 1 cells, 6 tets each: the outside has 2 (x) + 2 * 2 (y) + 2 * 2 (z) = 10 cell
    faces, 2 triangles each: 20; the 12 tets' 48 faces less 2 * 14 shared inner ones."""
    p, t = box_mesh((2.0, 1.0, 1.0), (2, 1, 1))
    f = boundary_faces(t)
    assert len(t) == 12 and len(f) == 20
    on_side = np.isclose(p[f], 0.0) | np.isclose(p[f], [2.0, 1.0, 1.0])  # (f, 3 nodes, 3 axes)
    assert np.all(np.any(np.all(on_side, axis=1), axis=1))  # each triangle lies in one outer plane
    q10 = np.hstack([t, np.zeros((len(t), 6), int)])  # a quadratic mesh: its vertices only
    np.testing.assert_array_equal(boundary_faces(q10), f)


def test_the_gif_has_one_frame_per_sample_at_the_window_size_and_is_reproducible():
    args, kw = _scene()
    gif = maze_animation(*args, **kw, window=(320, 240), title="test")
    im = Image.open(io.BytesIO(gif))
    assert im.format == "GIF" and im.n_frames == K and im.size == (320, 240)
    im.seek(K - 1)
    rgb = np.asarray(im.convert("RGB"))
    assert np.any(np.all(rgb == rgb[0, -1], axis=-1)) and len(np.unique(rgb.reshape(-1, 3), axis=0)) > 8
    assert maze_animation(*args, **kw, window=(320, 240), title="test") == gif


def test_the_gif_without_marble_path_or_walls():
    (tets, X, P, R, T), kw = _scene(2)
    kw.update(marble=None, path=None, walls=np.zeros((0, 2, 2)))
    im = Image.open(io.BytesIO(maze_animation(tets, X, P, R, T, **kw, window=(160, 120), fps=5)))
    assert im.n_frames == 2 and im.size == (160, 120) and im.info["duration"] == 200


@pytest.mark.parametrize("field", ["frames_x", "rod_p", "rod_R", "times", "marble", "path", "walls", "tets"])
def test_a_shape_mismatch_names_its_field(field):
    (tets, X, P, R, T), kw = _scene()
    bad = {"frames_x": X[:, :, :2], "rod_p": P[:2], "rod_R": R[:, :2], "times": T[:2], "tets": tets[:, :3],
           "marble": kw["marble"][:2], "path": [[0.0, 1.0, 2.0]], "walls": [[[0.0, 0.0, 0.0]]]}[field]
    args = dict(tets=tets, frames_x=X, rod_p=P, rod_R=R, times=T)
    (args if field in args else kw)[field] = bad
    with pytest.raises(ConfigError, match=field):
        maze_animation(args["tets"], args["frames_x"], args["rod_p"], args["rod_R"], args["times"], **kw)


def _png_size(png):
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    return Image.open(io.BytesIO(png)).size


def test_modes_picture_is_a_png_of_the_window_size():
    p, t = box_mesh((40.0, 40.0, 2.0), (2, 2, 1))
    shapes = np.stack([np.column_stack([0 * p[:, 0], 0 * p[:, 0], np.sin(k * p[:, 0] / 20.0) + 0.1])
                       for k in range(1, 5)])
    assert _png_size(modes_picture(p, t, shapes, [10.0, 20.0, 30.0, 40.0], window=(600, 400))) == (600, 400)
    w, h = _png_size(modes_picture(p, t, shapes, [10.0, 20.0, 30.0, 40.0], n_show=2, window=(600, 400),
                                   title="modes"))
    assert w == 600 and h > 400  # a title band above
    with pytest.raises(ConfigError, match="shapes"):
        modes_picture(p, t, shapes[:, :-1], [10.0, 20.0, 30.0, 40.0])
    with pytest.raises(ConfigError, match="frequencies_hz"):
        modes_picture(p, t, shapes, [10.0, 20.0])


def test_step_picture_is_a_png_and_checks_its_inputs():
    t = np.linspace(0.0, 0.1, 101)
    y = 1.0 - np.exp(-t / 0.01) * np.cos(t / 0.005)
    targets = np.array([1.0, 2.0, -1.0, 0.5, 0.5, 0.1])
    responses = targets[:, None] * y
    metrics = [dict(rise_s=0.004, overshoot_pct=12.5, settling_s=0.05)] * 5 + [
        dict(rise_s=None, overshoot_pct=None, settling_s=None)]
    labels = ["x [mm]", "y [mm]", "z [mm]", "rx [deg]", "ry [deg]", "rz [deg]"]
    w, h = _png_size(step_picture(t, responses, targets, labels, metrics, title="steps"))
    assert 900 < w < 1400 and 500 < h < 800
    with pytest.raises(ConfigError, match="responses"):
        step_picture(t, responses[:5], targets, labels, metrics)
    with pytest.raises(ConfigError, match="targets"):
        step_picture(t, responses, targets[:5], labels, metrics)
    with pytest.raises(ConfigError, match="metrics"):
        step_picture(t, responses, targets, labels, metrics[:1] * 5 + [dict(rise_s=0.0)])


def test_tracking_picture_is_a_png_and_checks_its_inputs():
    t = np.linspace(0.0, 2.0, 50)
    w, h = _png_size(tracking_picture(t, 0.1 * t, 0.5 * t, t[::2], 30.0 * t[::2], 60.0, title="run"))
    assert 700 < w < 1100 and 500 < h < 800
    with pytest.raises(ConfigError, match="gap_deg"):
        tracking_picture(t, t, t[1:], t, t, 60.0)
    with pytest.raises(ConfigError, match="marble_progress"):
        tracking_picture(t, t, t, t, t[1:], 60.0)
