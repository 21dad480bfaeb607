"""The strain-validity check away from the grips (metasheet/robot/validity.py).

Independent answers: the band's elements are the ones a brute-force distance to every held
node puts within it; a zero band is the raw maximum; the banded maximum never exceeds it; a
band wider than the sheet is refused with the field's name.
"""

import numpy as np
import pytest

from metasheet.errors import ConfigError
from metasheet.robot.equilibrium import solve_equilibrium
from metasheet.robot.validity import grip_distance, validity_elements, validity_strain
from metasheet.studies.adapter import paper_robot_spec


@pytest.fixture(scope="module")
def robot():
    return paper_robot_spec(mesh_size=16.0).build().robot


def test_grip_distance_is_the_brute_force_nearest_held_node(robot):
    c, body = robot.coupling, robot.body
    held = np.concatenate([c.effector_nodes] + [s.nodes for s in c.servos])
    centroids = body.rest[body.tets[:, :4]].mean(axis=1)
    brute = np.sqrt(((centroids[:, None, :] - body.rest[held][None]) ** 2).sum(-1)).min(axis=1)
    np.testing.assert_allclose(grip_distance(robot), brute, rtol=0, atol=1e-9)
    keep = validity_elements(robot, 5.0)
    assert np.array_equal(keep, brute > 5.0)
    assert 0 < keep.sum() < len(keep)  # the band holds some elements, not all


def test_zero_band_is_the_raw_maximum_and_a_band_never_exceeds_it(robot):
    lz = robot.linearizer()
    st = solve_equilibrium(robot, robot.coupling.rest_angles + np.radians([-10, 5, 10, -10, 5, 10]),
                           linearizer=lz).state
    raw = robot.body.max_principal_strain(st.x)
    assert validity_strain(robot.body, st.x, validity_elements(robot, 0.0)) == raw.max()
    banded = validity_strain(robot.body, st.x, validity_elements(robot, 5.0))
    assert 0 < banded <= raw.max()


def test_a_band_over_the_whole_sheet_is_refused(robot):
    with pytest.raises(ConfigError, match="strain_band_mm"):
        validity_elements(robot, 500.0)
    with pytest.raises(ConfigError, match="strain_band_mm"):
        validity_elements(robot, -1.0)


@pytest.mark.parametrize("element", ["p1", "p2"])
def test_the_counted_elements_alone_give_the_full_arrays_entries(element):
    """The strain of the counted elements only (issue 59: the check on a fraction of the sheets)
    is the full array's entries bit for bit, whichever mask came before."""
    rob = paper_robot_spec(mesh_size=16.0, element=element).build().robot
    body = rob.body
    x = body.rest + np.random.default_rng(3).normal(size=body.rest.shape) * 0.3
    full = body.max_principal_strain(x)
    for band in (5.0, 2.0, 5.0):
        keep = validity_elements(rob, band)
        assert np.array_equal(body.max_principal_strain(x, keep), full[keep])
        assert validity_strain(body, x, keep) == full[keep].max()
