"""Spiral fibre field: pitch, reflection, tilt, laws, against analytic answers."""

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.sheet.fibers import LAWS, fiber_angles, register_law, spiral_fibers


@pytest.fixture(scope="module")
def pts():
    rng = np.random.default_rng(7)
    r = rng.uniform(5, 70, 500)
    t = rng.uniform(-np.pi, np.pi, 500)
    return np.stack([r * np.cos(t), r * np.sin(t), rng.uniform(-2.5, 2.5, 500)], axis=1)


def _polar_parts(p, f):
    t = np.arctan2(p[:, 1], p[:, 0])
    e_r = np.stack([np.cos(t), np.sin(t), 0 * t], axis=1)
    e_t = np.stack([-np.sin(t), np.cos(t), 0 * t], axis=1)
    return np.einsum("ij,ij->i", f, e_r), np.einsum("ij,ij->i", f, e_t)


@pytest.mark.parametrize("pitch", [-60.0, 0.0, 30.0, 45.0, 90.0])
def test_log_spiral_has_constant_pitch(pts, pitch):
    f = spiral_fibers(pts, pitch_deg=pitch)
    assert np.allclose(np.linalg.norm(f, axis=1), 1.0, atol=1e-12)
    assert np.allclose(f[:, 2], 0.0)
    fr, ft = _polar_parts(pts, f)
    assert np.allclose(np.degrees(np.arctan2(fr, ft)), pitch, atol=1e-9)


def test_field_is_tangent_to_the_analytic_log_spiral():
    # r(t) = r0 exp(t tan(beta)): the curve's finite-difference tangent is the field
    beta, r0 = np.deg2rad(35.0), 6.0
    t = np.linspace(0.0, 2.5, 200)
    r = r0 * np.exp(t * np.tan(beta))
    curve = np.stack([r * np.cos(t), r * np.sin(t), 0 * t], axis=1)
    tangent = np.gradient(curve, t, axis=0, edge_order=2)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    f = spiral_fibers(curve, pitch_deg=35.0)
    assert np.allclose(f, tangent, atol=2e-4)


def test_mirrored_field_is_the_reflection(pts):
    M = np.diag([1.0, -1.0, 1.0])
    for kw in ({}, {"tilt_deg": 20.0}, {"law": "archimedean", "pitch_deg": 30.0}):
        f = spiral_fibers(pts, **kw)
        fm = spiral_fibers(pts @ M, mirrored=True, **kw)
        assert np.allclose(fm, f @ M, atol=1e-12)
    # and it is not a rotation of the original: the turning sense flips
    fr, ft = _polar_parts(pts, spiral_fibers(pts, pitch_deg=45.0, mirrored=True))
    assert np.allclose(np.degrees(np.arctan2(fr, -ft)), 45.0, atol=1e-9)


def test_tilt_lifts_the_fibre(pts):
    f = spiral_fibers(pts, tilt_deg=25.0)
    assert np.allclose(f[:, 2], np.sin(np.deg2rad(25.0)))
    _, phi = fiber_angles(f)
    assert np.allclose(np.degrees(phi), 25.0)


def test_archimedean_pitch_at_reference_radius():
    p = np.array([[20.0, 0, 0], [40.0, 0, 0], [80.0, 0, 0]])
    f = spiral_fibers(p, law="archimedean", pitch_deg=45.0, r_ref=40.0)
    beta = np.degrees(np.arctan2(f[:, 0], f[:, 1]))
    assert beta[1] == pytest.approx(45.0)
    assert np.allclose(np.tan(np.deg2rad(beta)), [2.0, 1.0, 0.5])  # tan(beta) = b / r


def test_pluggable_law(pts):
    register_law("ramp", lambda r, pitch, r_ref: np.clip(r / 70.0, 0, 1) * pitch)
    try:
        f = spiral_fibers(pts, law="ramp", pitch_deg=60.0)
        fr, ft = _polar_parts(pts, f)
        r = np.hypot(pts[:, 0], pts[:, 1])
        assert np.allclose(np.degrees(np.arctan2(fr, ft)), 60.0 * r / 70.0, atol=1e-9)
    finally:
        LAWS.pop("ramp")


def test_fiber_angles_round_trip(pts):
    f = spiral_fibers(pts, tilt_deg=-10.0)
    theta, phi = fiber_angles(f)
    back = np.stack([np.cos(phi) * np.cos(theta), np.cos(phi) * np.sin(theta), np.sin(phi)], axis=1)
    assert np.allclose(back, f)
    assert theta.min() >= 0 and theta.max() < 2 * np.pi


@pytest.mark.parametrize(
    "kw, field",
    [({"pitch_deg": 91}, "pitch_deg"), ({"tilt_deg": -95}, "tilt_deg"), ({"law": "helix"}, "law"),
     ({"r_ref": 0}, "r_ref")],
)
def test_bad_input(pts, kw, field):
    with pytest.raises(ConfigError, match=field):
        spiral_fibers(pts, **kw)
    with pytest.raises(ConfigError, match="centroids"):
        spiral_fibers(pts[:, :2])
