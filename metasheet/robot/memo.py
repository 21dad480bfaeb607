"""Fresh linearisations remembered by the content of the state they were taken at.

A linearisation (tangent, factorisation, Schur complement) is a pure function of the state's
arrays: taking it again at an equal state gives the same bits. The studies do that often: a
workspace point's Jacobian, then each of its rotation tries starting from the same state after
the previous try moved the kept tangent away; a reduced model's edge state lifted to the full
mesh once per try that leaves the box at its first step. Measured on the paper pipeline's
workspace study (3 rays per column): 206 of 1,036 full linearisations on the P1 5 mm robot,
8 of 30 full and 20 of 48 reduced ones on the converged P2 robot were repeats.

:class:`LinearizationMemo` keeps the last few, keyed by a digest of the state's arrays (and the
``exact`` flag), with their factor, within a memory budget (a factor of the converged P2 robot
holds ~50 MB). A hit hands back the same values as a recomputation, so results are unchanged.
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict

import numpy as np

#: Linearisations kept per linearizer [-] (the P1 5 mm robot: 8 catch 165 of its 206 repeats,
#: 1,000 all of them; its factor and Y hold ~4 MB).
MEMO_SIZE = 32
#: Bytes of factors kept per linearizer: two of the converged P2 robot's (~54 MB each), many P1
#: ones (a worker may hold a few models: :data:`metasheet.studies.model.MODELS`).
MEMO_BYTES = 120_000_000

_FIELDS = ("p", "R", "angles", "x", "a")  # a full RobotState's or a ReducedState's arrays


def state_key(state, exact: bool) -> bytes:
    """Digest (20 bytes) of ``state``'s arrays (p, R, angles and x or a) and the ``exact`` flag."""
    h = hashlib.blake2b(digest_size=20)
    h.update(b"e" if exact else b"i")
    for name in _FIELDS:
        a = getattr(state, name, None)
        if a is not None:
            a = np.ascontiguousarray(a, dtype=float)
            h.update(name.encode())
            h.update(np.asarray(a.shape, np.int64).tobytes())
            h.update(a.tobytes())
    return h.digest()


def factor_bytes(factor) -> int:
    """Rough size of a factor [bytes]: SuperLU's stored entries (value + index), else 0
    (dense reduced factors and CHOLMOD's are small or not ours to size)."""
    lu = getattr(getattr(factor, "_solve", None), "__self__", None)
    nnz = getattr(lu, "nnz", 0)
    return 12 * int(nnz)


class LinearizationMemo:
    """The last ``size`` linearisations by :func:`state_key`, their factors within ``max_bytes``.

    Entries are whatever the caller keeps for a key (a linearisation and its factor; a state's
    strain); the oldest used is dropped first. ``size`` 0 keeps nothing (benchmarks: the memo off).
    """

    def __init__(self, size: int = MEMO_SIZE, max_bytes: int = MEMO_BYTES):
        self.size = int(size)
        self.max_bytes = int(max_bytes)
        self.hits = 0
        self._entries: OrderedDict = OrderedDict()  # key -> (entry, bytes)

    def get(self, key: bytes):
        """The entry kept under ``key``, or None."""
        got = self._entries.get(key)
        if got is None:
            return None
        self._entries.move_to_end(key)
        self.hits += 1
        return got[0]

    def put(self, key: bytes, entry, nbytes: int = 0) -> None:
        """Keep ``entry`` (of ``nbytes`` [bytes]) under ``key``; older ones go past the limits."""
        if self.size < 1 or nbytes > self.max_bytes:
            return
        self._entries[key] = (entry, int(nbytes))
        self._entries.move_to_end(key)
        while len(self._entries) > self.size or sum(b for _, b in self._entries.values()) > self.max_bytes:
            self._entries.popitem(last=False)

    def clear(self) -> None:
        self._entries.clear()

    def __len__(self) -> int:
        return len(self._entries)
