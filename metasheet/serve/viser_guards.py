"""Where viser (1.1.1) takes a browser's values unchecked, and the guards the page puts there.

- A number field's update is cast in viser's own message handler (``type(old)(new)``,
  ``_gui_api.py``), before any callback of ours: a string or a null from the page raised there,
  a traceback in the server's log and no note on the page. :func:`guard_gui_updates` checks
  the cast first and hands a refusal to the page.
- The transform gizmo's update is stored as the client sent it (``np.array(message.wxyz)``,
  ``_scene_api.py``): one message with a 1-element quaternion left an array that every later
  assignment failed to write into. :func:`pose_of_handle` refuses such a pose and
  :func:`place` repairs the stored one before it writes.
"""

from __future__ import annotations

import logging
import reprlib
from collections.abc import Callable

import numpy as np

from ..errors import ConfigError
from ..mechanics.rotations import rotation_vector

log = logging.getLogger(__name__)


def wxyz(R) -> np.ndarray:
    """(4,) quaternion (w, x, y, z) of rotation matrix ``R`` (3, 3)."""
    import viser.transforms as tf

    return tf.SO3.from_matrix(np.asarray(R)).wxyz


def pose_of_handle(handle, scale: float) -> np.ndarray:
    """(6,) goal (mm, rotation vector deg) of a viser transform handle (``scale`` metres per mm,
    quaternion); ConfigError unless it holds 3 finite coordinates and a finite, non-zero
    quaternion."""
    import viser.transforms as tf

    try:
        p, q = (np.asarray(v, dtype=float).reshape(-1) for v in (handle.position, handle.wxyz))
    except (TypeError, ValueError):
        p, q = np.zeros(0), np.zeros(0)
    n = np.linalg.norm(q) if q.shape == (4,) else 0.0
    if p.shape != (3,) or not np.all(np.isfinite(p)) or not np.isfinite(n) or n < 1e-6:
        raise ConfigError(f"goal gizmo: position {reprlib.repr(handle.position)}, orientation "
                          f"{reprlib.repr(handle.wxyz)}: expected 3 finite numbers and a non-zero quaternion")
    R = tf.SO3(q / n).as_matrix()
    return np.concatenate([p / scale, np.degrees(rotation_vector(R))])


def place(handle, position, quaternion) -> None:
    """Set a transform handle's pose, first replacing a stored position or quaternion of the
    wrong shape (see the module docstring)."""
    impl = getattr(handle, "_impl", None)
    for name, size in (("position", 3), ("wxyz", 4)):
        stored = getattr(impl, name, None)
        if stored is not None and np.shape(stored) != (size,):
            setattr(impl, name, np.zeros(size))
    handle.position, handle.wxyz = position, quaternion


def castable(current, new) -> bool:
    """Whether viser's cast of a GUI value ``new`` to the type of ``current`` succeeds."""
    try:
        if isinstance(current, tuple):
            typ = type(current[0]) if current else None
            tuple(typ(x) for x in new) if typ else tuple(new)
        else:
            type(current)(new)
    except (TypeError, ValueError, OverflowError):
        return False
    return True


def guard_gui_updates(server, refuse: Callable[[str], None]) -> bool:
    """Check each GUI value update of ``server`` before viser casts it; a value that does not
    cast is dropped and ``refuse("label: value: expected ...")`` called (the page's note).
    False (nothing done, with a log line) when this viser's internals are not the ones known."""
    from viser import _messages

    gui = server.gui
    ws = getattr(gui, "_websock_interface", None)
    handles = getattr(gui, "_gui_input_handle_from_uuid", None)
    original = getattr(gui, "_handle_gui_updates", None)
    if ws is None or handles is None or original is None:
        log.warning("viser %s: GUI updates not guarded (its internals changed)", getattr(server, "version", "?"))
        return False

    async def guarded(client_id, message) -> None:
        handle = handles.get(message.uuid)
        if handle is not None and "value" in message.updates:
            current, new = handle._impl.value, message.updates["value"]
            if not castable(current, new):
                kind = "numbers" if isinstance(current, tuple) else f"a {type(current).__name__}"
                refuse(f"{getattr(handle, 'label', 'field')}: {reprlib.repr(new)}: expected {kind}"
                       .replace("a float", "a number").replace("a int", "a whole number"))
                return
        await original(client_id, message)

    ws.unregister_handler(_messages.GuiUpdateMessage, original)
    ws.register_handler(_messages.GuiUpdateMessage, guarded)
    return True
