"""The one 6-DOF builder: per-element constants and a uniform material give the same robot,
isotropic materials skip the fibres, and bad inputs name their field."""

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.mechanics.material import Isotropic, interpolate
from metasheet.published.paper import FOAM_DENSITY, PAPER_FOAM
from metasheet.robot.builder import SheetPair, element_stiffness, material_stiffness, six_dof_robot
from metasheet.sheet.geometry import SheetParams


@pytest.fixture(scope="module")
def sheets():
    return SheetPair.spiral(SheetParams(mesh_size=15.0))


def test_element_constants_equal_the_uniform_material(sheets):
    m = len(sheets.sheet.tets)
    consts = np.tile(PAPER_FOAM.as_tuple(), (m, 1))
    C_elem = element_stiffness(sheets.fibers, consts)
    C_mat = material_stiffness(PAPER_FOAM, sheets.fibers)
    assert np.array_equal(C_elem, C_mat)  # one group, the exact constants: the same tensors
    graded = SheetPair(sheets.sheet, sheets.mirrored, sheets.fibers, sheets.fibers_mirrored, consts,
                       np.tile(PAPER_FOAM.as_tuple(), (len(sheets.mirrored.tets), 1)))
    a = six_dof_robot(graded, density=FOAM_DENSITY)
    b = six_dof_robot(sheets, PAPER_FOAM, density=FOAM_DENSITY)
    assert np.array_equal(a.body.stiffness, b.body.stiffness)
    assert a.info == b.info


def test_two_groups_keep_their_own_constants(sheets):
    m = len(sheets.sheet.tets)
    soft = interpolate(PAPER_FOAM, 50.0)
    consts = np.tile(PAPER_FOAM.as_tuple(), (m, 1))
    consts[::2] = soft.as_tuple()
    C = element_stiffness(sheets.fibers, consts)
    assert np.array_equal(C[::2], material_stiffness(soft, sheets.fibers[::2]))
    assert np.array_equal(C[1::2], material_stiffness(PAPER_FOAM, sheets.fibers[1::2]))


def test_isotropic_limit_ignores_fibres(sheets):
    iso = interpolate(PAPER_FOAM, 0.0)  # transverse-isotropic form of an isotropic material
    rob = six_dof_robot(sheets, iso, density=FOAM_DENSITY)
    C = Isotropic(iso.E_t, iso.nu_t).stiffness()
    n_a = len(sheets.sheet.tets)
    # sheet A's stiffness is the isotropic tensor rotated to the world frame: the same for every element
    assert np.allclose(rob.body.stiffness[:n_a], rob.body.stiffness[0], rtol=0, atol=1e-15)
    assert np.isclose(np.trace(rob.body.stiffness[0]), np.trace(C), rtol=1e-12)


def test_bad_inputs_name_their_field(sheets):
    with pytest.raises(ConfigError, match="per-element constants"):
        six_dof_robot(sheets, density=FOAM_DENSITY)
    with pytest.raises(ConfigError, match="fibers: shape"):
        SheetPair(sheets.sheet, sheets.mirrored, sheets.fibers[:-1], sheets.fibers_mirrored)
    with pytest.raises(ConfigError, match="constants_mirrored: shape"):
        SheetPair(sheets.sheet, sheets.mirrored, sheets.fibers, sheets.fibers_mirrored,
                  np.zeros((len(sheets.sheet.tets), 5)), np.zeros((3, 5)))
    with pytest.raises(ConfigError, match="material: str"):
        six_dof_robot(sheets, "foam", density=FOAM_DENSITY)
