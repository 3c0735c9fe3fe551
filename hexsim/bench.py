"""``hexsim bench``: speed of the simulator against bare MuJoCo on the same model, in one process.

Cases, each timed ``repeats`` times (median reported) over ``duration`` simulated seconds:

* ``bare_mj_step``: the hexapod model, no control callback, ``mj_step`` at dt = 1e-4 s (legs held by
  their static forces) — the baseline (a);
* ``bare_mj_step_platform``: the same on the platform-only model (:mod:`hexsim.plant.platform`);
* ``hexapod_platform`` / ``hexapod_platform_uncompensated``: heave on the platform-only model with the
  buffered compensator / without;
* ``hexapod_full``: :func:`hexsim.engine.runner.simulate` on heave with the buffered compensator: six legs'
  hydraulics at 10 kHz, P control and the buffered compensator at 500 Hz (compiled,
  :func:`compensation.buffered.buffered_tick`), all inside the kernel, sensors recorded at 1 kHz — (b);
* ``hexapod_python``: the same with the Python control callback and the Python compensator, for the
  gain of the kernel;
* ``hexapod_uncompensated``: heave without a compensator;
* ``hexapod_fast``: the fastest scheme that passes the convergence test (tests/engine/test_convergence.py):
  dt = 1e-3 s, uncompensated heave — (c); with a compensator the 1e-3 s step misses the 2 % bound on
  single reversal peaks (docs/performance.md);
* ``actuator_full`` / ``actuator_fast``: the single actuator at dt = 1e-4 s / 1e-3 s, no compensator — (d);
* ``actuator_bare_fast``: bare ``mj_step`` of the single-actuator model at dt = 1e-3 s, no callback: the
  floor under ``actuator_fast``;
* ``replay_kernel``: the compiled valve replay (:mod:`hexsim.engine.native`) of one single-actuator window.

Besides, the start-up of the command line: ``hexsim --help`` (``python -m hexsim --help`` in a fresh
interpreter) against ``python -c pass``, the median of ``repeats`` (at least 3) of each, as a ratio.

The repeats go round the cases (case 1, 2, …, then again), so a machine that slows down or speeds up
during the benchmark biases no case against another; and the baseline is timed right before every
case: a ratio "÷ bare" is the median over the repeats of the case's wall time over its own baseline's
(the machine's speed swings by ±30 % between minutes, the pairs share theirs).

``calibrate=True`` adds ``hexsim calibrate`` on two 20 s open-loop logs of the built-in ``servo_cylinder``
(made by hexsim: a 2 V and a 6 V run, the command reversing every 2.5 s), ``repeats`` times, against bare
``mj_step`` of the single actuator over the logs' 40 s (the pair timed together); and on two 20 s
closed-loop logs of the seed's actuator (0.5 Hz, 60 mm and 1.5 Hz, 30 mm) made by hexsim with a machine
off the built-in file (port-limited valve, flow gain +5 %, 1.3 GPa, 44 kg), calibrated from their
transients against the built-in file (every flow-area form screened).

``sweep=True`` adds the throughput of ``hexsim sweep`` (8 runs of 20 s) with 1 worker (in this process),
2 forked and 2 spawned workers, ``repeats`` rounds, medians of the wall times.
"""

from __future__ import annotations

import platform
import statistics
import time

import mujoco
import numpy as np

from hexsim.plant.model import PlantIndex, load_model, reset_neutral


def _bare(duration: float, system: str = "hexapod", timestep: float | None = None, model: str = "full") -> float:
    """Wall time [s] of ``duration`` simulated seconds of bare ``mj_step``, the legs held by their static
    forces (on the platform-only model: the wrench of those forces, set once)."""
    from hexsim.engine.config import apply_leg_forces, static_leg_forces

    m = load_model(system, model)
    if timestep is not None:
        m.opt.timestep = timestep
    d = mujoco.MjData(m)
    idx = PlantIndex.from_model(m)
    mujoco.set_mjcb_control(None)
    reset_neutral(m, d)
    apply_leg_forces(d, idx, static_leg_forces(m, d, idx))
    steps = int(round(duration / m.opt.timestep))
    start = time.perf_counter()
    mujoco.mj_step(m, d, steps)
    return time.perf_counter() - start


def _full(system: str, compensator: str, duration: float, engine: str = "native", timestep: float | None = None,
          model: str = "full") -> float:
    from hexsim.control.scenario import make_scenario
    from hexsim.engine.config import RunConfig
    from hexsim.engine.runner import simulate

    scenario = make_scenario("heave" if system == "hexapod" else "actuator", duration=duration, frequency=2.0)
    return simulate(RunConfig(scenario, compensator=compensator, engine=engine, timestep=timestep,
                              model=model)).wall_time_s


