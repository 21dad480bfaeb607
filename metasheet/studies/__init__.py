"""The paper's studies (Sections IV-V) on top of a robot model: workspace (Fig. 5), motor
ranges (Fig. 6), anisotropy sweep (Fig. 7), maze, and their report.

The studies talk to a :class:`~.model.RobotModel` (the FEM robot through :mod:`.adapter`,
or the analytic :mod:`.standin`), and hand independent work units to an executor.
"""
