"""``hexsim`` command line: ``hexsim run SCENARIO [options]``.

Bad options and unreachable setpoints give one line on stderr and exit code 2, never a traceback and
never a half-written output file.
"""

from __future__ import annotations

import argparse
import math
import pathlib
import sys

from compensation import COMPENSATORS
from hexsim.errors import HexsimError, InputError
from hexsim.params import ControllerParams, HydraulicParams
from hexsim.scenario import DEFAULT_AMPLITUDE, DEFAULT_FREQUENCY, SCENARIOS, make_scenario


def _number(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="hexsim",
        description="Six-DOF hydraulic motion platform simulator (Micro Motion System): the reversal bump and its compensation.",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser(
        "run",
        help="simulate a scenario headless and report its smoothness",
        description="Simulate a scenario and print its smoothness figures. Scenarios: "
        + ", ".join(SCENARIOS)
        + ", or file:PATH (CSV with time_s and dof_ref_{x,y,z}_m / dof_ref_{roll,pitch,yaw}_rad).",
    )
    run.add_argument("scenario", help="actuator, heave, surge, sway, roll, pitch, yaw or file:PATH")
    run.add_argument("--duration", type=_number, help="simulated time [s] (default: max(20 s, 6 periods); file: its length)")
    run.add_argument("--amplitude", type=_number,
                     help=f"sine amplitude [m for actuator/heave/surge/sway, rad for roll/pitch/yaw] "
                          f"(default {DEFAULT_AMPLITUDE['heave']} m, {DEFAULT_AMPLITUDE['roll']:.4f} rad)")
    run.add_argument("--frequency", type=_number, help=f"sine frequency [Hz] (default {DEFAULT_FREQUENCY})")
    run.add_argument("--seed", type=int, default=0, help="seed of the position-sensor noise (default 0)")
    run.add_argument("--compensator", choices=sorted(COMPENSATORS), default="none",
                     help="reversal-bump compensator per leg (default none)")
    run.add_argument("--kp", type=_number, default=ControllerParams.kp, help="P gain K_p [V/m] (default %(default)s)")
    run.add_argument("--flow-area", choices=("smooth", "sharp"), default="smooth",
                     help="valve flow-area function: smooth a = 300 x_v^2 (seed eq. 3.11) or sharp-edged with "
                          "overlap (eq. 3.3) (default smooth)")
    run.add_argument("--sensor-noise", type=_number, default=ControllerParams.position_noise,
                     help="rms noise on the measured piston position [m] (default %(default)s)")
    run.add_argument("--rrd", type=pathlib.Path, help="write a rerun recording (.rrd)")
    run.add_argument("--plot", type=pathlib.Path, help="write a PNG of acceleration, flow curve, pressures, tracking")
    run.add_argument("--json", type=pathlib.Path, help="write the metrics as JSON")
    run.add_argument("--log", type=pathlib.Path, help="write the run as a measurement log (CSV + JSON sidecar)")
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    return parser


def _check_outputs(args: argparse.Namespace) -> None:
    for flag, suffix in (("rrd", ".rrd"), ("plot", ".png"), ("json", ".json"), ("log", ".csv")):
        path = getattr(args, flag)
        if path is None:
            continue
        if path.suffix.lower() != suffix:
            raise InputError(f"--{flag} {path}: expected a {suffix} file name")
        if not path.parent.exists():
            raise InputError(f"--{flag} {path}: folder {path.parent} does not exist")
    if args.log is not None and args.json is not None and args.log.with_suffix(".json").resolve() == args.json.resolve():
        raise InputError(f"--json {args.json} would be overwritten by the sidecar of --log {args.log}; choose another name")


def cmd_run(args: argparse.Namespace) -> int:
    from hexsim.logio import write_log
    from hexsim.metrics import run_smoothness
    from hexsim.plotting import plot_run
    from hexsim.report import run_report, summary_table, write_json
    from hexsim.rerun_log import write_rrd
    from hexsim.simulation import RunConfig, simulate

    _check_outputs(args)
    controller = ControllerParams(kp=args.kp, position_noise=args.sensor_noise)
    hydraulics = HydraulicParams(flow_area=args.flow_area)
    scenario = make_scenario(args.scenario, duration=args.duration, amplitude=args.amplitude,
                             frequency=args.frequency, controller_rate_hz=controller.rate_hz)
    config = RunConfig(scenario=scenario, hydraulics=hydraulics, controller=controller,
                       compensator=args.compensator, seed=args.seed,
                       progress=not args.quiet and sys.stderr.isatty())
    result = simulate(config)
    sm = run_smoothness(result)
    report = run_report(result, sm)
    print(summary_table(report))
    written = []
    if args.json:
        write_json(args.json, report)
        written.append(args.json)
    if args.plot:
        plot_run(args.plot, result, sm)
        written.append(args.plot)
    if args.rrd:
        write_rrd(args.rrd, result, sm)
        written.append(args.rrd)
    if args.log:
        written.extend(write_log(args.log, result))
    for path in written:
        print(f"wrote {path}")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return cmd_run(args)
    except HexsimError as exc:
        print(f"hexsim: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("hexsim: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