SWEEP_RUNS = 8


def _sweep(jobs: int, start_method: str | None = None) -> float:
    """Wall time [s] of a sweep of :data:`SWEEP_RUNS` runs (heave, 20 s at 1 Hz, buffered, one seed each)
    with ``jobs`` workers started by ``start_method`` (None: the default), start-up included."""
    from hexsim.control.scenario import make_scenario
    from hexsim.engine.config import RunConfig
    from hexsim.studies.sweeps import expand, run_sweep

    scenario = make_scenario("heave", duration=20.0, frequency=1.0)
    points = expand({"seed": list(range(SWEEP_RUNS))},
                    lambda s: RunConfig(scenario, compensator="buffered", seed=s["seed"]))
    return run_sweep(points, jobs=jobs, progress=False, start_method=start_method)[1]


def _replay(duration: float) -> float:
    """One window of ``duration`` through the compiled valve replay, on a synthetic 2 Hz valve signal."""
    import pathlib
    import tempfile

    from hexsim.measured.measurement import read_log
    from hexsim.measured.replay import PlantModel, Windows, replay
    from hexsim.plant.effects import Effects
    from hexsim.plant.params import HydraulicParams

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


def _startup(repeats: int) -> dict:
    """Wall time [s] of ``python -m hexsim --help`` and of ``python -c pass`` in fresh interpreters (medians
    of ``repeats`` each, alternating) and their ratio: what a user waits for before the first answer."""
    import subprocess
    import sys

    walls: dict[str, list[float]] = {"help": [], "python": []}
    for _ in range(max(3, repeats)):
        for name, args in (("help", ["-m", "hexsim", "--help"]), ("python", ["-c", "pass"])):
            start = time.perf_counter()
            subprocess.run([sys.executable, *args], check=True, capture_output=True)
            walls[name].append(time.perf_counter() - start)
    help_s, python_s = statistics.median(walls["help"]), statistics.median(walls["python"])
    return {"help_s": help_s, "python_s": python_s, "ratio": help_s / python_s}


