"""The compiled runners (hexsim.engine.native) against the straightforward Python loops over the same compiled leg
step (hexsim.plant.legs.step_plant, MuJoCo's control callback): same trajectories, every effect switched on."""

import numpy as np
import pytest

from compensation import CompensatorSettings
from hexsim.control.scenario import make_scenario
from hexsim.engine.config import RunConfig
from hexsim.engine.runner import simulate
from hexsim.measured.measurement import read_log
from hexsim.measured.replay import PlantModel, Windows, replay
from hexsim.outputs.logio import write_log
from hexsim.plant.effects import Effects
from hexsim.plant.machine import Machine
from hexsim.plant.params import HydraulicParams


def test_native_replay_equals_the_python_loop(tmp_path):
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


#: absolute floors [m] of channels that are themselves round-off: the connect constraints' residual
_FLOOR = {"constraint_violation": 1e-12}


def _same_run(a, b):
    for name in ("t", "y", "ydot", "y_ref", "u_v", "u_c", "p1", "p_s", "force", "acc", "gyro", "angacc", "pose",
                 "constraint_violation", "oil_temperature"):
        x, y = getattr(a, name), getattr(b, name)
        if y is None:
            assert x is None
            continue
        scale = np.max(np.abs(y)) + 1e-12
        assert np.max(np.abs(x - y)) <= 1e-9 * scale + _FLOOR.get(name, 0.0), name
    for key, value in b.compensator_state.items():
        assert np.allclose(a.compensator_state[key], value, rtol=1e-9, atol=1e-12), key
    assert a.saturated_samples == b.saturated_samples


def test_native_engine_equals_the_python_callback_on_the_hexapod_with_a_compensator():
    """The compiled leg kernel (hexsim.engine.native.run_block) against the numpy control callback: heave, with
    the buffered compensator adapting (buffers of 0.5 s) and the oil warming."""
    from compensation import CompensatorSettings
    from hexsim.plant.temperature import WarmUp

    base = RunConfig(make_scenario("heave", duration=1.5, frequency=2.0), compensator="buffered", seed=5,
                     compensator_settings=CompensatorSettings(buffer_time=0.5, fade_time=0.1),
                     warm_up=WarmUp(delta_c=15.0, duration_s=1.5))
    fast = simulate(base)
    ref = simulate(RunConfig(**{**base.__dict__, "engine": "python"}))
    assert np.max(np.abs(ref.u_c)) > 0.05  # the compensator acted within the run
    _same_run(fast, ref)


@pytest.mark.parametrize("compensator", ["buffered", "directional"])
def test_compiled_compensator_in_the_kernel_equals_the_python_reference(compensator):
    """Without warming oil or faults the P controller and the buffered/directional compensator run inside
    the kernel: the same run as the Python callback calling the compensator's update."""
    base = RunConfig(make_scenario("heave", duration=1.5, frequency=2.0), compensator=compensator, seed=4,
                     compensator_settings=CompensatorSettings(buffer_time=0.4, fade_time=0.1))
    fast = simulate(base)
    ref = simulate(RunConfig(**{**base.__dict__, "engine": "python"}))
    assert np.max(np.abs(ref.u_c)) > 0.05  # the compensator acted within the run
    assert set(fast.compensator_state) == {"a", "b", "c", "s"}
    _same_run(fast, ref)


def test_replayed_compensation_in_the_kernel_equals_the_python_reference():
    """A logged compensation fed forward (the hexapod log replay) runs in the kernel as a table row per
    controller sample: the same run as the Python callback with ReplayedCompensation; the table is
    shorter than the run, so its last row is held."""
    rng = np.random.default_rng(9)
    table = 0.2 * np.sin(np.linspace(0, 6, 600))[:, None] + rng.normal(0, 0.02, (600, 6))
    base = RunConfig(make_scenario("heave", duration=1.5, frequency=2.0), seed=6, feedforward=table)
    fast = simulate(base)
    ref = simulate(RunConfig(**{**base.__dict__, "engine": "python"}))
    assert np.array_equal(ref.u_c[::2][:600], table[: len(ref.u_c[::2])][:600])  # rows at 500 Hz, 1 kHz records
    _same_run(fast, ref)


def test_native_engine_equals_the_python_callback_with_every_effect():
    every = Effects(supply_resistance=5e9, supply_time_constant=0.03, spool_frequency=60.0, spool_damping=0.6,
                    spool_play=0.05, leakage=2e-12, sensor_delay=0.002, mass_kg=55.0, inclination_deg=20.0)
    base = RunConfig(make_scenario("actuator", duration=1.5, frequency=2.0), machine=Machine(effects=every), seed=2)
    _same_run(simulate(base), simulate(RunConfig(**{**base.__dict__, "engine": "python"})))


@pytest.mark.parametrize("compensator, engine", [("none", "native"), ("buffered", "native"), ("buffered", "python")])
def test_keeping_the_last_seconds_records_the_tail_of_the_full_run(compensator, engine):
    """--keep-last: the recording is a ring of the last samples, put back in time order (flat memory)."""
    scenario = make_scenario("actuator", duration=2.0, frequency=2.0)
    settings = CompensatorSettings(buffer_time=0.5)
    full = simulate(RunConfig(scenario, compensator=compensator, compensator_settings=settings, engine=engine))
    tail = simulate(RunConfig(scenario, compensator=compensator, compensator_settings=settings, engine=engine,
                              keep_last_s=0.7))
    assert len(tail.t) == 700 and tail.t[0] == pytest.approx(1.3)
    for name in ("t", "y", "ydot", "y_ref", "u_v", "u_c", "p1", "p_s", "force", "acc", "constraint_violation"):
        assert np.array_equal(getattr(tail, name), getattr(full, name)[-700:]), name


def test_the_mujoco_adapter_the_kernels_rely_on():
    # hexsim/engine/native.py calls mj_step of the library the bindings loaded (found by a glob in the mujoco
    # package) on the raw mjModel*/mjData* of the private MjModel._address / MjData._address. This checks
    # both on the installed MuJoCo: ten steps through that route equal ten mujoco.mj_step calls exactly.
    import ctypes

    import mujoco

    from hexsim.engine import native
    from hexsim.plant.model import load_model

    hint = (f"MuJoCo {mujoco.__version__} changed what hexsim/engine/native.py relies on to step MuJoCo from compiled "
            "code; update the adapter there (see docs/performance.md, The compiled loop)")
    m = load_model("hexapod")
    runs = [mujoco.MjData(m), mujoco.MjData(m)]
    assert all(hasattr(x, "_address") for x in (m, *runs)), hint
    assert native._lib_path and native._lib_path[0].parent == native.pathlib.Path(mujoco.__file__).parent, hint
    lib = ctypes.CDLL(str(native._lib_path[0]))
    for d in runs:
        mujoco.mj_resetDataKeyframe(m, d, 0)
        d.ctrl[:] = 1250.0
    for _ in range(10):
        lib.mj_step(ctypes.c_void_p(m._address), ctypes.c_void_p(runs[0]._address))
        mujoco.mj_step(m, runs[1])
    assert runs[0].time == runs[1].time > 0, hint
    assert np.array_equal(runs[0].qpos, runs[1].qpos) and np.array_equal(runs[0].qvel, runs[1].qvel), hint
