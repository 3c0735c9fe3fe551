"""MJCF models shipped with hexsim (installed as ``hexsim.models``; sources in the repository's ``models/``).

- ``hexapod.py``: the six-DOF Micro Motion System hexapod built as data with ``mujoco.MjSpec`` (the model
  hexsim compiles); ``micro_motion_system.xml`` is its ``to_xml()`` and ``scene.xml`` includes it.
- ``single_actuator.xml``: one vertical actuator with M = 40 kg, the seed's own model (ch. 3).
"""
