"""The linearisation memo (metasheet/robot/memo.py): an equal state gets the same bits back."""

from dataclasses import replace

import numpy as np

from metasheet.robot.memo import LinearizationMemo, state_key


def test_a_repeated_state_gets_the_same_linearisation_and_counts_a_factorisation(foam_robot_14, foam_rest_14):
    lz = foam_robot_14.linearizer()
    st = foam_rest_14.state
    a = lz.linearize(st)
    twin = replace(st, x=st.x.copy())  # equal arrays, another object
    n = lz.factorizations
    b = lz.linearize(twin)
    assert lz.memo.hits == 1 and lz.factorizations == n + 1
    assert b.state is twin  # the caller's state: identity tests (kept tangents) see their own
    for f in ("r", "S", "Y", "y_r", "C", "R_rigid", "res_e", "res_f"):
        assert np.array_equal(getattr(a, f), getattr(b, f))
    moved = replace(st, x=st.x + 1e-9)
    lz.linearize(moved)
    assert lz.memo.hits == 1  # another state: computed


def test_the_memo_keeps_the_newest_within_its_size_and_bytes():
    m = LinearizationMemo(size=2, max_bytes=100)
    for k in (b"a", b"b", b"c"):
        m.put(k, k.decode(), 10)
    assert m.get(b"a") is None and m.get(b"c") == "c" and len(m) == 2
    m.put(b"d", "d", 95)  # over the budget with the others: they go
    assert len(m) == 1 and m.get(b"d") == "d"
    m.put(b"e", "e", 101)  # larger than the budget: not kept
    assert m.get(b"e") is None
    off = LinearizationMemo(size=0)
    off.put(b"a", "a")
    assert off.get(b"a") is None


def test_the_key_tells_the_exact_flag_and_the_arrays_apart(foam_rest_14):
    st = foam_rest_14.state
    assert state_key(st, True) != state_key(st, False)
    assert state_key(st, True) == state_key(replace(st, x=st.x.copy()), True)
    assert state_key(st, True) != state_key(replace(st, angles=st.angles + 1e-12), True)
