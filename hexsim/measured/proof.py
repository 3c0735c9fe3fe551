"""Proof on logs: a log of the machine running with a compensator beside the machine simulated with it on
the log's own setpoints (``hexsim tune --check``; docs/compensation.md)."""

from __future__ import annotations

import dataclasses
import pathlib
from dataclasses import dataclass

import numpy as np
from scipy import signal, stats

from compensation import MODEL_BASED
from hexsim.control.scenario import Scenario
from hexsim.engine.config import RunConfig
from hexsim.engine.runner import simulate
from hexsim.errors import InputError
from hexsim.measured.measurement import MeasurementLog, read_log
from hexsim.measured.records import PLAUSIBLE_DRAWS, CalibrationRecord
from hexsim.measured.replay import measured_velocity
from hexsim.signals import dominant_frequency, fit_fundamental
from hexsim.studies.metrics import REVERSAL_WINDOW, Smoothness, smoothness
from hexsim.studies.perception import ISO_PERCEPTION_THRESHOLD, iso2631
from hexsim.studies.tuning import leg_model_of

#: Periods at the start of a log left out of its smoothness (the fade-in and the compensator's start).
PROOF_SKIP_PERIODS = 2.0
#: Seconds at the end of a log left out: the simulation's reference is held past the log's last setpoint,
#: and a feedforward answers the stop.
PROOF_END_S = 0.1


#: The physics step of hexsim's models when a run names none [s] (``models/*.xml``, RunConfig.timestep): an
#: instantaneous accelerometer is read from records at this rate.
MODEL_STEP_S = 1e-4

#: Confidence of the interval a prediction must hold the measured ratio in to be "within its uncertainty".
CONFIDENCE = 0.95
#: Fewest reversals (or stretches between them) a side needs before a ratio is judged.
MIN_EVENTS = 3
#: Spread [V] (interquartile) of the valve commands at the peaks between reversals below which they are said to
#: sit at one command: a corner of the flow curve crossed at the same speed every half period.
CORNER_SPREAD_V = 0.15


#: Bands [Hz] a run's departure from its fundamental is split into (:func:`band_rms`): the bump's own slow part
#: and the motion's harmonics; the valve and the P loop; an oil column's resonance (a 40 kg piston on a 40 mm
#: bore: 74-104 Hz over its stroke) and what rings above.
BANDS_HZ = ((0.0, 20.0), (20.0, 50.0), (50.0, 150.0))


def band_rms(sm: Smoothness) -> dict[str, float]:
    """The rms [``sm.unit``] of ``sm``'s departure from its fundamental (``sm.noise``, the judged window) in each
    band of :data:`BANDS_HZ` below its samples' Nyquist frequency, keyed "lo–hi Hz": the whole window's
    periodogram (scipy.signal.periodogram, no taper, so the bands' squares sum to the departure's mean square:
    Parseval) summed over the band. Welch's tapered segments weigh an event by where it falls in them, and a
    periodic run's reversals fall at the same places in every segment: a pulse each second read 33 % low in 2 s
    Hann segments. A measured and a predicted run read alike (the prediction carries the log's white noise) tell
    where in frequency the model leaves out what the machine does: on ``underlap``'s first tuned run
    (docs/compensation.md) 50-150 Hz read 3.4× the nine models' mean, the oil column's 83 Hz rung at each
    reversal by what the inverse of the calibrated curve misses near null."""
    fs = 1.0 / float(np.median(np.diff(sm.t)))
    f, psd = signal.periodogram(sm.noise, fs=fs, window="boxcar")  # its mean taken out (detrend "constant")
    df = float(f[1] - f[0])
    return {f"{lo:g}–{hi:g} Hz": float(np.sqrt(np.sum(psd[(f >= lo) & (f < hi)]) * df))
            for lo, hi in BANDS_HZ if hi <= fs / 2}


@dataclass(frozen=True)
class Ratio:
    """Measured over predicted of one kind of event (``what``: "reversals", "between reversals"): the ratio of the
    events' geometric means and its ``CONFIDENCE`` interval, from ``n_measured`` and ``n_predicted`` events over
    ``models`` predictions (:func:`ratio`); ``within`` when the interval holds 1."""

    what: str
    ratio: float
    low: float
    high: float
    n_measured: int
    n_predicted: int
    models: int = 1

    @property
    def within(self) -> bool:
        return self.low <= 1.0 <= self.high

    def text(self) -> str:
        over = f", over {self.models} plausible models" if self.models > 1 else ""
        return f"{self.ratio:.2f}× the prediction ({CONFIDENCE:.0%} interval {self.low:.2f}–{self.high:.2f}{over})"


