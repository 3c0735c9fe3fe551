"""``hexsim calibrate LOG…``: a machine file fitted to its logs."""

from __future__ import annotations

import argparse
import pathlib
import sys

from hexsim.cli.options import CORES, check_outputs, machine_option, parse_flow_areas
from hexsim.errors import InputError
from hexsim.tables import write_atomic, write_json


def add_calibrate(sub) -> None:
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
    machine_option(ca)
    ca.add_argument("--out", type=pathlib.Path, required=True, metavar="CALIBRATED.json",
                    help="write the calibrated machine file here")
    ca.add_argument("--hold-out", type=pathlib.Path, nargs="+", default=[], metavar="LOG",
                    help="logs predicted, not fitted (their error before and after is reported)")
    ca.add_argument("--dynamics", choices=("auto", "always", "never"), default="auto",
                    help="evidence from transients (the windowed valve replay): auto (default) for every log that is "
                         "not an open-loop constant-command experiment, always (those too), never (steady features only)")
    ca.add_argument("--flow-area", type=parse_flow_areas, metavar="FORM[,FORM…]",
                    help="with transients, the valve flow-area forms to calibrate and choose among by the held-out "
                         "windows (smooth, port, quadratic, sharp; default the machine's own and, for the seed's "
                         "(3.11) family, the others); curve: then each edge's curve read from the logs' flows over "
                         "every command they reach (corners and an underlap included; needs p1_Pa), kept if it "
                         "predicts the held-out windows 10 %% better; without this option the curves are tried "
                         "whenever the chosen form misses its own logs' budget (docs/calibration.md)")
    ca.add_argument("--curve-passes", type=int, choices=(1, 2, 3), default=1, metavar="N",
                    help="read the valve's curves from the flows up to N times (1, 2 or 3), each from the flows as "
                         "the machine calibrated on the last reading replays them, while the calibration misses its "
                         "own logs' budget (default 1; 2 took the 4-way axis of docs/calibration.md from 4.3 to 1.7 "
                         "budgets, in 66 s where one reading takes 42)")
    ca.add_argument("--no-cross-validation", action="store_true",
                    help="skip the leave-one-log-out refits (one per log)")
    ca.add_argument("--keep-worse", action="store_true",
                    help="write the calibrated file even when it predicts its own logs' held-out windows worse than "
                         "the prior (by default nothing is written then, exit 2)")
    ca.add_argument("--jobs", type=int, default=CORES,
                    help="processes that replay the logs for each fit's Jacobian (default: the cores available, "
                         "%(default)s here; the same calibration with any number)")
    ca.add_argument("--report", type=pathlib.Path, metavar="DIR",
                    help="write report.md and features.png (measured against predicted) here")
    ca.add_argument("--json", type=pathlib.Path, help="write the report as JSON; - for stdout")


def cmd_calibrate(args: argparse.Namespace) -> int:
    from hexsim.measured.calibration import calibrate
    from hexsim.measured.measurement import read_log
    from hexsim.measured.reports.calibration import table
    from hexsim.plant.machine import dump, load_machine, machine_from_document

    check_outputs(args)
    if args.jobs < 1:
        raise InputError(f"--jobs must be at least 1, got {args.jobs}")
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
    result = calibrate(logs, machine, held_out=held, cross_validate=not args.no_cross_validation,
                       dynamics=args.dynamics, flow_areas=args.flow_area, jobs=args.jobs,
                       curve_passes=args.curve_passes, notify=lambda text: print(text, file=sys.stderr, flush=True))
    calibrated, report = result.machine, result.report
    print(table(report))
    worse = report.get("own_budget", {}).get("worse_than_prior", {})
    on = report.get("own_budget", {}).get("worse_than_prior_on", {})
    if worse and not args.keep_worse:
        raise InputError(
            "calibrate: the calibrated model predicts its own logs' held-out windows worse than the prior "
            f"{machine.label} did (" + ", ".join(f"{ch} {b:.3g} → {a:.3g}" + (f" on {on[ch]}" if on.get(ch) else "")
                                                 for ch, (b, a) in worse.items())
            + " budgets); nothing written. There the prior is the better model: give logs that excite what "
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
