"""The run's figures as a JSON-ready dict and as a short summary table for stdout."""

from __future__ import annotations

import numpy as np

from hexsim.engine.config import SimulationResult
from hexsim.studies.metrics import Smoothness, max_tracking_error, steady_segments


def run_report(result: SimulationResult, sm: Smoothness, perception=None) -> dict:
    """The metrics of a run (JSON keys documented in docs/outputs.md). SI units throughout.
    ``perception``: the run's :class:`~hexsim.studies.perception.BumpPerception` (a hexapod's), reported
    under ``"perception"``; None: the key is null."""
    sc, cfg = result.config.scenario, result.config
    return {
        "scenario": sc.name,
        "machine": cfg.machine_label,
        "system": sc.system,
        "duration_s": sc.duration,
        "axis": sc.axis_name,
        "frequency_hz": sc.frequency,
        "amplitude": sc.amplitude,
        "compensator": cfg.compensator_name,
        "seed": cfg.seed,
        "flow_area": cfg.hydraulics.flow_area,
        "kp_V_per_m": cfg.controller.kp,
        "controller_rate_hz": cfg.controller.rate_hz,
        "engine": cfg.engine,
        "model": cfg.model if sc.system == "hexapod" else "full",
        "timestep_s": result.timestep,
        "signal": sm.signal,
        "unit": sm.unit,
        "window_s": list(sm.window),
        "fundamental": sm.fundamental_amplitude,
        "offset": sm.offset,
        "noise_ratio": sm.noise_ratio,
        "peak_noise": sm.peak_noise,
        "peak_noise_g": sm.peak_noise_g,
        "noise_floor": sm.noise_floor,
        "reversal_times_s": sm.reversal_times.tolist(),
        "reversal_peaks": sm.reversal_peaks.tolist(),
        "mean_reversal_peak": sm.mean_reversal_peak,
        "max_tracking_error_m": max_tracking_error(result),
        "max_constraint_violation_m": float(np.max(result.constraint_violation)),
        "p1_initial_Pa": result.p1_initial.tolist(),
        "valve_saturated_samples": result.saturated_samples,
        "compensator_parameters": {k: v[-1].tolist() for k, v in result.compensator_state.items()},
        "oil_temperature_C": [float(result.oil_temperature[0]), float(result.oil_temperature[-1])],
        "faults": fault_outcomes(result),
        "perception": None if perception is None else perception.figures(),
        "realtime_factor": result.realtime_factor,
        "wall_time_s": result.wall_time_s,
    }


def open_loop_report(result: SimulationResult) -> dict:
    """The figures of an open-loop run (a ``valve:`` scenario): per leg the steady motions at each
    constant valve setpoint (:func:`hexsim.studies.metrics.steady_segments`: speed, P1 and, with a
    4-way valve, P2), the piston's range and the lowest and highest pressures. SI units."""
    sc, cfg = result.config.scenario, result.config
    four_way = cfg.hydraulics.four_way
    legs = []
    for i in range(result.n_legs):
        pressures = {"p1_Pa": result.p1[:, i], **({"p2_Pa": result.p2[:, i]} if four_way else {})}
        legs.append({"steady": steady_segments(result.t, result.u_v[:, i], result.y[:, i], pressures),
                     "piston_range_m": [float(result.y[:, i].min()), float(result.y[:, i].max())],
                     "p1_range_Pa": [float(result.p1[:, i].min()), float(result.p1[:, i].max())],
                     **({"p2_range_Pa": [float(result.p2[:, i].min()), float(result.p2[:, i].max())]}
                        if four_way else {})})
    return {"scenario": sc.name, "machine": cfg.machine_label, "system": sc.system,
            "open_loop": True, "valve_type": cfg.hydraulics.valve_type, "duration_s": sc.duration,
            "engine": cfg.engine, "timestep_s": result.timestep, "legs": legs,
            "realtime_factor": result.realtime_factor, "wall_time_s": result.wall_time_s}


def open_loop_table(report: dict) -> str:
    """The summary lines of an open-loop run: what ran, and each leg's steady motions."""
    rows = [("scenario", f"{report['scenario']} ({report['system']}, open loop, {report['duration_s']:g} s)"),
            ("machine", f"{report['machine']} ({report['valve_type']} valve)")]
    for i, leg in enumerate(report["legs"]):
        lo, hi = leg["piston_range_m"]
        rows.append((f"leg{i + 1}", f"piston {lo * 1e3:.1f}…{hi * 1e3:.1f} mm"))
        for s in leg["steady"]:
            p2 = f", P2 {s['p2_Pa'] / 1e5:.2f} bar" if "p2_Pa" in s else ""
            rows.append(("  steady", f"u_v {s['u_V']:+.2f} V: {s['velocity_mps'] * 1e3:+.1f} mm/s, "
                                     f"P1 {s['p1_Pa'] / 1e5:.2f} bar{p2} ({s['t_start_s']:.2f}…{s['t_end_s']:.2f} s)"))
    rows.append(("realtime_factor", f"{report['realtime_factor']:.2f}x ({report['wall_time_s']:.1f} s wall)"))
    width = max(len(k) for k, _ in rows)
    return "\n".join(f"{k:<{width}}  {v}" for k, v in rows)


