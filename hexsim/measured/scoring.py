"""The scoring layer under calibration and identification: a log's replay problem and its budget, the
sensors' calibration as nuisance parameters, and the score of a model (steps 1 and 2 of
:mod:`hexsim.measured.identify`'s method).

1. **Noise budget** (:class:`Budget`, :func:`measure_budget`): every channel c is judged against
   b_c = sqrt(sigma_c^2 + tau_c^2), sigma_c the sensor noise, tau_c the replay's numerical error (the
   step's by Richardson, the closed-loop replay's reconstruction) and, on a calibrated machine, what the
   calibration left uncertain, in quadrature.
2. **Calibration** (:func:`calibrate_sensors`): every model fits the sensors' offsets and scales as nuisance
   parameters within the machine file's sensor tolerances (:class:`hexsim.plant.params.SensorSpec`).
3. **Score** (:class:`Scored`, :func:`score`, :func:`residual_vector`, :func:`within_budget`): the calibrated
   residuals over the budget, per window (fitted, held out) and per channel.

Identification (:mod:`hexsim.measured.identify`: candidates, the judge, forward selection) and calibration of a
machine's nominal (:mod:`hexsim.measured.calibration`, :mod:`hexsim.measured.dynamics`) both stand on it.
A single actuator's log is replayed in windows (:class:`Problem`), a hexapod's in closed loop
(:class:`hexsim.measured.hexapod_replay.HexapodProblem`); both are a
:class:`~hexsim.measured.replay.ReplayProblem`.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from hexsim.errors import InputError
from hexsim.measured.measurement import MeasurementLog
from hexsim.measured.records import CalibrationRecord, value_in
from hexsim.measured.replay import (
    CHANNELS,
    PlantModel,
    ReplayProblem,
    Windows,
    clear_of_jumps,
    measured_velocity,
    nominal_plant,
    replay,
)
from hexsim.measured.residuals import clipped, noise_of
from hexsim.plant.machine import with_keys
from hexsim.signals import near_reversals
from hexsim.studies.metrics import STANDARD_GRAVITY

#: Valve-replay window [s]: long enough to see a flow offset integrate, short enough not to drift away.
WINDOW_S = 0.3
#: Start of each window left out of the cost [s]: the initial state taken from the measurements
#: (velocity from a filtered derivative, P1 with its sensor noise) is not exact, and the 100 Hz oil
#: spring rings the difference out over some 10–40 ms.
SETTLE_S = 0.05
#: [m] A window whose measured position comes this close to an end of travel the log reaches is left out:
#: the end stops' position and stiffness, and the transducer's offset there, are no part of the machine
#: file (the real servo cylinder's retracted end reads 4-6 mm, not 0).
STOP_MARGIN_M = 3e-3
#: [m] An extreme of the log's travel within this of the stroke's end (0 or L_s) is an end stop it reached.
STOP_REACHED_M = 1e-2
#: Replay step [s] (the simulator's) and the factor of the coarse replay for the numerical tolerance.
REPLAY_DT = 1e-4
RICHARDSON = 2
#: A channel is explained when its held-out mean square is within this many budgets squared
#: (RMS within sqrt(2) b_c: noise, numerical tolerance and the sampling scatter of both).
WITHIN = 2.0
#: Channels whose sensors get a calibration scale (the others an offset only).
SCALED = ("position", "acceleration")
# The largest calibration scale error |scale - 1| and offset fitted per channel are the machine file's
# ``sensors`` tolerances (hexsim.plant.params.SensorSpec: accelerometers ±5 % and ±0.2 m/s², pressure
# transducers ±1.25 bar, position transducers ±1 %: a looser position scale trades with the valve's flow
# gain, the increments of a window scale with both). What a fit asks beyond them stays in the residual for
# the effects and is reported under "beyond".

#: A scale is fitted only to a signal whose replayed motion is at least this many times the log's noise
#: estimate (standard deviations; that estimate includes the accelerometer's real high-frequency content,
#: 0.26 m/s^2 on a single-actuator log whose motion is 1.4 m/s^2): a hexapod's accelerometer axes across
#: a heave motion replay at ~0.05 of it, and their scale clamped at the limit by chance.
SCALE_MIN_SNR = 3.0
#: ... and at least this share of the largest motion among the channel's signals (standard deviations):
#: on a noise-free log (hexsim's own) the noise estimate sits at its floor and the cross axes of a heave
#: replay, moving by numerical noise alone (1e-6 of the heave axis), had their scales fitted at 0.969
#: and reported as a sensitivity error.
SCALE_MIN_SHARE = 0.1


def available_channels(log: MeasurementLog) -> list[str]:
    return [ch for ch, (col, _, _) in CHANNELS.items() if col in log.columns]


def channel_scales(log: MeasurementLog) -> dict[str, float]:
    """Scale of each channel for the NRMSE: the standard deviation of the measured signal, floored (so a
    constant supply pressure is judged against 0.1 bar, not against its sensor noise)."""
    return {ch: max(float(np.std(log.columns[CHANNELS[ch][0]])), CHANNELS[ch][2]) for ch in available_channels(log)}


def as_signals(a: np.ndarray) -> np.ndarray:
    """(k, n) -> (k, n, 1); (k, n, s) unchanged."""
    return a[..., None] if a.ndim == 2 else a


class Problem:
    """A single-actuator log cut into valve-replay windows (:func:`hexsim.measured.replay.replay`); channel arrays
    (windows, samples), the first :data:`SETTLE_S` of each window not scored."""

    windowed = True  # each window starts from the measured state (position residual 0 at its start)
    position_offset_limit = math.inf  # (unused: a window's position starts at the measured one)
    focus_leg = None  # one actuator: no leg to look at
    screens = False  # a window replays in milliseconds: every candidate is fitted
    model = "single actuator"  # the formulation it is replayed on: the actuator has one

    def __init__(self, log: MeasurementLog, window_s: float = WINDOW_S) -> None:
        self.log = log
        length = int(round(window_s * log.sample_rate_hz))
        tiles = clear_of_jumps(log, Windows.tile(len(log.time), length))  # each start's velocity measurable
        usable, self.left_out = usable_windows(log, tiles)
        self.windows = Windows(tiles.starts[usable], length)
        self.fit_rows = np.arange(0, len(self.windows.starts), 2)
        self.test_rows = np.arange(1, len(self.windows.starts), 2)
        if len(self.test_rows) < 2 and usable.all():
            raise InputError(f"{log.path}: the log is shorter than four replay windows of {window_s} s")
        if len(self.test_rows) < 2:
            raise InputError(f"{log.path}: the log has fewer than four replay windows of {window_s} s away from "
                             f"its end stops and clipped sensors ({len(tiles.starts) - int(usable.sum())} of its "
                             f"{len(tiles.starts)} left out: {left_out_text(self.left_out)}); a replay needs motion "
                             f"in mid-stroke")
        self.settle = int(round(SETTLE_S * log.sample_rate_hz))
        self.channels = available_channels(log)
        self.scales = channel_scales(log)
        self.measured = {ch: self.windows.take(log.columns[CHANNELS[ch][0]]) for ch in self.channels}
        self.log_noise = {ch: noise_of(log.columns[CHANNELS[ch][0]], ch) for ch in self.channels}
        self.nominal = nominal_plant(log)

    def only(self, rows: np.ndarray) -> "Problem":
        """A copy whose windows are this problem's windows ``rows`` alone, all of them fit windows: a residual
        on them replays only them (the windows are independent bodies of one batch model, so each replays as
        it does among the others)."""
        out = copy.copy(self)
        out.windows = Windows(self.windows.starts[rows], self.windows.length)
        out.measured = {ch: m[rows] for ch, m in self.measured.items()}
        out.fit_rows, out.test_rows = np.arange(len(rows)), np.arange(0)
        return out

    def fit_windows(self) -> "Problem":
        """The fit windows alone (:meth:`only`): what a least-squares residual replays."""
        return self.only(self.fit_rows)

    def simulate(self, model: PlantModel, dt: float = REPLAY_DT) -> dict[str, np.ndarray]:
        """Replayed channels, name -> (windows, samples), physical units."""
        out = replay(self.log, model, self.windows, dt=dt)
        return {ch: out[ch] for ch in self.channels}

    def replay_error(self, model: PlantModel) -> dict[str, float]:
        """The replay's own error beyond the step's (see :meth:`HexapodProblem.replay_error`): none here,
        the logged u_v drives the model as logged and each window's start state is left out of the score
        (:data:`SETTLE_S`)."""
        return {ch: 0.0 for ch in self.channels}

    replay_mode = ("valve replay: the logged u_v drives the model open loop in windows, each started from "
                   "the measured state")
    scored = "windows after their settling time"

    @property
    def units(self) -> dict[str, str]:
        return {ch: CHANNELS[ch][1] for ch in self.channels}

    @property
    def window_doc(self) -> dict:
        fs = self.log.sample_rate_hz
        return {"count": int(len(self.windows.starts)), "length_s": self.windows.length / fs,
                "settle_s": self.settle / fs, "fit": "even windows", "held_out": "odd windows",
                "left_out": self.left_out}

    def analysis_view(self, res: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Residuals (k, n) per channel as the residual analysis takes them: windows without the settling."""
        return {ch: r[:, self.settle:] for ch, r in res.items()}

    def motion_state(self):
        """(u_v, velocity, position, near a reversal), each (k, n) like :meth:`analysis_view`."""
        log = self.log
        pos = log.columns["pos_m"]
        vel = measured_velocity(log, pos)
        near = near_reversals(log.time, vel)
        take = lambda x: self.windows.take(x)[:, self.settle:]  # noqa: E731
        return take(log.columns["valve_cmd_V"]), take(vel), take(pos), take(near)

    def sample_times(self) -> np.ndarray:
        """Log times [s] of the samples of :meth:`analysis_view` (k, n)."""
        fs = self.log.sample_rate_hz
        return self.log.time[self.windows.starts][:, None] + np.arange(self.settle, self.windows.length)[None, :] / fs


