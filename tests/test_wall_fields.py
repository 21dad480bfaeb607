"""The walls' fields kept from the sheet's DNS (metasheet/sheet/wall_fields.py): every grip
motion's field from the 18 relative columns and the centre's rigid motion, against solving all 24
(a second solve); the stiffness untouched by keeping them; the file's round trip and its checks."""

import numpy as np
import pytest

from metasheet.cells.foam import voxel_centres
from metasheet.errors import ConfigError
from metasheet.mechanics.material import Isotropic
from metasheet.sheet.dns import grip_labels
from metasheet.sheet.grips import grip_references
from metasheet.sheet.printed_foam import tripod_region
from metasheet.sheet.voxel_grips import held_solid, rigid_bodies_stiffness
from metasheet.sheet.wall_fields import WallFields
from metasheet.sheet.wall_limits import MotorWalls, SheetWalls

from test_wall_limits import SMALL


@pytest.fixture(scope="module")
def solved():
    """The small tripod with holes at 1 mm voxels, solved three ways: K only, the 18 relative
    fields, all 24 fields."""
    reg = tripod_region(SMALL)
    ext = reg.hi - reg.lo
    shape = tuple(int(v) for v in np.maximum(1, np.round(ext / 1.0)))
    x = reg.lo + voxel_centres(ext, np.array(shape))
    inside = reg.inside(x).reshape(shape)
    holes = (np.sin(1.3 * x[:, 0]) * np.sin(1.1 * x[:, 1]) > 0.6).reshape(shape)  # voids between walls
    phases = (inside & ~holes).astype(np.int64)
    h = ext / np.array(shape)
    bodies = grip_labels(shape, reg.lo, h, SMALL)
    refs = grip_references(SMALL) - reg.lo
    kw = dict(bodies=bodies, references=refs, rtol=1e-10)
    C = {1: Isotropic(12.0, 0.3).stiffness()}
    plain = rigid_bodies_stiffness(phases, ext, C, **kw)
    rel = rigid_bodies_stiffness(phases, ext, C, displacements="relative", **kw)
    full = rigid_bodies_stiffness(phases, ext, C, displacements=True, **kw)
    solid = held_solid(phases > 0, bodies > 0)
    fields = WallFields.from_solve(solid, h, rel.U, refs, bodies, {"label": "normal", "seed": 1})
    return plain, rel, full, SheetWalls(solid, h, full.U), fields


def test_keeping_the_fields_leaves_the_stiffness_bit_for_bit(solved):
    plain, rel, full, _, _ = solved
    assert rel.U.shape[-1] == 18 and full.U.shape[-1] == 24
    assert np.array_equal(plain.K, rel.K)
    assert np.allclose(full.K, plain.K, rtol=0, atol=1e-7 * np.abs(plain.K).max())


def test_every_grip_motions_field_from_the_relative_ones(solved):
    _, _, _, walls, fields = solved
    rng = np.random.default_rng(5)
    G = rng.normal(size=(24, 6))
    want, got = walls.per_motor(G), fields.per_motor(G)
    on = np.zeros(want.shape[:3], bool)
    on.ravel()[fields.nodes] = True
    assert not got[~on].any()
    tied = np.zeros_like(on)
    tied.ravel()[fields.nodes[fields.body > 0]] = True
    assert tied.any() and (on & ~tied).any()
    assert np.allclose(got[tied], want[tied], rtol=0, atol=1e-12 * np.abs(want).max())  # with its grip, exactly
    # the CG tolerance (1e-10) and float32's rounding of the kept fields
    assert np.abs(got[on] - want[on]).max() <= 1e-6 * np.abs(want[on]).max()
    assert np.array_equal(fields.solid, walls.solid)
    a, b = MotorWalls.from_fields(walls, G), MotorWalls.from_fields(fields, G)
    d = np.array([1.0, 1.0, 1.0, -0.5, 0.2, 0.0])
    assert b.strain_travel(d, 0.3) == pytest.approx(a.strain_travel(d, 0.3), rel=1e-5)
    np.testing.assert_allclose(b.rates(), a.rates(), rtol=1e-5)


def test_a_rigid_motion_of_every_grip_moves_the_kept_walls_rigidly(solved):
    _, _, _, _, fields = solved
    refs = fields.references
    N = tuple(n + 1 for n in fields.shape)
    x = np.stack(np.unravel_index(fields.nodes, N), 1) * fields.h
    t, theta = np.array([0.1, -0.2, 0.3]), np.array([0.01, 0.02, -0.015])
    q = np.concatenate([np.r_[t + np.cross(theta, r - refs[0]), theta] for r in refs])  # about each grip's reference
    u = fields.per_motor(q[:, None]).reshape(-1, 3)[fields.nodes]
    want = t + np.cross(theta, x - refs[0])
    assert np.abs(u - want).max() <= 1e-6 * np.abs(want).max()


def test_the_file_round_trip_and_its_checks(solved, tmp_path):
    _, _, _, _, fields = solved
    path = tmp_path / "walls" / "normal-seed1.npz"
    fields.save(path)
    assert [p.name for p in path.parent.iterdir()] == ["normal-seed1.npz"]  # no temporary left
    back = WallFields.load(path, {"label": "normal", "seed": 1})
    for k in ("h", "solid_bits", "nodes", "body", "U", "references"):
        assert np.array_equal(getattr(back, k), getattr(fields, k)), k
    assert back.shape == fields.shape and back.meta == fields.meta
    with pytest.raises(ConfigError, match="seed is 1, the print asked has 2"):
        WallFields.load(path, {"seed": 2})


def test_a_bad_displacements_value_is_named():
    with pytest.raises(ConfigError, match="displacements: 'all'"):
        rigid_bodies_stiffness(np.ones((2, 2, 2), np.int64), np.ones(3), {1: Isotropic(12.0, 0.3).stiffness()},
                               bodies=np.ones((3, 3, 3), np.int64), references=np.zeros((1, 3)),
                               displacements="all")
