"""``hexsim`` command line: ``hexsim run SCENARIO [options]``.

Bad options and unreachable setpoints give one line on stderr and exit code 2, never a traceback and
never a half-written output file.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import math
import os
import pathlib
import sys
import warnings

from compensation import NAMES as COMPENSATORS
from compensation import CompensatorSettings, SettingsError
from hexsim import __version__
from hexsim.control.scenario import (
    DEFAULT_AMPLITUDE,
    DEFAULT_FREQUENCY,
    SCENARIOS,
    make_scenario,
)
from hexsim.errors import HexsimError, InputError, ModelNote, WorkspaceError
from hexsim.plant.params import FLOW_AREAS, ControllerParams
from hexsim.plant.temperature import WarmUp
from hexsim.simulation.workers import START_METHODS, worker_count
from hexsim.tables import StdoutTarget, write_atomic, write_json

#: Worker processes by default: the cores this process may run on.
CORES = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def _number(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return value


def build_parser() -> argparse.ArgumentParser:
    """The command line: ``hexsim run|compare|tune|validate|friction|calibrate|sweep|modes|accept|bench|machine|serve|fmu|cue-tune``
    (``--help`` on each)."""
    parser = argparse.ArgumentParser(
        prog="hexsim",
        description="Six-DOF hydraulic motion platform simulator (Micro Motion System): the reversal bump and its compensation.",
    )
    parser.add_argument("--version", action="version", version=f"hexsim {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    _add_run(sub)
    _add_compare(sub)
    _add_tune(sub)
    _add_validate(sub)
    _add_friction(sub)
    _add_calibrate(sub)
    _add_sweep(sub)
    _add_modes(sub)
    _add_accept(sub)
    _add_bench(sub)
    _add_machine(sub)
    _add_serve(sub)
    _add_fmu(sub)
    _add_cue_tune(sub)
    return parser


def _machine_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--machine", metavar="NAME|FILE.json", default=None,
                   help="the machine: a machine file (docs/machine-file.md) or a built-in's name "
                        "(hexsim machine list; default micro_motion_system, the seed's appendix A)")


def _add_machine(sub) -> None:
    """The ``machine`` command: show, set and list machine files."""
    ma = sub.add_parser("machine", help="show, edit or list machine files (valve, cylinder, supply, load, controller)",
                        description="A machine file says everything hexsim assumes about a machine "
                        "(docs/machine-file.md). show prints a complete one, set edits keys of one (checked "
                        "before it is written), list names the built-in ones.")
    actions = ma.add_subparsers(dest="action", required=True)
    show = actions.add_parser("show", help="print a complete machine file (default: the built-in micro_motion_system)")
    show.add_argument("machine", nargs="?", default=None, metavar="NAME|FILE.json")
    st = actions.add_parser("set", help="set keys of a machine file: hexsim machine set FILE key=value …")
    st.add_argument("file", type=pathlib.Path, help="the machine file to edit (made from the built-in default if "
                    "it does not exist)")
    st.add_argument("assignments", nargs="+", metavar="key=value",
                    help="dotted key and JSON value, e.g. valve.type=4-way cylinder.bore_m=0.016 load.mass_kg=null")
    actions.add_parser("list", help="the built-in machines")


def _worker_options(parser: argparse.ArgumentParser, what: str) -> None:
    """--jobs (default: the cores available) and --scheduler (Dask) for a command that runs workers."""
    parser.add_argument("--jobs", type=int, default=CORES, help=f"{what} (default: the cores available, %(default)s here)")
    parser.add_argument("--scheduler", metavar="ADDRESS", default=None,
                        help="run the workers on Dask: 'local' (a LocalCluster of --jobs processes) or a scheduler's "
                        "address, e.g. tcp://head-node:8786 (needs pip install \"hexsim[cluster]\")")


def _add_run(sub) -> None:
    """The ``run`` command's options."""
    run = sub.add_parser(
        "run",
        help="simulate a scenario headless and report its smoothness",
        description="Simulate a scenario and print its smoothness figures. Scenarios: "
        + ", ".join(SCENARIOS)
        + ", or file:PATH (CSV with time_s and dof_ref_{x,y,z}_m / dof_ref_{roll,pitch,yaw}_rad).",
    )
    _scenario_options(run)
    run.add_argument("--compensator", type=_compensator_arg, default="none", metavar="NAME|FILE.json",
                     help=f"reversal-bump compensator per leg: {', '.join(COMPENSATORS)} (default none), or a tuned "
                          "file written by hexsim tune")
    run.add_argument("--rrd", type=pathlib.Path, help="write a rerun recording (.rrd)")
    run.add_argument("--plot", type=pathlib.Path, help="write a figure of acceleration, flow curve, pressures, tracking (.png, .pdf or .svg)")
    run.add_argument("--json", type=pathlib.Path, help="write the metrics as JSON; - for stdout")
    run.add_argument("--log", type=pathlib.Path, help="write the run as a measurement log (CSV + JSON sidecar)")
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    run.add_argument("--cueing", choices=("classical", "mpc"), default="classical",
                     help="vehicle:PATH: the classical washout (default) or model-predictive cueing within the "
                          "machine's envelope (docs/motion-cueing.md)")
    run.add_argument("--washout", type=pathlib.Path, metavar="WASHOUT.json",
                     help="vehicle:PATH: the cueing's parameters, the classical washout's or, with --cueing mpc, the "
                          "MPC's (any subset; default: docs/motion-cueing.md)")
    _thresholds_option(run)


def _address(text: str) -> tuple[str, int]:
    """``HOST:PORT`` for argparse."""
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise argparse.ArgumentTypeError(f"{text!r} is not HOST:PORT")
    return host, int(port)


def _add_serve(sub) -> None:
    """The ``serve`` command's options."""
    se = sub.add_parser(
        "serve", help="a real-time virtual motion system your host computer drives over UDP (docs/serve.md)",
        description="Listen for the host's setpoint packets, simulate the platform in real time at the controller "
        "rate (hydraulics, bump, compensator) and send its state back; engage, neutral and park ramped; a lost host "
        "returns it to neutral. With --client: be the host instead (send a scenario's motion to --to).")
    _machine_option(se)
    se.add_argument("--compensator", type=_compensator_arg, default="none", metavar="NAME|FILE.json",
                    help=f"compensator per leg: {', '.join(COMPENSATORS)} (default none), or a tuned file")
    se.add_argument("--bind", default="127.0.0.1", help="address to listen on (default %(default)s; 0.0.0.0: all)")
    se.add_argument("--port", type=int, default=5005, help="UDP port to listen on (default %(default)s)")
    se.add_argument("--reply", type=_address, metavar="HOST:PORT",
                    help="where to send the state packets (default: the sender of the last accepted packet)")
    se.add_argument("--layout", type=pathlib.Path, metavar="LAYOUT.json",
                    help="the host packet's layout (default hexsim's, docs/serve.md)")
    se.add_argument("--state-layout", type=pathlib.Path, metavar="LAYOUT.json",
                    help="the state packet's layout (default hexsim's)")
    se.add_argument("--state-rate", type=_number, default=100.0, help="state packets per second (default %(default)s)")
    se.add_argument("--duration", type=_number, default=None,
                    help="seconds to serve (default 3600); with --client: the motion's length (default the scenario's)")
    se.add_argument("--keep", type=_number, default=600.0,
                    help="seconds of recording kept for --log / --rrd (the last; default %(default)s)")
    se.add_argument("--engage-time", type=_number, default=2.0, help="fade-in of the host's motion [s] (default 2)")
    se.add_argument("--timeout", type=_number, default=0.5,
                    help="silence after which the host is lost and the platform returns to neutral [s] (default 0.5)")
    se.add_argument("--log", type=pathlib.Path, help="write the session as a measurement log (CSV + JSON sidecar)")
    se.add_argument("--rrd", type=pathlib.Path, help="write the session as a rerun recording (.rrd)")
    se.add_argument("--json", type=pathlib.Path, help="write the session's report (timing, packets, modes) as JSON")
    se.add_argument("--client", metavar="SCENARIO",
                    help="be the host: send SCENARIO's platform motion (heave, file:PATH, vehicle:PATH, …) to --to")
    se.add_argument("--to", type=_address, default=("127.0.0.1", 5005), metavar="HOST:PORT",
                    help="--client: the motion system's address (default 127.0.0.1:5005)")
    se.add_argument("--rate", type=_number, default=100.0, help="--client: packets per second (default %(default)s)")


