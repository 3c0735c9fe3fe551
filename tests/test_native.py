"""The compiled replay kernel (hexsim.native) against the numpy reference (hexsim.effects.step_plant +
hexsim.hydraulics.leg_force): same trajectories on the same log, every effect switched on."""

import numpy as np

from hexsim.effects import Effects
from hexsim.logio import write_log
from hexsim.measurement import read_log
from hexsim.params import HydraulicParams
from hexsim.replay import PlantModel, Windows, replay
from hexsim.scenario import make_scenario
from hexsim.simulation import RunConfig, simulate


def test_native_replay_equals_numpy_reference(tmp_path):
    result = simulate(RunConfig(make_scenario("actuator", duration=6.0), seed=3))
    write_log(tmp_path / "run.csv", result, noise=np.random.default_rng(3))
    log = read_log(tmp_path / "run.csv")
    windows = Windows.tile(len(log.time), 300)
    every = Effects(supply_resistance=5e9, supply_time_constant=0.03, spool_frequency=60.0, spool_damping=0.6,
                    spool_play=0.05, leakage=2e-12, sensor_delay=0.002, mass_kg=55.0, inclination_deg=20.0)
    for model in (PlantModel(HydraulicParams(), Effects()),
                  PlantModel(HydraulicParams(null_offset=0.05, bulk_modulus=1e9, coulomb_pos=90.0), every)):
        fast = replay(log, model, windows, native=True)
        ref = replay(log, model, windows, native=False)
        for ch in ("position", "p1", "p_s", "acceleration"):
            scale = np.max(np.abs(ref[ch])) + 1e-12
            assert np.max(np.abs(fast[ch] - ref[ch])) <= 1e-9 * scale, ch