def _calibration_logs(folder) -> list:
    """Two 20 s open-loop logs of the built-in servo cylinder (2 V and 6 V, the command reversing every
    2.5 s), read back as measurement logs."""
    import pathlib

    from hexsim.control.scenario import make_scenario
    from hexsim.engine.config import RunConfig
    from hexsim.engine.runner import simulate
    from hexsim.measured.measurement import read_log
    from hexsim.outputs.logio import write_log
    from hexsim.plant.machine import load_machine

    machine = load_machine("servo_cylinder")
    logs = []
    for volts in (2.0, 6.0):
        t = np.arange(0.0, 20.0, 1e-3)
        u = np.where(t < 0.1, 0.0, np.where(((t - 0.1) // 2.5) % 2 == 0, volts, -volts))
        path = pathlib.Path(folder) / f"valve_{volts:g}V.csv"
        np.savetxt(path, np.column_stack([t, u]), delimiter=",", header="time_s,valve_cmd_V", comments="", fmt="%.6g")
        result = simulate(RunConfig.from_machine(machine, make_scenario(f"valve:{path}")))
        write_log(path.with_name(f"log_{volts:g}V.csv"), result, noise=np.random.default_rng(1))
        logs.append(read_log(path.with_name(f"log_{volts:g}V.csv"), machine=machine))
    return logs


def _transient_logs(folder) -> list:
    """Two 20 s closed-loop logs of the seed's actuator on a machine off the built-in file (module doc), with
    the sensors' noise, read back against the built-in file."""
    import pathlib

    from hexsim.control.scenario import make_scenario
    from hexsim.engine.config import RunConfig
    from hexsim.engine.runner import simulate
    from hexsim.measured.measurement import read_log
    from hexsim.outputs.logio import write_log
    from hexsim.plant.machine import load_machine, machine_from_document, set_keys

    prior = load_machine(None)
    doc = set_keys(prior.document(), [("valve.flow_area", "port"), ("valve.edge_gain_PA", 1.05),
                                      ("oil.bulk_modulus_Pa", 1.3e9), ("load.mass_kg", 44.0)])
    truth = machine_from_document(doc, "bench: off the built-in file")
    logs = []
    for i, (freq, amp) in enumerate(((0.5, 0.06), (1.5, 0.03))):
        path = pathlib.Path(folder) / f"sine_{i}.csv"
        result = simulate(RunConfig.from_machine(truth, make_scenario("actuator", duration=20.0, frequency=freq,
                                                                      amplitude=amp)))
        write_log(path, result, noise=np.random.default_rng(i))
        logs.append(read_log(path, machine=prior))
    return logs


def _hexapod_logs(folder) -> list:
    """One 20 s closed-loop hexapod log (heave, 1 Hz) of the full multi-body model at 5e-5 s on a Micro Motion
    System off its file (each leg's valve edges ±6 %, bulk modulus 1.2 GPa, 40 kg payload off centre), with the
    sensors' noise, read back against the built-in file."""
    import pathlib

    from hexsim.control.scenario import make_scenario
    from hexsim.engine.config import RunConfig
    from hexsim.engine.runner import simulate
    from hexsim.measured.measurement import read_log
    from hexsim.outputs.logio import write_log
    from hexsim.plant.effects import Effects, LegChange
    from hexsim.plant.machine import Machine
    from hexsim.plant.params import HydraulicParams

    gains = (1.06, 0.95, 1.03, 0.97, 1.08, 0.94)
    legs = tuple(LegChange.of(i + 1, edge_gain_pa=g, edge_gain_at=1.02 * g) for i, g in enumerate(gains))
    machine = Machine(hydraulics=HydraulicParams(bulk_modulus=1.2e9),
                      effects=Effects(payload_kg=40.0, payload_at_m=(0.05, -0.03, 0.0)))
    config = RunConfig(make_scenario("heave", duration=20.0, frequency=1.0), machine, model="full", timestep=5e-5,
                       leg_changes=legs)
    path = pathlib.Path(folder) / "hexapod_heave.csv"
    write_log(path, simulate(config), noise=np.random.default_rng(3))
    return [read_log(path)]


def _calibration(repeats: int) -> dict:
    """Median wall time [s] of ``calibrate`` on two 20 s single-actuator logs of each kind (steady, transients)
    and of bare ``mj_step`` over their 40 s, and on one 20 s hexapod log against bare ``mj_step`` of the
    hexapod over 20 s, the pairs timed together."""
    import tempfile

    from hexsim.measured.calibration import calibrate

    out = {}
    with tempfile.TemporaryDirectory() as folder:
        for kind, logs, what in (("steady", _calibration_logs(folder), "2 × 20 s, servo_cylinder, open loop"),
                                 ("transients", _transient_logs(folder), "2 × 20 s, the seed's actuator, closed loop"),
                                 ("hexapod", _hexapod_logs(folder), "1 × 20 s, the Micro Motion System, closed loop")):
            pairs = []
            for _ in range(repeats):
                base = _bare(20.0, "hexapod") if kind == "hexapod" else _bare(40.0, "actuator")
                start = time.perf_counter()
                calibrate(logs, logs[0].machine, cross_validate=False)
                pairs.append((time.perf_counter() - start, base))
            out[kind] = {"logs": what, "wall_s": statistics.median(w for w, _ in pairs),
                         "to_bare": statistics.median(w / b for w, b in pairs),
                         "bare": "the hexapod's full model over 20 s" if kind == "hexapod" else
                         "the single actuator over the logs' 40 s", "pairs": pairs}
    return out


def run_bench(duration: float = 2.0, repeats: int = 3, sweep: bool = False, calibrate: bool = False) -> dict:
    """Median wall time per simulated second of each case, real-time factors and the ratios to bare
    ``mj_step``. ``duration`` [s] of simulated time per repeat (>= 1.5 s for the scenarios)."""
    cases = {
        "bare_mj_step": lambda: _bare(duration),
        "bare_mj_step_platform": lambda: _bare(duration, model="platform"),
        "hexapod_platform": lambda: _full("hexapod", "buffered", duration, model="platform"),
        "hexapod_platform_uncompensated": lambda: _full("hexapod", "none", duration, model="platform"),
        "hexapod_full": lambda: _full("hexapod", "buffered", duration),
        "hexapod_python": lambda: _full("hexapod", "buffered", duration, engine="python"),
        "hexapod_uncompensated": lambda: _full("hexapod", "none", duration),
        "hexapod_fast": lambda: _full("hexapod", "none", duration, timestep=1e-3),
        "actuator_full": lambda: _full("actuator", "none", duration),
        "actuator_fast": lambda: _full("actuator", "none", duration, timestep=1e-3),
        "actuator_bare_fast": lambda: _bare(duration, "actuator", timestep=1e-3),
        "replay_kernel": lambda: _replay(duration),
    }
    out: dict = {"machine": {"cpu": platform.processor() or platform.machine(), "python": platform.python_version(),
                             "mujoco": mujoco.__version__}, "duration_s": duration, "repeats": repeats, "cases": {}}
    walls: dict[str, list[float]] = {name: [] for name in cases}
    pairs: dict[str, list[tuple[float, float]]] = {name: [] for name in cases}
    for _ in range(repeats):
        for name, fn in cases.items():
            base = cases["bare_mj_step"]()  # the baseline right before each case: the pair shares the minute
            walls["bare_mj_step"].append(base)
            if name != "bare_mj_step":
                walls[name].append(fn())
                pairs[name].append((walls[name][-1], base))
    for name in cases:
        per_s = statistics.median(walls[name]) / duration
        out["cases"][name] = {"wall_per_sim_s": per_s, "us_per_sim_s": per_s * 1e6, "realtime_factor": 1.0 / per_s,
                              "to_bare": statistics.median(w / b for w, b in pairs[name]) if pairs[name] else 1.0,
                              "walls_with_baseline_s": pairs[name]}
    ratio = {name: c["to_bare"] for name, c in out["cases"].items()}
    out["ratio_hexapod_full_to_bare"] = ratio["hexapod_full"]
    out["ratio_platform_bare_to_bare"] = ratio["bare_mj_step_platform"]
    out["ratio_hexapod_platform_to_bare"] = ratio["hexapod_platform"]
    out["ratio_hexapod_fast_to_bare"] = ratio["hexapod_fast"]
    out["fast_scheme"] = "dt = 1e-3 s, uncompensated (tests/engine/test_convergence.py)"
    out["ratio_actuator_fast_to_bare_fast"] = (out["cases"]["actuator_fast"]["wall_per_sim_s"]
                                               / out["cases"]["actuator_bare_fast"]["wall_per_sim_s"])
    out["startup"] = _startup(repeats)
    if calibrate:
        out["calibration"] = _calibration(repeats)
    if sweep:
        from hexsim.engine.workers import default_start_method

        rounds = [(_sweep(1), _sweep(2), _sweep(2, "spawn")) for _ in range(repeats)]  # round the cases too
        one, two, spawned = (statistics.median(r[i] for r in rounds) for i in range(3))
        out["sweep"] = {"runs": SWEEP_RUNS, "wall_1_worker_s": one, "wall_2_workers_s": two, "speedup": one / two,
                        "start_method": default_start_method(), "wall_2_spawned_workers_s": spawned,
                        "speedup_spawned": one / spawned, "rounds": rounds}
    return out


def table(result: dict) -> str:
    lines = [f"{'case':30s} {'µs per sim s':>13s} {'× real time':>12s} {'÷ bare':>8s}"]
    for name, c in result["cases"].items():
        lines.append(f"{name:30s} {c['us_per_sim_s']:13.0f} {c['realtime_factor']:12.2f} {c['to_bare']:8.2f}")
    lines.append(f"hexapod_full / bare_mj_step = {result['ratio_hexapod_full_to_bare']:.2f}")
    lines.append(f"bare_mj_step_platform / bare_mj_step = {result['ratio_platform_bare_to_bare']:.2f}  "
                 "(a step of the platform-only model over a step of the full model)")
    lines.append(f"hexapod_platform / bare_mj_step = {result['ratio_hexapod_platform_to_bare']:.2f}")
    lines.append(f"hexapod_fast / bare_mj_step = {result['ratio_hexapod_fast_to_bare']:.2f}  "
                 f"(fast scheme: {result['fast_scheme']})")
    lines.append(f"actuator_fast / actuator_bare_fast = {result['ratio_actuator_fast_to_bare_fast']:.2f}  "
                 "(the single actuator over bare mj_step of its own model, both at dt = 1e-3 s)")
    st = result["startup"]
    lines.append(f"hexsim --help {st['help_s']:.2f} s, python -c pass {st['python_s']:.2f} s: "
                 f"{st['ratio']:.1f}x the bare interpreter's start")
    for ca in result.get("calibration", {}).values():
        lines.append(f"hexsim calibrate on {ca['logs']}: {ca['wall_s']:.1f} s, {ca['to_bare']:.1f}x bare mj_step of "
                     f"{ca['bare']}")
    if "sweep" in result:
        sw = result["sweep"]
        lines.append(f"sweep of {sw['runs']} runs: {sw['wall_1_worker_s']:.1f} s with 1 worker, "
                     f"{sw['wall_2_workers_s']:.1f} s with 2 ({sw['start_method']}): {sw['speedup']:.2f}× the "
                     f"throughput; {sw['wall_2_spawned_workers_s']:.1f} s with 2 spawned: {sw['speedup_spawned']:.2f}×")
    return "\n".join(lines)
