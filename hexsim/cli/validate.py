"""``hexsim validate LOG``: the measured log against the model, the effect it lacks named."""

from __future__ import annotations

import argparse
import pathlib
import sys

from hexsim.cli.options import (
    check_outputs,
    machine_option,
    progress_line,
    worker_options,
)
from hexsim.errors import InputError


def add_validate(sub) -> None:
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
    worker_options(val, "worker processes for the fits")
    val.add_argument("--without", default="", metavar="EFFECT[,EFFECT…]",
                     help="leave these library effects out of the candidates (an effect you know the machine "
                          "cannot have, or a check of what the tool says about an effect outside its list)")
    val.add_argument("--model", choices=("platform", "full"), default="platform",
                     help="hexapod logs: replay on the platform-only model (default) or the full multi-body model")
    machine_option(val)
    val.add_argument("--quiet", action="store_true",
                     help="no progress (a bar on a terminal, one line per step otherwise)")


def cmd_validate(args: argparse.Namespace) -> int:
    from hexsim.measured.measurement import read_log
    from hexsim.measured.reports.validation import log_lines, summary
    from hexsim.measured.validation import validate

    check_outputs(args)
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
    print("\n".join(log_lines(log)))
    doc = validate(log, report=args.report, json_path=args.json, jobs=args.jobs, without=without, model=args.model,
                   progress=not args.quiet and sys.stderr.isatty(),
                   notify=None if args.quiet or sys.stderr.isatty() else progress_line)
    print(summary(doc))
    for path in (args.report, args.json):
        if path is not None:
            print(f"wrote {path}")
    return 0