def ratio(what: str, measured: np.ndarray, predicted: np.ndarray | list[np.ndarray]) -> Ratio | None:
    """The :class:`Ratio` of ``measured`` (n,) to ``predicted`` peaks [m/s^2] (positive): one run's (m,), or a list
    of runs', one per plausible model (:meth:`~hexsim.measured.records.CalibrationRecord.plausible`); None with
    fewer than ``MIN_EVENTS`` on a side. One run: Welch's t on the peaks' logarithms (scipy.stats.ttest_ind,
    the uncertainty the event-to-event scatter of both runs gives). Several: the prediction is the mean over the
    models of their mean log peak, and its uncertainty adds to the scatter's the spread between the models (the
    machine is one of them, not their mean: a prediction interval, variance s_b^2 (1 + 1/K) over K models);
    t quantile on the measured events' n - 1 degrees of freedom."""
    a = np.asarray(measured, float)
    a = a[a > 0]
    runs = [np.asarray(r, float) for r in (predicted if isinstance(predicted, list) else [predicted])]
    runs = [r[r > 0] for r in runs]
    runs = [r for r in runs if r.size]
    n_pred = sum(r.size for r in runs)
    if a.size < MIN_EVENTS or n_pred < MIN_EVENTS:
        return None
    la = np.log(a)
    if len(runs) == 1:
        lb = np.log(runs[0])
        ci = stats.ttest_ind(la, lb, equal_var=False).confidence_interval(CONFIDENCE)
        return Ratio(what, float(np.exp(la.mean() - lb.mean())), float(np.exp(ci.low)), float(np.exp(ci.high)),
                     int(a.size), int(lb.size))
    logs = [np.log(r) for r in runs]
    means = np.array([lr.mean() for lr in logs])
    within = float(np.mean(np.concatenate([lr - lr.mean() for lr in logs]) ** 2))  # pooled scatter about each
    k = len(logs)
    se = np.sqrt(la.var(ddof=1) / la.size + within / n_pred + means.var(ddof=1) * (1.0 + 1.0 / k))
    d = la.mean() - means.mean()
    half = stats.t.ppf(0.5 + CONFIDENCE / 2, la.size - 1) * se
    return Ratio(what, float(np.exp(d)), float(np.exp(d - half)), float(np.exp(d + half)), int(a.size), n_pred, k)


def between_peaks(sm: Smoothness) -> tuple[np.ndarray, np.ndarray]:
    """(peaks (k,) [unit], their times (k,) [s]): the largest departure from the fundamental in each stretch between
    consecutive reversals, more than ``REVERSAL_WINDOW`` from both (where a valve curve's corner is crossed at
    speed, or whatever else the motion meets between its turns)."""
    peaks, times = [], []
    for r0, r1 in zip(sm.reversal_times[:-1], sm.reversal_times[1:]):
        k = np.flatnonzero((sm.t > r0 + REVERSAL_WINDOW) & (sm.t < r1 - REVERSAL_WINDOW))
        if k.size:
            j = k[np.argmax(np.abs(sm.noise[k]))]
            peaks.append(abs(sm.noise[j]))
            times.append(sm.t[j])
    return np.array(peaks), np.array(times)