def _add_fmu(sub) -> None:
    """The ``fmu`` command's options."""
    fm = sub.add_parser(
        "fmu", help="a leg or the platform as an FMI 3.0 co-simulation FMU for your system model (docs/fmu.md)",
        description="Build an FMI 3.0 co-simulation FMU (pythonfmu3) of one leg (piston or valve setpoint and an "
        "external force in; position, velocity, acceleration, pressures, force, u_v and U_c out) or of the platform "
        "(six DOF setpoints in; pose, specific force at the head, legs out), from a machine file and a compensator. "
        "It runs hexsim's simulation in the Python hexsim is installed in.")
    fm.add_argument("kind", choices=("leg", "platform"), help="which FMU")
    _machine_option(fm)
    fm.add_argument("--compensator", type=_compensator_arg, default="none", metavar="NAME|FILE.json",
                    help=f"compensator: {', '.join(COMPENSATORS)} (default none), or a tuned file")
    fm.add_argument("--out", type=pathlib.Path, default=pathlib.Path("."),
                    help="folder to write HexsimLeg.fmu / HexsimPlatform.fmu into (default: here)")


def cmd_fmu(args: argparse.Namespace) -> int:
    from hexsim.interfaces.fmu import LEG_OUTPUTS, PLATFORM_INPUTS, PLATFORM_OUTPUTS, build_fmu

    path = build_fmu(args.kind, args.out, args.machine, args.compensator)
    inputs = "y_ref [m] or u_v_set [V], F_ext [N]" if args.kind == "leg" else \
        ", ".join(f"{p.name} [{p.unit}]" for p in PLATFORM_INPUTS)
    outputs = LEG_OUTPUTS if args.kind == "leg" else PLATFORM_OUTPUTS
    print(f"wrote {path} (FMI 3.0 co-simulation; communication steps of whole milliseconds)")
    print(f"  inputs: {inputs}")
    print(f"  outputs: {', '.join(p.name for p in outputs)}")
    print("  parameters: duration_s (at least the stop time), interpolation (2 cubic, 1 linear, 0 hold)"
          + (", closed_loop" if args.kind == "leg" else ""))
    return 0


def _add_cue_tune(sub) -> None:
    """The ``cue-tune`` command's options."""
    ct = sub.add_parser(
        "cue-tune", help="fit the classical washout to your manoeuvres and platform, write the --washout file "
        "(docs/motion-cueing.md)",
        description="Fit the classical washout's scales and corners to vehicle motions (docs/motion-cueing.md's "
        "vehicle files) on the machine's platform: the sensed-cue error on the ideal platform, in each axis' "
        "threshold, within the legs' stroke; write the washout file hexsim run vehicle:FILE --washout loads.")
    ct.add_argument("vehicles", nargs="+", metavar="VEHICLE.csv", help="the manoeuvres (vehicle-motion files)")
    _machine_option(ct)
    ct.add_argument("--washout", type=pathlib.Path, metavar="START.json",
                    help="the washout to start from and whose untuned numbers are kept (default the built-in)")
    ct.add_argument("--out", type=pathlib.Path, required=True, metavar="WASHOUT.json", help="the tuned washout file")
    ct.add_argument("--margin", type=_number, default=0.01, help="stroke kept free at each end [m] (default 0.01)")
    ct.add_argument("--iterations", type=int, default=30, help="differential evolution's generations (default 30)")
    ct.add_argument("--population", type=int, default=6, help="its population per tuned number (default 6)")
    ct.add_argument("--seed", type=int, default=0, help="the search's seed (default 0)")
    ct.add_argument("--json", type=pathlib.Path, help="write the figures before and after as JSON")


def cmd_cue_tune(args: argparse.Namespace) -> int:
    from hexsim.control.kinematics import HexapodGeometry
    from hexsim.control.washout import WashoutParams, read_vehicle
    from hexsim.plant.geometry import MICRO_MOTION_SYSTEM
    from hexsim.plant.machine import load_machine
    from hexsim.plant.model import load_model
    from hexsim.simulation.cue_tuning import tune_washout
    from hexsim.tables import write_json

    _check_outputs(args)
    if args.out.suffix.lower() != ".json" or not args.out.parent.exists():
        raise InputError(f"--out {args.out}: expected a .json file name in an existing folder")
    if args.iterations < 1 or args.population < 1:
        raise InputError(f"--iterations and --population must be at least 1, got {args.iterations} and {args.population}")
    machine = load_machine(args.machine)
    if machine.system != "hexapod":
        raise InputError(f"cue-tune needs a hexapod; --machine {machine.label} is a {machine.system}")
    vehicles = [read_vehicle(path) for path in args.vehicles]
    start = WashoutParams.from_file(args.washout) if args.washout else WashoutParams()
    geometry = HexapodGeometry.from_model(load_model("hexapod", "full", machine.effects, machine.geometry))
    head = (machine.geometry or MICRO_MOTION_SYSTEM).head_point
    tuning = tune_washout(vehicles, geometry, head, start=start, margin_m=args.margin, seed=args.seed,
                          maxiter=args.iterations, popsize=args.population)
    print("\n".join(tuning.lines()))
    write_json(args.out, tuning.tuned.document())
    print(f"wrote {args.out}; through the hydraulics: hexsim run vehicle:{args.vehicles[0]} --washout {args.out}")
    if args.json is not None:
        write_json(args.json, {"start": tuning.start.document(), "tuned": tuning.tuned.document(),
                               "before": [dataclasses.asdict(f) for f in tuning.before],
                               "after": [dataclasses.asdict(f) for f in tuning.after],
                               "evaluations": tuning.evaluations})
    return 0


def _compensator_arg(text: str) -> str:
    """A built-in compensator's name or a tuned file's path (``*.json``), for argparse."""
    if text in COMPENSATORS or text.endswith(".json"):
        return text
    raise argparse.ArgumentTypeError(f"invalid choice: {text!r} (choose from {', '.join(COMPENSATORS)}, or a tuned "
                                     "file FILE.json)")


def _add_tune(sub) -> None:
    """The ``tune`` command's options."""
    tu = sub.add_parser(
        "tune",
        help="choose and tune the reversal-bump compensator for a machine; write its file",
        description="Run every candidate compensator (the seed's buffered and directional, the model-based "
        "feedforward and its adaptive version, at several settings) on the motions of interest on the machine, "
        "choose the one whose worst motion keeps the smallest reversal bump against none, print the predicted "
        "smoothness of none, the seed's buffered and the tuned one, and write the tuned file that "
        "hexsim run --compensator FILE loads (docs/compensation.md).",
    )
    tu.add_argument("motions", nargs="?", default=None,
                    help="comma-separated scenarios to tune on (default: heave,roll,surge on a hexapod, actuator on "
                         "a single actuator)")
    tu.add_argument("--machine", metavar="NAME|FILE.json", help="the machine (a calibrated machine file or a built-in)")
    tu.add_argument("--duration", type=_number, default=20.0, help="simulated time of each run [s] (default 20)")
    tu.add_argument("--dead-band-tolerance", type=_number, default=None, metavar="V",
                    help="how far [V] each valve edge may open earlier or later than the machine file says: the "
                         "tuned compensator must not make a reversal worse on those neighbours (default 0.01; 0: "
                         "judge on the file and a drifting null only; docs/compensation.md)")
    tu.add_argument("--out", type=pathlib.Path, help="the tuned compensator file to write (.json)")
    tu.add_argument("--check", type=pathlib.Path, nargs="+", metavar="LOG.csv",
                    help="proof instead of tuning: logs of the machine running with --compensator, beside the machine "
                         "simulated with it on each log's setpoints (measured and predicted smoothness)")
    tu.add_argument("--from-logs", nargs="+", type=pathlib.Path, metavar="LOG.csv",
                    help="commissioning instead of tuning: logs of the machine running with --compensator (a tuned "
                    "file) read back into the model (each valve edge's curve from their flows and the calibration's "
                    "own logs'); writes the improved tuned file to --out (docs/compensation.md)")
    tu.add_argument("--machine-out", type=pathlib.Path, metavar="FILE.json",
                    help="--from-logs: also write the machine file with the curves read from the logs")
    tu.add_argument("--compensator", type=_compensator_arg, metavar="NAME|FILE.json",
                    help="--check: the compensator the logs ran with (a tuned file, or a built-in's name)")
    tu.add_argument("--json", type=pathlib.Path, help="also write every candidate's figures as JSON; - for stdout")
    _worker_options(tu, "worker processes")


def _add_compare(sub) -> None:
    """The ``compare`` command's options."""
    cmp = sub.add_parser(
        "compare",
        help="run every compensator on one scenario and print a league table",
        description="Run none, iterative-1, iterative-2, buffered, directional and oracle on the same scenario "
        "(in parallel worker processes) and print noise ratio, peak noise, reduction of the mean reversal peak "
        "against none and settling time, measured on the last quarter of the run.",
    )
    _scenario_options(cmp)
    cmp.add_argument("--compensators", default=",".join(COMPENSATORS[1:]),
                     help="comma-separated compensators to compare: built-in names or tuned files (FILE.json, "
                          "from hexsim tune); none is always included")
    _worker_options(cmp, "worker processes")
    cmp.add_argument("--plot", type=pathlib.Path, help="write the comparison figure (seed Fig. 5.12 layout; .png, .pdf or .svg)")
    cmp.add_argument("--json", type=pathlib.Path, help="write the per-compensator figures as JSON; - for stdout")
    _thresholds_option(cmp)


