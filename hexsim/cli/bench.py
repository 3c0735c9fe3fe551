"""``hexsim bench``: hexsim's speed against bare ``mj_step``, in one process."""

from __future__ import annotations

import argparse
import pathlib

from hexsim.cli.options import check_outputs, parse_number
from hexsim.errors import InputError
from hexsim.tables import write_json


def add_bench(sub) -> None:
    """The ``bench`` command's options."""
    be = sub.add_parser(
        "bench",
        help="time the simulator against bare mj_step on the same model (ratios, real-time factors)",
        description="In one process: bare mj_step on the hexapod, the full hexapod (compiled hydraulics, P control, "
        "buffered compensator) with the native and the python engine, the fast scheme (dt 1e-3 s), the single "
        "actuator and the compiled replay kernel; median of the repeats.",
    )
    be.add_argument("--duration", type=parse_number, default=2.0, help="simulated seconds per repeat (default 2, min 1.5)")
    be.add_argument("--repeats", type=int, default=3, help="repeats per case, median reported (default 3)")
    be.add_argument("--json", type=pathlib.Path, help="write the timings as JSON; - for stdout")
    be.add_argument("--calibrate", action="store_true", help="also time hexsim calibrate on two 20 s open-loop logs "
                    "of the built-in servo_cylinder, two 20 s closed-loop logs of the seed's actuator (against bare "
                    "mj_step over their 40 s) and one 20 s hexapod log (against bare mj_step of the hexapod over 20 s)")
    be.add_argument("--sweep", action="store_true", help="also time an 8-run sweep with 1 worker, 2 forked and 2 spawned workers "
                    "(about 75 s per repeat)")


def cmd_bench(args: argparse.Namespace) -> int:
    from hexsim.bench import run_bench, table

    check_outputs(args)
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