@dataclass(frozen=True)
class ProofVerdict:
    """Whether a log's run is what hexsim predicted (:func:`verdict`): the ``reversals``' and the ``between``
    stretches' :class:`Ratio` (None: too few), and the valve commands [V] at the measured peaks between reversals
    when they sit at one (``corner_V``: median, or None), and the commands at the spool [V] the machine's
    calibration logs measured the curve over (``measured_V``, :func:`hexsim.measured.envelope.measured_commands`;
    None: not known)."""

    reversals: Ratio | None
    between: Ratio | None
    corner_V: float | None
    measured_V: tuple[float, float] | None = None  # the commands the machine's calibration measured (envelope.py)

    @property
    def within(self) -> bool | None:
        judged = [r for r in (self.reversals, self.between) if r is not None]
        return all(r.within for r in judged) if judged else None

    def _corner_words(self) -> str:
        """What the one command of the peaks between reversals is: a corner the model lacks, and whether the
        calibration's logs measured the curve there."""
        if self.measured_V is None:
            return "a corner of the flow curve the model lacks?"
        lo, hi = self.measured_V
        if lo <= self.corner_V <= hi or lo <= -self.corner_V <= hi:
            return f"a corner of the flow curve the model lacks? the calibration's logs measured {lo:.3g}…{hi:.3g} V"
        return (f"beyond the {lo:.3g}…{hi:.3g} V the calibration's logs measured: the model's curve there is the "
                "calibration's extrapolation until commissioning reads it, tune --from-logs")

    def sentence(self) -> str:
        """One line: within its uncertainty, or by how much not and where, then the parts that are within (a
        reversal ratio of 2.3 held by a wide interval is news beside the 1.2 between reversals that was not)."""
        if self.within is None:
            return f"too few reversals to judge (at least {MIN_EVENTS} a side)"
        if self.within:
            parts = [f"{r.what} {r.text()}" for r in (self.reversals, self.between) if r is not None]
            return "within its uncertainty: " + "; ".join(parts)
        off = [r for r in (self.reversals, self.between) if r is not None and not r.within]
        parts = []
        for r in off:
            where = r.what
            if r.what == "between reversals":
                where += (f", at a valve command of {self.corner_V:.2f} V each time ({self._corner_words()})"
                          if self.corner_V is not None else ", at no one valve command")
            parts.append(f"{where}: measured {r.text()}")
        held = [f"{r.what} within: {r.text()}" for r in (self.reversals, self.between) if r is not None and r.within]
        return "not within its uncertainty: " + "; ".join(parts + held)


def verdict(measured: Smoothness, predicted: Smoothness | list[Smoothness], valve_cmd: np.ndarray | None = None,
            t: np.ndarray | None = None, measured_V: tuple[float, float] | None = None) -> ProofVerdict:
    """A log's ``measured`` smoothness against the ``predicted`` (same window; or a list, one per plausible model,
    :func:`ratio`) as a :class:`ProofVerdict`; the log's ``valve_cmd`` (N,) [V] at its times ``t`` (N,) [s], where
    it has one, places the peaks between reversals on the valve's curve, and ``measured_V`` (the commands the
    calibration measured) says whether the calibration saw it there."""
    runs = predicted if isinstance(predicted, list) else [predicted]
    bm, tm = between_peaks(measured)
    corner = None
    if valve_cmd is not None and t is not None and tm.size >= MIN_EVENTS:
        u = np.abs(np.interp(tm, t, valve_cmd))
        q1, q3 = np.percentile(u, [25, 75])
        corner = float(np.median(u)) if q3 - q1 < CORNER_SPREAD_V else None
    return ProofVerdict(ratio("reversals", measured.reversal_peaks, [r.reversal_peaks for r in runs]),
                        ratio("between reversals", bm, [between_peaks(r)[0] for r in runs]), corner, measured_V)


def accelerometer_noise(t: np.ndarray, acc: np.ndarray) -> float:
    """The white noise [m/s^2] (standard deviation a sample) of a logged acceleration ``acc`` (N,) at times t (N,)
    [s]: the flat floor of its power spectral density (Welch, scipy.signal.welch) above a tenth of the sampling
    rate, where a motion of a few hertz leaves nothing, taken as the median over that band (a ringing's or a
    valve's narrow lines do not count), sigma^2 = PSD fs / 2. A logged acceleration already averaged (hexsim's
    1 ms means, a filtered accelerometer) has a falling floor and gives less than its instantaneous noise."""
    acc = np.asarray(acc, float)
    if acc.size < 64:
        return 0.0
    fs = 1.0 / float(np.median(np.diff(t)))
    f, psd = signal.welch(acc - acc.mean(), fs=fs, nperseg=min(1024, acc.size))
    return float(np.sqrt(np.median(psd[f >= fs / 10]) * fs / 2))