def _add_validate(sub) -> None:
    """The ``validate`` command's options."""
    val = sub.add_parser(
        "validate",
        help="confront the model with a measurement log: residual, missing effect, error before/after",
        description="Replay a measurement log (docs/measurement-log.md) through the model with the logged "
        "valve setpoints, judge every channel against its noise and numerical tolerance with the sensor "
        "calibration fitted, select the effects the nominal model lacks that pass a held-out test, and give a "
        "verdict: none, explained, partial or unexplained (with a sparse correction of the model's equations "
        "for the last two). Single-actuator logs: valve replay in windows; hexapod logs: closed-loop replay of "
        "the logged leg setpoints with the logged compensation fed forward.",
    )
    val.add_argument("log", type=pathlib.Path, help="the log's CSV file (its JSON sidecar next to it)")
    val.add_argument("--report", type=pathlib.Path, help="write report.md, residuals.png and validation.json here")
    val.add_argument("--json", type=pathlib.Path, help="write the result as JSON; - for stdout")
    _worker_options(val, "worker processes for the fits")
    val.add_argument("--without", default="", metavar="EFFECT[,EFFECT…]",
                     help="leave these library effects out of the candidates (an effect you know the machine "
                          "cannot have, or a check of what the tool says about an effect outside its list)")
    val.add_argument("--model", choices=("platform", "full"), default="platform",
                     help="hexapod logs: replay on the platform-only model (default) or the full multi-body model")
    _machine_option(val)
    val.add_argument("--quiet", action="store_true",
                     help="no progress (a bar on a terminal, one line per step otherwise)")


def _add_friction(sub) -> None:
    """The ``friction`` command's options."""
    fr = sub.add_parser(
        "friction",
        help="identify the Stribeck friction curve from a log (seed §2.3.3, eq. 2.3-2.4)",
        description="Estimate F_f = F_L - M ydd - M g along the stroke from P1 and P_s (or force_N) and the "
        "position, and fit the asymmetric Stribeck curve of seed eq. (2.4) with standard errors.",
    )
    fr.add_argument("logs", nargs="+", metavar="LOG[+LOG]",
                    help="the logs' CSV files (sidecars next to them); LOG_A+LOG_B pairs two runs of one experiment "
                    "that logged different pressures (p1_Pa in one, p2_Pa in the other)")
    _machine_option(fr)
    fr.add_argument("--plot", type=pathlib.Path, help="write the friction-velocity map (.png, .pdf or .svg)")
    fr.add_argument("--json", type=pathlib.Path, help="write the fitted parameters as JSON; - for stdout")


def _flow_areas(text: str) -> tuple[str, ...]:
    forms = tuple(f.strip() for f in text.split(",") if f.strip())
    bad = [f for f in forms if f not in FLOW_AREAS]
    if not forms or bad:
        raise argparse.ArgumentTypeError(f"unknown flow-area form {', '.join(bad) or repr(text)} "
                                         f"({', '.join(FLOW_AREAS)})")
    return forms


def _add_calibrate(sub) -> None:
    """The ``calibrate`` command's options."""
    ca = sub.add_parser(
        "calibrate",
        help="fit a machine file's nominal parameters to calibration experiments (open-loop constant commands, "
             "closed-loop motions; a hexapod's closed-loop logs: each leg's valve, the payload)",
        description="Grey-box calibration (docs/calibration.md): the valve's flow gain, overlap, null offset and "
        "edge matching, the supply and tank pressures and the friction per direction are fitted, each inside its "
        "data-sheet bracket, to the steady motions and end-stop pressures of open-loop constant-command logs; "
        "standard errors, correlations, what the logs cannot separate and which experiment would; held-out logs "
        "predicted. A hexapod's closed-loop logs calibrate each leg's valve edges (the legs section), the bulk "
        "modulus, the friction and the payload. Writes the calibrated machine file.",
    )
    ca.add_argument("logs", nargs="+", type=pathlib.Path, metavar="LOG", help="the calibration experiments' CSV files")
    _machine_option(ca)
    ca.add_argument("--out", type=pathlib.Path, required=True, metavar="CALIBRATED.json",
                    help="write the calibrated machine file here")
    ca.add_argument("--hold-out", type=pathlib.Path, nargs="+", default=[], metavar="LOG",
                    help="logs predicted, not fitted (their error before and after is reported)")
    ca.add_argument("--dynamics", choices=("auto", "always", "never"), default="auto",
                    help="evidence from transients (the windowed valve replay): auto (default) for every log that is "
                         "not an open-loop constant-command experiment, always (those too), never (steady features only)")
    ca.add_argument("--flow-area", type=_flow_areas, metavar="FORM[,FORM…]",
                    help="with transients, the valve flow-area forms to calibrate and choose among by the held-out "
                         "windows (smooth, port, quadratic, sharp; default the machine's own and, for the seed's "
                         "(3.11) family, the others); curve: then each edge's curve read from the logs' flows over "
                         "every command they reach (corners and an underlap included; needs p1_Pa), kept if it "
                         "predicts the held-out windows 10 %% better; without this option the curves are tried "
                         "whenever the chosen form misses its own logs' budget (docs/calibration.md)")
    ca.add_argument("--no-cross-validation", action="store_true",
                    help="skip the leave-one-log-out refits (one per log)")
    ca.add_argument("--keep-worse", action="store_true",
                    help="write the calibrated file even when it predicts its own logs' held-out windows worse than "
                         "the prior (by default nothing is written then, exit 2)")
    ca.add_argument("--report", type=pathlib.Path, metavar="DIR",
                    help="write report.md and features.png (measured against predicted) here")
    ca.add_argument("--json", type=pathlib.Path, help="write the report as JSON; - for stdout")


def _add_sweep(sub) -> None:
    """The ``sweep`` command's options."""
    sw = sub.add_parser(
        "sweep",
        help="run a grid of scenarios / controller / compensator settings in worker processes",
        description="Run every combination of the --grid values (any run option, e.g. --grid compensator=none,"
        "buffered --grid buffer-time=1,3 --grid frequency=0.5,1) in worker processes, with a progress bar, and "
        "write one row of metrics per grid point (CSV and/or JSON). Options not in the grid apply to every run.",
    )
    _scenario_options(sw)
    sw.add_argument("--compensator", choices=sorted(COMPENSATORS), default="none",
                    help="compensator of every run unless the grid varies it (default none)")
    sw.add_argument("--grid", action="append", default=[], metavar="NAME=V1,V2,…",
                    help="an option to vary and its values (repeatable); NAME is a run option without the dashes")
    _worker_options(sw, "worker processes")
    sw.add_argument("--start-method", choices=START_METHODS, default=None,
                    help="how workers start: fork (default where available: they inherit everything imported) "
                    "or spawn/forkserver (a fresh interpreter, ~2.5 s of imports each)")
    sw.add_argument("--csv", type=pathlib.Path, help="write the table as CSV")
    sw.add_argument("--json", type=pathlib.Path, help="write the table as JSON; - for stdout")
    sw.add_argument("--quiet", action="store_true", help="no progress bar")
    sw.set_defaults(command_parser=sw)  # the grid reads its options' types and choices


def _add_modes(sub) -> None:
    """The ``modes`` command's options."""
    mo = sub.add_parser(
        "modes",
        help="oil-spring modes of the hexapod (linearised, Hz, with the dominant degree of freedom)",
        description="Linearise the hexapod at the neutral pose: each leg's oil column a spring E A1^2 / V1 (seed "
        "eq. 3.7), the inertia MuJoCo's (platform, legs, constraints); print the six modes in Hz with the degree "
        "of freedom that holds most of each mode's kinetic energy.",
    )
    mo.add_argument("--payload", type=_payload, metavar="KG[@X,Y[,Z]]",
                    help="a payload of KG kg added to the platform (600 kg built in) at X,Y,Z m (platform frame), as for run")
    mo.add_argument("--json", type=pathlib.Path, help="write the modes as JSON; - for stdout")
    _machine_option(mo)


def _thresholds_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--thresholds", type=pathlib.Path, metavar="THRESHOLDS.json",
                   help="your perception thresholds (any of x_mps2, y_mps2, z_mps2, roll_degps, pitch_degps, "
                        "yaw_degps, stimulus_s, seat_mps2; default Benson et al. and ISO 2631-1 Annex C; "
                        "docs/perception.md)")


def _thresholds(args: argparse.Namespace):
    from hexsim.simulation.perception import DEFAULT_THRESHOLDS, Thresholds

    return DEFAULT_THRESHOLDS if getattr(args, "thresholds", None) is None else Thresholds.from_file(args.thresholds)


