"""The per-leg P controller: gain, compensation added before the ±u_v,max saturation, saturation count."""

from __future__ import annotations

import dataclasses

import numpy as np

from compensation import Compensator
from hexsim.control.controller import PController
from hexsim.control.scenario import make_scenario
from hexsim.engine.config import RunConfig
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


def test_live_derivatives_follow_a_sine_and_stay_bounded_on_a_hosts_straight_lines():
    """The reference's derivatives of rows written while the run goes (hexsim serve, the FMUs): on a smooth
    0.5 Hz sine within the low pass's lag (2 x 10 ms: 6 % at 0.5 Hz) of the true ones; on a host's 100 Hz
    packets played on straight lines, whose slope steps every 10 ms, bounded near the sine's own (central
    differences of those rows put the steps into r⃛ as spikes a hundred times larger)."""
    from hexsim.control.feedforward import LiveDerivatives, setpoint_derivatives

    dt = 0.002
    t = np.arange(0.0, 6.0, dt)
    live = LiveDerivatives(1, dt)
    got = np.array([np.concatenate(live(np.array([0.05 * np.sin(np.pi * ti)]))) for ti in t])
    w, later = np.pi, t > 1.0
    true = np.stack([0.05 * w * np.cos(w * t), -0.05 * w**2 * np.sin(w * t), -0.05 * w**3 * np.cos(w * t)], axis=1)
    err = np.abs(got[later] - true[later]).max(axis=0) / np.abs(true).max(axis=0)
    assert err[0] < 0.005 and err[1] < 0.08 and err[2] < 0.08, err
    host = np.interp(t, np.arange(0.0, 6.01, 0.01), 0.05 * np.sin(np.pi * np.arange(0.0, 6.01, 0.01)))[:, None]
    live = LiveDerivatives(1, dt)
    got = np.array([np.concatenate(live(row)) for row in host])
    assert np.abs(got[later, 2]).max() < 20 * 0.05 * w**3  # measured 23 m/s^3 (the sine's 1.55)
    assert np.abs(setpoint_derivatives(host, dt)[2][later]).max() > 100 * 0.05 * w**3  # measured 308


def test_a_model_based_compensator_tracks_live_rows_as_it_tracks_a_table():
    """The feedforward on setpoint rows written one controller sample at a time (a live scenario, as hexsim serve
    and the FMUs write them) tracks a heave sine as closely as on the same sine given as a table. Before the
    live derivatives it saw a reference at rest (the table it was built with) and tracked like no compensator
    (4.4 mm; the adaptive one then learned from that and drifted to 30 mm in served sessions)."""
    from hexsim.control.scenario import live_scenario
    from hexsim.engine.runner import Simulator
    from hexsim.plant.machine import load_machine

    base = RunConfig.from_machine(load_machine(None), "heave", compensator="feedforward")
    table = Simulator(dataclasses.replace(base, scenario=make_scenario("heave", duration=6.0))).run()
    sim = Simulator(dataclasses.replace(base, scenario=live_scenario("hexapod", table.y_ref[0], 6.0)))
    period = sim.ctrl_div * sim.dt
    for n in range(int(round(6.0 / period))):
        sim.coupling.setpoints[sim.k // sim.ctrl_div] = [np.interp(n * period, table.t, leg) for leg in table.y_ref.T]
        sim.step(period)
    live = sim.result()
    late = lambda r: r.t > 3.0  # noqa: E731
    err_table = np.abs(table.y - table.y_ref)[late(table)].max()
    err_live = np.abs(live.y - live.y_ref)[late(live)].max()
    assert err_table < 5e-4 and err_live < 2 * err_table + 1e-4, (err_table, err_live)