def _proof_columns(log: MeasurementLog) -> tuple[np.ndarray, np.ndarray, int, np.ndarray, np.ndarray]:
    """(the legs' setpoints (n, legs) [m], their positions (n, legs) [m], the accelerometer's axis (-1: the
    single actuator's), the setpoint judged (n,) [m] and the acceleration on it (n,) [m/s^2]) of a proof's
    ``log``: a hexapod's on the translation whose setpoint moves most. Raises InputError naming what it
    lacks."""
    cols = log.columns
    if log.system == "hexapod":
        ref = np.column_stack([cols[f"leg{i}_ref_m"] for i in range(1, log.n_legs + 1)])
        pos = np.column_stack([cols[f"leg{i}_pos_m"] for i in range(1, log.n_legs + 1)])
        dofs = [k for k in ("x", "y", "z") if f"dof_ref_{k}_m" in cols and f"platform_acc_{k}_mps2" in cols]
        if not dofs:
            raise InputError(f"{log.path}: a proof needs a translation's setpoint and the platform accelerometer on it "
                             "(dof_ref_{x,y,z}_m and platform_acc_{x,y,z}_mps2)")
        k = max(dofs, key=lambda d: np.ptp(cols[f"dof_ref_{d}_m"]))
        return ref, pos, "xyz".index(k), cols[f"dof_ref_{k}_m"], cols[f"platform_acc_{k}_mps2"]
    for name, what in (("acc_mps2", "the accelerometer"), ("ref_m", "the setpoint")):
        if name not in cols:
            raise InputError(f"{log.path}: a proof needs {what} ({name})")
    return cols["ref_m"][:, None], cols["pos_m"][:, None], -1, cols["ref_m"], cols["acc_mps2"]


def proof(path: pathlib.Path, base: RunConfig, draws: int = PLAUSIBLE_DRAWS) -> dict:
    """A log of the machine running with a compensator beside the machine simulated with it on the log's own
    setpoints: the smoothness (mean and max reversal peak, noise ratio, the departure's rms by band: ``band_rms``,
    :func:`band_rms`) of both, from the third period on.

    ``base``: the machine and the compensator (a tuned file's, ``run --compensator FILE``). The log
    (docs/measurement-log.md): a single actuator's ``ref_m`` and ``acc_mps2``, or a hexapod's
    ``leg{i}_ref_m`` and the platform accelerometer on the axis whose setpoint moves most (a translation:
    ``dof_ref_{x,y,z}_m`` needed). The simulation starts at the log's first positions and follows its
    setpoints held sample by sample; the prediction is read as the log's accelerometer would read it, on the log's
    samples with the white noise the log shows (:func:`accelerometer_noise`). On a calibrated machine it is made
    again on ``draws`` machines drawn from what the calibration leaves uncertain
    (:meth:`~hexsim.measured.records.CalibrationRecord.plausible`), the compensator's leg model the nominal's:
    ``predicted`` is then the mean over the nominal and the draws in each of its figures (``predicted_models``:
    each one's mean reversal peak). The ``verdict`` (:func:`verdict`): the measured reversal peaks, and the peaks
    between reversals, against the predicted, within the uncertainty their scatter and the models' spread give or
    by how much not and where. Raises InputError naming the log and what it lacks."""
    log = read_log(path, base.machine, needs=("pos_m",))
    t = log.time - log.time[0]
    ref, pos, axis, setpoint, acc = _proof_columns(log)
    try:
        frequency = dominant_frequency(t, setpoint)
    except ValueError:
        raise InputError(f"{path}: the setpoint does not move; a proof needs a periodic motion") from None
    t0 = PROOF_SKIP_PERIODS / frequency
    if t[-1] < t0 + 1.0 / frequency:
        raise InputError(f"{path}: {t[-1]:.1f} s hold less than three periods of its {frequency:.3g} Hz motion")
    scenario = Scenario(f"log:{path.name}", log.system if log.system == "hexapod" else "actuator", float(t[-1]),
                        axis, frequency, 0.0, legs=(t, ref), start=pos[0].copy())
    sigma = accelerometer_noise(t, acc)
    keep = t <= t[-1] - PROOF_END_S  # where the log's setpoints end, the held reference stops at once

    def judged(name: str, a: np.ndarray, v: np.ndarray | None) -> Smoothness:
        return smoothness(t[keep], a[keep], frequency, t0, setpoint[keep], name=name, unit="m/s^2",
                          velocity=None if v is None else v[keep])

    measured = judged("measured", acc, measured_velocity(log, pos[:, 0]) if axis < 0 else None)
    record = CalibrationRecord.of(base.machine.calibration, f"{base.machine.label}: calibration")
    plausible = record.plausible(base.machine, draws) if record is not None and draws else []
    runs = [judged("predicted", *run) for run in _predicted(dataclasses.replace(base, scenario=scenario), plausible,
                                                             t, axis, sigma)]
    rows = {"measured": _figures([measured]), "predicted": _figures(runs)}
    models = [sm.mean_reversal_peak for sm in runs]
    valve = log.columns.get("valve_cmd_V") if axis < 0 else None
    judgement = verdict(measured, runs, valve, t, None if record is None else record.commands_measured_V)
    return {"log": str(path), "frequency_hz": frequency, "compensator": base.compensator_name,
            "accelerometer_noise_mps2": sigma, **rows, "predicted_models": models,
            "verdict": {"within": judgement.within, "sentence": judgement.sentence(),
                        **{r.what: dataclasses.asdict(r) for r in (judgement.reversals, judgement.between) if r},
                        "corner_V": judgement.corner_V}}