def usable_windows(log: MeasurementLog, windows: Windows) -> tuple[np.ndarray, dict]:
    """Which replay windows of a single-actuator log are evidence: (windows,) bool, and what was left out
    (``end_stops``: windows within :data:`STOP_MARGIN_M` of an end of travel the log reaches, its lowest or
    highest position within :data:`STOP_REACHED_M` of 0 or the machine's stroke; ``clipped``: windows with
    a sample where a channel sits at the end of its sensor's range, :func:`hexsim.measured.residuals.clipped`,
    and ``clipped_columns``: column -> {"value", "samples"}). Neither the stops nor the sensors' ranges are
    in the machine file: a window there would judge the nominal on what it does not describe."""
    pos = windows.take(log.columns["pos_m"])
    lo, hi = float(np.min(log.columns["pos_m"])), float(np.max(log.columns["pos_m"]))
    free = np.ones(len(pos), dtype=bool)
    if lo < STOP_REACHED_M:
        free &= pos.min(axis=1) > lo + STOP_MARGIN_M
    if hi > log.machine.hydraulics.stroke - STOP_REACHED_M:
        free &= pos.max(axis=1) < hi - STOP_MARGIN_M
    unclipped = np.ones(len(pos), dtype=bool)
    columns = {}
    for ch in available_channels(log):
        col = CHANNELS[ch][0]
        at = clipped(log.columns[col], ch)
        if at.any():
            columns[col] = {"value": float(log.columns[col][at][0]), "samples": int(at.sum())}
            unclipped &= ~windows.take(at).any(axis=1)
    return free & unclipped, {"end_stops": int(np.count_nonzero(~free)),
                              "clipped": int(np.count_nonzero(free & ~unclipped)), "clipped_columns": columns}


