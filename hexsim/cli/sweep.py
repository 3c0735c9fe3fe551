"""``hexsim sweep``: a grid of runs in worker processes."""

from __future__ import annotations

import argparse
import pathlib
import sys

from compensation import NAMES as COMPENSATORS
from hexsim.cli.options import (
    check_outputs,
    run_config,
    scenario_options,
    worker_options,
)
from hexsim.engine.workers import START_METHODS, worker_count
from hexsim.errors import HexsimError, InputError
from hexsim.tables import write_atomic, write_json

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


def add_sweep(sub) -> None:
    """The ``sweep`` command's options."""
    sw = sub.add_parser(
        "sweep",
        help="run a grid of scenarios / controller / compensator settings in worker processes",
        description="Run every combination of the --grid values (any run option, e.g. --grid compensator=none,"
        "buffered --grid buffer-time=1,3 --grid frequency=0.5,1) in worker processes, with a progress bar, and "
        "write one row of metrics per grid point (CSV and/or JSON). Options not in the grid apply to every run.",
    )
    scenario_options(sw)
    sw.add_argument("--compensator", choices=sorted(COMPENSATORS), default="none",
                    help="compensator of every run unless the grid varies it (default none)")
    sw.add_argument("--grid", action="append", default=[], metavar="NAME=V1,V2,…",
                    help="an option to vary and its values (repeatable); NAME is a run option without the dashes")
    worker_options(sw, "worker processes")
    sw.add_argument("--start-method", choices=START_METHODS, default=None,
                    help="how workers start: fork (default where available: they inherit everything imported) "
                    "or spawn/forkserver (a fresh interpreter, ~2.5 s of imports each)")
    sw.add_argument("--csv", type=pathlib.Path, help="write the table as CSV")
    sw.add_argument("--json", type=pathlib.Path, help="write the table as JSON; - for stdout")
    sw.add_argument("--quiet", action="store_true", help="no progress bar")
    sw.set_defaults(command_parser=sw)  # the grid reads its options' types and choices


def cmd_sweep(args: argparse.Namespace) -> int:
    import csv
    import io

    from hexsim.studies.sweeps import METRICS, expand, run_sweep, sweep_lines

    check_outputs(args)
    if args.jobs < 1:
        raise InputError(f"--jobs must be at least 1, got {args.jobs}")
    grid = _parse_grid(args.command_parser, args.grid)
    if not grid:
        raise InputError("sweep needs at least one --grid NAME=V1,V2,…")

    def make_config(settings: dict):
        ns = argparse.Namespace(**{**vars(args), **settings, "quiet": True})
        try:
            return run_config(ns, ns.compensator)
        except HexsimError as exc:
            raise InputError(f"grid point {settings}: {exc}") from None

    points = expand(grid, make_config)
    print(f"sweeping {len(points)} runs ({' × '.join(f'{len(v)} {k}' for k, v in grid.items())}, machine "
          f"{points[0].config.machine_label}) with {worker_count(args.jobs)} worker(s)…", flush=True)
    rows, wall = run_sweep(points, jobs=args.jobs, progress=not args.quiet and sys.stderr.isatty(),
                           start_method=args.start_method)
    columns = ["point", *grid, *METRICS]
    print("\n".join(sweep_lines(rows, tuple(grid), sum(p.config.scenario.duration for p in points), wall,
                                 worker_count(args.jobs))))
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