def _figures(runs: list[Smoothness]) -> dict:
    """A row of :func:`proof`: the mean and max reversal peak, the noise ratio and :func:`band_rms` of one run, or
    each the mean over ``runs`` (the plausible models': the nominal's max beside the models' mean once read 0.0201
    against a mean of 0.0274), and the reversals the first run counted."""
    peaks = [float(sm.reversal_peaks.max()) for sm in runs if sm.reversal_peaks.size]
    bands = [band_rms(sm) for sm in runs]
    return {"mean_reversal_peak": float(np.mean([sm.mean_reversal_peak for sm in runs])),
            "reversals": int(runs[0].reversal_peaks.size),
            "max_reversal_peak": float(np.mean(peaks)) if peaks else None,
            "noise_ratio": float(np.mean([sm.noise_ratio for sm in runs])),
            "band_rms": {band: float(np.mean([b[band] for b in bands])) for band in bands[0]}}


def _predicted(config: RunConfig, plausible: list, t: np.ndarray, axis: int, sigma: float):
    """(acceleration (N,) [m/s^2] as the log's accelerometer reads it — on the log's samples t (N,) [s], each the mean
    over the millisecond before it or, where the machine file's ``sensors.acceleration_sampling`` is "instant", its
    value at that instant (plus the file's ``acceleration_skew``), with the log's white noise ``sigma`` —, and the
    piston's velocity (N,) [m/s], or None on a hexapod, whose reversals are its setpoint's) of ``config`` and of
    the ``plausible`` machines (:meth:`CalibrationRecord.plausible`), each with the nominal's compensator (a
    model-based one keeps the nominal's leg model)."""
    machine = config.machine
    if config.compensator_model is None and config.compensator in MODEL_BASED:
        config = dataclasses.replace(config, compensator_model=leg_model_of(config))
    machines = [machine, *plausible]
    noise = np.random.default_rng(0).normal(0.0, sigma, t.size)
    spec = machine.sensors
    if spec.acceleration_sampling == "instant":  # the log's accelerometer read at an instant: every physics step's
        config = dataclasses.replace(config, record_rate_hz=1.0 / (config.timestep or MODEL_STEP_S))
    at = t + (spec.acceleration_skew if spec.acceleration_sampling == "instant" else 0.0)
    for m in machines:
        result = simulate(dataclasses.replace(config, machine=m, progress=False))
        a = result.acc[:, 2] if axis < 0 else result.acc[:, axis]
        yield np.interp(at, result.t, a) + noise, np.interp(t, result.t, result.ydot[:, 0]) if axis < 0 else None


