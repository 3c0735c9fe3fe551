"""The valve commands a calibration measured, and a log that runs the valve beyond them.

A calibration reads the valve's flow curve where its logs *dwelt*: a chirp measures the small commands it sweeps
slowly, a step passes the rest in milliseconds. On the reference plant R1 the shipped calibration logs spend 10-20 ms
per 50 mV above 0.8 V, where every sine log runs (and where R1's spool meets its port, a corner): the calibrated curve
there is the flow-area form's extrapolation, and a null log was answered `unexplained`, 15 budgets off in position, an
effect log `partial`. The misfit is the calibration's envelope, not an effect:

- :func:`measured_commands` gives the commands a calibration's logs measured (written into the calibrated file's
  ``calibration.commands_measured_V``);
- :func:`beyond_curve` says where a log runs beyond them, and how much of its time;
- :func:`splice` joins the calibrated curve within them to one read beyond them;
  :mod:`hexsim.measured.curve_read` reads the curve there from the log itself, with the effects the identification
  named refitted on it (R1's nulls: `none`; its five effects `explained`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from hexsim.measured.flow_curve import (
    GRID_MIN_V,
    GRID_REL,
    FlowCurves,
    edge_grid,
    edge_opening,
)
from hexsim.measured.measurement import MeasurementLog
from hexsim.measured.records import CalibrationRecord
from hexsim.plant.machine import Machine
from hexsim.plant.params import thin_curve

#: A command is measured where the logs spent at least this long [s] within a knot spacing of the flow curve's grid
#: either side of it (max(GRID_MIN_V, GRID_REL u)): five of the flow balance's 10 ms intervals. R1's calibration
#: logs: 0.2-0.3 s at 0.7 V, 10 ms at 0.85 V.
MIN_DWELL_S = 0.05

#: A log's commands beyond the measured ones by more than this fraction of their range are reported.
CURVE_MARGIN = 0.05


def measured_commands(logs: list[MeasurementLog], null_offset: float | None = None) -> tuple[float, float]:
    """The commands at the spool [V] (u_v - u_0: ``null_offset``, default each log's machine's), (lowest, highest),
    over which ``logs`` measured the valve's flow curve: on each edge out to the end of the run of knots of the
    curve's grid (:func:`hexsim.measured.flow_curve.edge_grid`) on each of which the logs together spent at least
    :data:`MIN_DWELL_S` within a knot spacing, the run with the most time (:func:`_run_end`). 0 on an edge the logs
    never dwelt on."""
    u = np.concatenate([log.columns["valve_cmd_V"] - (log.machine.hydraulics.null_offset if null_offset is None
                                                      else null_offset) for log in logs])
    dt = np.concatenate([np.full(len(log.columns["valve_cmd_V"]), 1.0 / log.sample_rate_hz) for log in logs])
    out = []
    for sign in (-1.0, 1.0):
        v = sign * u
        order = np.argsort(v)
        v, time = v[order], np.concatenate([[0.0], np.cumsum(dt[order])])
        knots = edge_grid(max(float(v[-1]), GRID_MIN_V))
        knots = knots[knots > 0.0]
        half = np.maximum(GRID_MIN_V, GRID_REL * knots)
        dwell = time[np.searchsorted(v, knots + half, "right")] - time[np.searchsorted(v, knots - half, "left")]
        out.append(sign * _run_end(knots, dwell))
    return out[0], out[1]


def _run_end(knots: np.ndarray, dwell: np.ndarray) -> float:
    """The last knot [V] of the run of neighbouring knots each dwelt on for :data:`MIN_DWELL_S` whose dwell adds up
    to the most (a sine crosses the overlap near null in a few milliseconds, a saturated step dwells at the
    range's end alone); 0 where no knot was dwelt on."""
    dwelt = np.r_[False, dwell >= MIN_DWELL_S, False].astype(int)
    starts, ends = np.flatnonzero(np.diff(dwelt) == 1), np.flatnonzero(np.diff(dwelt) == -1)
    if starts.size == 0:
        return 0.0
    best = max(range(len(starts)), key=lambda r: float(dwell[starts[r]:ends[r]].sum()))
    return float(knots[ends[best] - 1])


def _measured(record: CalibrationRecord) -> tuple[float, float] | None:
    """The commands the record's calibration measured, or for a file calibrated before they were written, those
    its curve was read to (None: neither)."""
    return record.commands_measured_V or record.curve_commands_V


def beyond_curve(log: MeasurementLog) -> dict | None:
    """Where a single-actuator ``log``'s valve commands (at the spool, u_v - u_0) go beyond those its machine's
    calibration measured (:func:`measured_commands`) by more than :data:`CURVE_MARGIN` of that range: the
    commands, the measured range, the share of the log's time beyond it and a sentence (a misfit there is the
    calibration's envelope, not an effect); None where the machine was not calibrated on transients or the log
    stays inside."""
    record = CalibrationRecord.of(log.machine.calibration, f"{log.machine.label}: calibration")
    measured = None if log.system != "single-actuator" or record is None else _measured(record)
    if measured is None:
        return None
    lo, hi = measured
    u = log.columns["valve_cmd_V"] - log.machine.hydraulics.null_offset
    margin = CURVE_MARGIN * (hi - lo)
    outside = (u < lo - margin) | (u > hi + margin)
    if not outside.any():
        return None
    share = float(np.mean(outside))
    return {"commands_V": [float(u.min()), float(u.max())], "calibrated_V": [lo, hi], "time_share": share,
            "sentence": f"The log runs the valve at {u.min():.3g}…{u.max():.3g} V, {share:.0%} of its time beyond "
                        f"the {lo:.3g}…{hi:.3g} V its machine's calibration logs measured the flow curve over (they "
                        f"passed the rest in less than {MIN_DWELL_S * 1e3:g} ms per knot): a misfit at those "
                        f"commands is the calibration's envelope before it is an effect. Calibrate with a log "
                        f"that dwells there (a null log of this motion), or see below what reading the curve there "
                        f"from this log leaves."}


def windows_beyond_text(report: dict) -> str:
    """Whether the worst held-out windows a calibration ``report`` names (those of
    :func:`hexsim.measured.dynamics.worst_windows_text`: the log of largest held-out cost among its ``transients``)
    run the valve beyond the commands at the spool it measured (``commands_measured_V`` [V], lowest and highest:
    :func:`measured_commands`) by more than :data:`CURVE_MARGIN` of their range, the calibrated null offset taken
    off: one sentence, or "" where none does or nothing was measured."""
    errors = [t["after"] for t in report.get("transients", []) if "after" in t]
    measured = report.get("commands_measured_V")
    null_offset = next((r["value"] for r in report.get("parameters", []) if r.get("key") == "valve.null_offset_V"), 0.0)
    rows = [e for e in errors if e.get("worst_windows")]
    if not rows or not measured:
        return ""
    lo, hi = measured
    margin = CURVE_MARGIN * (hi - lo)
    windows = max(rows, key=lambda e: e["held_out_cost"])["worst_windows"]
    beyond = [w for w in windows if w["command_V"][0] - null_offset < lo - margin
              or w["command_V"][1] - null_offset > hi + margin]
    if not beyond:
        return ""
    verb = "runs" if len(beyond) == 1 else "run"
    return (f"{len(beyond)} of those {len(windows)} {verb} the valve beyond the {lo:.3g}…{hi:.3g} V at the spool "
            f"the logs dwelt on (less than {MIN_DWELL_S * 1e3:g} ms per knot beyond), where the flow curve is the "
            "calibration's extrapolation: a corner of the valve's curve there is not read.")


def splice(machine: Machine, curves: FlowCurves, lo: float, hi: float) -> Callable[[tuple], tuple[list, list]]:
    """Each edge's points for the machine file as a function of ``gains`` (P→A, A→T): ``machine``'s own opening
    (its form or curve, with its edge gain) within the commands ``lo``…``hi`` [V] its calibration measured, exactly
    (there the calibration refined the curve's scale by the replays, to parts in a thousand; the flows give it to
    about a percent), and beyond them the ``curves`` read from the log (:meth:`FlowCurves.points`), scaled to meet
    it, their rise beyond it times the edge's gain, blended in over :data:`BLEND` of the limit. The points are
    chosen once, at unit gains (:func:`hexsim.plant.params.thin_curve`), and each gain evaluated at them (a gain
    within :data:`GAIN_BOUNDS` changes the rise's shape by a factor only)."""
    points = curves.points(machine)
    edges = []
    for side, edge, limit in ((0, curves.pa, hi), (1, curves.at, -lo)):
        u = np.unique(np.concatenate([edge.knots, np.linspace(edge.knots[0], machine.hydraulics.u_v_max, 2001),
                                      [limit]]))
        own = edge_opening(machine, side, u)
        knots, values = np.array(points[side], dtype=float).T
        at_limit, own_limit = float(np.interp(limit, knots, values)), float(np.interp(limit, u, own))
        x = np.clip((u - limit) / max(BLEND * limit, GRID_MIN_V), 0.0, 1.0)  # an edge never dwelt on: limit 0
        blend = x * x * (3.0 - 2.0 * x)  # smoothstep
        rise = blend * ((own_limit / at_limit if at_limit > 0.0 else 1.0) * np.interp(u, knots, values) - own_limit)
        base = (1.0 - blend) * own + blend * own_limit
        chosen = np.array(thin_curve(u, np.maximum.accumulate(np.maximum(base + rise, 0.0))))[:, 0]
        edges.append((chosen, np.interp(chosen, u, base), np.interp(chosen, u, rise)))

    def at(gains) -> tuple[list, list]:
        return tuple([[float(c), float(v)] for c, v in zip(chosen, np.maximum.accumulate(np.maximum(b + k * r, 0.0)))]
                     for (chosen, b, r), k in zip(edges, gains))

    return at


#: The calibrated curve passes into the one read beyond over this share of the measured command (a smoothstep: a kink
#: where their slopes differ would be an acceleration step at every crossing).
BLEND = 0.15
#: The bounds of the replays' scale of each edge's curve beyond the measured commands
#: (:func:`hexsim.measured.curve_read.curve_read_from_log`).
GAIN_BOUNDS = (0.8, 1.25)
