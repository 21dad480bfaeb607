"""The robot in time (issue 64): mass and damping, time integration, modes, the marble on the maze.

One module per concept: :mod:`.mass` (consistent mass matrices, rigid bodies, Rayleigh damping),
:mod:`.schemes` (implicit Euler as SOFA integrates, generalised-alpha), :mod:`.integrate` (a
second-order system stepped in time), :mod:`.modes` (natural frequencies and shapes),
:mod:`.robot` (the corotational robot with prescribed servo horns), :mod:`.marble` and
:mod:`.maze_geometry` (a sphere rolling on the moving maze plate between its walls).
Units are metasheet's (:mod:`metasheet.conventions`): mm, N, t, s; so K/M is in 1/s^2.
"""
