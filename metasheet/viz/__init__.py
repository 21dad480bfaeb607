"""Off-screen pictures and plots, one module per stage area.

VTK logs a harmless "bad X server connection" warning when it falls back to
off-screen (EGL) rendering on a machine with no screen; only its errors are shown.

Pictures are made one at a time in a process (:func:`one_at_a_time`): pyplot's figure
registry and VTK's render windows are process-wide, and a pipeline may run independent
stages in threads at once.
"""

import functools
import threading

try:
    from vtkmodules.vtkCommonCore import vtkLogger

    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
except ImportError:  # pragma: no cover - pyvista brings vtk; without it no 3D picture is made
    pass

_PICTURES = threading.RLock()


def one_at_a_time(fn):
    """Decorator: ``fn`` (a picture maker) runs under the process's picture lock."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        with _PICTURES:
            return fn(*args, **kwargs)

    return wrapper


def image_png(image) -> bytes:
    """An (h, w, 3 or 4) uint8 image (a pyvista screenshot) as PNG bytes without metadata (the
    same image gives the same bytes)."""
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.image as mpimg

    buf = io.BytesIO()
    mpimg.imsave(buf, image, format="png", metadata={"Software": None})
    return buf.getvalue()


def figure_png(fig, *, dpi: int = 100, tight: bool = True) -> bytes:
    """A matplotlib figure as PNG bytes, with fixed metadata (the same figure gives the same
    bytes); the figure is closed."""
    import io

    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight" if tight else None, metadata={"Software": None})
    plt.close(fig)
    return buf.getvalue()
