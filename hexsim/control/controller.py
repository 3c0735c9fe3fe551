"""Per-leg proportional position control at the motion computer's rate (seed §2.2.4, Fig. 2.6, Fig. 5.3)."""

from __future__ import annotations

import numba
import numpy as np

from compensation import Compensator
from hexsim.plant.params import ControllerParams

_law = numba.njit(cache=True, inline="always")


@_law
def p_output(kp, r, y_measured):
    """u_p = K_p (r - y_measured) [V]: the P controller's output (seed §2.2.4, Fig. 2.6) for setpoint r and
    measured piston position y_measured [m] (scalars or arrays of one shape), K_p [V/m]. Compiled into the
    kernel (:func:`hexsim.engine.native.run_block`); the Python engine runs the same source interpreted."""
    return kp * (r - y_measured)


@_law
def valve_setpoint(u_p, u_c, u_v_max):
    """u_v = sat(u_p + U_c, ±u_v,max) [V]: the compensation voltage U_c added to the P output before the
    valve's input saturation (seed Fig. 5.3). Scalars or arrays of one shape."""
    return np.minimum(np.maximum(u_p + u_c, -u_v_max), u_v_max)


class PController:
    """u_v = sat(K_p (r - y_measured) + U_c, ±u_v,max) for every leg, once per controller sample.

    The hydraulic actuator is flow-controlled and behaves like a first-order (integrating) system, so a
    P controller suffices (seed §2.2.4). The compensator (seed Fig. 5.3) sees the unsaturated P output and
    the measured position and returns U_c; the sum is saturated at ±u_v,max. The output is held between
    samples (zero-order hold) by the caller.
    """

    def __init__(self, params: ControllerParams, u_v_max: float, compensator: Compensator) -> None:
        self.params = params
        self.u_v_max = float(u_v_max)
        self.compensator = compensator
        self.saturated_samples = 0

    def sample(self, r: np.ndarray, y_measured: np.ndarray, reference=None) -> tuple[np.ndarray, np.ndarray]:
        """(u_v, U_c), each (n_legs,) [V], from setpoints r and measured positions y_measured (n_legs,) [m];
        ``reference`` (a :class:`compensation.leg_model.Reference`) is handed to the compensator's
        ``observe`` first."""
        u_p = p_output.py_func(self.params.kp, r, y_measured)
        if reference is not None:
            self.compensator.observe(reference)
        u_c = self.compensator.update(u_p, y_measured)
        u_v = valve_setpoint.py_func(u_p, u_c, self.u_v_max)
        if (u_v != u_p + u_c).any():
            self.saturated_samples += 1
        return u_v, u_c
