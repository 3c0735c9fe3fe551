"""The per-leg P controller: gain, compensation added before the ±u_v,max saturation, saturation count."""

from __future__ import annotations

import numpy as np

from compensation import Compensator
from hexsim.control.controller import PController
from hexsim.plant.params import ControllerParams


class ConstantCompensator(Compensator):
    name = "constant"

    def update(self, u_v, y_measured):
        return np.full(self.n_legs, 3.0)


def test_compensation_is_added_before_saturation_and_saturation_is_counted():
    ctrl = PController(ControllerParams(kp=200.0), 10.0, ConstantCompensator(2, 500.0))
    u, u_c = ctrl.sample(np.array([0.11, 0.10]), np.array([0.10, 0.10]))
    np.testing.assert_allclose(u_c, [3.0, 3.0])
    np.testing.assert_allclose(u, [5.0, 3.0])  # 200 V/m * 10 mm + 3 V, and 0 + 3 V
    assert ctrl.saturated_samples == 0
    u, _ = ctrl.sample(np.array([0.15, 0.05]), np.array([0.10, 0.10]))
    np.testing.assert_allclose(u, [10.0, -7.0])  # 13 V clipped to the valve range, -10 + 3 = -7 V
    assert ctrl.saturated_samples == 1
