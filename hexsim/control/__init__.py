"""From motion to valve: DOF setpoints (:mod:`.scenario`), inverse kinematics to the six actuator
setpoints (:mod:`.kinematics`), the per-actuator P controller at 500 Hz (:mod:`.controller`, seed §2.3)."""