def left_out_text(left_out: dict) -> str:
    """What :func:`usable_windows` left out, one phrase ("" for nothing), e.g. "14 windows at the end stops,
    2 more with a clipped channel (pos_m reads its range's end, 0.1999756, in 3312 samples)"."""
    parts = []
    if left_out["end_stops"]:
        parts.append(f"{left_out['end_stops']} windows at the end stops")
    if left_out["clipped"]:
        parts.append(f"{left_out['clipped']} {'more ' if parts else ''}with a clipped channel")
    text = ", ".join(parts)
    if left_out["clipped_columns"]:
        text += " (" + "; ".join(f"{col} reads its range's end, {c['value']:.7g}, in {c['samples']} samples"
                                 for col, c in left_out["clipped_columns"].items()) + ")"
    return text


@dataclass(frozen=True)
class Budget:
    """Per channel [SI]: sensor noise sigma_c, the model's tolerance tau_c, budget b_c = sqrt(sigma^2 + tau^2).
    tau_c holds the replay's numerical error and, on a calibrated machine, what the calibration left
    uncertain (``calibration``, already inside tau_c, :func:`calibration_uncertainty`), in quadrature."""

    noise: dict[str, float]
    tolerance: dict[str, float]
    calibration: dict[str, float] = field(default_factory=dict)

    @property
    def total(self) -> dict[str, float]:
        return {ch: math.hypot(self.noise[ch], self.tolerance[ch]) for ch in self.noise}

    def as_dict(self, units: dict[str, str]) -> dict:
        return {ch: {"noise": self.noise[ch], "tolerance": self.tolerance[ch], "budget": self.total[ch],
                     "calibration": self.calibration.get(ch, 0.0), "unit": units[ch]} for ch in self.noise}


