"""``hexsim run SCENARIO``: one run, its summary and its outputs (plot, rerun recording, log, JSON)."""

from __future__ import annotations

import argparse
import pathlib

from compensation import NAMES as COMPENSATORS
from hexsim.cli.options import (
    check_outputs,
    parse_compensator,
    perception_thresholds,
    run_config,
    scenario_options,
    thresholds_option,
)
from hexsim.control.scenario import SCENARIOS
from hexsim.errors import WorkspaceError
from hexsim.tables import write_json


def add_run(sub) -> None:
    """The ``run`` command's options."""
    run = sub.add_parser(
        "run",
        help="simulate a scenario headless and report its smoothness",
        description="Simulate a scenario and print its smoothness figures. Scenarios: "
        + ", ".join(SCENARIOS)
        + ", or file:PATH (CSV with time_s and dof_ref_{x,y,z}_m / dof_ref_{roll,pitch,yaw}_rad).",
    )
    scenario_options(run)
    run.add_argument("--compensator", type=parse_compensator, default="none", metavar="NAME|FILE.json",
                     help=f"reversal-bump compensator per leg: {', '.join(COMPENSATORS)} (default none), or a tuned "
                          "file written by hexsim tune")
    run.add_argument("--rrd", type=pathlib.Path, help="write a rerun recording (.rrd)")
    run.add_argument("--plot", type=pathlib.Path, help="write a figure of acceleration, flow curve, pressures, tracking (.png, .pdf or .svg)")
    run.add_argument("--json", type=pathlib.Path, help="write the metrics as JSON; - for stdout")
    run.add_argument("--log", type=pathlib.Path, help="write the run as a measurement log (CSV + JSON sidecar)")
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    run.add_argument("--cueing", choices=("classical", "mpc"), default="classical",
                     help="vehicle:PATH: the classical washout (default) or model-predictive cueing within the "
                          "machine's envelope (docs/motion-cueing.md)")
    run.add_argument("--washout", type=pathlib.Path, metavar="WASHOUT.json",
                     help="vehicle:PATH: the cueing's parameters, the classical washout's or, with --cueing mpc, the "
                          "MPC's (any subset; default: docs/motion-cueing.md)")
    thresholds_option(run)


def cmd_run(args: argparse.Namespace) -> int:
    check_outputs(args)
    config = run_config(args, args.compensator)  # every option checked before the heavy imports
    thresholds = perception_thresholds(args)
    from hexsim.engine.runner import simulate
    from hexsim.outputs.plotting import plot_run
    from hexsim.outputs.report import run_report, summary_table
    from hexsim.outputs.rerun_log import write_rrd
    from hexsim.studies.metrics import run_smoothness

    try:
        result = simulate(config)
    except WorkspaceError as exc:
        if config.scenario.cueing is None:
            raise
        raise WorkspaceError(f"{exc}: the washout's setpoints leave the workspace; lower its scale_specific_force or "
                             f"raise its hp_omega_radps / hp_break_radps (--washout FILE, docs/motion-cueing.md)") from None
    if config.scenario.cueing is not None:
        return _vehicle_outputs(args, result, thresholds)
    if config.scenario.open_loop:
        from hexsim.outputs.plotting import plot_open_loop
        from hexsim.outputs.report import open_loop_report, open_loop_table

        sm, report = None, open_loop_report(result)
        print(open_loop_table(report))
    else:
        sm = run_smoothness(result)
        perception = None
        if config.scenario.system == "hexapod":
            from hexsim.studies.perception import bump_perception

            perception = bump_perception(result, sm, thresholds=thresholds)
        report = run_report(result, sm, perception)
        print(summary_table(report))
    written = []
    if args.json:  # without the wall time, so the same command writes the same bytes
        write_json(args.json, {k: v for k, v in report.items() if k not in ("realtime_factor", "wall_time_s")})
        written.append(args.json)
    if args.plot:
        if sm is None:
            plot_open_loop(args.plot, result)
        else:
            plot_run(args.plot, result, sm, perception)
        written.append(args.plot)
    if args.rrd:
        write_rrd(args.rrd, result, sm, perception if sm is not None else None)
        written.append(args.rrd)
    return _log_and_say(args, result, written)


def _vehicle_outputs(args: argparse.Namespace, result, thresholds) -> int:
    """``hexsim run vehicle:PATH``: the cue report on stdout, and the files asked for."""
    from hexsim.outputs.plotting import plot_cueing
    from hexsim.outputs.rerun_log import write_rrd
    from hexsim.studies.cueing import cue_lines, cue_report

    cfg = result.config
    report = cue_report(result, thresholds)
    solver = cfg.scenario.cueing[2].solver
    print("\n".join(cue_lines(cfg, report)))
    written = []
    if args.json:
        doc = {"scenario": cfg.scenario.name, "machine": cfg.machine_label, "compensator": cfg.compensator_name,
               "duration_s": cfg.scenario.duration, "cueing": "classical" if solver is None else "mpc",
               "cueing_solver": solver, **report.document()}
        write_json(args.json, doc)
        written.append(args.json)
    if args.plot:
        plot_cueing(args.plot, result, report)
        written.append(args.plot)
    if args.rrd:
        write_rrd(args.rrd, result, None, cueing=report)
        written.append(args.rrd)
    return _log_and_say(args, result, written)


def _log_and_say(args: argparse.Namespace, result, written: list) -> int:
    """Write the run's measurement log if ``--log`` asked for it, then say every file written (``written``
    and the log's); exit code 0."""
    from hexsim.outputs.logio import write_log

    if args.log:
        written = [*written, *write_log(args.log, result)]
    for path in written:
        print(f"wrote {path}")
    return 0
