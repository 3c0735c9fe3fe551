"""Options and helpers the commands share: numbers, the machine and worker options, the scenario's options and the run they make."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import math
import os
import pathlib
import sys

from compensation import NAMES as COMPENSATORS
from compensation import CompensatorSettings, SettingsError
from hexsim.control.scenario import DEFAULT_AMPLITUDE, DEFAULT_FREQUENCY, make_scenario
from hexsim.errors import InputError
from hexsim.plant.params import FLOW_AREAS, ControllerParams
from hexsim.plant.temperature import WarmUp
from hexsim.tables import StdoutTarget

#: Worker processes by default: the cores this process may run on.
CORES = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def parse_number(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return value


def machine_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--machine", metavar="NAME|FILE.json", default=None,
                   help="the machine: a machine file (docs/machine-file.md) or a built-in's name "
                        "(hexsim machine list; default micro_motion_system, the seed's appendix A)")


def worker_options(parser: argparse.ArgumentParser, what: str) -> None:
    """--jobs (default: the cores available) and --scheduler (Dask) for a command that runs workers."""
    parser.add_argument("--jobs", type=int, default=CORES, help=f"{what} (default: the cores available, %(default)s here)")
    parser.add_argument("--scheduler", metavar="ADDRESS", default=None,
                        help="run the workers on Dask: 'local' (a LocalCluster of --jobs processes) or a scheduler's "
                        "address, e.g. tcp://head-node:8786 (needs pip install \"hexsim[cluster]\")")


def parse_compensator(text: str) -> str:
    """A built-in compensator's name or a tuned file's path (``*.json``), for argparse."""
    if text in COMPENSATORS or text.endswith(".json"):
        return text
    raise argparse.ArgumentTypeError(f"invalid choice: {text!r} (choose from {', '.join(COMPENSATORS)}, or a tuned "
                                     "file FILE.json)")


def parse_flow_areas(text: str) -> tuple[str, ...]:
    forms = tuple(f.strip() for f in text.split(",") if f.strip())
    bad = [f for f in forms if f not in FLOW_AREAS]
    if not forms or bad:
        raise argparse.ArgumentTypeError(f"unknown flow-area form {', '.join(bad) or repr(text)} "
                                         f"({', '.join(FLOW_AREAS)})")
    return forms


def thresholds_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--thresholds", type=pathlib.Path, metavar="THRESHOLDS.json",
                   help="your perception thresholds (any of x_mps2, y_mps2, z_mps2, roll_degps, pitch_degps, "
                        "yaw_degps, stimulus_s, seat_mps2; default Benson et al. and ISO 2631-1 Annex C; "
                        "docs/perception.md)")


def perception_thresholds(args: argparse.Namespace):
    from hexsim.studies.perception import DEFAULT_THRESHOLDS, Thresholds

    return DEFAULT_THRESHOLDS if getattr(args, "thresholds", None) is None else Thresholds.from_file(args.thresholds)


def progress_line(text: str) -> None:
    """A progress line on stderr for runs whose stderr is not a terminal (a log file, CI)."""
    print(f"hexsim: {text}", file=sys.stderr, flush=True)


def parse_payload(text: str) -> tuple[float, tuple[float, float, float]]:
    """``KG``, ``KG@X,Y`` or ``KG@X,Y,Z`` -> (kg, (x, y, z) m); z 0 if not given."""
    mass, _, at = text.partition("@")
    try:
        xyz = tuple(float(v) for v in at.split(",")) if at else (0.0, 0.0, 0.0)
        value = float(mass)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not KG[@X,Y[,Z]]: {text!r}") from None
    if len(xyz) == 2:
        xyz = (*xyz, 0.0)
    if len(xyz) != 3 or not all(math.isfinite(v) for v in (value, *xyz)):
        raise argparse.ArgumentTypeError(f"not KG[@X,Y[,Z]] with finite numbers: {text!r}")
    return value, xyz


def scenario_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("scenario", help="actuator, heave, surge, sway, roll, pitch, yaw, file:PATH (platform setpoints), "
                   "vehicle:PATH (a vehicle's motion at the driver's head, through the classical washout; "
                   "docs/motion-cueing.md) or valve:PATH (valve commands, open loop; a measurement log's CSV replays "
                   "as it is)")
    p.add_argument("--duration", type=parse_number, help="simulated time [s] (default: max(20 s, 6 periods); file: its length)")
    p.add_argument("--amplitude", type=parse_number,
                   help=f"sine amplitude [m for actuator/heave/surge/sway, rad for roll/pitch/yaw] "
                        f"(default {DEFAULT_AMPLITUDE['heave']} m, {DEFAULT_AMPLITUDE['roll']:.4f} rad)")
    p.add_argument("--frequency", type=parse_number, help=f"sine frequency [Hz] (default {DEFAULT_FREQUENCY})")
    p.add_argument("--seed", type=int, default=0, help="seed of the position-sensor noise (default 0)")
    machine_option(p)
    p.add_argument("--kp", type=parse_number, help=f"P gain K_p [V/m] (default: the machine's, {ControllerParams.kp:g} built in); "
                   "this and the options below override the machine file")
    p.add_argument("--flow-area", choices=[f for f in FLOW_AREAS if f not in ("table", "curve")],
                   help="valve flow-area function: smooth a = 300 x_v^2 (seed eq. 3.11) blended onto the port's "
                        "opening above 0.78 V (default), quadratic (3.11 at every opening, as the seed simulated), "
                        "port (3.11 until the port's opening is smaller, a kink at 0.90 V) or sharp-edged with "
                        "overlap (eq. 3.3)")
    p.add_argument("--sensor-noise", type=parse_number,
                   help=f"rms noise on the measured piston position [m] (default {ControllerParams.position_noise:g})")
    p.add_argument("--fault", action="append", default=[], metavar="KIND:key=value,…",
                   help="inject a fault (repeatable): valve_stuck:leg=N,t=S,value=V | supply_loss:t=S[,ramp=S] | "
                        "sensor_frozen:leg=N,t=S | sensor_dropout:leg=N,t=S | end_stop:leg=N,t=S[,value=M] "
                        "(see hexsim/plant/faults.py)")
    p.add_argument("--payload", type=parse_payload, metavar="KG[@X,Y[,Z]]",
                   help="hexapod: a payload of KG kg added to the platform (600 kg built in), its centre of gravity at X,Y,Z m "
                        "in the platform frame (default its centre; Z default 0); negative KG: a lighter platform")
    p.add_argument("--keep-last", type=parse_number, metavar="SECONDS",
                   help="keep only the last SECONDS of the 1 kHz recording (long runs: memory stays flat; the "
                        "metrics and outputs cover that window)")
    p.add_argument("--engine", choices=("native", "python"), default="native",
                   help="the loop compiled (default) or as a Python MuJoCo control callback (same compiled leg step; runs any Python compensator at Python speed)")
    p.add_argument("--model", choices=("platform", "full"), default="platform",
                   help="the hexapod's formulation: 'platform' (default), the platform as the only body with the "
                        "legs as geometry, lumped masses and end stops (about 4x faster), or 'full', the multi-body "
                        "MJCF with leg bodies and closing constraints, the reference (see docs/performance.md)")
    p.add_argument("--timestep", type=parse_number, default=1e-4,
                   help="physics step [s] (default 1e-4, the seed's 10 kHz; must divide the 2 ms controller "
                        "period and the 1 ms record period; see docs/performance.md for the accuracy of larger steps)")
    p.add_argument("--warm-up", type=parse_number, metavar="DELTA_C",
                   help="warm the oil by DELTA_C °C over the run (seed §5.5 uses 15): density, viscous friction "
                        "and valve null change (see hexsim/plant/temperature.py)")
    d = CompensatorSettings()
    g = p.add_argument_group("compensator settings (defaults from the seed where it gives one)")
    g.add_argument("--buffer-time", type=parse_number, default=d.buffer_time,
                   help="buffered/directional: buffer length [s] (seed: 30000 samples at 10 kHz = %(default)s s)")
    g.add_argument("--velocity-band", type=parse_number, default=d.velocity_band,
                   help="|velocity| [m/s] counted as zero for the null estimate (seed k = %(default)s)")
    g.add_argument("--q-threshold", type=parse_number, default=d.q_threshold,
                   help="iterative: start value of the valve range q [V] (default %(default)s)")
    g.add_argument("--iterative-gain", type=parse_number, default=d.iterative_gain,
                   help="iterative: table update per velocity error [V/(m/s)] (default %(default)s)")
    g.add_argument("--held-maximum", choices=("per-side", "seed"), default=d.held_maximum,
                   help="iterative: read a off the table per side (default) or as the seed, one signed maximum")
    g.add_argument("--fade-time", type=parse_number, default=d.fade_time,
                   help="buffered/directional: parameter fade-in time constant [s] (default %(default)s)")
    g.add_argument("--velocity-cutoff", type=parse_number, default=d.velocity_cutoff_hz,
                   help="low-pass on the differentiated position [Hz] (default %(default)s)")


def run_config(args: argparse.Namespace, compensator: str):
    from hexsim.plant.faults import Fault
    from hexsim.plant.machine import load_machine

    machine = load_machine(args.machine)
    hydraulics, controller, effects = machine.hydraulics, machine.controller, machine.effects
    if args.kp is not None:
        controller = controller.replace(kp=args.kp)
    if args.sensor_noise is not None:
        controller = controller.replace(position_noise=args.sensor_noise)
    if args.flow_area is not None:
        hydraulics = hydraulics.replace(flow_area=args.flow_area)
    if args.payload is not None:
        effects = effects.replace(payload_kg=args.payload[0], payload_at_m=args.payload[1])
    mpc = None
    if getattr(args, "cueing", "classical") == "mpc":
        if not args.scenario.startswith("vehicle:"):
            raise InputError(f"--cueing applies to a vehicle:PATH scenario, not {args.scenario}")
        if machine.system != "hexapod":
            raise InputError(f"--cueing mpc needs a hexapod; --machine {machine.label} is a {machine.system}")
        mpc = _platform_envelope(machine, hydraulics, effects)
    scenario = make_scenario(args.scenario, duration=args.duration, amplitude=args.amplitude,
                             frequency=args.frequency, controller_rate_hz=controller.rate_hz,
                             washout=getattr(args, "washout", None), mpc=mpc)
    check_machine_scenario(machine, scenario)
    if scenario.cueing is not None and getattr(args, "command", "run") in ("compare", "sweep"):
        raise InputError(f"{args.command} judges the smoothness of periodic motions; a vehicle: scenario's figures are "
                         f"its cue report: hexsim run {args.scenario} [--compensator NAME]")
    try:
        settings = CompensatorSettings(
            velocity_cutoff_hz=args.velocity_cutoff, velocity_band=args.velocity_band, q_threshold=args.q_threshold,
            iterative_gain=args.iterative_gain, buffer_time=args.buffer_time, fade_time=args.fade_time,
            held_maximum=args.held_maximum)
    except SettingsError as exc:
        raise InputError(str(exc)) from None
    model = None
    if compensator.endswith(".json"):
        from hexsim.studies.tuning import read_tuned

        compensator, settings, model = read_tuned(compensator)
    warm_up = WarmUp(delta_c=args.warm_up, duration_s=scenario.duration) if args.warm_up else None
    faults = tuple(Fault.parse(text) for text in args.fault)
    from hexsim.engine.config import (
        RunConfig,  # MuJoCo and the kernels: only once the options are checked
    )

    machine = dataclasses.replace(machine, hydraulics=hydraulics, controller=controller, effects=effects)
    return RunConfig(scenario=scenario, machine=machine, compensator=compensator,
                     compensator_settings=settings, compensator_model=model,
                     warm_up=warm_up, faults=faults, seed=args.seed,
                     engine=args.engine, keep_last_s=args.keep_last, model=args.model,
                     timestep=args.timestep, progress=not getattr(args, "quiet", True) and sys.stderr.isatty())


def _platform_envelope(machine, hydraulics, effects):
    """(PlatformLimits, head point (3,) [m]) of a hexapod machine for the MPC cueing: its envelope at the
    neutral pose (:func:`hexsim.studies.acceptance.platform_limits`) and its occupant's head."""
    from hexsim.engine.config import RunConfig
    from hexsim.plant.geometry import MICRO_MOTION_SYSTEM
    from hexsim.studies.acceptance import platform_limits

    base = RunConfig(make_scenario("heave", duration=6.0),
                     dataclasses.replace(machine, hydraulics=hydraulics, effects=effects))
    return platform_limits(base), (machine.geometry or MICRO_MOTION_SYSTEM).head_point


