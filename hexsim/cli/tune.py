"""``hexsim tune``: a compensator tuned for a machine, from its logs (commissioning) or checked on a log."""

from __future__ import annotations

import argparse
import pathlib
import sys

from hexsim.cli.options import (
    check_machine_scenario,
    check_outputs,
    parse_compensator,
    parse_number,
    worker_options,
)
from hexsim.control.scenario import make_scenario
from hexsim.engine.workers import worker_count
from hexsim.errors import InputError
from hexsim.tables import read_json_object, write_json


def add_tune(sub) -> None:
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
    tu.add_argument("--duration", type=parse_number, default=20.0, help="simulated time of each run [s] (default 20)")
    tu.add_argument("--dead-band-tolerance", type=parse_number, default=None, metavar="V",
                    help="how far [V] each valve edge may open earlier or later than the machine file says: the "
                         "tuned compensator must not make a reversal worse on those neighbours (default 0.01; 0: "
                         "judge on the file and a drifting null only; docs/compensation.md)")
    tu.add_argument("--out", type=pathlib.Path, help="the tuned compensator file to write (.json)")
    tu.add_argument("--check", type=pathlib.Path, nargs="+", metavar="LOG.csv",
                    help="proof instead of tuning: logs of the machine running with --compensator, beside the machine "
                         "simulated with it on each log's setpoints (measured and predicted smoothness)")
    tu.add_argument("--draws", type=int, default=None, metavar="N",
                    help="machines drawn from what a calibrated file's calibration leaves uncertain: tuning judges "
                         "every candidate on N of them too (default 2); --check predicts on N and judges against "
                         "the spread they give (default 8); 0: the machine file alone")
    tu.add_argument("--from-logs", nargs="+", type=pathlib.Path, metavar="LOG.csv",
                    help="commissioning instead of tuning: logs of the machine running with --compensator (a tuned "
                    "file) read back into the model (each valve edge's curve from their flows and the calibration's "
                    "own logs'); writes the improved tuned file to --out, or the file run before it where the "
                    "logs measured --compensator worse on the machine (give all the runs so far; "
                    "docs/compensation.md)")
    tu.add_argument("--machine-out", type=pathlib.Path, metavar="FILE.json",
                    help="--from-logs: also write the machine file with the curves read from the logs")
    tu.add_argument("--compensator", type=parse_compensator, metavar="NAME|FILE.json",
                    help="--check: the compensator the logs ran with (a tuned file, or a built-in's name)")
    tu.add_argument("--json", type=pathlib.Path, help="also write every candidate's figures as JSON; - for stdout")
    worker_options(tu, "worker processes")


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
    if args.draws is not None and args.draws < 0:
        raise InputError(f"tune: --draws must be 0 or more, got {args.draws}")
    if args.out.suffix != ".json":
        raise InputError(f"--out {args.out}: the tuned file is JSON (.json)")
    if not args.out.parent.exists():
        raise InputError(f"--out {args.out}: folder {args.out.parent} does not exist")
    check_outputs(args)
    machine = load_machine(args.machine)
    default = "heave,roll,surge" if machine.system == "hexapod" else "actuator"
    motions = tuple(m.strip() for m in (args.motions or default).split(",") if m.strip())
    for m in motions:
        check_machine_scenario(machine, make_scenario(m, duration=args.duration))
    from hexsim.engine.config import RunConfig
    from hexsim.measured.records import plausible_machines
    from hexsim.studies.tuning import (
        CANDIDATES,
        DEAD_BAND_TOLERANCE_V,
        TUNE_DRAWS,
        neighbours,
        tune,
        tune_lines,
        write_tuned,
    )

    tolerance = DEAD_BAND_TOLERANCE_V if args.dead_band_tolerance is None else args.dead_band_tolerance
    around = neighbours(tolerance, plausible_machines(machine, TUNE_DRAWS if args.draws is None else args.draws))
    base = RunConfig.from_machine(machine, make_scenario(motions[0], duration=args.duration))
    print(f"tuning on {', '.join(motions)} ({args.duration:g} s each, machine {base.machine_label} and "
          f"{len(around) - 1} neighbours): {len(CANDIDATES)} candidates with {worker_count(args.jobs)} worker(s)…",
          flush=True)
    result = tune(base, motions, jobs=args.jobs, progress=sys.stderr.isatty(), neighbours=around)
    print("\n".join(tune_lines(result, around)))
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
    from hexsim.measured.commissioning import commissioning_step
    from hexsim.measured.reports import commissioning as report
    from hexsim.plant.machine import dump, load_machine

    machine = load_machine(args.machine)
    step = commissioning_step(list(args.from_logs), pathlib.Path(args.compensator), machine, jobs=args.jobs)
    learned, doc = step.learned, step.doc
    print("\n".join(report.learned_lines(learned)))
    print("\n".join(report.step_lines(step, args.compensator)))
    if step.kept is None:
        print("\n".join(report.predicted_lines(doc["predicted"])))
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
    if args.draws is not None and args.draws < 0:
        raise InputError(f"tune --check: --draws must be 0 or more, got {args.draws}")
    from hexsim.engine.config import RunConfig
    from hexsim.measured.null_drift import last_drift, with_drift
    from hexsim.measured.proof import proof
    from hexsim.measured.reports.commissioning import check_lines
    from hexsim.plant.machine import load_machine
    from hexsim.studies.tuning import compensator_options

    machine = load_machine(args.machine)
    scenario = "heave" if machine.system == "hexapod" else "actuator"
    base = RunConfig.from_machine(machine, scenario, **compensator_options(args.compensator))
    drift = last_drift(read_json_object(args.compensator, "a tuned compensator")) if args.compensator.endswith(
        ".json") else None
    if drift is not None:  # the machine drifts as the run its last commissioning read did
        base = with_drift(base, drift, drift.duration)
        print(f"predicted with the valve's null drifting {drift.rate * 1e3:+.3f} mV/s from {drift.offset * 1e3:+.1f} "
              f"mV, as the tuned file's last commissioning read it ({pathlib.Path(drift.log).name})")
    draws = {} if args.draws is None else {"draws": args.draws}
    rows = [proof(path, base, **draws) for path in args.check]
    print("\n".join(check_lines(rows, base.machine_label, base.compensator_name)))
    if args.json:
        write_json(args.json, {"machine": base.machine_label, "proofs": rows})
        print(f"wrote {args.json}")
    return 0
