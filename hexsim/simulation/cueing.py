"""The cue report of a ``vehicle:`` run: what the driver senses in the simulator against the vehicle.

Three motions of the driver's head are sensed with the vestibular models of
:mod:`hexsim.simulation.perception` (otoliths on specific force less 1 g, canals on angular velocity):

* the **vehicle**'s (the input file, at the head, vehicle axes);
* the **ideal platform**'s: the washout's setpoints as a rigid platform would follow them exactly (their
  kinematics, :func:`pose_motion`) -- what the cueing algorithm alone gives;
* the **simulator**'s: the simulated hexapod (hydraulics, controller, compensator) from its recorded
  rigid-body state (:func:`~hexsim.simulation.perception.point_motion`).

Per axis the report gives the sensed-cue error against the vehicle (rms, and the correlation coefficient,
as the motion-cueing literature reports them, e.g. Grant & Reid 1997, Telban & Cardullo 2005) and the
false cues: stretches where the simulator's sensed cue is above threshold while the vehicle's is below it
or of the opposite sign (stretches less than 0.2 s apart are one). A false cue the ideal platform also has
within 0.2 s comes from the **washout**; one it does
not have comes from the **hardware**, and from a **reversal bump** when a leg reverses within 0.15 s of
it. Bumps are short and mostly felt through the seat: the ISO 2631-1 weighted difference between the
simulator's and the ideal platform's specific force at the seat is counted as hardware cues above the
0.015 m/s^2 threshold, near leg reversals or elsewhere. Leg excursions, valve saturation and the
washout's limiting close the report.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import find_peaks
from scipy.spatial.transform import Rotation

from hexsim.signals import zero_crossings
from hexsim.simulation.perception import (
    AXES,
    ISO_PERCEPTION_THRESHOLD,
    ISO_WEIGHTINGS,
    PointMotion,
    iso2631,
    point_motion,
    sensed_threshold,
    vestibular_model,
)

#: a false cue within this of a leg's velocity reversal is a reversal bump [s]
REVERSAL_NEAR_S = 0.15
#: false cues closer than this are one; the ideal platform's within this of one make it the washout's [s]
MERGE_S = 0.2


def pose_motion(t: np.ndarray, poses: np.ndarray, point_m, gravity: float = 9.81) -> PointMotion:
    """The motion at ``point_m`` (3,) [m, platform frame] of a rigid platform following ``poses`` (N, 6)
    [m, rad] (x, y, z relative to neutral, world; roll, pitch, yaw as hexsim's poses: intrinsic Z-Y-X) at
    times t (N,) [s] exactly: the point's world position differentiated twice (numpy.gradient), gravity
    added, in platform axes; the body rates from consecutive orientations."""
    rot = Rotation.from_euler("ZYX", poses[:, [5, 4, 3]])
    p = poses[:, :3] + rot.apply(np.asarray(point_m, dtype=float))
    a = np.gradient(np.gradient(p, t, axis=0), t, axis=0)
    f = rot.inv().apply(a + np.array([0.0, 0.0, gravity]))
    dt = np.diff(t)
    w_mid = (rot[:-1].inv() * rot[1:]).as_rotvec() / dt[:, None]  # body rates between samples
    w = np.empty_like(p)
    w[1:-1] = 0.5 * (w_mid[:-1] + w_mid[1:])
    w[0], w[-1] = w_mid[0], w_mid[-1]
    alpha = np.gradient(w, t, axis=0)
    return PointMotion(t, f, w, alpha, np.asarray(point_m, dtype=float))


def sensed(motion_channels: np.ndarray, fs: float, gravity: float) -> np.ndarray:
    """The vestibular models' output (N, 6) to channels (N, 6) (specific force x, y, z with 1 g on z,
    angular velocity), from a state at rest in 1 g."""
    x = motion_channels - np.array([0.0, 0.0, gravity, 0.0, 0.0, 0.0])
    return np.stack([vestibular_model(a).apply(x[:, k], fs) for k, a in enumerate(AXES)], axis=1)


def _episodes(mask: np.ndarray, merge: int = 0) -> list[tuple[int, int]]:
    """Contiguous True stretches of ``mask`` as (start, stop) index pairs, stretches fewer than ``merge``
    samples apart joined (a cue hovering about its threshold is one false cue, not many)."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    out: list[tuple[int, int]] = []
    for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)):
        if out and a - out[-1][1] < merge:
            out[-1] = (out[-1][0], b)
        else:
            out.append((a, b))
    return out