def _add_accept(sub) -> None:
    """The ``accept`` command's options."""
    ac = sub.add_parser(
        "accept",
        help="run the objective motion tests (frequency response, turn-around, leg balance, repeatability, envelope, "
             "OMCT) against your tolerance file",
        description="The motion tests simulators are qualified with (14 CFR Part 60 app. A/C, ICAO 9625, the OMCT; "
        "docs/acceptance.md) on the simulated machine: the sections of the tolerance file are the tests run, each "
        "measured figure is checked against its limits, and the report (report.md with figures, acceptance.json) "
        "gives figure, tolerance and pass/fail; with --compensator, beside the uncompensated machine's. Exit code 1 "
        "when a check fails.",
    )
    ac.add_argument("--tolerances", type=pathlib.Path, required=True, metavar="TOLERANCES.json",
                    help="your tolerance file (docs/acceptance.md; examples/acceptance_tolerances.json)")
    ac.add_argument("--report", type=pathlib.Path, required=True, metavar="DIR",
                    help="write report.md, acceptance.json and the figures here")
    ac.add_argument("--compensator", choices=sorted(COMPENSATORS), default="none",
                    help="also run the tests with this compensator, beside none (default: none only)")
    ac.add_argument("--washout", type=pathlib.Path, metavar="WASHOUT.json",
                    help="the classical washout of the OMCT (default: docs/motion-cueing.md)")
    ac.add_argument("--log", type=pathlib.Path, action="append", default=[], metavar="LOG.csv",
                    help="a measured log of a test motion (dof_ref_* and leg positions; repeatable): its frequency-"
                         "response point and turn-around bump, measured and simulated, checked beside the tests")
    _machine_option(ac)
    _thresholds_option(ac)
    _worker_options(ac, "worker processes for the sine runs")
    ac.add_argument("--quiet", action="store_true", help="no progress lines")


def cmd_accept(args: argparse.Namespace) -> int:
    from hexsim.control.washout import WashoutParams
    from hexsim.simulation.acceptance import Tolerances

    if args.jobs < 1:
        raise InputError(f"--jobs must be at least 1, got {args.jobs}")
    if not args.report.parent.exists():
        raise InputError(f"--report {args.report}: folder {args.report.parent} does not exist")
    if args.report.exists() and not args.report.is_dir():
        raise InputError(f"--report {args.report}: exists and is not a folder")
    tol = Tolerances.read(args.tolerances)
    thresholds = _thresholds(args)
    washout = WashoutParams.from_file(args.washout) if args.washout else None
    from hexsim.plant.machine import load_machine

    machine = load_machine(args.machine)
    if machine.system != "hexapod":
        raise InputError(f"--machine {machine.label}: the motion tests are a hexapod's; this machine is a {machine.system}")
    from hexsim.outputs.acceptance_report import write_report
    from hexsim.simulation.acceptance import run_acceptance
    from hexsim.simulation.config import RunConfig

    if args.log:  # every log checked before the tests run
        from hexsim.measured.acceptance_logs import read_test_log

        for path in args.log:
            read_test_log(path, RunConfig.from_machine(machine, "heave"))
    results = []
    for name in dict.fromkeys(("none", args.compensator)):
        base = RunConfig.from_machine(machine, "heave", compensator=name)
        say = None if args.quiet else (lambda text, n=name: _progress_line(f"compensator {n}: {text}"))
        results.append(run_acceptance(base, tol, washout, jobs=args.jobs, progress=say, thresholds=thresholds))
        if args.log:
            from hexsim.measured.acceptance_logs import add_log_tests

            if say:
                say(f"{len(args.log)} measured log(s)")
            add_log_tests(results[-1], args.log, base, tol)
    for r in results:
        judged = [c for c in r.checks if c.passed is not None]
        failed = [c for c in judged if not c.passed]
        print(f"compensator {r.compensator}: {len(judged) - len(failed)} of {len(judged)} checks passed"
              + "".join(f"\n  FAIL {c.test}: {c.item} = {c.value:.4g} {c.unit} (tolerance {c.limit})" for c in failed))
    for path in write_report(args.report, results, tol):
        print(f"wrote {path}")
    return 1 if any(r.passed is False for r in results) else 0


def _add_bench(sub) -> None:
    """The ``bench`` command's options."""
    be = sub.add_parser(
        "bench",
        help="time the simulator against bare mj_step on the same model (ratios, real-time factors)",
        description="In one process: bare mj_step on the hexapod, the full hexapod (compiled hydraulics, P control, "
        "buffered compensator) with the native and the python engine, the fast scheme (dt 1e-3 s), the single "
        "actuator and the compiled replay kernel; median of the repeats.",
    )
    be.add_argument("--duration", type=_number, default=2.0, help="simulated seconds per repeat (default 2, min 1.5)")
    be.add_argument("--repeats", type=int, default=3, help="repeats per case, median reported (default 3)")
    be.add_argument("--json", type=pathlib.Path, help="write the timings as JSON; - for stdout")
    be.add_argument("--calibrate", action="store_true", help="also time hexsim calibrate on two 20 s open-loop logs "
                    "of the built-in servo_cylinder, two 20 s closed-loop logs of the seed's actuator (against bare "
                    "mj_step over their 40 s) and one 20 s hexapod log (against bare mj_step of the hexapod over 20 s)")
    be.add_argument("--sweep", action="store_true", help="also time an 8-run sweep with 1 worker, 2 forked and 2 spawned workers "
                    "(about 75 s per repeat)")


def cmd_bench(args: argparse.Namespace) -> int:
    from hexsim.bench import run_bench, table

    _check_outputs(args)
    if args.repeats < 1:
        raise InputError(f"--repeats must be at least 1, got {args.repeats}")
    if args.duration < 1.5:
        raise InputError(f"--duration must be at least 1.5 s (2 Hz scenarios), got {args.duration:g}")
    result = run_bench(args.duration, args.repeats, sweep=args.sweep, calibrate=args.calibrate)
    print(table(result))
    if args.json:
        write_json(args.json, result)
        print(f"wrote {args.json}")
    return 0


def _progress_line(text: str) -> None:
    """A progress line on stderr for runs whose stderr is not a terminal (a log file, CI)."""
    print(f"hexsim: {text}", file=sys.stderr, flush=True)


def cmd_validate(args: argparse.Namespace) -> int:
    from hexsim.measured.scoring import left_out_text
    from hexsim.measured.measurement import read_log
    from hexsim.measured.reports.validation import effect_label, plus_minus
    from hexsim.measured.validation import validate

    _check_outputs(args)
    if args.jobs < 1:
        raise InputError(f"--jobs must be at least 1, got {args.jobs}")
    from hexsim.measured.candidates import CANDIDATE_NAMES

    without = tuple(name.strip() for name in args.without.split(",") if name.strip())
    for name in without:
        if name not in CANDIDATE_NAMES:
            raise InputError(f"--without: unknown effect {name!r} (the library: {', '.join(CANDIDATE_NAMES)})")
    if args.report is not None and args.report.exists() and not args.report.is_dir():
        raise InputError(f"--report {args.report}: exists and is not a folder")
    log = read_log(args.log, machine=args.machine)
    print(f"machine: {log.machine.label}")
    for note in log.assumed:
        print(f"assumed: {note}")
    if log.missing:
        print(f"not checked (missing columns): {', '.join(log.missing)}")
    doc = validate(log, report=args.report, json_path=args.json, jobs=args.jobs, without=without, model=args.model,
                   progress=not args.quiet and sys.stderr.isatty(),
                   notify=None if args.quiet or sys.stderr.isatty() else _progress_line)
    left_out = doc["windows"].get("left_out")
    if left_out and left_out_text(left_out):
        print(f"left out: {left_out_text(left_out)}")
    print(f"verdict: {doc['verdict']}")
    for line in doc["conclusions"]:
        print(f"  {line}")
    print(f"added effect: {doc['added_effect']}")
    for effect in doc["added_effects"]:
        print(f"  {effect_label(effect)}: " + ", ".join(f"{k} = {plus_minus(v)}" for k, v in effect["parameters"].items()))
    print(f"{'channel':14s} {'NRMSE before':>13s} {'after':>9s} {'held-out RMS / budget':>22s}")
    for ch, before in doc["error_before"].items():
        print(f"{ch:14s} {before:13.4g} {doc['error_after'][ch]:9.4g} {doc['held_out_rms_in_budgets'][ch]:22.3g}")
    if doc["candidates"]:
        print(f"{'candidate':20s} {'on top of':>16s} {'held-out gain':>13s} {'p':>9s}  verdict")
    for c in doc["candidates"]:
        why = "accepted" if c["accepted"] else "; ".join(c["rejected_because"])
        print(f"{effect_label(c):20s} {'+'.join(c['on_top_of']) or 'nominal':>16s} {c['held_out_gain']:+13.3f} "
              f"{c['p_value']:9.2g}  {why}")
    for path in (args.report, args.json):
        if path is not None:
            print(f"wrote {path}")
    return 0