def measure_budget(problem: ReplayProblem, nominal_sim: dict[str, np.ndarray]) -> Budget:
    """The noise budget of :data:`problem` (see the module doc, step 1); ``nominal_sim`` is the nominal
    model's replay at :data:`REPLAY_DT`."""
    s = problem.settle
    noise = {ch: min(problem.log_noise[ch], noise_of((nominal_sim[ch] - problem.measured[ch])[:, s:], ch))
             for ch in problem.channels}
    numerical = numerical_tolerance(problem, problem.nominal, nominal_sim)
    cal = calibration_uncertainty(problem, nominal_sim)
    return Budget(noise, {ch: math.hypot(numerical[ch], cal.get(ch, 0.0)) for ch in problem.channels}, cal)


def calibration_uncertainty(problem: ReplayProblem, nominal_sim: dict[str, np.ndarray]) -> dict[str, float]:
    """Per channel [SI], what the calibration of the log's machine leaves uncertain in the replay: with the
    fitted parameters' standard errors s_i and correlations C_ij (the machine file's ``calibration`` block,
    :func:`hexsim.measured.calibration.calibrate`), the replay's change d_i when parameter i moves by s_i,
    and the RMS over the scored samples of sqrt(sum_ij d_i C_ij d_j) (first-order propagation of the
    covariance). The changes are taken after the sensors' calibration (:func:`calibrate_sensors`): what an offset or a
    scale takes up of a parameter's change (the position scale of a flow gain) is no uncertainty of the
    replay. Added in quadrature: the calibrated model's own held-out misfit on its calibration logs
    (:func:`model_floor`). Empty for a machine that was not calibrated (nothing fitted, or no standard
    errors, and no transients)."""

    record = CalibrationRecord.of(problem.log.machine.calibration, f"{problem.log.machine.label}: calibration")
    if record is None:
        return {}
    floor = model_floor(record, problem.channels)
    moved = record.identified()
    if not moved:
        return floor
    keys = list(record.correlated)
    corr = record.correlation[np.ix_(*[[keys.index(k) for k in moved]] * 2)]
    machine, s = problem.log.machine, problem.settle
    base = calibrate_sensors(problem, nominal_sim, problem.fit_rows)[0]
    deltas = []
    doc = machine.document()
    for key in moved:
        est = record.estimates[key]
        shifted = with_keys(machine, {key: value_in(doc, key, est.value) + est.std_error})
        sim = problem.simulate(nominal_plant(dataclasses.replace(problem.log, machine=shifted)))
        after = calibrate_sensors(problem, sim, problem.fit_rows)[0]
        deltas.append({ch: (after[ch] - base[ch])[:, s:] for ch in problem.channels})
    out = {}
    for ch in problem.channels:
        d = np.stack([dl[ch].ravel() for dl in deltas])  # (parameters, samples)
        var = np.einsum("is,ij,js->s", d, corr, d)
        out[ch] = float(math.hypot(np.sqrt(max(float(np.mean(var)), 0.0)), floor.get(ch, 0.0)))
    return out


def model_floor(record: CalibrationRecord, channels) -> dict[str, float]:
    """Per channel [SI], what the calibrated model could not reproduce of its own calibration logs' held-out
    windows beyond their budget: b sqrt(max(r^2 - 1, 0)) with r the held-out RMS in budgets b after the
    calibration (the record's own fits, :attr:`hexsim.measured.records.CalibrationRecord.own_fits`), the root
    mean square over those logs. A model cannot be held to a closer fit on a new log than on the held-out part of the logs it
    was calibrated on (model-form uncertainty, e.g. Kennedy & O'Hagan 2001; ASME V&V 20): a part of the
    calibration's uncertainty. A steady calibration's logs count with every window (``replayed``: none was
    fitted). Empty for a machine that was not calibrated."""
    out = {}
    for ch in channels:
        excess = [r.budget[ch] ** 2 * max(r.held_out_rms_in_budgets[ch] ** 2 - 1.0, 0.0) for r in record.own_fits
                  if ch in r.held_out_rms_in_budgets and ch in r.budget]
        if excess:
            out[ch] = float(math.sqrt(np.mean(excess)))
    return out