def leg_reversals(t: np.ndarray, ydot: np.ndarray, min_speed: float = 2e-3) -> np.ndarray:
    """Times [s] where some leg's piston velocity ydot (N, n_legs) [m/s] changes sign between motions of
    at least ``min_speed`` on both sides within 0.2 s (a reversal, not the noise of a leg at rest)."""
    out = []
    for i in range(ydot.shape[1]):
        for tc in zero_crossings(t, ydot[:, i]):
            before = (t >= tc - 0.2) & (t < tc)
            after = (t > tc) & (t <= tc + 0.2)
            if np.any(before) and np.any(after) and np.max(np.abs(ydot[before, i])) > min_speed \
                    and np.max(np.abs(ydot[after, i])) > min_speed:
                out.append(tc)
    return np.unique(np.round(np.array(out), 4))


def cue_report(result) -> dict:
    """The cue report of a ``vehicle:`` run (module doc) as a JSON-ready dict. Raises ValueError for a run
    of another scenario."""
    from hexsim.plant.geometry import MICRO_MOTION_SYSTEM

    sc = result.config.scenario
    if sc.cueing is None:
        raise ValueError(f"scenario {sc.name} is not a vehicle motion: no cue report")
    vehicle, params, out = sc.cueing
    geometry = result.config.geometry or MICRO_MOTION_SYSTEM
    t, g = result.t, result.gravity
    fs = 1.0 / float(np.median(np.diff(t)))
    f_v, w_v = vehicle.at(t)
    head = geometry.head_point
    sim = point_motion(result, head)
    ideal = pose_motion(t, sc.poses(t), head, g)
    s_veh = sensed(np.concatenate([f_v - np.array([0.0, 0.0, 9.81 - g]), w_v], axis=1), fs, g)
    s_sim, s_ideal = sensed(sim.channels, fs, g), sensed(ideal.channels, fs, g)
    reversals = leg_reversals(t, result.ydot)
    axes = {}
    for k, axis in enumerate(AXES):
        thr = sensed_threshold(axis, fs)
        axes[axis] = _axis_figures(t, s_veh[:, k], s_sim[:, k], s_ideal[:, k], thr, reversals)
    seat = _seat_figures(result, geometry.seat_point, sc, fs, reversals)
    y = result.y
    margin = np.minimum(y.min(axis=0) - result.stroke[:, 0], result.stroke[:, 1] - y.max(axis=0))
    return {
        "vehicle": vehicle.source, "washout": params.source, "washout_parameters": params.document(),
        "head_at_m": head.tolist(), "seat_at_m": geometry.seat_point.tolist(),
        "axes": axes, "seat": seat,
        "false_cues": {src: sum(a["false_cues"][src] for a in axes.values())
                       for src in ("washout", "hardware", "reversal_bump")},
        "leg_reversals": int(reversals.size),
        "legs": {"stroke_margin_m": margin.tolist(), "min_stroke_margin_m": float(margin.min()),
                 "valve_saturated_samples": result.saturated_samples,
                 "max_tracking_error_m": float(np.max(np.abs(result.y_ref - result.y)))},
        "washout_limiting": {"limited_samples": dict(zip(("f_x", "f_y", "f_z", "p", "q", "r"),
                                                         out.limited.tolist())),
                             "tilt_rate_limited_samples": out.tilt_rate_limited,
                             "max_tilt_deg": np.degrees(np.abs(out.tilt).max(axis=0)).tolist()},
        "traces": {"t": t, "vehicle": s_veh, "simulator": s_sim, "ideal": s_ideal},
    }