def fault_outcomes(result: SimulationResult) -> list[dict]:
    """Each injected fault (kind, t_s, leg, its value) and what followed from its start: the leg's
    extreme piston positions and how far past the stroke (the soft end stops' penetration) [m], the
    lowest supply pressure [Pa], the largest connect violation [m]. The run stayed finite, or it would
    have raised."""
    out = []
    stroke = result.stroke
    for fault in result.config.faults:
        after = result.t >= fault.t
        doc = fault.as_dict()
        if not np.any(after):
            doc["outcome"] = "not reached (starts after the end of the run)"
            out.append(doc)
            continue
        legs = [fault.leg - 1] if fault.leg is not None else list(range(result.n_legs))
        y = result.y[after][:, legs]
        lo, hi = stroke[legs, 0], stroke[legs, 1]
        doc["outcome"] = {
            "piston_min_m": float(y.min()),
            "piston_max_m": float(y.max()),
            "beyond_stroke_m": float(max(0.0, np.max(y - hi), np.max(lo - y))),
            "p_s_min_Pa": float(result.p_s[after].min()),
            "max_constraint_violation_m": float(result.constraint_violation[after].max()),
            "finite": True,
        }
        out.append(doc)
    return out


def summary_table(report: dict) -> str:
    """A few lines for stdout: what ran and the smoothness figures."""
    unit = report["unit"]
    g = f" ({report['peak_noise_g']:.4f} g)" if report["peak_noise_g"] is not None else ""
    peaks = report["reversal_peaks"]
    connects = report["system"] == "hexapod" and report["model"] == "full"  # the only model with connects
    rows = [
        ("scenario", f"{report['scenario']} ({report['system']}"
                     f"{', ' + report['model'] + ' model' if report['system'] == 'hexapod' else ''}, {report['duration_s']:g} s, "
                     f"{report['frequency_hz']:g} Hz, compensator {report['compensator']})"),
        ("machine", report["machine"]),
        ("signal", report["signal"]),
        ("fundamental", f"{report['fundamental']:.4f} {unit}"),
        ("noise_ratio", f"{report['noise_ratio']:.4f}"),
        ("peak_noise", f"{report['peak_noise']:.4f} {unit}{g}"),
        ("reversal_peaks", f"{len(peaks)} reversals, mean {report['mean_reversal_peak']:.4f} {unit}, "
                           f"max {max(peaks, default=float('nan')):.4f} {unit}; noise floor {report['noise_floor']:.4f} {unit}"),
        *((("perceptible", _perception_line(report["perception"])),) if report.get("perception") else ()),
        ("max_tracking_error", f"{report['max_tracking_error_m'] * 1e3:.2f} mm"),
        *((("constraint_violation", f"{report['max_constraint_violation_m'] * 1e6:.3f} µm max (the legs' closures)"),)
          if connects else ()),
        ("valve_saturated", f"{report['valve_saturated_samples']} controller samples"),
        *(("fault", _fault_line(f, connects)) for f in report["faults"]),
        ("realtime_factor", f"{report['realtime_factor']:.2f}x ({report['wall_time_s']:.1f} s wall)"),
    ]
    width = max(len(k) for k, _ in rows)
    return "\n".join(f"{k:<{width}}  {v}" for k, v in rows)


def _perception_line(p: dict) -> str:
    """How many bumps the occupant feels, on which path, and the worst axis of each (its ratio to threshold)."""
    if not p["reversals"]:
        return "no reversal in the analysis window"
    seat = max("xyz", key=lambda a: p["axes"][a]["seat_max_ratio"] or 0)
    vest = max(p["axes"], key=lambda a: p["axes"][a]["vestibular_max_ratio"] or 0)
    return (f"{p['perceptible']} of {p['reversals']} bumps (seat: {p['perceptible_seat']}, worst {seat} "
            f"{p['axes'][seat]['seat_max_ratio']:.2f}x the seat threshold; vestibular: "
            f"{p['perceptible_vestibular']}, worst {vest} {p['axes'][vest]['vestibular_max_ratio']:.2f}x)")


def _fault_line(f: dict, connects: bool) -> str:
    where = f"leg{f['leg']} " if f["leg"] is not None else ""
    o = f["outcome"]
    if isinstance(o, str):
        return f"{f['kind']} {where}at {f['t_s']:g} s: {o}"
    return (f"{f['kind']} {where}at {f['t_s']:g} s: piston {o['piston_min_m'] * 1e3:.1f}…{o['piston_max_m'] * 1e3:.1f} mm "
            f"({o['beyond_stroke_m'] * 1e3:.2f} mm past the stroke), P_s min {o['p_s_min_Pa'] / 1e5:.1f} bar, "
            + (f"connect violation {o['max_constraint_violation_m'] * 1e6:.2f} µm; " if connects else "")
            + "stayed finite")