def cmd_friction(args: argparse.Namespace) -> int:
    from hexsim.measured.friction_id import identify_friction
    from hexsim.measured.reports.friction import plot_map
    from hexsim.measured.measurement import read_log

    _check_outputs(args)
    logs = [[read_log(pathlib.Path(part), machine=args.machine, needs=("pos_m",)) for part in item.split("+")] for item in args.logs]
    result = identify_friction(logs)
    print(f"machine: {result['machine']}")
    print(f"friction from {result['force_source']}, M = {result['mass_kg']:g} kg, "
          f"inclination {result['inclination_deg']:g}°, {result['experiments']} experiment(s); "
          f"acceleration: {result['acceleration_source']}")
    for row in result["steady"]:
        fitted = "no fit" if row["fitted_N"] is None else f"{row['fitted_N']:7.1f} N fitted"
        print(f"  steady {row['velocity_mps'] * 1e3:+8.1f} mm/s: F_f = {row['friction_N']:7.1f} N measured, {fitted}")
    for side in ("positive", "negative"):
        if "cannot_fit" in result[side]:
            print(f"  {side:8s}: cannot fit: {result[side]['cannot_fit']}")
            continue
        ps = result[side]["parameters"]
        print(f"  {side:8s}: " + ", ".join(
            f"{k} unidentifiable" if "unidentifiable" in v else f"{k} = {v['value']:.4g} ± {v['std_error']:.2g} {v['unit']}"
            for k, v in ps.items()) + f"  (rms {result[side]['rms_N']:.3g} N, robust scatter "
            f"{result[side]['scatter_N']:.3g} N, {result[side]['samples']} samples)")
        reasons: dict[str, list[str]] = {}
        for k, v in ps.items():
            if "unidentifiable" in v:
                reasons.setdefault(v["unidentifiable"], []).append(k)
        for why, names in reasons.items():
            print(f"    {', '.join(names)}: {why}")
    if args.json:
        write_json(args.json, result)
        print(f"wrote {args.json}")
    if args.plot:
        plot_map(result, args.plot)
        print(f"wrote {args.plot}")
    return 0


def cmd_calibrate(args: argparse.Namespace) -> int:
    from hexsim.measured.calibration import calibrate
    from hexsim.measured.reports.calibration import table
    from hexsim.measured.measurement import read_log
    from hexsim.plant.machine import dump, load_machine, machine_from_document

    _check_outputs(args)
    if args.out.suffix.lower() != ".json":
        raise InputError(f"--out {args.out}: expected a .json machine file name")
    if not args.out.parent.exists():
        raise InputError(f"--out {args.out}: folder {args.out.parent} does not exist")
    if args.report is not None and args.report.exists() and not args.report.is_dir():
        raise InputError(f"--report {args.report}: exists and is not a folder")
    for path in (*args.logs, *args.hold_out):
        if path.with_suffix(".json").resolve() == args.out.resolve():
            raise InputError(f"--out {args.out} is the sidecar of the log {path}: name the calibrated machine file "
                             f"otherwise")
    machine = load_machine(args.machine)
    logs = [read_log(path, machine=machine) for path in args.logs]
    held = [read_log(path, machine=machine) for path in args.hold_out]
    print(f"machine: {machine.label}; calibrating on {len(logs)} log(s), {len(held)} held out", flush=True)
    calibrated, report = calibrate(logs, machine, held_out=held, cross_validate=not args.no_cross_validation,
                                   dynamics=args.dynamics, flow_areas=args.flow_area,
                                   notify=lambda text: print(text, file=sys.stderr, flush=True))
    print(table(report))
    worse = report.get("own_budget", {}).get("worse_than_prior", {})
    if worse and not args.keep_worse:
        raise InputError(
            "calibrate: the calibrated model predicts its own logs' held-out windows worse than the prior "
            f"{machine.label} did (" + ", ".join(f"{ch} {b:.3g} → {a:.3g}" for ch, (b, a) in worse.items())
            + " budgets); nothing written. The prior is the better model of these logs: give logs that excite what "
            "was fitted (docs/calibration.md), another --flow-area, or --keep-worse to write it anyway")
    doc = calibrated.document()
    machine_from_document(doc, str(args.out))  # checked as any machine file before it is written
    write_atomic(args.out, lambda tmp: tmp.write_text(dump(doc), encoding="utf-8"))
    print(f"wrote {args.out}")
    if args.report is not None:
        from hexsim.measured.reports.calibration import write_folder

        write_folder(args.report, report)
        print(f"wrote {args.report}")
    if args.json:
        write_json(args.json, report)
        print(f"wrote {args.json}")
    return 0


def cmd_modes(args: argparse.Namespace) -> int:
    from hexsim.plant.machine import load_machine
    from hexsim.simulation.modes import modes_table, oil_spring_modes

    _check_outputs(args)
    machine = load_machine(args.machine)
    if machine.system != "hexapod":
        raise InputError(f"--machine {machine.label}: modes are the hexapod's; this machine is a {machine.system}")
    from hexsim.plant.model import load_model

    mass = float(load_model("hexapod", geometry=machine.geometry).body("platform").mass[0])
    effects, payload = machine.effects, f"machine {machine.label}, {mass:g} kg platform"
    if args.payload is not None:
        kg, at = args.payload
        effects = effects.replace(payload_kg=kg, payload_at_m=at)
        payload = f"{mass:g} kg platform with {kg:g} kg at ({', '.join(f'{v:g}' for v in at)}) m"
    modes = oil_spring_modes(machine.hydraulics, effects=effects, geometry=machine.geometry)
    print(modes_table(modes, payload))
    if args.json:
        data = {"configuration": payload, "pose": "neutral",
                "modes": [{"frequency_hz": mode.frequency_hz, "dominant": mode.dominant, "share": mode.share,
                           "shape": dict(zip(("x_m", "y_m", "z_m", "roll_rad", "pitch_rad", "yaw_rad"),
                                             mode.shape.tolist()))} for mode in modes]}
        write_json(args.json, data)
        print(f"wrote {args.json}")
    return 0


def _payload(text: str) -> tuple[float, tuple[float, float, float]]:
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


def _scenario_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("scenario", help="actuator, heave, surge, sway, roll, pitch, yaw, file:PATH (platform setpoints), "
                   "vehicle:PATH (a vehicle's motion at the driver's head, through the classical washout; "
                   "docs/motion-cueing.md) or valve:PATH (valve commands, open loop; a measurement log's CSV replays "
                   "as it is)")
    p.add_argument("--duration", type=_number, help="simulated time [s] (default: max(20 s, 6 periods); file: its length)")
    p.add_argument("--amplitude", type=_number,
                   help=f"sine amplitude [m for actuator/heave/surge/sway, rad for roll/pitch/yaw] "
                        f"(default {DEFAULT_AMPLITUDE['heave']} m, {DEFAULT_AMPLITUDE['roll']:.4f} rad)")
    p.add_argument("--frequency", type=_number, help=f"sine frequency [Hz] (default {DEFAULT_FREQUENCY})")
    p.add_argument("--seed", type=int, default=0, help="seed of the position-sensor noise (default 0)")
    _machine_option(p)
    p.add_argument("--kp", type=_number, help=f"P gain K_p [V/m] (default: the machine's, {ControllerParams.kp:g} built in); "
                   "this and the options below override the machine file")
    p.add_argument("--flow-area", choices=[f for f in FLOW_AREAS if f not in ("table", "curve")],
                   help="valve flow-area function: smooth a = 300 x_v^2 (seed eq. 3.11) blended onto the port's "
                        "opening above 0.78 V (default), quadratic (3.11 at every opening, as the seed simulated), "
                        "port (3.11 until the port's opening is smaller, a kink at 0.90 V) or sharp-edged with "
                        "overlap (eq. 3.3)")
    p.add_argument("--sensor-noise", type=_number,
                   help=f"rms noise on the measured piston position [m] (default {ControllerParams.position_noise:g})")
    p.add_argument("--fault", action="append", default=[], metavar="KIND:key=value,…",
                   help="inject a fault (repeatable): valve_stuck:leg=N,t=S,value=V | supply_loss:t=S[,ramp=S] | "
                        "sensor_frozen:leg=N,t=S | sensor_dropout:leg=N,t=S | end_stop:leg=N,t=S[,value=M] "
                        "(see hexsim/plant/faults.py)")
    p.add_argument("--payload", type=_payload, metavar="KG[@X,Y[,Z]]",
                   help="hexapod: a payload of KG kg added to the platform (600 kg built in), its centre of gravity at X,Y,Z m "
                        "in the platform frame (default its centre; Z default 0); negative KG: a lighter platform")
    p.add_argument("--keep-last", type=_number, metavar="SECONDS",
                   help="keep only the last SECONDS of the 1 kHz recording (long runs: memory stays flat; the "
                        "metrics and outputs cover that window)")
    p.add_argument("--engine", choices=("native", "python"), default="native",
                   help="the loop compiled (default) or as a Python MuJoCo control callback (same compiled leg step; runs any Python compensator at Python speed)")
    p.add_argument("--model", choices=("platform", "full"), default="platform",
                   help="the hexapod's formulation: 'platform' (default), the platform as the only body with the "
                        "legs as geometry, lumped masses and end stops (about 4x faster), or 'full', the multi-body "
                        "MJCF with leg bodies and closing constraints, the reference (see docs/performance.md)")
    p.add_argument("--timestep", type=_number, default=1e-4,
                   help="physics step [s] (default 1e-4, the seed's 10 kHz; must divide the 2 ms controller "
                        "period and the 1 ms record period; see docs/performance.md for the accuracy of larger steps)")
    p.add_argument("--warm-up", type=_number, metavar="DELTA_C",
                   help="warm the oil by DELTA_C °C over the run (seed §5.5 uses 15): density, viscous friction "
                        "and valve null change (see hexsim/plant/temperature.py)")
    d = CompensatorSettings()
    g = p.add_argument_group("compensator settings (defaults from the seed where it gives one)")
    g.add_argument("--buffer-time", type=_number, default=d.buffer_time,
                   help="buffered/directional: buffer length [s] (seed: 30000 samples at 10 kHz = %(default)s s)")
    g.add_argument("--velocity-band", type=_number, default=d.velocity_band,
                   help="|velocity| [m/s] counted as zero for the null estimate (seed k = %(default)s)")
    g.add_argument("--q-threshold", type=_number, default=d.q_threshold,
                   help="iterative: start value of the valve range q [V] (default %(default)s)")
    g.add_argument("--iterative-gain", type=_number, default=d.iterative_gain,
                   help="iterative: table update per velocity error [V/(m/s)] (default %(default)s)")
    g.add_argument("--held-maximum", choices=("per-side", "seed"), default=d.held_maximum,
                   help="iterative: read a off the table per side (default) or as the seed, one signed maximum")
    g.add_argument("--fade-time", type=_number, default=d.fade_time,
                   help="buffered/directional: parameter fade-in time constant [s] (default %(default)s)")
    g.add_argument("--velocity-cutoff", type=_number, default=d.velocity_cutoff_hz,
                   help="low-pass on the differentiated position [Hz] (default %(default)s)")


