"""``hexsim machine show|set|list``: machine files."""

from __future__ import annotations

import argparse
import pathlib
import sys

from hexsim.errors import InputError
from hexsim.tables import write_atomic


def add_machine(sub) -> None:
    """The ``machine`` command: show, set and list machine files."""
    ma = sub.add_parser("machine", help="show, edit or list machine files (valve, cylinder, supply, load, controller)",
                        description="A machine file says everything hexsim assumes about a machine "
                        "(docs/machine-file.md). show prints a complete one, set edits keys of one (checked "
                        "before it is written), list names the built-in ones.")
    actions = ma.add_subparsers(dest="action", required=True)
    show = actions.add_parser("show", help="print a complete machine file (default: the built-in micro_motion_system)")
    show.add_argument("machine", nargs="?", default=None, metavar="NAME|FILE.json")
    st = actions.add_parser("set", help="set keys of a machine file: hexsim machine set FILE key=value …")
    st.add_argument("file", type=pathlib.Path, help="the machine file to edit (made from the built-in default if "
                    "it does not exist)")
    st.add_argument("assignments", nargs="+", metavar="key=value",
                    help="dotted key and JSON value, e.g. valve.type=4-way cylinder.bore_m=0.016 load.mass_kg=null")
    actions.add_parser("list", help="the built-in machines")


def cmd_machine(args: argparse.Namespace) -> int:
    import json

    from hexsim.plant.machine import (
        OCCUPANT_KEYS,
        builtin_names,
        dump,
        load_machine,
        machine_from_document,
        parse_assignment,
        set_keys,
    )

    if args.action == "list":
        for name in builtin_names():
            m = load_machine(name)
            print(f"{name:24s} {m.system:16s} {m.hydraulics.valve_type} valve  {m.description.split(': ')[0][:60]}")
        return 0
    if args.action == "show":
        sys.stdout.write(dump(load_machine(args.machine).document()))
        return 0
    path: pathlib.Path = args.file
    if path.suffix.lower() != ".json":
        raise InputError(f"{path}: expected a .json machine file")
    if not path.parent.exists():
        raise InputError(f"{path}: folder {path.parent} does not exist")
    if path.exists():
        try:
            doc = json.loads(path.read_text(encoding="utf-8"))
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise InputError(f"{path}: not valid JSON ({exc})") from None
        machine_from_document(doc, str(path))  # the file as it is must be a machine file
    else:
        doc = load_machine(None).document()
        doc["name"] = path.stem
    assignments = [parse_assignment(a) for a in args.assignments]
    new = set_keys(doc, assignments)
    if any(key == "hexapod.mjcf" and value is not None for key, value in assignments):
        # an MJCF is the hexapod now: the built hexapod's numbers a shown file carries go, unless set here
        given = {key for key, _ in assignments}
        dropped = [k for k in new.get("hexapod", {})
                   if not k.startswith("mjcf") and k not in OCCUPANT_KEYS and f"hexapod.{k}" not in given]
        for k in dropped:
            del new["hexapod"][k]
        if dropped:
            print("dropped " + ", ".join(f"hexapod.{k}" for k in dropped) + " (the MJCF is the hexapod now)")
    machine_from_document(new, str(path))  # checked before anything is written
    write_atomic(path, lambda tmp: tmp.write_text(dump(new), encoding="utf-8"))
    print(f"wrote {path}")
    return 0