def numerical_tolerance(problem: ReplayProblem, model: PlantModel, fine: dict[str, np.ndarray]) -> dict[str, float]:
    """Per channel [SI], the replay's numerical error for ``model`` (its replay ``fine`` at
    :data:`REPLAY_DT`): the step's, RMS of the replay at 2h minus that at h (Richardson: the error itself
    for a first-order scheme, three times it for a second-order one), and the replay's own
    (``problem.replay_error``), added in quadrature."""
    coarse = problem.simulate(model, dt=RICHARDSON * REPLAY_DT)
    own = problem.replay_error(model)
    s = problem.settle
    return {ch: math.hypot(float(np.sqrt(np.mean((fine[ch] - coarse[ch])[:, s:] ** 2))), own[ch])
            for ch in problem.channels}


def with_model_tolerance(problem: ReplayProblem, model: PlantModel, budget: Budget) -> Budget:
    """``budget`` with each channel's numerical tolerance the larger of its own and ``model``'s
    (:func:`numerical_tolerance`): a model with effects (a heavier platform, a sagging supply) has its
    own discretisation error, which the nominal's does not measure."""
    own = numerical_tolerance(problem, model, problem.simulate(model))
    return Budget(budget.noise, {ch: max(budget.tolerance[ch], math.hypot(own[ch], budget.calibration.get(ch, 0.0)))
                                 for ch in problem.channels}, budget.calibration)


def _lstsq1(x: np.ndarray, y: np.ndarray) -> float:
    den = float(x @ x)
    return float(x @ y) / den if den > 0 else 0.0


def _bounded(beta: float, limit: float) -> float:
    return float(np.clip(beta, -limit, limit))


def calibrate_sensors(problem: ReplayProblem, sim: dict[str, np.ndarray],
                      rows: np.ndarray) -> tuple[dict[str, np.ndarray], dict]:
    """Residuals with the sensor calibration fitted on ``rows`` (least squares, scored samples):
    measured ≈ offset + scale · simulated, the scale for :data:`SCALED` channels only. For windowed
    replays the position starts each window at the measured value, so only its scale is fitted, on the
    increments from the window start. Scales and offsets are limited to the log's machine's sensor
    tolerances (:class:`hexsim.plant.params.SensorSpec`; what a fit asks beyond an offset's limit is left in
    the residual for the effects and listed per signal under ``"beyond"``), scales fitted only to
    signals that move, against the noise (:data:`SCALE_MIN_SNR`) and against the channel's other signals
    (:data:`SCALE_MIN_SHARE`). A closed-loop replay's position (hexapod) gets its scale on the motion about
    its mean and an offset within ``problem.position_offset_limit`` of the legs' common one
    (:func:`_closed_loop_position`): the rest of a leg's offset is a static tracking error, left in the
    residual for the effects (a valve null offset, a leak) and reported under ``"static_error"``. Returns
    (calibrated residual = offset + scale sim - measured per channel, calibration: channel -> {"offset":
    [...], "scale": [...]} per signal)."""
    out, cal = {}, {}
    s0 = problem.settle
    spec = problem.log.machine.sensors
    for ch in problem.channels:
        sim_c, meas = as_signals(sim[ch]), as_signals(problem.measured[ch])
        res = sim_c - meas
        offsets, scales, beyond = [], [], []
        motion = [float(np.std(sim_c[rows, s0:, j])) for j in range(sim_c.shape[2])]
        if ch == "position" and not problem.windowed:  # closed loop: each leg's offset near the legs' common one
            cal[ch] = _closed_loop_position(problem, sim_c, res, rows, motion)
            out[ch] = res[..., 0] if sim[ch].ndim == 2 else res
            continue
        scale_limit, offset_limit = spec.scale_limit(ch), spec.offset_limit(ch)
        for j in range(sim_c.shape[2]):
            x = sim_c[:, :, j]
            r = res[rows, s0:, j].ravel()
            if ch == "position" and problem.windowed:  # increments from the window start: scale only
                inc = x - x[:, :1]
                beta = _bounded(_lstsq1(inc[rows, s0:].ravel(), -r), scale_limit)
                res[:, :, j] += beta * inc
                offsets.append(0.0)
                scales.append(1.0 + beta)
                beyond.append(None)
                continue
            scaled = (ch in SCALED and motion[j] >= SCALE_MIN_SNR * problem.log_noise[ch]
                      and motion[j] >= SCALE_MIN_SHARE * max(motion))
            # an accelerometer offset of about ±g is the log's convention (acceleration for specific force, or
            # the reverse), which the validation says; the data sheet's bias is taken about it
            centres = (0.0, STANDARD_GRAVITY, -STANDARD_GRAVITY) if ch == "acceleration" else (0.0,)
            offset, beta, asked = _offset_and_scale(x[rows, s0:].ravel(), r, scaled, scale_limit, offset_limit,
                                                    centres)
            res[:, :, j] += offset + beta * x
            offsets.append(float(offset))
            scales.append(1.0 + float(beta))
            beyond.append(asked)
        out[ch] = res[..., 0] if sim[ch].ndim == 2 else res
        cal[ch] = {"offset": offsets, "scale": scales}
        if any(b is not None for b in beyond):
            cal[ch]["beyond"] = beyond
    return out, cal