def _run_config(args: argparse.Namespace, compensator: str):
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
    _check_machine_scenario(machine, scenario)
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
        from hexsim.simulation.tuning import read_tuned

        compensator, settings, model = read_tuned(compensator)
    warm_up = WarmUp(delta_c=args.warm_up, duration_s=scenario.duration) if args.warm_up else None
    faults = tuple(Fault.parse(text) for text in args.fault)
    from hexsim.simulation.config import (
        RunConfig,  # MuJoCo and the kernels: only once the options are checked
    )

    return RunConfig(scenario=scenario, hydraulics=hydraulics, controller=controller, compensator=compensator,
                     machine=machine.name if machine.path is None else str(machine.path),
                     geometry=machine.geometry if machine.system == "hexapod" else None,
                     leg_changes=machine.leg_changes, compensator_settings=settings, compensator_model=model,
                     warm_up=warm_up, effects=effects, faults=faults, seed=args.seed,
                     engine=args.engine, keep_last_s=args.keep_last, model=args.model,
                     timestep=args.timestep, progress=not getattr(args, "quiet", True) and sys.stderr.isatty())


def _platform_envelope(machine, hydraulics, effects):
    """(PlatformLimits, head point (3,) [m]) of a hexapod machine for the MPC cueing: its envelope at the
    neutral pose (:func:`hexsim.simulation.acceptance.platform_limits`) and its occupant's head."""
    from hexsim.plant.geometry import MICRO_MOTION_SYSTEM
    from hexsim.simulation.acceptance import platform_limits
    from hexsim.simulation.config import RunConfig

    base = RunConfig(scenario=make_scenario("heave", duration=6.0), hydraulics=hydraulics,
                     controller=machine.controller, machine=machine.name if machine.path is None else str(machine.path),
                     geometry=machine.geometry, leg_changes=machine.leg_changes, effects=effects)
    return platform_limits(base), (machine.geometry or MICRO_MOTION_SYSTEM).head_point


def _check_machine_scenario(machine, scenario) -> None:
    """InputError if ``scenario`` cannot run on ``machine``: a hexapod motion on a single actuator, or a
    position setpoint on a machine without a position controller (controller.type none)."""
    if machine.system == "single-actuator" and scenario.system == "hexapod":
        raise InputError(f"--machine {machine.label} is a single actuator; scenario {scenario.name} needs a hexapod")
    if machine.open_loop and not scenario.open_loop:
        raise InputError(f"--machine {machine.label} has no position controller (controller.type none): run a valve "
                         f"command, valve:PATH, or set controller.type to P")


def cmd_machine(args: argparse.Namespace) -> int:
    import json

    from hexsim.plant.machine import (
        OCCUPANT_KEYS,
        builtin_names,
        dump,
        load_machine,
        machine_from_document,
        parse_assignment,
        set_keys,
    )

    if args.action == "list":
        for name in builtin_names():
            m = load_machine(name)
            print(f"{name:24s} {m.system:16s} {m.hydraulics.valve_type} valve  {m.description.split(': ')[0][:60]}")
        return 0
    if args.action == "show":
        sys.stdout.write(dump(load_machine(args.machine).document()))
        return 0
    path: pathlib.Path = args.file
    if path.suffix.lower() != ".json":
        raise InputError(f"{path}: expected a .json machine file")
    if not path.parent.exists():
        raise InputError(f"{path}: folder {path.parent} does not exist")
    if path.exists():
        try:
            doc = json.loads(path.read_text(encoding="utf-8"))
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise InputError(f"{path}: not valid JSON ({exc})") from None
        machine_from_document(doc, str(path))  # the file as it is must be a machine file
    else:
        doc = load_machine(None).document()
        doc["name"] = path.stem
    assignments = [parse_assignment(a) for a in args.assignments]
    new = set_keys(doc, assignments)
    if any(key == "hexapod.mjcf" and value is not None for key, value in assignments):
        # an MJCF is the hexapod now: the built hexapod's numbers a shown file carries go, unless set here
        given = {key for key, _ in assignments}
        dropped = [k for k in new.get("hexapod", {})
                   if not k.startswith("mjcf") and k not in OCCUPANT_KEYS and f"hexapod.{k}" not in given]
        for k in dropped:
            del new["hexapod"][k]
        if dropped:
            print("dropped " + ", ".join(f"hexapod.{k}" for k in dropped) + " (the MJCF is the hexapod now)")
    machine_from_document(new, str(path))  # checked before anything is written
    write_atomic(path, lambda tmp: tmp.write_text(dump(new), encoding="utf-8"))
    print(f"wrote {path}")
    return 0


def _check_outputs(args: argparse.Namespace) -> None:
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


def cmd_run(args: argparse.Namespace) -> int:
    _check_outputs(args)
    config = _run_config(args, args.compensator)  # every option checked before the heavy imports
    thresholds = _thresholds(args)
    from hexsim.outputs.logio import write_log
    from hexsim.outputs.plotting import plot_run
    from hexsim.outputs.report import run_report, summary_table
    from hexsim.outputs.rerun_log import write_rrd
    from hexsim.simulation.metrics import run_smoothness
    from hexsim.simulation.runner import simulate

    try:
        result = simulate(config)
    except WorkspaceError as exc:
        if config.scenario.cueing is None:
            raise
        raise WorkspaceError(f"{exc}: the washout's setpoints leave the workspace; lower its scale_specific_force or "
                             f"raise its hp_omega_radps / hp_break_radps (--washout FILE, docs/motion-cueing.md)") from None
    if config.scenario.cueing is not None:
        return _vehicle_outputs(args, result, thresholds)
    if config.scenario.open_loop:
        from hexsim.outputs.plotting import plot_open_loop
        from hexsim.outputs.report import open_loop_report, open_loop_table

        sm, report = None, open_loop_report(result)
        print(open_loop_table(report))
    else:
        sm = run_smoothness(result)
        perception = None
        if config.scenario.system == "hexapod":
            from hexsim.simulation.perception import bump_perception

            perception = bump_perception(result, sm, thresholds=thresholds)
        report = run_report(result, sm, perception)
        print(summary_table(report))
    written = []
    if args.json:  # without the wall time, so the same command writes the same bytes
        write_json(args.json, {k: v for k, v in report.items() if k not in ("realtime_factor", "wall_time_s")})
        written.append(args.json)
    if args.plot:
        if sm is None:
            plot_open_loop(args.plot, result)
        else:
            plot_run(args.plot, result, sm, perception)
        written.append(args.plot)
    if args.rrd:
        write_rrd(args.rrd, result, sm, perception if sm is not None else None)
        written.append(args.rrd)
    if args.log:
        written.extend(write_log(args.log, result))
    for path in written:
        print(f"wrote {path}")
    return 0


