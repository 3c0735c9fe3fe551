"""``hexsim fmu leg|platform``: an FMI 3.0 co-simulation FMU."""

from __future__ import annotations

import argparse
import pathlib

from compensation import NAMES as COMPENSATORS
from hexsim.cli.options import machine_option, parse_compensator


def add_fmu(sub) -> None:
    """The ``fmu`` command's options."""
    fm = sub.add_parser(
        "fmu", help="a leg or the platform as an FMI 3.0 co-simulation FMU for your system model (docs/fmu.md)",
        description="Build an FMI 3.0 co-simulation FMU (pythonfmu3) of one leg (piston or valve setpoint and an "
        "external force in; position, velocity, acceleration, pressures, force, u_v and U_c out) or of the platform "
        "(six DOF setpoints in; pose, specific force at the head, legs out), from a machine file and a compensator. "
        "It runs hexsim's simulation in the Python hexsim is installed in.")
    fm.add_argument("kind", choices=("leg", "platform"), help="which FMU")
    machine_option(fm)
    fm.add_argument("--compensator", type=parse_compensator, default="none", metavar="NAME|FILE.json",
                    help=f"compensator: {', '.join(COMPENSATORS)} (default none), or a tuned file")
    fm.add_argument("--out", type=pathlib.Path, default=pathlib.Path("."),
                    help="folder to write HexsimLeg.fmu / HexsimPlatform.fmu into (default: here)")


def cmd_fmu(args: argparse.Namespace) -> int:
    from hexsim.interfaces.fmu import (
        LEG_OUTPUTS,
        PLATFORM_INPUTS,
        PLATFORM_OUTPUTS,
        build_fmu,
    )

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
