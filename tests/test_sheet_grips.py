"""The sheet condensed onto its four grips (metasheet.sheet.grips, issue 44) on coarse meshes
(15 mm sheets, 1,178 tets; P1 and P2)."""

import metasheet  # noqa: F401  (pins numpy's code paths before numpy is imported)

# isort: split
import numpy as np
import pytest

from metasheet.published import paper
from metasheet.errors import ConfigError
from metasheet.mechanics.material import Isotropic
from metasheet.robot.builder import SheetPair, material_stiffness
from metasheet.sheet.grips import (
    GRIPS,
    eigen_pairs,
    eigen_ratios,
    fem_condensed,
    full_from_relative,
    global_rigid_modes,
    grip_references,
    readable_compliances,
    reflect_grip_stiffness,
    relative_stiffness,
    rigid_defect,
    rigid_modes,
)
from metasheet.sheet.outline import ARM_ANGLES, SheetParams


@pytest.fixture(scope="module")
def sheets():
    return SheetPair.spiral(SheetParams(mesh_size=15.0), pitch_deg=30.0)


@pytest.fixture(scope="module", params=["p1", "p2"])
def condensed(request, sheets):
    """Sheet A and its mirror B condensed, with the foam along the spiral (anisotropic)."""
    Ca = material_stiffness(paper.PAPER_FOAM, sheets.fibers)
    Cb = material_stiffness(paper.PAPER_FOAM, sheets.fibers_mirrored)
    return (fem_condensed(sheets.sheet, Ca, request.param),
            fem_condensed(sheets.mirrored, Cb, request.param))


def _scaled(K, L):
    """K with rotations counted as arc lengths at radius L [mm] (one unit for all entries)."""
    d = np.tile(np.r_[np.ones(3), np.full(3, L)], len(K) // 6)
    return K / d[:, None] / d[None, :]


def test_references_and_rigid_modes():
    p = SheetParams(mesh_size=15.0)
    r = grip_references(p)
    assert r.shape == (4, 3) and len(GRIPS) == 4
    assert np.allclose(r[0], 0) and np.allclose(np.linalg.norm(r[1:], axis=1), p.reach)
    assert np.allclose(np.arctan2(r[1:, 1], r[1:, 0]) % (2 * np.pi), ARM_ANGLES)
    m = rigid_modes(np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 2.0]]), np.zeros(3))
    assert np.allclose(m[0, :, 5], [0, 1, 0])  # theta_z at (1, 0, 0): moves along +y
    assert np.allclose(m[1, :, 3], [0, -2, 0])  # theta_x at (0, 0, 2): moves along -y
    assert np.allclose(m[:, :, :3], np.eye(3))
    G = global_rigid_modes(r)  # body b's coordinates of a rotation about z through the origin
    assert np.allclose(G[6:9, 5], np.cross([0, 0, 1], r[1]))


def test_condensed_sheet_is_symmetric_psd_with_six_rigid_modes(condensed):
    for cs in condensed:
        K = cs.K
        assert K.shape == (24, 24) and cs.n_dof > 0 and cs.seconds > 0
        assert np.array_equal(K, K.T)
        L = float(np.linalg.norm(cs.references[1]))
        w = np.linalg.eigvalsh(_scaled(K, L))
        assert np.all(np.abs(w[:6]) < 1e-10 * w[-1])  # the six global rigid motions
        assert w[6] > 1e-6 * w[-1]  # nothing else is free
        assert rigid_defect(K, cs.references) < 1e-11


def test_full_from_relative_inverts_relative_stiffness(condensed):
    for cs in condensed:
        K, r = cs.K, cs.references
        Kr = relative_stiffness(K, r)
        assert Kr.shape == (18, 18)
        L = float(np.linalg.norm(r[1]))
        back = _scaled(full_from_relative(Kr, r), L)
        assert np.abs(back - _scaled(K, L)).max() < 1e-9 * np.abs(_scaled(K, L)).max()


