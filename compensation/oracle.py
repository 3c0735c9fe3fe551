"""Oracle compensator: the yardstick, not a product feature.

The exact static inverse of the plant's true flow curve with the plant's true parameters (read from
:class:`~compensation.base.PlantTruth`, updated as the oil warms): the static piston velocity of leg i
at valve setpoint v is F_i(v) = phi_1(x_v(v), P1_static,i) / A1 (seed eq. 3.2, 3.3/3.11, 3.4 with
dP1/dt = 0, i.e. seed eq. 5.1). The desired curve is linear, s_i u_v, through F_i at ±``oracle_u_ref``
(mean of the two chords), and U_c = F_i^-1(s_i u_v) - u_v. It shows the best smoothness a static
compensation of the valve non-linearity can reach; what remains is dynamics (pressure transients,
friction), which no compensator of this kind removes.
"""

from __future__ import annotations

import numpy as np

from compensation.base import Compensator, SettingsError
from compensation.leg_model import refined_grid

#: Points of the grid over ±u_v,max before :func:`~compensation.leg_model.refined_grid` adds them where the curve
#: bends (an edge opening, a port's corner).
GRID_POINTS = 4001


class OracleCompensator(Compensator):
    name = "oracle"

    def __init__(self, *args, plant=None, **kwargs) -> None:
        super().__init__(*args, plant=plant, **kwargs)
        if plant is None or plant.flow_curve is None:
            raise SettingsError("the oracle compensator needs the plant's true parameters and flow curve (PlantTruth)")
        self.plant = plant
        self._params = None
        self._about_null = None  # the refined grid less the null it was refined at [V]

    def _refresh(self) -> None:
        p = self.plant.params
        if p is self._params:
            return
        self._params = p
        p1 = np.asarray(self.plant.p1_static, dtype=float)

        def curve(u):
            return self.plant.flow_curve(u[None, :], p1[:, None], p)

        # The grid is refined once; warming oil moves the parameters every controller sample, and of what places
        # the curve's bends on the u_v axis only the null: x_v depends on u_v - u_0 (seed eq. 3.2), so the grid
        # follows it.
        if self._about_null is None:
            grid, _ = refined_grid(curve, np.linspace(-self.u_v_max, self.u_v_max, GRID_POINTS))
            self._about_null = grid - p.null_offset
        self._grid = self._about_null + p.null_offset
        # (n_legs, grid) static velocity; a vanishing slope keeps it strictly increasing inside the overlap
        self._curve = curve(self._grid) + 1e-12 * self._grid[None, :]
        u_ref = self.settings.oracle_u_ref
        ends = np.stack([np.interp([-u_ref, u_ref], self._grid, row) for row in self._curve])
        self.slope = (ends[:, 1] - ends[:, 0]) / (2 * u_ref)

    def update(self, u_p: np.ndarray, y_measured: np.ndarray) -> np.ndarray:
        self._refresh()
        target = self.slope * u_p
        v = np.array([np.interp(target[i], self._curve[i], self._grid) for i in range(self.n_legs)])
        return v - u_p

    def state(self) -> dict[str, np.ndarray]:
        self._refresh()
        return {"s": self.slope.copy()}
