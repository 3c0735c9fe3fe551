"""``hexsim bench``: speed of the simulator against bare MuJoCo on the same model, in one process.

Cases, each timed ``repeats`` times (median reported) over ``duration`` simulated seconds:

* ``bare_mj_step``: the hexapod model, no control callback, ``mj_step`` at dt = 1e-4 s (legs held by
  their static forces);
* ``hexapod_full``: :func:`hexsim.simulation.simulate` on heave with the buffered compensator
  (hydraulics of six legs, P control at 500 Hz, compensator, sensors recorded at 1 kHz);
* ``actuator_full``: the same on the single actuator, no compensator;
* ``replay_kernel``: the compiled valve replay (:mod:`hexsim.native`) of one single-actuator window,
  per simulated second.

A faster integration scheme (issue 5 item c) is not implemented; the benchmark says so.
"""

from __future__ import annotations

import platform
import statistics
import time

import mujoco
import numpy as np

from hexsim.model import PlantIndex, load_model, reset_neutral


def _bare(duration: float) -> float:
    from hexsim.simulation import static_leg_forces

    m = load_model("hexapod")
    d = mujoco.MjData(m)
    idx = PlantIndex.from_model(m)
    mujoco.set_mjcb_control(None)
    reset_neutral(m, d)
    forces = static_leg_forces(m, d, idx)
    d.ctrl[idx.actuator_id] = forces
    steps = int(round(duration / m.opt.timestep))
    start = time.perf_counter()
    mujoco.mj_step(m, d, steps)
    return time.perf_counter() - start


def _full(system: str, compensator: str, duration: float) -> float:
    from hexsim.scenario import make_scenario
    from hexsim.simulation import RunConfig, simulate

    scenario = make_scenario("heave" if system == "hexapod" else "actuator", duration=duration, frequency=2.0)
    return simulate(RunConfig(scenario, compensator=compensator)).wall_time_s


def _replay(duration: float) -> float:
    """One window of ``duration`` through the compiled valve replay, on a synthetic 2 Hz valve signal."""
    import pathlib
    import tempfile

    from hexsim.effects import Effects
    from hexsim.measurement import read_log
    from hexsim.params import HydraulicParams
    from hexsim.replay import PlantModel, Windows, replay

    fs = 1000.0
    t = np.arange(int(duration * fs) + 1) / fs
    u = 0.8 * np.sin(2 * np.pi * 2.0 * t)
    with tempfile.TemporaryDirectory() as tmp:
        path = pathlib.Path(tmp) / "bench.csv"
        np.savetxt(path, np.column_stack([t, u, np.full_like(t, 0.1)]), delimiter=",",
                   header="time_s,valve_cmd_V,pos_m", comments="")
        path.with_suffix(".json").write_text('{"system": "single-actuator", "sample_rate_hz": 1000.0}')
        log = read_log(path)
    model = PlantModel(HydraulicParams(), Effects())
    windows = Windows.tile(len(t), len(t))
    replay(log, model, windows)  # compile
    start = time.perf_counter()
    replay(log, model, windows)
    return time.perf_counter() - start


def run_bench(duration: float = 2.0, repeats: int = 3) -> dict:
    """Median wall time per simulated second of each case, real-time factors and the ratios to bare
    ``mj_step``. ``duration`` [s] of simulated time per repeat (>= 1.5 s for the scenarios)."""
    cases = {
        "bare_mj_step": lambda: _bare(duration),
        "hexapod_full": lambda: _full("hexapod", "buffered", duration),
        "actuator_full": lambda: _full("actuator", "none", duration),
        "replay_kernel": lambda: _replay(duration),
    }
    out: dict = {"machine": {"cpu": platform.processor() or platform.machine(), "python": platform.python_version(),
                             "mujoco": mujoco.__version__}, "duration_s": duration, "repeats": repeats, "cases": {}}
    for name, fn in cases.items():
        walls = [fn() for _ in range(repeats)]
        per_s = statistics.median(walls) / duration
        out["cases"][name] = {"wall_per_sim_s": per_s, "us_per_step": per_s * 1e6 / 1e4,
                              "realtime_factor": 1.0 / per_s}
    bare = out["cases"]["bare_mj_step"]["wall_per_sim_s"]
    out["ratio_hexapod_full_to_bare"] = out["cases"]["hexapod_full"]["wall_per_sim_s"] / bare
    out["faster_scheme"] = "not implemented (issue 5 item c)"
    return out


def table(result: dict) -> str:
    lines = [f"{'case':16s} {'µs/step':>9s} {'s per sim s':>12s} {'× real time':>12s}"]
    for name, c in result["cases"].items():
        lines.append(f"{name:16s} {c['us_per_step']:9.2f} {c['wall_per_sim_s']:12.4f} {c['realtime_factor']:12.2f}")
    lines.append(f"hexapod_full / bare_mj_step = {result['ratio_hexapod_full_to_bare']:.2f}")
    lines.append(f"faster accurate scheme: {result['faster_scheme']}")
    return "\n".join(lines)
