"""Post stage: machine kinematics, controller dialects, feeds and machining time."""