def check_machine_scenario(machine, scenario) -> None:
    """InputError if ``scenario`` cannot run on ``machine``: a hexapod motion on a single actuator, or a
    position setpoint on a machine without a position controller (controller.type none)."""
    if machine.system == "single-actuator" and scenario.system == "hexapod":
        raise InputError(f"--machine {machine.label} is a single actuator; scenario {scenario.name} needs a hexapod")
    if machine.open_loop and not scenario.open_loop:
        raise InputError(f"--machine {machine.label} has no position controller (controller.type none): run a valve "
                         f"command, valve:PATH, or set controller.type to P")


def check_outputs(args: argparse.Namespace) -> None:
    suffixes = {"rrd": (".rrd",), "plot": (".png", ".pdf", ".svg"), "json": (".json",), "log": (".csv",),
                "csv": (".csv",)}
    for flag, allowed in suffixes.items():
        path = getattr(args, flag, None)
        if path is None or isinstance(path, StdoutTarget):
            continue
        if path.suffix.lower() not in allowed:
            raise InputError(f"--{flag} {path}: expected a {' or '.join(allowed)} file name")
        if not path.parent.exists():
            raise InputError(f"--{flag} {path}: folder {path.parent} does not exist")
    if (getattr(args, "log", None) is not None and isinstance(args.json, pathlib.Path)
            and args.log.with_suffix(".json").resolve() == args.json.resolve()):
        raise InputError(f"--json {args.json} would be overwritten by the sidecar of --log {args.log}; choose another name")


def workers(args: argparse.Namespace):
    """The Dask client of ``--scheduler`` for the command's duration (hexsim.engine.workers.dask_client), or nothing."""
    if getattr(args, "scheduler", None) is None:
        return contextlib.nullcontext()
    if args.jobs < 1:
        raise InputError(f"--jobs must be at least 1, got {args.jobs}")
    from hexsim.engine.workers import dask_client

    return dask_client(args.scheduler, args.jobs)


def parse_address(text: str) -> tuple[str, int]:
    """``HOST:PORT`` for argparse."""
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise argparse.ArgumentTypeError(f"{text!r} is not HOST:PORT")
    return host, int(port)
