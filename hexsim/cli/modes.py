"""``hexsim modes``: the hexapod's oil-spring modes."""

from __future__ import annotations

import argparse
import pathlib

from hexsim.cli.options import check_outputs, machine_option, parse_payload
from hexsim.errors import InputError
from hexsim.tables import write_json


def add_modes(sub) -> None:
    """The ``modes`` command's options."""
    mo = sub.add_parser(
        "modes",
        help="oil-spring modes of the hexapod (linearised, Hz, with the dominant degree of freedom)",
        description="Linearise the hexapod at the neutral pose: each leg's oil column a spring E A1^2 / V1 (seed "
        "eq. 3.7), the inertia MuJoCo's (platform, legs, constraints); print the six modes in Hz with the degree "
        "of freedom that holds most of each mode's kinetic energy.",
    )
    mo.add_argument("--payload", type=parse_payload, metavar="KG[@X,Y[,Z]]",
                    help="a payload of KG kg added to the platform (600 kg built in) at X,Y,Z m (platform frame), as for run")
    mo.add_argument("--json", type=pathlib.Path, help="write the modes as JSON; - for stdout")
    machine_option(mo)


def cmd_modes(args: argparse.Namespace) -> int:
    from hexsim.plant.machine import load_machine
    from hexsim.studies.modes import modes_table, oil_spring_modes

    check_outputs(args)
    machine = load_machine(args.machine)
    if machine.system != "hexapod":
        raise InputError(f"--machine {machine.label}: modes are the hexapod's; this machine is a {machine.system}")
    from hexsim.plant.model import load_model

    mass = float(load_model("hexapod", geometry=machine.geometry).body("platform").mass[0])
    effects, payload = machine.effects, f"machine {machine.label}, {mass:g} kg platform"
    if args.payload is not None:
        kg, at = args.payload
        effects = effects.replace(payload_kg=kg, payload_at_m=at)
        payload = f"{mass:g} kg platform with {kg:g} kg at ({', '.join(f'{v:g}' for v in at)}) m"
    modes = oil_spring_modes(machine.hydraulics, effects=effects, geometry=machine.geometry)
    print(modes_table(modes, payload))
    if args.json:
        data = {"configuration": payload, "pose": "neutral",
                "modes": [{"frequency_hz": mode.frequency_hz, "dominant": mode.dominant, "share": mode.share,
                           "shape": dict(zip(("x_m", "y_m", "z_m", "roll_rad", "pitch_rad", "yaw_rad"),
                                             mode.shape.tolist()))} for mode in modes]}
        write_json(args.json, data)
        print(f"wrote {args.json}")
    return 0
