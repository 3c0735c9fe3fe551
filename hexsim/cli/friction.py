"""``hexsim friction LOG``: the friction map read from a log."""

from __future__ import annotations

import argparse
import pathlib

from hexsim.cli.options import check_outputs, machine_option
from hexsim.tables import write_json


def add_friction(sub) -> None:
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
    machine_option(fr)
    fr.add_argument("--plot", type=pathlib.Path, help="write the friction-velocity map (.png, .pdf or .svg)")
    fr.add_argument("--json", type=pathlib.Path, help="write the fitted parameters as JSON; - for stdout")


def cmd_friction(args: argparse.Namespace) -> int:
    from hexsim.measured.friction_id import identify_friction
    from hexsim.measured.measurement import read_log
    from hexsim.measured.reports.friction import plot_map, summary

    check_outputs(args)
    logs = [[read_log(pathlib.Path(part), machine=args.machine, needs=("pos_m",)) for part in item.split("+")] for item in args.logs]
    result = identify_friction(logs)
    print(summary(result))
    if args.json:
        write_json(args.json, result.record())
        print(f"wrote {args.json}")
    if args.plot:
        plot_map(result, args.plot)
        print(f"wrote {args.plot}")
    return 0
