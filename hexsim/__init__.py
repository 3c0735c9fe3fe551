"""hexsim: a six-DOF hydraulic motion platform simulator (the Micro Motion System of Rexroth-Hydraudyne).

It reproduces the reversal bump, the acceleration spike each time a valve-controlled actuator changes
direction (seed: "Compensation of the reversal bump", Rexroth-Hydraudyne / TU Eindhoven, 2005), and
compensates it. The chain, one module per step: :mod:`hexsim.scenario` (setpoints) →
:mod:`hexsim.kinematics` (IK) → :mod:`hexsim.controller` (P control at 500 Hz) → :mod:`compensation` →
:mod:`hexsim.hydraulics` (valve, chamber, friction) → :mod:`hexsim.simulation` (MuJoCo control callback)
→ :mod:`hexsim.metrics` → outputs (:mod:`hexsim.report`, :mod:`hexsim.logio`, :mod:`hexsim.plotting`,
:mod:`hexsim.rerun_log`).
"""

__version__ = "0.1.0"