def _axis_figures(t, veh, sim, ideal, thr, reversals) -> dict:
    """One axis' sensed-cue error and false cues (module doc)."""
    err = sim - veh
    corr = None
    if np.std(veh) > 1e-12 and np.std(sim) > 1e-12:
        corr = float(np.corrcoef(veh, sim)[0, 1])
    false_sim = (np.abs(sim) > thr) & ((np.abs(veh) < thr) | (np.sign(sim) != np.sign(veh)))
    false_ideal = (np.abs(ideal) > thr) & ((np.abs(veh) < thr) | (np.sign(ideal) != np.sign(veh)))
    counts = {"washout": 0, "hardware": 0, "reversal_bump": 0}
    near = int(round(MERGE_S / float(np.median(np.diff(t)))))
    for a, b in _episodes(false_sim, near):
        if np.any(false_ideal[max(0, a - near):b + near]):
            counts["washout"] += 1
        elif reversals.size and np.min(np.abs(reversals - 0.5 * (t[a] + t[b - 1]))) <= REVERSAL_NEAR_S:
            counts["reversal_bump"] += 1
        else:
            counts["hardware"] += 1
    return {"sensed_threshold": thr, "rms_error": float(np.sqrt(np.mean(err**2))),
            "rms_vehicle": float(np.sqrt(np.mean(veh**2))), "correlation": corr,
            "peak_vehicle": float(np.max(np.abs(veh))), "peak_simulator": float(np.max(np.abs(sim))),
            "false_cue_s": float(np.sum(false_sim) / (1.0 / np.median(np.diff(t)))), "false_cues": counts}


def _seat_figures(result, seat_m, sc, fs, reversals) -> dict:
    """The hardware's part at the seat: ISO 2631-1 weighted (simulator - ideal platform) per axis, its
    peaks above the perception threshold (0.2 s apart) counted near leg reversals and elsewhere."""
    t = result.t
    diff = point_motion(result, seat_m).specific_force - pose_motion(t, sc.poses(t), seat_m, result.gravity).specific_force
    out = {}
    for k, axis in enumerate("xyz"):
        w = iso2631(ISO_WEIGHTINGS[axis]).apply(diff[:, k], fs)
        peaks, _ = find_peaks(np.abs(w), height=ISO_PERCEPTION_THRESHOLD, distance=max(1, int(0.2 * fs)))
        near = [p for p in peaks if reversals.size and np.min(np.abs(reversals - t[p])) <= REVERSAL_NEAR_S]
        out[axis] = {"weighting": ISO_WEIGHTINGS[axis], "max_weighted_mps2": float(np.max(np.abs(w))),
                     "perceptible_at_reversals": len(near), "perceptible_elsewhere": int(len(peaks) - len(near))}
    return out


def cue_table(report: dict) -> str:
    """The cue report as aligned text: one row per axis, then the seat, legs and the washout's limiting."""
    head = f"{'axis':<6} {'rms error':>10} {'vehicle rms':>11} {'corr':>6} {'false cues: washout':>20} {'hardware':>8} {'bump':>5}"
    rows = [head, "-" * len(head)]
    for axis, a in report["axes"].items():
        unit = "m/s^2" if axis in "xyz" else "rad/s"
        corr = f"{a['correlation']:.2f}" if a["correlation"] is not None else "—"
        fc = a["false_cues"]
        rows.append(f"{axis:<6} {a['rms_error']:>10.4f} {a['rms_vehicle']:>11.4f} {corr:>6} {fc['washout']:>20} "
                    f"{fc['hardware']:>8} {fc['reversal_bump']:>5}  [{unit}, sensed]")
    seat = report["seat"]
    rows.append("seat (ISO 2631-1, simulator - ideal platform): " + ", ".join(
        f"{axis} {s['max_weighted_mps2']:.3f} m/s^2 max, {s['perceptible_at_reversals']} felt at reversals, "
        f"{s['perceptible_elsewhere']} elsewhere" for axis, s in seat.items()))
    legs = report["legs"]
    rows.append(f"legs: {report['leg_reversals']} reversals, stroke margin {legs['min_stroke_margin_m'] * 1e3:.1f} mm "
                f"at least, valve saturated {legs['valve_saturated_samples']} samples, tracking error "
                f"{legs['max_tracking_error_m'] * 1e3:.2f} mm max")
    lim = report["washout_limiting"]
    rows.append(f"washout: limited samples {lim['limited_samples']}, tilt at its rate limit "
                f"{lim['tilt_rate_limited_samples']} samples, tilt up to {max(lim['max_tilt_deg']):.2f} deg")
    return "\n".join(rows)
