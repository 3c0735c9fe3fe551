"""``hexsim cue-tune``: the classical washout fitted to a driver's manoeuvres and the platform."""

from __future__ import annotations

import argparse
import dataclasses
import pathlib

from hexsim.cli.options import check_outputs, machine_option, parse_number
from hexsim.errors import InputError
from hexsim.tables import write_json


def add_cue_tune(sub) -> None:
    """The ``cue-tune`` command's options."""
    ct = sub.add_parser(
        "cue-tune", help="fit the classical washout to your manoeuvres and platform, write the --washout file "
        "(docs/motion-cueing.md)",
        description="Fit the classical washout's scales and corners to vehicle motions (docs/motion-cueing.md's "
        "vehicle files) on the machine's platform: the sensed-cue error and correlation on the ideal platform, every "
        "moving axis counting alike, within the legs' stroke; write the washout file hexsim run vehicle:FILE "
        "--washout loads.")
    ct.add_argument("vehicles", nargs="+", metavar="VEHICLE.csv", help="the manoeuvres (vehicle-motion files)")
    machine_option(ct)
    ct.add_argument("--washout", type=pathlib.Path, metavar="START.json",
                    help="the washout to start from and whose untuned numbers are kept (default the built-in)")
    ct.add_argument("--out", type=pathlib.Path, required=True, metavar="WASHOUT.json", help="the tuned washout file")
    ct.add_argument("--margin", type=parse_number, default=0.01, help="stroke kept free at each end [m] (default 0.01)")
    ct.add_argument("--iterations", type=int, default=30, help="differential evolution's generations (default 30)")
    ct.add_argument("--population", type=int, default=6, help="its population per tuned number (default 6)")
    ct.add_argument("--seed", type=int, default=0, help="the search's seed (default 0)")
    ct.add_argument("--json", type=pathlib.Path, help="write the figures before and after as JSON")


def cmd_cue_tune(args: argparse.Namespace) -> int:
    from hexsim.control.kinematics import HexapodGeometry
    from hexsim.control.washout import WashoutParams, read_vehicle
    from hexsim.plant.geometry import MICRO_MOTION_SYSTEM
    from hexsim.plant.machine import load_machine
    from hexsim.plant.model import load_model
    from hexsim.studies.cue_tuning import tune_washout

    check_outputs(args)
    if args.out.suffix.lower() != ".json" or not args.out.parent.exists():
        raise InputError(f"--out {args.out}: expected a .json file name in an existing folder")
    if args.iterations < 1 or args.population < 1:
        raise InputError(f"--iterations and --population must be at least 1, got {args.iterations} and {args.population}")
    machine = load_machine(args.machine)
    if machine.system != "hexapod":
        raise InputError(f"cue-tune needs a hexapod; --machine {machine.label} is a {machine.system}")
    vehicles = [read_vehicle(path) for path in args.vehicles]
    start = WashoutParams.from_file(args.washout) if args.washout else WashoutParams()
    geometry = HexapodGeometry.from_model(load_model("hexapod", "full", machine.effects, machine.geometry))
    head = (machine.geometry or MICRO_MOTION_SYSTEM).head_point
    tuning = tune_washout(vehicles, geometry, head, start=start, margin_m=args.margin, seed=args.seed,
                          maxiter=args.iterations, popsize=args.population)
    print("\n".join(tuning.lines()))
    write_json(args.out, tuning.tuned.document())
    print(f"wrote {args.out}; through the hydraulics: hexsim run vehicle:{args.vehicles[0]} --washout {args.out}")
    if args.json is not None:
        write_json(args.json, {"start": tuning.start.document(), "tuned": tuning.tuned.document(),
                               "before": [dataclasses.asdict(f) for f in tuning.before],
                               "after": [dataclasses.asdict(f) for f in tuning.after],
                               "evaluations": tuning.evaluations})
    return 0
