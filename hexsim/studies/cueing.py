"""The cue report of a ``vehicle:`` run: what the driver senses in the simulator against the vehicle.

Three motions of the driver's head are sensed with the vestibular models of
:mod:`hexsim.studies.perception` (otoliths on specific force less 1 g, canals on angular velocity):

* the **vehicle**'s (the input file, at the head, vehicle axes);
* the **ideal platform**'s: the washout's setpoints as a rigid platform would follow them exactly (their
  kinematics, :func:`pose_motion`) -- what the cueing algorithm alone gives;
* the **simulator**'s: the simulated hexapod (hydraulics, controller, compensator) from its recorded
  rigid-body state (:func:`~hexsim.studies.perception.point_motion`).

Per axis the report gives the sensed-cue error against the vehicle (rms, and the correlation coefficient,
as the motion-cueing literature reports them, e.g. Grant & Reid 1997, Telban & Cardullo 2005) and the
false cues: stretches where the simulator's sensed cue is above threshold while the vehicle's is below it
or of the opposite sign (stretches less than 0.2 s apart are one). A false cue the ideal platform also has
within 0.2 s comes from the **washout**; one it does
not have comes from the **hardware**, and from a **reversal bump** when a leg reverses within 0.15 s of
it. Bumps are short and mostly felt through the seat: where the ideal platform's ISO 2631-1 weighted
specific force at the seat is below the 0.015 m/s^2 threshold, the simulator's peaks above it are hardware
cues, counted near leg reversals or elsewhere. Leg excursions, valve saturation and the
washout's limiting close the report.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import maximum_filter1d
from scipy.signal import find_peaks
from scipy.spatial.transform import Rotation

from hexsim.signals import zero_crossings
from hexsim.studies.perception import (
    AXES,
    DEFAULT_THRESHOLDS,
    ISO_WEIGHTINGS,
    PointMotion,
    Thresholds,
    iso2631,
    point_motion,
    sensed_threshold,
    vestibular_model,
)

#: a false cue within this of a leg's velocity reversal is a reversal bump [s]
REVERSAL_NEAR_S = 0.15
#: false cues closer than this are one; the ideal platform's within this of one make it the washout's [s]
MERGE_S = 0.2


@dataclass(frozen=True)
class AxisCue:
    """One axis' sensed cue (m/s^2 for x, y, z; rad/s for roll, pitch, yaw): the vestibular model's
    ``sensed_threshold``; ``rms_error`` of the simulator's sensed cue against the vehicle's, ``rms_vehicle``,
    their ``correlation`` (None where either does not move); the peaks; ``false_cue_s``: time the simulator's
    cue was false; ``false_cues``: false cues by source (washout, hardware, reversal_bump)."""

    sensed_threshold: float
    rms_error: float
    rms_vehicle: float
    correlation: float | None
    peak_vehicle: float
    peak_simulator: float
    false_cue_s: float
    false_cues: dict[str, int]


@dataclass(frozen=True)
class SeatCue:
    """The hardware's cues at the seat on one axis: the ISO 2631-1 ``weighting``, the simulator's largest
    weighted specific force [m/s^2] where the ideal platform's is below the perception threshold, and its
    peaks above the threshold there, near leg reversals and elsewhere."""

    weighting: str
    max_weighted_mps2: float
    perceptible_at_reversals: int
    perceptible_elsewhere: int


@dataclass(frozen=True)
class CueReport:
    """The cue report of a ``vehicle:`` run (module doc): the inputs (vehicle source, washout parameters),
    the occupant's points (3,) [m, platform frame], ``axes`` (AXES -> :class:`AxisCue`), ``seat`` (x, y, z ->
    :class:`SeatCue`), ``false_cues`` summed over the axes by source, the legs' reversals, stroke margins (6,)
    [m], valve saturation and tracking error, the washout's limiting, and ``t`` (N,) with the sensed cues
    (N, 6) of ``vehicle``, ``ideal`` platform and ``simulator`` for plots."""

    vehicle: str
    washout: str
    washout_parameters: dict
    head_m: np.ndarray
    seat_m: np.ndarray
    axes: dict[str, AxisCue]
    seat: dict[str, SeatCue]
    false_cues: dict[str, int]
    leg_reversals: int
    stroke_margin_m: np.ndarray
    valve_saturated_samples: int
    max_tracking_error_m: float
    washout_limited_samples: dict[str, int]
    tilt_rate_limited_samples: int
    max_tilt_deg: tuple[float, float]
    t: np.ndarray = dataclasses.field(repr=False)
    sensed_vehicle: np.ndarray = dataclasses.field(repr=False)
    sensed_ideal: np.ndarray = dataclasses.field(repr=False)
    sensed_simulator: np.ndarray = dataclasses.field(repr=False)

    def document(self) -> dict:
        """JSON-ready (without the traces)."""
        return {"vehicle": self.vehicle, "washout": self.washout, "washout_parameters": self.washout_parameters,
                "head_at_m": self.head_m.tolist(), "seat_at_m": self.seat_m.tolist(),
                "axes": {k: dataclasses.asdict(v) for k, v in self.axes.items()},
                "seat": {k: dataclasses.asdict(v) for k, v in self.seat.items()},
                "false_cues": self.false_cues, "leg_reversals": self.leg_reversals,
                "legs": {"stroke_margin_m": self.stroke_margin_m.tolist(),
                         "min_stroke_margin_m": float(self.stroke_margin_m.min()),
                         "valve_saturated_samples": self.valve_saturated_samples,
                         "max_tracking_error_m": self.max_tracking_error_m},
                "washout_limiting": {"limited_samples": self.washout_limited_samples,
                                     "tilt_rate_limited_samples": self.tilt_rate_limited_samples,
                                     "max_tilt_deg": list(self.max_tilt_deg)}}


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


def cue_report(result, thresholds: Thresholds = DEFAULT_THRESHOLDS) -> CueReport:
    """The cue report of a ``vehicle:`` run (module doc) with the perception ``thresholds`` (default
    Benson's and ISO 2631-1's). Raises ValueError for a run of another scenario."""
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
    ideal = _ideal(sc, t, head, g)
    s_veh = sensed(np.concatenate([f_v - np.array([0.0, 0.0, 9.81 - g]), w_v], axis=1), fs, g)
    s_sim, s_ideal = sensed(sim.channels, fs, g), sensed(ideal.channels, fs, g)
    reversals = leg_reversals(t, result.ydot)
    axes = {}
    for k, axis in enumerate(AXES):
        thr = sensed_threshold(axis, fs, thresholds)
        axes[axis] = _axis_figures(t, s_veh[:, k], s_sim[:, k], s_ideal[:, k], thr, reversals)
    seat = _seat_figures(result, geometry.seat_point, sc, fs, reversals, thresholds.seat_mps2)
    margin = np.minimum(result.y.min(axis=0) - result.stroke[:, 0], result.stroke[:, 1] - result.y.max(axis=0))
    return CueReport(
        vehicle=vehicle.source, washout=params.source, washout_parameters=params.document(), head_m=head,
        seat_m=geometry.seat_point, axes=axes, seat=seat,
        false_cues={src: sum(a.false_cues[src] for a in axes.values()) for src in ("washout", "hardware", "reversal_bump")},
        leg_reversals=int(reversals.size), stroke_margin_m=margin, valve_saturated_samples=result.saturated_samples,
        max_tracking_error_m=float(np.max(np.abs(result.y_ref - result.y))),
        washout_limited_samples=dict(zip(("f_x", "f_y", "f_z", "p", "q", "r"), out.limited.tolist())),
        tilt_rate_limited_samples=out.tilt_rate_limited,
        max_tilt_deg=tuple(np.degrees(np.abs(out.tilt).max(axis=0)).tolist()),
        t=t, sensed_vehicle=s_veh, sensed_ideal=s_ideal, sensed_simulator=s_sim)


def _ideal(sc, t: np.ndarray, point_m, gravity: float) -> PointMotion:
    """The ideal platform's motion at ``point_m`` differentiated on the washout's own samples (a linear
    interpolation of them would put spikes into its second derivative at every knot), read at t (N,)."""
    out = sc.cueing[2]
    pm = pose_motion(out.t, out.poses, point_m, gravity)

    def at(x: np.ndarray) -> np.ndarray:
        return np.stack([np.interp(t, out.t, x[:, k]) for k in range(3)], axis=1)

    return PointMotion(t, at(pm.specific_force), at(pm.angular_velocity), at(pm.angular_acceleration), pm.point)


def _axis_figures(t, veh, sim, ideal, thr, reversals) -> AxisCue:
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
    return AxisCue(thr, float(np.sqrt(np.mean(err**2))), float(np.sqrt(np.mean(veh**2))), corr,
                   float(np.max(np.abs(veh))), float(np.max(np.abs(sim))),
                   float(np.sum(false_sim) * np.median(np.diff(t))), counts)


def _seat_figures(result, seat_m, sc, fs, reversals, threshold: float) -> dict[str, SeatCue]:
    """The hardware's cues at the seat: the ISO 2631-1 weighted specific force of the simulator where the
    ideal platform's, weighted alike, stays below the perception threshold within 0.1 s; its peaks above the
    threshold (0.2 s apart) counted near leg reversals and elsewhere."""
    t = result.t
    sim = point_motion(result, seat_m).specific_force
    ideal = _ideal(sc, t, seat_m, result.gravity).specific_force
    out = {}
    half = max(1, int(0.1 * fs))
    for k, axis in enumerate("xyz"):
        weighting = iso2631(ISO_WEIGHTINGS[axis])
        w_sim, w_ideal = weighting.apply(sim[:, k], fs), weighting.apply(ideal[:, k], fs)
        quiet = maximum_filter1d(np.abs(w_ideal), 2 * half + 1) < threshold
        peaks, _ = find_peaks(np.where(quiet, np.abs(w_sim), 0.0), height=threshold,
                              distance=max(1, int(0.2 * fs)))
        near = [p for p in peaks if reversals.size and np.min(np.abs(reversals - t[p])) <= REVERSAL_NEAR_S]
        largest = float(np.max(np.abs(w_sim[quiet]))) if np.any(quiet) else 0.0
        out[axis] = SeatCue(ISO_WEIGHTINGS[axis], largest, len(near), int(len(peaks) - len(near)))
    return out


def cue_table(report: CueReport) -> str:
    """The cue report as aligned text: one row per axis, then the seat, legs and the washout's limiting."""
    head = f"{'axis':<6} {'rms error':>10} {'vehicle rms':>11} {'corr':>6} {'false cues: washout':>20} {'hardware':>8} {'bump':>5}"
    rows = [head, "-" * len(head)]
    for axis, a in report.axes.items():
        unit = "m/s^2" if axis in "xyz" else "rad/s"
        corr = f"{a.correlation:.2f}" if a.correlation is not None else "—"
        fc = a.false_cues
        rows.append(f"{axis:<6} {a.rms_error:>10.4f} {a.rms_vehicle:>11.4f} {corr:>6} {fc['washout']:>20} "
                    f"{fc['hardware']:>8} {fc['reversal_bump']:>5}  [{unit}, sensed]")
    rows.append("seat (ISO 2631-1, where the ideal platform is below threshold): " + ", ".join(
        f"{axis} {s.max_weighted_mps2:.3f} m/s^2 max, {s.perceptible_at_reversals} felt at reversals, "
        f"{s.perceptible_elsewhere} elsewhere" for axis, s in report.seat.items()))
    rows.append(f"legs: {report.leg_reversals} reversals, stroke margin {report.stroke_margin_m.min() * 1e3:.1f} mm "
                f"at least, valve saturated {report.valve_saturated_samples} samples, tracking error "
                f"{report.max_tracking_error_m * 1e3:.2f} mm max")
    rows.append(f"washout: limited samples {report.washout_limited_samples}, tilt at its rate limit "
                f"{report.tilt_rate_limited_samples} samples, tilt up to {max(report.max_tilt_deg):.2f} deg")
    return "\n".join(rows)


def cue_lines(config, report: CueReport) -> list[str]:
    """What ``hexsim run vehicle:FILE`` says of a drive: the scenario and machine of ``config`` (the run's
    :class:`~hexsim.engine.config.RunConfig`), the MPC's programmes where it cued, then :func:`cue_table`."""
    solver = config.scenario.cueing[2].solver
    cueing = "washout" if solver is None else "mpc cueing"
    lines = [f"scenario  {config.scenario.name} (hexapod, {config.scenario.duration:g} s, {cueing} {report.washout}, "
             f"compensator {config.compensator_name})", f"machine   {config.machine_label}"]
    if solver is not None:
        lines.append(f"mpc       {solver['programmes']} programmes of {solver['variables']} variables, "
                     f"{solver['unsolved']} unsolved; solve {solver['solve_ms_mean']:.1f} ms mean, "
                     f"{solver['solve_ms_max']:.1f} ms largest: {solver['real_time_factor']:.1f}x real time")
    lines.append(cue_table(report))
    return lines
