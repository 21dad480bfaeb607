"""Fibre streaks (metasheet/viz/streaks.py) against fields whose integral curves are known."""

import numpy as np
import pytest

from metasheet.viz.streaks import streak_lines

XS = YS = np.linspace(-10.0, 10.0, 81)
X, Y = np.meshgrid(XS, YS)


def test_a_uniform_field_gives_straight_streaks_of_the_asked_length():
    a = np.radians(30.0)
    U, V = np.full_like(X, np.cos(a)), np.full_like(X, np.sin(a))
    lines = streak_lines(XS, YS, U, V, spacing=2.0, length=0.8)
    assert len(lines) > 50
    for line in lines:
        seg = np.diff(line, axis=0)
        np.testing.assert_allclose(np.arctan2(seg[:, 1], seg[:, 0]), a, atol=1e-12)
    inner = [line for line in lines if np.abs(line).max() < 8.0]  # away from the grid's edge
    assert inner and all(np.linalg.norm(line[-1] - line[0]) == pytest.approx(1.6, rel=1e-12) for line in inner)


def test_circles_stay_circles_whatever_the_sign_of_the_axis_field():
    """The field (-y, x) / r with its sign flipped at random texels (an axis field: f and -f
    are one fibre): each streak stays on its seed's circle (the midpoint rule's error on a
    bilinear field, 2 % of the radius here, and none beyond it) and never turns back."""
    r = np.hypot(X, Y)
    flip = np.where(np.random.default_rng(0).random(X.shape) < 0.5, -1.0, 1.0)
    inside = (r > 2.0) & (r < 9.0)
    U = np.where(inside, -Y / np.maximum(r, 1e-9) * flip, np.nan)
    V = np.where(inside, X / np.maximum(r, 1e-9) * flip, np.nan)
    lines = streak_lines(XS, YS, U, V, spacing=1.5, length=1.2)
    assert len(lines) > 40
    for line in lines:
        rad = np.hypot(*line.T)
        assert np.ptp(rad) < 0.02 * rad.mean() + 0.05
        seg = np.diff(line, axis=0)
        assert np.all(np.sum(seg[1:] * seg[:-1], axis=1) > 0)  # no reversal at a flipped texel


def test_streaks_end_where_the_field_ends():
    U = np.where(X < 0, 1.0, np.nan)
    V = np.zeros_like(X)
    for line in streak_lines(XS, YS, U, V, spacing=2.0, length=3.0):
        assert line[:, 0].max() <= 0.0 + 1e-12 and np.all(np.isfinite(line))