def _vehicle_outputs(args: argparse.Namespace, result, thresholds) -> int:
    """``hexsim run vehicle:PATH``: the cue report on stdout, and the files asked for."""
    from hexsim.outputs.logio import write_log
    from hexsim.outputs.plotting import plot_cueing
    from hexsim.outputs.rerun_log import write_rrd
    from hexsim.simulation.cueing import cue_report, cue_table

    cfg = result.config
    report = cue_report(result, thresholds)
    solver = cfg.scenario.cueing[2].solver
    cueing = "washout" if solver is None else "mpc cueing"
    print(f"scenario  {cfg.scenario.name} (hexapod, {cfg.scenario.duration:g} s, {cueing} {report.washout}, "
          f"compensator {cfg.compensator_name})\nmachine   {cfg.machine_label}")
    if solver is not None:
        print(f"mpc       {solver['programmes']} programmes of {solver['variables']} variables, "
              f"{solver['unsolved']} unsolved; solve {solver['solve_ms_mean']:.1f} ms mean, "
              f"{solver['solve_ms_max']:.1f} ms largest: {solver['real_time_factor']:.1f}x real time")
    print(cue_table(report))
    written = []
    if args.json:
        doc = {"scenario": cfg.scenario.name, "machine": cfg.machine_label, "compensator": cfg.compensator_name,
               "duration_s": cfg.scenario.duration, "cueing": "classical" if solver is None else "mpc",
               "cueing_solver": solver, **report.document()}
        write_json(args.json, doc)
        written.append(args.json)
    if args.plot:
        plot_cueing(args.plot, result, report)
        written.append(args.plot)
    if args.rrd:
        write_rrd(args.rrd, result, None, cueing=report)
        written.append(args.rrd)
    if args.log:
        written.extend(write_log(args.log, result))
    for path in written:
        print(f"wrote {path}")
    return 0


def cmd_compare(args: argparse.Namespace) -> int:
    from hexsim.outputs.plotting import plot_compare
    from hexsim.simulation.comparison import compare, league_table

    _check_outputs(args)
    given = tuple(n.strip() for n in args.compensators.split(",") if n.strip())
    names = tuple(n for n in given if not n.endswith(".json"))
    unknown = [n for n in names if n not in COMPENSATORS]
    if unknown:
        raise InputError(f"--compensators: unknown compensator {unknown[0]!r}; choose from {', '.join(COMPENSATORS)} "
                         "or a tuned file (.json)")
    if args.jobs < 1:
        raise InputError(f"--jobs must be at least 1, got {args.jobs}")
    base = _run_config(args, "none")
    labelled = []
    for path in dict.fromkeys(n for n in given if n.endswith(".json")):
        from hexsim.simulation.tuning import read_tuned

        name, settings, model = read_tuned(path)  # InputError naming the file
        labelled.append((f"{pathlib.Path(path).name} ({name})", dataclasses.replace(
            base, compensator=name, compensator_settings=settings, compensator_model=model)))
    thresholds = _thresholds(args)
    print(f"comparing {', '.join(dict.fromkeys(('none', *names, *(label for label, _ in labelled))))} on {base.scenario.name} "
          f"({base.scenario.duration:g} s, machine {base.machine_label}) with {worker_count(args.jobs)} worker(s)…",
          flush=True)
    entries = compare(base, names, jobs=args.jobs, thresholds=thresholds, labelled=tuple(labelled))
    print(league_table(entries))
    written = []
    if args.json:
        sc = base.scenario
        write_json(args.json, {"scenario": sc.name, "machine": base.machine_label, "duration_s": sc.duration,
                               "frequency_hz": sc.frequency,
                               "compensators": {e.compensator: e.figures() for e in entries}})
        written.append(args.json)
    if args.plot:
        plot_compare(args.plot, entries, base.scenario)
        written.append(args.plot)
    for path in written:
        print(f"wrote {path}")
    return 0


def cmd_tune(args: argparse.Namespace) -> int:
    from hexsim.plant.machine import load_machine

    if args.check:
        return _tune_check(args)
    if args.from_logs:
        return _tune_from_logs(args)
    if args.out is None:
        raise InputError("tune: --out FILE.json is needed (or --check LOG.csv … --compensator FILE.json)")
    if args.jobs < 1:
        raise InputError(f"--jobs must be at least 1, got {args.jobs}")
    if args.out.suffix != ".json":
        raise InputError(f"--out {args.out}: the tuned file is JSON (.json)")
    if not args.out.parent.exists():
        raise InputError(f"--out {args.out}: folder {args.out.parent} does not exist")
    _check_outputs(args)
    machine = load_machine(args.machine)
    default = "heave,roll,surge" if machine.system == "hexapod" else "actuator"
    motions = tuple(m.strip() for m in (args.motions or default).split(",") if m.strip())
    for m in motions:
        _check_machine_scenario(machine, make_scenario(m, duration=args.duration))
    from hexsim.simulation.config import RunConfig
    from hexsim.simulation.tuning import CANDIDATES, DEAD_BAND_TOLERANCE_V, neighbours, tune, tune_table, write_tuned

    tolerance = DEAD_BAND_TOLERANCE_V if args.dead_band_tolerance is None else args.dead_band_tolerance
    around = neighbours(tolerance)
    base = RunConfig.from_machine(machine, make_scenario(motions[0], duration=args.duration))
    print(f"tuning on {', '.join(motions)} ({args.duration:g} s each, machine {base.machine_label} and "
          f"{len(around) - 1} neighbours): {len(CANDIDATES)} candidates with {worker_count(args.jobs)} worker(s)…",
          flush=True)
    result = tune(base, motions, jobs=args.jobs, progress=sys.stderr.isatty(), neighbours=around)
    for label, why in result.refused.items():
        print(f"refused {label}: {why}")
    for label, why in result.worse.items():
        print(f"not chosen {label}: {why}")
    print(tune_table(result))
    motion, neighbour = result.worst_at
    print(f"tuned: {result.chosen.label} (worst case {100 * (1 - result.worst_ratio):.0f} % below none, on {motion}, "
          f"{neighbour}; neighbours: {', '.join(n.name for n in around)})")
    write_tuned(args.out, result, base, motions)
    print(f"wrote {args.out}")
    if args.json:
        write_json(args.json, {"motions": list(motions), "machine": base.machine_label, "chosen": result.chosen.label,
                               "refused": result.refused, "candidates": result.rows})
        print(f"wrote {args.json}")
    return 0


def _tune_from_logs(args: argparse.Namespace) -> int:
    """``hexsim tune --from-logs LOG… --compensator FILE --machine CAL --out FILE``: commissioning (the logs' evidence
    into the model, the tuned file's leg model built again from it)."""
    if args.check:
        raise InputError("tune: --from-logs and --check are two steps; run one at a time")
    if args.compensator is None or not args.compensator.endswith(".json"):
        raise InputError("tune --from-logs: --compensator FILE.json (the tuned file the logs ran with) is needed")
    for path in (*args.from_logs, pathlib.Path(args.compensator)):
        if not path.exists():
            raise InputError(f"{path}: no such file")
    if args.out is None or args.out.suffix != ".json" or not args.out.parent.exists():
        raise InputError(f"tune --from-logs: --out FILE.json in an existing folder is needed, got {args.out}")
    for out in (args.out, args.machine_out):
        if out is not None and out.resolve() == pathlib.Path(args.compensator).resolve():
            raise InputError(f"{out}: would overwrite the tuned file the logs ran with; write the improved one elsewhere")
    from hexsim.measured.commissioning import commission
    from hexsim.plant.machine import dump, load_machine
    from hexsim.simulation.config import RunConfig
    from hexsim.simulation.tuning import retuned

    machine = load_machine(args.machine)
    learned = commission(list(args.from_logs), machine)
    curves = learned.curves
    print(f"read the valve's curves from {len(learned.logs)} log(s) (P→A to {curves.pa.reach:.3g} V, A→T to "
          f"{curves.at.reach:.3g} V): " + ", ".join(pathlib.Path(p).name for p in learned.logs))
    base = RunConfig.from_machine(learned.machine, "actuator")
    doc = retuned(args.compensator, base, learned.model, learned.report(), jobs=args.jobs)
    for label, rows in doc["predicted"].items():
        for row in rows:
            print(f"predicted {label:<30} {row['motion']:<9} mean rev. peak {row['final_mean_reversal_peak']:.4f}")
    write_json(args.out, doc)
    print(f"wrote {args.out}")
    if args.machine_out:
        args.machine_out.write_text(dump(learned.machine.document()))
        print(f"wrote {args.machine_out}")
    return 0


