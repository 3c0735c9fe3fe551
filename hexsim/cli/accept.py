"""``hexsim accept``: an acceptance test of a machine against its tolerances."""

from __future__ import annotations

import argparse
import pathlib

from compensation import NAMES as COMPENSATORS
from hexsim.cli.options import (
    machine_option,
    perception_thresholds,
    progress_line,
    thresholds_option,
    worker_options,
)
from hexsim.errors import InputError


def add_accept(sub) -> None:
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
    machine_option(ac)
    thresholds_option(ac)
    worker_options(ac, "worker processes for the sine runs")
    ac.add_argument("--quiet", action="store_true", help="no progress lines")


def cmd_accept(args: argparse.Namespace) -> int:
    from hexsim.control.washout import WashoutParams
    from hexsim.studies.acceptance import Tolerances

    if args.jobs < 1:
        raise InputError(f"--jobs must be at least 1, got {args.jobs}")
    if not args.report.parent.exists():
        raise InputError(f"--report {args.report}: folder {args.report.parent} does not exist")
    if args.report.exists() and not args.report.is_dir():
        raise InputError(f"--report {args.report}: exists and is not a folder")
    tol = Tolerances.read(args.tolerances)
    thresholds = perception_thresholds(args)
    washout = WashoutParams.from_file(args.washout) if args.washout else None
    from hexsim.plant.machine import load_machine

    machine = load_machine(args.machine)
    if machine.system != "hexapod":
        raise InputError(f"--machine {machine.label}: the motion tests are a hexapod's; this machine is a {machine.system}")
    from hexsim.engine.config import RunConfig
    from hexsim.outputs.acceptance_report import write_report
    from hexsim.studies.acceptance import run_acceptance

    if args.log:  # every log checked before the tests run
        from hexsim.measured.acceptance_logs import read_test_log

        for path in args.log:
            read_test_log(path, RunConfig.from_machine(machine, "heave"))
    results = []
    for name in dict.fromkeys(("none", args.compensator)):
        base = RunConfig.from_machine(machine, "heave", compensator=name)
        say = None if args.quiet else (lambda text, n=name: progress_line(f"compensator {n}: {text}"))
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
