"""The library's error hierarchy.

Every error a user can provoke with bad input or a hard problem is a
:class:`MetasheetError`, so the CLI can print one clean line instead of a traceback.
"""


class MetasheetError(Exception):
    """Base of every error metasheet raises on purpose."""


class ConfigError(MetasheetError, ValueError):
    """A parameter or config value is missing, of the wrong type or out of range.

    The message names the field, the value and what is allowed.
    """


class MeshError(MetasheetError):
    """A mesh or a geometry is unusable (inverted elements, not watertight, not periodic...)."""


class ConvergenceError(MetasheetError):
    """An iterative solver did not converge; ``history`` holds its residuals."""

    def __init__(self, message: str, history=()):
        super().__init__(message)
        self.history = tuple(history)


class InfeasibleError(MetasheetError):
    """A target cannot be met (an unreachable density, an empty feasible set...)."""


class StageError(MetasheetError):
    """A pipeline stage failed; the message names the stage and the cause."""


def check_range(field: str, value, lo=None, hi=None, *, lo_open=False, hi_open=False):
    """Raise :class:`ConfigError` unless ``lo <= value <= hi`` (open ends if asked).

    Returns ``value`` so it can be used inline.
    """
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{field}: {value!r}: expected a number") from None
    if v != v:
        raise ConfigError(f"{field}: {value!r}: expected a finite number, got NaN")
    bad = (lo is not None and (v <= lo if lo_open else v < lo)) or (
        hi is not None and (v >= hi if hi_open else v > hi)
    )
    if bad:
        left = "(" if lo_open else "["
        right = ")" if hi_open else "]"
        lo_s = "-inf" if lo is None else f"{lo:g}"
        hi_s = "inf" if hi is None else f"{hi:g}"
        raise ConfigError(f"{field}: {value!r}: allowed range is {left}{lo_s}, {hi_s}{right}")
    return value