def _tune_check(args: argparse.Namespace) -> int:
    """``hexsim tune --check LOG… --compensator FILE``: measured and predicted smoothness side by side."""
    if args.compensator is None:
        raise InputError("tune --check: --compensator NAME|FILE.json (the compensator the logs ran with) is needed")
    for path in args.check:
        if not path.exists():
            raise InputError(f"--check {path}: no such file")
    from hexsim.plant.machine import load_machine
    from hexsim.simulation.config import RunConfig
    from hexsim.measured.proof import proof
    from hexsim.simulation.tuning import compensator_options

    machine = load_machine(args.machine)
    scenario = "heave" if machine.system == "hexapod" else "actuator"
    base = RunConfig.from_machine(machine, scenario, **compensator_options(args.compensator))
    rows = [proof(path, base) for path in args.check]
    print(f"{'log':<28} {'':<10} {'mean rev. peak':>14} {'max rev. peak':>13} {'noise ratio':>11}")
    for r in rows:
        for what in ("measured", "predicted"):
            f = r[what]
            peak = f"{f['max_reversal_peak']:.4f}" if f["max_reversal_peak"] is not None else "—"
            print(f"{pathlib.Path(r['log']).name:<28} {what:<10} {f['mean_reversal_peak']:>14.4f} {peak:>13} "
                  f"{f['noise_ratio']:>11.4f}")
    print(f"predicted: {base.machine_label} with {base.compensator_name} on each log's setpoints, read with the "
          "log's accelerometer noise (m/s², from the third period)")
    for r in rows:
        print(f"{pathlib.Path(r['log']).name} (accelerometer noise {r['accelerometer_noise_mps2']:.3f} m/s²): "
              f"{r['verdict']['sentence']}")
    if args.json:
        write_json(args.json, {"machine": base.machine_label, "proofs": rows})
        print(f"wrote {args.json}")
    return 0


#: Options a sweep grid may vary (argparse dest names).
GRID_OPTIONS = ("scenario", "machine", "duration", "amplitude", "frequency", "seed", "kp", "flow_area", "sensor_noise", "engine", "model",
                "timestep", "warm_up", "compensator", "buffer_time", "velocity_band", "q_threshold", "iterative_gain",
                "held_maximum", "fade_time", "velocity_cutoff")


def _parse_grid(parser: argparse.ArgumentParser, items: list[str]) -> dict[str, list]:
    """``NAME=V1,V2`` items to {dest: [values]}, each value converted and checked like the option itself."""
    actions = {a.dest: a for a in parser._actions}
    grid: dict[str, list] = {}
    for item in items:
        name, sep, values = item.partition("=")
        dest = name.strip().lstrip("-").replace("-", "_")
        if not sep or not values.strip():
            raise InputError(f"--grid {item!r}: expected NAME=V1,V2,…")
        if dest not in GRID_OPTIONS:
            raise InputError(f"--grid {item!r}: {name!r} is not an option a sweep can vary; "
                             f"choose from {', '.join(o.replace('_', '-') for o in GRID_OPTIONS)}")
        if dest in grid:
            raise InputError(f"--grid {item!r}: {name!r} is given twice")
        action = actions[dest]
        parsed = []
        for text in values.split(","):
            text = text.strip()
            try:
                value = action.type(text) if action.type else text
            except (argparse.ArgumentTypeError, ValueError) as exc:
                raise InputError(f"--grid {name}: value {text!r}: {exc}") from None
            if action.choices is not None and value not in action.choices:
                raise InputError(f"--grid {name}: value {text!r} is not one of {', '.join(map(str, action.choices))}")
            parsed.append(value)
        grid[dest] = parsed
    return grid


def cmd_sweep(args: argparse.Namespace) -> int:
    import csv
    import io

    from hexsim.simulation.sweeps import METRICS, expand, run_sweep

    _check_outputs(args)
    if args.jobs < 1:
        raise InputError(f"--jobs must be at least 1, got {args.jobs}")
    grid = _parse_grid(args.command_parser, args.grid)
    if not grid:
        raise InputError("sweep needs at least one --grid NAME=V1,V2,…")

    def make_config(settings: dict):
        ns = argparse.Namespace(**{**vars(args), **settings, "quiet": True})
        try:
            return _run_config(ns, ns.compensator)
        except HexsimError as exc:
            raise InputError(f"grid point {settings}: {exc}") from None

    points = expand(grid, make_config)
    print(f"sweeping {len(points)} runs ({' × '.join(f'{len(v)} {k}' for k, v in grid.items())}, machine "
          f"{points[0].config.machine_label}) with {worker_count(args.jobs)} worker(s)…", flush=True)
    rows, wall = run_sweep(points, jobs=args.jobs, progress=not args.quiet and sys.stderr.isatty(),
                           start_method=args.start_method)
    columns = ["point", *grid, *METRICS]
    shown = ["point", *grid, "noise_ratio", "peak_noise_g", "mean_reversal_peak", "final_mean_reversal_peak",
             "max_tracking_error_mm"]
    print("  ".join(f"{c:>12.12s}" for c in shown))
    for row in rows:
        print("  ".join(f"{row[c]:>12.5g}" if isinstance(row[c], float) else f"{str(row[c]):>12.12s}" for c in shown))
    sim_s = sum(p.config.scenario.duration for p in points)
    print(f"{len(points)} runs, {sim_s:g} simulated s in {wall:.1f} s wall: {len(points) / wall * 60:.1f} runs/min, "
          f"{sim_s / wall:.1f}× real time over {worker_count(args.jobs)} worker(s)")
    if args.csv:
        buf = io.StringIO()
        writer = csv.DictWriter(buf, fieldnames=columns, lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
        write_atomic(args.csv, lambda tmp: tmp.write_text(buf.getvalue()))
        print(f"wrote {args.csv}")
    if args.json:
        data = {"machine": points[0].config.machine_label, "grid": grid, "rows": rows}
        write_json(args.json, data)
        print(f"wrote {args.json}")
    return 0


def cmd_serve(args: argparse.Namespace) -> int:
    from hexsim.interfaces.packets import HOST_PACKET, STATE_PACKET, PacketLayout

    host = PacketLayout.from_file(args.layout).check_host() if args.layout else HOST_PACKET
    state = PacketLayout.from_file(args.state_layout).check_state() if args.state_layout else STATE_PACKET
    if args.client:
        from hexsim.interfaces.host import client_lines, run_client

        record = run_client(args.client, args.to, host, state, args.rate, args.duration)
        print("\n".join(client_lines(record)))
        return 0
    _check_outputs(args)
    from hexsim.interfaces.operating_modes import ModeSettings
    from hexsim.interfaces.server import ServeSettings, serve_session

    settings = ServeSettings(bind=args.bind, port=args.port, reply_to=args.reply, state_rate_hz=args.state_rate,
                             duration_s=3600.0 if args.duration is None else args.duration, keep_s=args.keep,
                             modes=ModeSettings(engage_s=args.engage_time, host_timeout_s=args.timeout),
                             host_layout=host, state_layout=state)
    from hexsim.plant.machine import load_machine
    from hexsim.simulation.config import RunConfig

    from hexsim.simulation.tuning import compensator_options

    machine = load_machine(args.machine)
    if machine.system != "hexapod":
        raise InputError(f"hexsim serve needs a hexapod machine; --machine {machine.label} is a {machine.system}")
    base = RunConfig.from_machine(machine, "heave", **compensator_options(args.compensator))
    written = serve_session(base, settings, log=args.log, rrd=args.rrd, json_path=args.json, out=print)
    for path in written:
        print(f"wrote {path}")
    return 0


def _workers(args: argparse.Namespace):
    """The Dask client of ``--scheduler`` for the command's duration (hexsim.simulation.workers.dask_client), or nothing."""
    if getattr(args, "scheduler", None) is None:
        return contextlib.nullcontext()
    if args.jobs < 1:
        raise InputError(f"--jobs must be at least 1, got {args.jobs}")
    from hexsim.simulation.workers import dask_client

    return dask_client(args.scheduler, args.jobs)


def _show_note(message, category, filename, lineno, file=None, line=None) -> None:
    """A :class:`~hexsim.errors.ModelNote` as one line ``hexsim: note: …`` on stderr; other warnings as Python
    shows them."""
    if issubclass(category, ModelNote):
        print("hexsim: note: " + " ".join(str(message).split()), file=sys.stderr)
    else:
        sys.stderr.write(warnings.formatwarning(message, category, filename, lineno, line))


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    streams = contextlib.nullcontext()
    if str(getattr(args, "json", None)) == "-":  # the JSON document on stdout, the human-readable lines on stderr
        args.json = StdoutTarget(sys.stdout)
        streams = contextlib.redirect_stdout(sys.stderr)
    try:
        with streams, _workers(args), warnings.catch_warnings():
            warnings.simplefilter("default", ModelNote)  # each note once
            warnings.showwarning = _show_note
            commands = {"run": cmd_run, "compare": cmd_compare, "validate": cmd_validate, "friction": cmd_friction,
                        "sweep": cmd_sweep, "modes": cmd_modes, "bench": cmd_bench, "machine": cmd_machine,
                        "calibrate": cmd_calibrate, "accept": cmd_accept, "tune": cmd_tune, "serve": cmd_serve,
                        "fmu": cmd_fmu, "cue-tune": cmd_cue_tune}
            return commands[args.command](args)
    except HexsimError as exc:
        # one line, whatever a file put into the message (a key or a value with a line break in it)
        print("hexsim: error: " + " ".join(str(exc).splitlines()), file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("hexsim: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # stdout closed early (e.g. piped into head): not an error of ours
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    sys.exit(main())
