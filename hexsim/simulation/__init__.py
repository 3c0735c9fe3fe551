"""Runs: what a run is (:mod:`.config`: ``RunConfig``, the hydraulic coupling, ``SimulationResult``), the one
runner (:mod:`.runner`: scenario → kinematics → controller → compensator → plant → MuJoCo → recorder) and
its compiled loop (:mod:`.native`), the smoothness metrics (:mod:`.metrics`), many runs (:mod:`.comparison`,
:mod:`.sweeps`, :mod:`.workers`) and the oil-spring modes (:mod:`.modes`)."""
