"""``hexsim compare``: the compensators side by side on one scenario."""

from __future__ import annotations

import argparse
import dataclasses
import pathlib

from compensation import NAMES as COMPENSATORS
from hexsim.cli.options import (
    check_outputs,
    perception_thresholds,
    run_config,
    scenario_options,
    thresholds_option,
    worker_options,
)
from hexsim.engine.workers import worker_count
from hexsim.errors import InputError
from hexsim.tables import write_json


def add_compare(sub) -> None:
    """The ``compare`` command's options."""
    cmp = sub.add_parser(
        "compare",
        help="run every compensator on one scenario and print a league table",
        description="Run none, iterative-1, iterative-2, buffered, directional and oracle on the same scenario "
        "(in parallel worker processes) and print noise ratio, peak noise, reduction of the mean reversal peak "
        "against none and settling time, measured on the last quarter of the run.",
    )
    scenario_options(cmp)
    cmp.add_argument("--compensators", default=",".join(COMPENSATORS[1:]),
                     help="comma-separated compensators to compare: built-in names or tuned files (FILE.json, "
                          "from hexsim tune); none is always included")
    worker_options(cmp, "worker processes")
    cmp.add_argument("--plot", type=pathlib.Path, help="write the comparison figure (seed Fig. 5.12 layout; .png, .pdf or .svg)")
    cmp.add_argument("--json", type=pathlib.Path, help="write the per-compensator figures as JSON; - for stdout")
    thresholds_option(cmp)


def cmd_compare(args: argparse.Namespace) -> int:
    from hexsim.outputs.plotting import plot_compare
    from hexsim.studies.comparison import compare, league_table

    check_outputs(args)
    given = tuple(n.strip() for n in args.compensators.split(",") if n.strip())
    names = tuple(n for n in given if not n.endswith(".json"))
    unknown = [n for n in names if n not in COMPENSATORS]
    if unknown:
        raise InputError(f"--compensators: unknown compensator {unknown[0]!r}; choose from {', '.join(COMPENSATORS)} "
                         "or a tuned file (.json)")
    if args.jobs < 1:
        raise InputError(f"--jobs must be at least 1, got {args.jobs}")
    base = run_config(args, "none")
    labelled = []
    for path in dict.fromkeys(n for n in given if n.endswith(".json")):
        from hexsim.studies.tuning import read_tuned

        name, settings, model = read_tuned(path)  # InputError naming the file
        labelled.append((f"{pathlib.Path(path).name} ({name})", dataclasses.replace(
            base, compensator=name, compensator_settings=settings, compensator_model=model)))
    thresholds = perception_thresholds(args)
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
