"""What leaves metasheet for the users' own tools: a SOFA scene of the robot
(:mod:`.sofa`), motor programs for the real servos (:mod:`.program`, :mod:`.servo`) and
time series ParaView plays (:mod:`.series`)."""
