"""MJCF models shipped with hexsim (installed as ``hexsim.models``; sources in the repository's ``models/``).

- ``scene.xml`` includes ``micro_motion_system.xml``: the six-DOF Micro Motion System hexapod.
- ``single_actuator.xml``: one vertical actuator with M = 40 kg, the seed's own model (ch. 3).
"""