def _offset_and_scale(x: np.ndarray, r: np.ndarray, scaled: bool, scale_limit: float | None,
                      offset_limit: float | None, centres: tuple[float, ...] = (0.0,)
                      ) -> tuple[float, float, float | None]:
    """Least squares of offset + beta x = -r (beta only where ``scaled``), each within its limit (None: free),
    the offset about the nearest of ``centres``: (offset, beta, the offset asked beyond its limit or None).
    A clamped scale refits the offset and a clamped offset the scale."""
    if scaled:
        offset, beta = np.linalg.lstsq(np.stack([np.ones(r.size), x], axis=1), -r, rcond=None)[0]
    else:
        offset, beta = -float(np.mean(r)), 0.0
    if scaled and abs(beta) > scale_limit:  # clamp the scale, refit the offset
        beta = _bounded(beta, scale_limit)
        offset = -float(np.mean(r + beta * x))
    centre = min(centres, key=lambda c: abs(offset - c))
    if offset_limit is None or abs(offset - centre) <= offset_limit:
        return float(offset), float(beta), None
    asked = float(offset)
    offset = centre + _bounded(offset - centre, offset_limit)
    if scaled:  # the scale on what the offset leaves
        beta = _bounded(_lstsq1(x, -r - offset), scale_limit)
    return float(offset), float(beta), asked


def position_offsets(problem: ReplayProblem, sim_position: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Each signal's mean of measured minus replayed position over ``rows`` (their scored samples) [m],
    shape (signals,): a closed-loop replay's legs' offsets (a scale fitted on the motion about its mean does
    not change them)."""
    d = as_signals(problem.measured["position"] - sim_position)[rows, problem.settle:]
    return d.mean(axis=(0, 1))


def _closed_loop_position(problem: ReplayProblem, sim_c: np.ndarray, res: np.ndarray, rows: np.ndarray,
                          motion: list[float]) -> dict:
    """:func:`calibrate_sensors`' closed-loop position, ``res`` (rows, samples, legs; replayed - measured [m])
    calibrated in place: each leg's least-squares scale on the replayed motion ``sim_c`` about its mean (where
    it moves: :data:`SCALE_MIN_SNR`, :data:`SCALE_MIN_SHARE`) and an offset within
    ``problem.position_offset_limit`` of the legs' common offset (the median of :func:`position_offsets`),
    the rest of a leg's offset left in the residual as a static tracking error (module doc of
    :mod:`hexsim.measured.hexapod_replay`). Returns the channel's calibration: "offset" (intercepts) and
    "scale" per leg, "common_offset" [m], and "static_error" (leg label -> its whole offset [m]) if any."""
    s0 = problem.settle
    free = position_offsets(problem, sim_c, rows)
    common = float(np.median(free))
    limit = problem.position_offset_limit
    out = {"offset": [], "scale": [], "common_offset": common}
    for j, offset in enumerate(np.clip(free, common - limit, common + limit)):
        mean = float(np.mean(sim_c[rows, s0:, j]))
        moves = (motion[j] >= SCALE_MIN_SNR * problem.log_noise["position"]
                 and motion[j] >= SCALE_MIN_SHARE * max(motion))
        beta = _bounded(_lstsq1(sim_c[rows, s0:, j].ravel() - mean, -res[rows, s0:, j].ravel()),
                        problem.log.machine.sensors.position_scale) \
            if moves else 0.0
        res[:, :, j] += offset + beta * (sim_c[:, :, j] - mean)
        out["offset"].append(float(offset - beta * mean))
        out["scale"].append(float(1.0 + beta))
        if offset != free[j]:
            out.setdefault("static_error", {})[f"leg{j + 1}"] = float(free[j])
    return out


@dataclass
class Scored:
    """A model's calibrated residuals as the decision sees them."""

    residuals: dict[str, np.ndarray]  # calibrated, physical units, like problem.measured
    calibration: dict
    window_cost: np.ndarray  # (windows,) sum of (residual / b_c)^2 over the scored samples
    held_out_rms: dict[str, float]  # channel -> RMS on the held-out windows [SI]
    held_out_rms_signals: dict[str, list[float]]  # channel -> RMS per signal (hexapod: per leg / axis) [SI]


