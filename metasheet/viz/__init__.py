"""Off-screen pictures and plots, one module per stage area.

VTK logs a harmless "bad X server connection" warning when it falls back to
off-screen (EGL) rendering on a machine with no screen; only its errors are shown.
"""

try:
    from vtkmodules.vtkCommonCore import vtkLogger

    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
except ImportError:  # pragma: no cover - pyvista brings vtk; without it no 3D picture is made
    pass
