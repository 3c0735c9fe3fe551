"""The engine: what a run is (:mod:`.config`: ``RunConfig``, the hydraulic coupling, ``SimulationResult``), the
one runner (:mod:`.runner`: scenario → kinematics → controller → compensator → plant → MuJoCo → recorder), its
compiled loop (:mod:`.native`, which also serves the measured valve replay) and runs in worker processes
(:mod:`.workers`). The studies built on it are in :mod:`hexsim.studies`; nothing here imports them."""