def score(problem: ReplayProblem, sim: dict[str, np.ndarray], budget: Budget) -> Scored:
    res, cal = calibrate_sensors(problem, sim, problem.fit_rows)
    b = budget.total
    s0 = problem.settle
    cost = np.zeros(len(next(iter(res.values()))))  # per window (segment), fitted, held out or left out
    held, signals = {}, {}
    for ch in problem.channels:
        r = res[ch][:, s0:]
        cost += np.sum((r / b[ch]) ** 2, axis=tuple(range(1, r.ndim)))
        held[ch] = float(np.sqrt(np.mean(r[problem.test_rows] ** 2)))
        signals[ch] = [float(v) for v in np.sqrt(np.mean(as_signals(r[problem.test_rows]) ** 2, axis=(0, 1)))]
    return Scored(res, cal, cost, held, signals)


def residual_vector(problem: ReplayProblem, sim: dict[str, np.ndarray], budget: Budget, rows: np.ndarray) -> np.ndarray:
    """Calibrated residuals of ``rows`` (scored samples) divided by the budget, as one vector."""
    return budget_vector(problem, calibrate_sensors(problem, sim, rows)[0], budget, rows)


def budget_vector(problem: ReplayProblem, res: dict[str, np.ndarray], budget: Budget, rows: np.ndarray) -> np.ndarray:
    """Residuals ``res`` (channel -> rows, samples[, signals]) of ``rows`` (scored samples) over the budget,
    as one vector."""
    b = budget.total
    return np.concatenate([(res[ch][rows, problem.settle:] / b[ch]).ravel() for ch in problem.channels])


def budget_clusters(problem: ReplayProblem, rows: np.ndarray) -> np.ndarray:
    """The window (0 … len(rows) − 1) of each entry of :func:`budget_vector` over ``rows``, shaped like it: a
    window is replayed from its own measured start, so its residuals are one independent group
    (:mod:`hexsim.measured.statistics`)."""
    return np.concatenate([np.repeat(np.arange(len(rows)), window_samples(problem, ch)) for ch in problem.channels])


def window_samples(problem: ReplayProblem, channel: str) -> int:
    """Scored samples of one window of ``channel``, all its signals together."""
    return problem.measured[channel][0, problem.settle:].size


def tolerance_cost(problem: ReplayProblem, budget: Budget) -> float:
    """Cost per window that the numerical tolerance alone accounts for: sum over channels of
    (scored samples x signals) tau_c^2 / b_c^2."""
    b = budget.total
    return sum(window_samples(problem, ch) * (budget.tolerance[ch] / b[ch]) ** 2 for ch in problem.channels)


def within_budget(scored: Scored, budget: Budget) -> dict[str, float]:
    """Held-out mean square per channel in budgets squared (<= :data:`WITHIN`: explained)."""
    b = budget.total
    return {ch: (rms / b[ch]) ** 2 for ch, rms in scored.held_out_rms.items()}