@dataclass(frozen=True)
class PassengerView:
    """A machine's run as its passenger gets it (:func:`passenger_view`): the reversal bump on the acceleration
    (``reversal_peaks`` [m/s^2], each the largest departure from the fundamental within ±0.1 s of a reversal,
    :func:`hexsim.studies.metrics.smoothness`; their ``mean`` and ``max``), the ISO 2631-1 W_k weighted false
    cue at the seat over the whole window (``seat_peak`` [m/s^2]: every reversal and every crossing of a corner
    of the valve's curve between them) and its multiple of the perception threshold (``seat_ratio``, 0.015 m/s^2:
    ISO 2631-1:1997 Annex C), and the ``noise_ratio``."""

    reversal_peaks: np.ndarray
    seat_peak: float
    noise_ratio: float

    @property
    def mean(self) -> float:
        return float(np.mean(self.reversal_peaks)) if self.reversal_peaks.size else float("nan")

    @property
    def max(self) -> float:
        return float(np.max(self.reversal_peaks)) if self.reversal_peaks.size else float("nan")

    @property
    def seat_ratio(self) -> float:
        return self.seat_peak / ISO_PERCEPTION_THRESHOLD

    def worst_against(self, none: PassengerView) -> float:
        """The largest ratio of a reversal's peak to the same reversal's without compensation (the runs' reversals
        in order; the shorter count): above 1, a reversal the compensation made worse."""
        n = min(self.reversal_peaks.size, none.reversal_peaks.size)
        return float(np.max(self.reversal_peaks[:n] / none.reversal_peaks[:n])) if n else float("nan")


def passenger_view(t: np.ndarray, acc: np.ndarray, setpoint: np.ndarray, frequency: float, t_start: float,
                   velocity: np.ndarray | None = None) -> PassengerView:
    """The :class:`PassengerView` of an acceleration ``acc`` [m/s^2] along a vertical axis, sampled at t (N,) [s]
    (uniform), from ``t_start`` [s]: its reversal peaks where ``setpoint`` (N,) [m] turns (moved to the measured
    motion's turns when ``velocity`` (N,) [m/s] is given), the W_k weighting (ISO 2631-1 Annex A, vertical,
    :func:`hexsim.studies.perception.iso2631`) of its departure from the fundamental at ``frequency`` [Hz],
    started a period earlier so that the filter has settled. Raises ValueError for a window shorter than a
    period."""
    sm = smoothness(t, acc, frequency, t_start, setpoint, name="acceleration", unit="m/s^2", velocity=velocity)
    lead = t >= t_start - 1.0 / frequency
    cue = acc[lead] - fit_fundamental(t[lead], acc[lead], frequency)[3]
    weighted = iso2631("Wk").apply(cue, 1.0 / float(np.median(np.diff(t))))
    seat = float(np.max(np.abs(weighted[t[lead] >= t_start])))
    return PassengerView(sm.reversal_peaks, seat, sm.noise_ratio)


#: Band [Hz] the period average's reversal peaks are read in (:func:`run_figures`).
RUN_BAND_HZ = 50.0
#: Share of a setpoint's variance its fundamental holds for the log to be judged as a periodic run.
RUN_PERIODIC = 0.9


@dataclass(frozen=True)
class RunFigures:
    """A periodic run of the machine as its log measures it, with the accelerometer's noise averaged out
    (:func:`run_figures`): the motion (``frequency_hz`` [Hz], ``amplitude_m`` [m], the setpoint's fundamental),
    the ``periods`` averaged, the bump of the period average (``reversal_peak`` [m/s^2]: the mean over its two
    reversals of the largest departure from the fundamental within ``REVERSAL_WINDOW`` of each), its ISO 2631-1
    W_k ``seat_peak`` [m/s^2] (every reversal and every corner crossing of the period), and the ``noise`` [m/s^2]
    left in the average below ``RUN_BAND_HZ``, where the reversal peaks are read (the scatter about the average, a
    sample, over the square root of the periods and of the band's share of the samples' bandwidth)."""

    log: str
    frequency_hz: float
    amplitude_m: float
    periods: int
    reversal_peak: float
    seat_peak: float
    noise: float

    @property
    def seat_ratio(self) -> float:
        return self.seat_peak / ISO_PERCEPTION_THRESHOLD

    def same_motion(self, other: RunFigures) -> bool:
        """Whether ``other`` ran the same motion (frequency within 2 %, amplitude within 5 %): only then do their
        figures compare."""
        return (abs(self.frequency_hz / other.frequency_hz - 1.0) <= 0.02
                and abs(self.amplitude_m / other.amplitude_m - 1.0) <= 0.05)

    def record(self) -> dict:
        return dataclasses.asdict(self)


