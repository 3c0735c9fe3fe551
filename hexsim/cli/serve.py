"""``hexsim serve``: a real-time virtual motion system on UDP (and its host client)."""

from __future__ import annotations

import argparse
import pathlib

from compensation import NAMES as COMPENSATORS
from hexsim.cli.options import (
    check_outputs,
    machine_option,
    parse_address,
    parse_compensator,
    parse_number,
)
from hexsim.errors import InputError


def add_serve(sub) -> None:
    """The ``serve`` command's options."""
    se = sub.add_parser(
        "serve", help="a real-time virtual motion system your host computer drives over UDP (docs/serve.md)",
        description="Listen for the host's setpoint packets, simulate the platform in real time at the controller "
        "rate (hydraulics, bump, compensator) and send its state back; engage, neutral and park ramped; a lost host "
        "returns it to neutral. With --client: be the host instead (send a scenario's motion to --to).")
    machine_option(se)
    se.add_argument("--compensator", type=parse_compensator, default="none", metavar="NAME|FILE.json",
                    help=f"compensator per leg: {', '.join(COMPENSATORS)} (default none), or a tuned file")
    se.add_argument("--bind", default="127.0.0.1", help="address to listen on (default %(default)s; 0.0.0.0: all)")
    se.add_argument("--port", type=int, default=5005, help="UDP port to listen on (default %(default)s)")
    se.add_argument("--reply", type=parse_address, metavar="HOST:PORT",
                    help="where to send the state packets (default: the sender of the last accepted packet)")
    se.add_argument("--layout", type=pathlib.Path, metavar="LAYOUT.json",
                    help="the host packet's layout (default hexsim's, docs/serve.md)")
    se.add_argument("--state-layout", type=pathlib.Path, metavar="LAYOUT.json",
                    help="the state packet's layout (default hexsim's)")
    se.add_argument("--perception", action="store_true",
                    help="the occupant's perception in the loop: the state packet (version 2, or --state-layout's "
                    "sensed_* / seat_* fields) carries what the vestibular organs sense and the ISO 2631-1 weighted "
                    "seat acceleration")
    se.add_argument("--state-rate", type=parse_number, default=100.0, help="state packets per second (default %(default)s)")
    se.add_argument("--duration", type=parse_number, default=None,
                    help="seconds to serve (default 3600); with --client: the motion's length (default the scenario's)")
    se.add_argument("--keep", type=parse_number, default=600.0,
                    help="seconds of recording kept in memory (the last; default %(default)s); --log and "
                         "--rrd are written while the session runs and hold all of it")
    se.add_argument("--engage-time", type=parse_number, default=2.0, help="fade-in of the host's motion [s] (default 2)")
    se.add_argument("--timeout", type=parse_number, default=0.5,
                    help="silence after which the host is lost and the platform returns to neutral [s] (default 0.5)")
    se.add_argument("--priority", type=int, metavar="1-99",
                    help="run the loop at this real-time priority (Linux SCHED_FIFO; needs root or CAP_SYS_NICE)")
    se.add_argument("--log", type=pathlib.Path,
                    help="write the session as a measurement log (CSV + JSON sidecar) while it runs")
    se.add_argument("--rrd", type=pathlib.Path, help="write the session as a rerun recording (.rrd) while it runs")
    se.add_argument("--json", type=pathlib.Path, help="write the session's report (timing, packets, modes) as JSON")
    se.add_argument("--client", metavar="SCENARIO",
                    help="be the host: send SCENARIO's platform motion (heave, file:PATH, vehicle:PATH, …) to --to")
    se.add_argument("--to", type=parse_address, default=("127.0.0.1", 5005), metavar="HOST:PORT",
                    help="--client: the motion system's address (default 127.0.0.1:5005)")
    se.add_argument("--rate", type=parse_number, default=100.0, help="--client: packets per second (default %(default)s)")


def cmd_serve(args: argparse.Namespace) -> int:
    from hexsim.interfaces.packets import (
        HOST_PACKET,
        STATE_PACKET,
        STATE_PACKET_PERCEPTION,
        PacketLayout,
    )

    host = PacketLayout.from_file(args.layout).check_host() if args.layout else HOST_PACKET
    state = (PacketLayout.from_file(args.state_layout).check_state() if args.state_layout else
             STATE_PACKET_PERCEPTION if args.perception else STATE_PACKET)
    if args.client:
        from hexsim.interfaces.host import client_lines, run_client

        record = run_client(args.client, args.to, host, state, args.rate, args.duration)
        print("\n".join(client_lines(record)))
        return 0
    check_outputs(args)
    from hexsim.interfaces.operating_modes import ModeSettings
    from hexsim.interfaces.server import ServeSettings, serve_session

    settings = ServeSettings(bind=args.bind, port=args.port, reply_to=args.reply, state_rate_hz=args.state_rate,
                             duration_s=3600.0 if args.duration is None else args.duration, keep_s=args.keep,
                             modes=ModeSettings(engage_s=args.engage_time, host_timeout_s=args.timeout),
                             host_layout=host, state_layout=state, priority=args.priority)
    from hexsim.engine.config import RunConfig
    from hexsim.plant.machine import load_machine
    from hexsim.studies.tuning import compensator_options

    machine = load_machine(args.machine)
    if machine.system != "hexapod":
        raise InputError(f"hexsim serve needs a hexapod machine; --machine {machine.label} is a {machine.system}")
    base = RunConfig.from_machine(machine, "heave", **compensator_options(args.compensator))
    written = serve_session(base, settings, log=args.log, rrd=args.rrd, json_path=args.json, out=print)
    for path in written:
        print(f"wrote {path}")
    return 0