def test_mirrored_sheet_is_the_reflection(condensed):
    """mirror_sheet reflects y -> -y and swaps the tags of arms 1 and 2: B's K is A's with
    t_y, theta_x, theta_z flipped and bodies 2 and 3 traded."""
    a, b = condensed
    assert np.array_equal(a.references, b.references)
    L = float(np.linalg.norm(a.references[1]))
    Ka, Kb = _scaled(reflect_grip_stiffness(a.K), L), _scaled(b.K, L)
    assert np.abs(Ka - Kb).max() < 1e-9 * np.abs(Kb).max()
    # and the spiral sheet is chiral: the mirror is not the sheet itself
    assert np.abs(_scaled(a.K, L) - Kb).max() > 1e-3 * np.abs(Kb).max()


def test_eigen_ratios(condensed):
    K, r = condensed[0].K, condensed[0].references
    assert np.allclose(eigen_ratios(K, K, r), 1.0, rtol=0, atol=1e-9)
    assert np.allclose(eigen_ratios(2.0 * K, K, r), 2.0, rtol=0, atol=2e-9)
    pairs = eigen_pairs(K, condensed[1].K, r)  # A against its mirror: same ratios in pairs
    assert pairs.ratios.shape == (18,) and pairs.modes.shape == (18, 18)
    assert np.all(np.diff(pairs.ratios) >= 0)
    # reciprocal: the ratios of b over a are those of a over b inverted
    back = eigen_ratios(condensed[1].K, K, r)
    assert np.allclose(np.sort(1.0 / back), pairs.ratios, rtol=1e-8)


def test_readable_compliances_scale_as_inverse_modulus(sheets):
    out = []
    for E in (1.0, 2.0):
        cs = fem_condensed(sheets.sheet, Isotropic(E, 0.3).stiffness(), "p1")
        out.append(readable_compliances(cs.K))
    one, two = out
    for key, v in one.items():
        assert v > 0, key
        assert abs(two[key] - 0.5 * v) < 1e-9 * v, key
    assert abs(one["roll_deg_per_Nmm"] - np.degrees(one["roll_rad_per_Nmm"])) < 1e-12 * one["roll_deg_per_Nmm"]
    # the 3-fold symmetric isotropic sheet: no in-plane direction is preferred
    assert abs(one["in_plane_x_mm_per_N"] - one["in_plane_y_mm_per_N"]) < 0.05 * one["in_plane_x_mm_per_N"]
    assert abs(one["tilt_x_rad_per_Nmm"] - one["tilt_y_rad_per_Nmm"]) < 0.05 * one["tilt_x_rad_per_Nmm"]


def test_bad_shapes_name_the_argument(sheets, condensed):
    K, r = condensed[0].K, condensed[0].references
    with pytest.raises(ConfigError, match="C:"):
        fem_condensed(sheets.sheet, np.eye(5), "p1")
    with pytest.raises(ConfigError, match="element"):
        fem_condensed(sheets.sheet, np.eye(6), "p3")
    with pytest.raises(ConfigError, match="references"):
        fem_condensed(sheets.sheet, np.eye(6), "p1", references=np.zeros((3, 3)))
    with pytest.raises(ConfigError, match="K:"):
        relative_stiffness(K[:23], r)
    with pytest.raises(ConfigError, match="K_rel"):
        full_from_relative(K, r)
    with pytest.raises(ConfigError, match="K_b"):
        eigen_ratios(K, K[:, :20], r)
    with pytest.raises(ConfigError, match="K_b"):
        eigen_ratios(K, np.zeros((24, 24)), r)  # not positive definite
    with pytest.raises(ConfigError, match="references"):
        relative_stiffness(K, r[:3])
    with pytest.raises(ConfigError, match="K:"):
        readable_compliances(np.zeros((24, 24)))
    with pytest.raises(ConfigError, match="params"):
        grip_references(None)