def run_figures(path: pathlib.Path, machine) -> RunFigures:
    """The :class:`RunFigures` of a single actuator's log at ``path`` running a periodic motion (``ref_m``,
    ``pos_m``, ``acc_mps2``), judged on ``machine``, over its second half (where an adaptive compensator has
    learned; the log's last ``PROOF_END_S`` left out), in whole periods of the setpoint's fundamental.

    A real accelerometer's noise (R1's: 0.05 m/s^2 a sample at 1 kHz) is larger than the bump a compensator
    leaves (0.02 m/s^2), so one run's reversal peaks measure the noise. The bump is the same at every period and
    the noise is not: the acceleration less its fundamental is averaged over the periods at the same phase of the
    setpoint (time-synchronous averaging, as rotating machinery's vibration is read), which leaves the noise over
    the square root of the periods (5.5 times less over a 60 s log's last 30 s at 0.5 Hz). The reversals are the
    period average position's highest and lowest points, their peaks read below ``RUN_BAND_HZ`` (zero-phase
    Butterworth, scipy.signal.sosfiltfilt), where the noise falls by the square root of the band's share again;
    the seat's W_k weighting is applied to the average as it is. Raises InputError naming the log for one without
    those columns, without a periodic setpoint (:data:`RUN_PERIODIC`), or with less than two periods in its second
    half."""
    log = read_log(path, machine, needs=("pos_m",))
    if log.system != "single-actuator":
        raise InputError(f"{path}: a run is judged on a single actuator's log (this is {log.system})")
    _, pos, _, ref, acc = _proof_columns(log)  # raises for a log without the accelerometer or the setpoint
    pos = pos[:, 0]
    t = log.time - log.time[0]
    try:
        frequency = dominant_frequency(t, ref)
    except ValueError:
        raise InputError(f"{path}: the setpoint does not move; a run is judged on a periodic motion") from None
    end = t[-1] - PROOF_END_S
    periods = int(np.floor((end - t[-1] / 2) * frequency))
    if periods < 2:
        raise InputError(f"{path}: its second half holds {periods} period(s) of its {frequency:.3g} Hz motion; "
                         "a run is judged on two or more")
    window = (t > end - periods / frequency) & (t <= end)
    tw = t[window]
    _, amplitude, phase, fit = fit_fundamental(tw, ref[window], frequency)
    if np.var(ref[window] - fit) > (1.0 - RUN_PERIODIC) * np.var(ref[window]):
        raise InputError(f"{path}: its setpoint is not a periodic motion (its {frequency:.3g} Hz fundamental holds "
                         f"less than {RUN_PERIODIC:.0%} of its variance in its second half)")
    residual = acc[window] - fit_fundamental(tw, acc[window], frequency)[3]
    bins = max(8, int(round(log.sample_rate_hz / frequency)))
    at = np.floor(((tw * frequency + phase / (2 * np.pi)) % 1.0) * bins).astype(int) % bins
    count = np.bincount(at, minlength=bins)
    if np.any(count == 0):
        raise InputError(f"{path}: its samples do not cover every phase of its {frequency:.3g} Hz motion")
    average = np.bincount(at, residual, bins) / count
    place = np.bincount(at, pos[window], bins) / count
    rate = bins * frequency
    # the reversal peaks read below RUN_BAND_HZ, where the noise is less again: zero phase, over the period
    # repeated (the average is cyclic)
    sos = signal.butter(4, min(RUN_BAND_HZ, 0.45 * rate), fs=rate, output="sos")
    smooth = signal.sosfiltfilt(sos, np.tile(average, 3))[bins:2 * bins]
    noise = float(np.std(residual - average[at]) / np.sqrt(periods) * np.sqrt(2 * min(RUN_BAND_HZ, 0.45 * rate) / rate))
    turns = (int(np.argmax(place)), int(np.argmin(place)))  # the period average position's two turns
    half = max(1, int(round(REVERSAL_WINDOW * frequency * bins)))
    idx = np.arange(-half, half + 1)
    peaks = [float(np.max(np.abs(smooth[(k + idx) % bins]))) for k in turns]
    weighted = iso2631("Wk").apply(np.tile(average, 4), rate)[3 * bins:]  # settled over three periods
    return RunFigures(str(path), float(frequency), float(amplitude), periods, float(np.mean(peaks)),
                      float(np.max(np.abs(weighted))), noise)
