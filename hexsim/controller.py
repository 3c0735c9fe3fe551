"""Per-leg proportional position control at the motion computer's rate (seed §2.2.4, Fig. 2.6, Fig. 5.3)."""

from __future__ import annotations

import numpy as np

from compensation import Compensator
from hexsim.params import ControllerParams


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

    def sample(self, r: np.ndarray, y_measured: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(u_v, U_c), each (n_legs,) [V], from setpoints r and measured positions y_measured (n_legs,) [m]."""
        u_p = self.params.kp * (r - y_measured)
        u_c = self.compensator.update(u_p, y_measured)
        u = u_p + u_c
        u_v = np.minimum(np.maximum(u, -self.u_v_max), self.u_v_max)
        if (u_v != u).any():
            self.saturated_samples += 1
        return u_v, u_c
