"""The library's error hierarchy.

Every error a user can provoke with bad input or a hard problem is a
:class:`MetasheetError`, so the CLI can print one clean line instead of a traceback
(``metasheet --debug`` shows it). Each class carries the exit status the CLI returns:

| status | meaning |
|---|---|
| 0 | success (``robot goto``: the goal was reached) |
| 1 | ``metasheet diff``: the trees differ |
| 2 | an error: bad config or command line, missing file, failed stage, outputs not writable, disk full |
| 3 | :class:`LockedError`: another run holds the output folder (``--no-wait``) |
| 4 | :class:`UnreachableError`: ``robot goto`` stopped short of the goal |
| 129, 130, 143 | interrupted: 128 + the signal (SIGHUP, Ctrl-C's SIGINT, SIGTERM); the workers are stopped and the temporary folders removed |
"""

import errno as _errno
import os as _os


class MetasheetError(Exception):
    """Base of every error metasheet raises on purpose; ``exit_code``: the CLI's exit status."""

    exit_code = 2


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


class OutputError(MetasheetError):
    """An output folder or file cannot be written: no permission, read-only, disk full.

    The message names the path and the cause; nothing half-written is left behind.
    """


class Interrupted(BaseException):
    """The run was told to stop (Ctrl-C, SIGTERM, SIGHUP): raised in a stage still under way at
    its next progress report, so that it unwinds (its temporary folder removed) as the main
    thread does. Not an ``Exception``: a stage's ``except Exception`` does not swallow it."""


class LockedError(MetasheetError):
    """Another run holds the output folder (``metasheet run --no-wait``); names its pid and start."""

    exit_code = 3


class UnreachableError(InfeasibleError):
    """A goal pose was not reached; the message gives the closest pose and the remaining error."""

    exit_code = 4


#: errno -> what a user can do about it, for :func:`output_error`.
_OS_HINTS = {
    _errno.ENOSPC: "no space left on device: free some space or choose another output root (--out)",
    _errno.EDQUOT: "disk quota exceeded: free some space or choose another output root (--out)",
    _errno.EACCES: "permission denied: make it writable or choose another output root (--out)",
    _errno.EPERM: "operation not permitted (immutable or not owned): choose another output root (--out)",
    _errno.EROFS: "read-only file system: choose another output root (--out)",
    _errno.EFBIG: "file too large for this process's limit (ulimit -f) or the file system: raise the limit "
                  "or choose another output root (--out)",
}


def output_error(exc: OSError, what: str) -> OutputError:
    """An :class:`OutputError` for an ``OSError`` met while writing ``what`` (a path or a stage).

    The message is ``what: cannot write PATH: cause (ERRNO)``; the path is the one the
    operating system named, else ``what`` alone.
    """
    name = _errno.errorcode.get(exc.errno or 0, "")
    cause = _OS_HINTS.get(exc.errno, exc.strerror or str(exc))
    path = _os.fsdecode(exc.filename) if isinstance(exc.filename, (str, bytes, _os.PathLike)) else ""
    where = f"cannot write {path}: " if path and str(path) != what else "cannot write: "
    return OutputError(f"{what}: {where}{cause}" + (f" ({name})" if name else ""))


def check_range(field: str, value, lo=None, hi=None, *, lo_open=False, hi_open=False):
    """Raise :class:`ConfigError` unless ``lo <= value <= hi`` (open ends if asked).

    Returns ``value`` so it can be used inline.
    """
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{field}: {value!r}: expected a number") from None
    if v != v or v in (float("inf"), float("-inf")):
        raise ConfigError(f"{field}: {value!r}: expected a finite number")
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


#: pydantic's strict type errors in words (a parameter file's values are not coerced: "8" and
#: true are no numbers, 2.5 is no count).
TYPE_WORDS = {
    "float_type": "expected a number, without quotes (a string or true / false is not read as one)",
    "int_type": "expected a whole number, without quotes or decimals",
    "bool_type": "expected true or false",
    "string_type": "expected a string, in quotes",
}
