"""A valve's null that moved during a run, read from the run's own flows (commissioning, ``hexsim tune
--from-logs``; docs/compensation.md, "Proven on the machine").

A proportional valve's zero point drifts with the oil's temperature and the spool's wear (seed §5.5's warm-up; a
data sheet gives about 1 % of the rated signal over tens of kelvin). A compensated run on a warming machine then
crosses the valve's curve at commands that move with it: a corner at 0.9 V is met at 0.9 V + d(t), d the null's
drift, and a curve read from the run as if the null stood still smears the corner over the drift and moves it by
its mean. On an independent actuator whose null drifts 1 mV/s (60 mV over a minute's run; the proof's ``drift``
machine) the file commissioned from the run as it came left the reversals 18 % above the tuned one's (0.0748 against
0.0631 m/s^2); read with the drift taken out (found at 0.988 mV/s from +0.8 mV), 29 % below (0.0448; with the true
drift taken out, 0.0462).

Each run's drift is read from its flow balance (:func:`hexsim.measured.flow_balance.flow_samples`, seed eq. 3.6,
3.7 integrated) against the curves read from the runs (:func:`hexsim.measured.flow_curve.fit_flow_curves`): a
null moved by d passes, at command u, the flow the curve has at u - d, so the balance's residual is, to first
order, -d(t) times the curve's slope at the commands. d(t) = d_0 + r t (an offset from the calibration's null at
the log's start, a rate), one line per log: the rate by robust linear least squares on that residual (soft L1,
``scipy.optimize.least_squares``) with its standard error, the offset as the one at which the curves read again
fit the flows best (:func:`drifts_taken_out`). A log's drift is taken out where its rate moves the null by more
than :data:`MIN_DRIFT_V` within the log and the rate is more than :data:`SIGNIFICANCE` standard errors; otherwise
the log is read as it is (on the proof's machines whose null stands still, R1, ``corner`` and ``underlap``, the rates
read were 0.3–1.1 µV/s, within their standard errors).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.stats import median_abs_deviation

from hexsim.engine.config import RunConfig
from hexsim.errors import InputError
from hexsim.measured.fitting import bounded_fit
from hexsim.measured.flow_balance import flow_samples
from hexsim.measured.flow_curve import (
    FlowCurves,
    edge_rows,
    fit_flow_curves,
    intervals,
    unit_gains,
)
from hexsim.measured.measurement import MeasurementLog
from hexsim.plant.machine import Machine
from hexsim.plant.temperature import WarmUp

#: [V] The smallest move of the null within a log that is taken out: 2 mV, a tenth of
#: the curve's 20 mV knots near 1 V (a corner is placed to within a knot) and twice the null shift the adaptive
#: compensator's own work at a reversal shows (docs/compensation.md: ±1.7 mV on a model with no error).
MIN_DRIFT_V = 0.002
#: The drift's rate must also exceed this many standard errors.
SIGNIFICANCE = 3.0
#: [V] The offsets tried reach this far beyond the drift's move within the log either way.
OFFSET_MARGIN_V = 0.02
#: [V] The offset's tolerance in its search.
OFFSET_TOLERANCE_V = 0.0005
#: [V] Half the step of the central difference that gives the curves' slope at a command.
SLOPE_STEP_V = 0.0025


@dataclass(frozen=True)
class NullDrift:
    """One log's null, d(t) = ``offset`` + ``rate`` t [V, V/s] (t from the log's first sample), relative to the
    machine's; their standard errors ``offset_se``, ``rate_se`` (the offset's NaN where it was searched for, not
    regressed); ``duration`` [s] of the log; ``taken``: whether
    the commissioning took it out of the log's commands (:data:`MIN_DRIFT_V`, :data:`SIGNIFICANCE`)."""

    log: str
    offset: float
    rate: float
    offset_se: float
    rate_se: float
    duration: float
    taken: bool

    def at(self, t: np.ndarray) -> np.ndarray:
        """d(t) [V] at the log's times ``t`` [s] (from its first sample)."""
        return self.offset + self.rate * np.asarray(t, dtype=float)

    def record(self) -> dict:
        """The drift as the commissioning report gives it."""
        def finite(x: float) -> float | None:
            return x if math.isfinite(x) else None

        return {"log": self.log, "offset_V": self.offset, "rate_V_per_s": self.rate,
                "offset_se_V": finite(self.offset_se), "rate_se_V_per_s": finite(self.rate_se),
                "duration_s": self.duration, "taken_out": self.taken}


def read_drift(log: MeasurementLog, machine: Machine, curves: FlowCurves) -> NullDrift:
    """The null's drift in ``log`` (:class:`NullDrift`, not yet judged: ``taken`` False) against ``curves`` read on
    ``machine``: the flow balance's residual per interval (:func:`hexsim.measured.flow_curve.edge_rows` with the
    curves' rises, bulk modulus and dead volume as its unknowns: displaced less what the curves pass at the commands
    less the compressed volume), regressed on minus the curves' slope at the commands (a central difference over
    :data:`SLOPE_STEP_V`) times (1, t) by soft-L1 least squares; standard errors from the Jacobian, scaled by the
    residuals' robust spread."""
    x = np.concatenate([np.diff(curves.pa.openings), np.diff(curves.at.openings),
                        [1.0 / curves.bulk_modulus, curves.pipeline_volume / curves.bulk_modulus]])
    samples = flow_samples(log, unit_gains(machine), machine.sensors.sample_skew)

    def rows(shift: float) -> tuple[np.ndarray, np.ndarray]:
        moved = [dataclasses.replace(s, u=s.u + shift) for s in samples]
        a, displaced, _, _ = edge_rows(moved, curves.pa.knots, curves.at.knots)
        return a @ x, displaced

    entered, displaced = rows(0.0)
    slope = (rows(SLOPE_STEP_V)[0] - rows(-SLOPE_STEP_V)[0]) / (2 * SLOPE_STEP_V)
    t0 = float(log.time[0])

    def mean_time(s) -> np.ndarray:  # each interval's mean time since the log's start [s]
        starts = intervals(s)[0]
        return np.add.reduceat(s.time - t0, starts) / np.diff(np.r_[starts, len(s.u)])

    t = np.concatenate([mean_time(s) for s in samples])
    a, b = -slope[:, None] * np.column_stack([np.ones_like(t), t]), displaced - entered
    scale = max(float(median_abs_deviation(b, scale="normal")), 1e-15)
    fit = bounded_fit(lambda z: (a @ z - b) / scale, [np.zeros(2)], -np.inf, np.inf, loss="soft_l1",
                      x_scale=np.array([1e-3, 1e-4]))
    jac = a / scale
    dof = max(len(b) - 2, 1)
    cov = np.linalg.pinv(jac.T @ jac) * float(np.sum(fit.fun**2)) / dof
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    return NullDrift(str(log.path), float(fit.x[0]), float(fit.x[1]), float(se[0]), float(se[1]),
                     float(log.time[-1] - t0), False)


def judged(drift: NullDrift) -> NullDrift:
    """``drift`` with ``taken`` set: its rate moves the null by more than :data:`MIN_DRIFT_V` within the log, and the
    rate is more than :data:`SIGNIFICANCE` standard errors."""
    moved = abs(drift.rate) * drift.duration
    return dataclasses.replace(drift, taken=bool(moved > MIN_DRIFT_V and abs(drift.rate) > SIGNIFICANCE * drift.rate_se))


def without_drift(log: MeasurementLog, drift: NullDrift) -> MeasurementLog:
    """``log`` with the valve command less ``drift``'s null, d(t) (the command the valve's curve saw at the
    machine's null)."""
    cols = dict(log.columns)
    cols["valve_cmd_V"] = cols["valve_cmd_V"] - drift.at(log.time - log.time[0])
    return dataclasses.replace(log, columns=cols)


def drifts_taken_out(runs: list[MeasurementLog], others: list[MeasurementLog], machine: Machine
                     ) -> tuple[list[MeasurementLog], list[NullDrift], FlowCurves]:
    """The ``runs`` (a commissioning's logs) with each one's null drift taken out where one is found, each run's
    drift, and the curves read from the runs so returned and ``others`` (the calibration's own logs, whose null is
    the machine's), as a commissioning reads them (held to ``machine``).

    The rate is read against those curves (:func:`read_drift`) and judged (:func:`judged`). The offset is not: the
    curves, read from the drifting runs, have moved with the drift's mean (on the ``drift`` machine the regression
    put the offset at -17 mV; rounds of reading again crept towards 0 by a few mV a round). It is the one at which
    the curves read again from all the logs fit their flows best, the fit's rms flow error being sharply least at
    the true offset (there 5.8e-9 m^3 at 0 mV, 6.4e-9 and 6.9e-9 at ±5 mV, 1.1e-8 at ±15 mV). The runs' regressed
    offsets share their bias (they are read against the same curves: -17.10 and -17.12 mV on two runs of that
    machine), so one shift of them all is searched for, by a bounded scalar minimisation
    (``scipy.optimize.minimize_scalar``), each trial a whole reading. (One run at a time, the other held at its
    regressed offset, two runs were put at -15.6 and -13.2 mV, and the file commissioned from them left 0.21 m/s^2
    at the reversals where the first left 0.045; with the first reading's penalty weight and edges kept in each
    trial, ``like``, a single run's least moved to -15…-21 mV.) About 100 s for a 60 s run."""
    curves = fit_flow_curves([*runs, *others], machine, toward_machine=True)
    drifts = [judged(read_drift(run, machine, curves)) for run in runs]
    if not any(d.taken for d in drifts):
        return list(runs), drifts, curves
    reach = max(abs(d.rate) * d.duration + abs(d.offset) for d in drifts if d.taken) + OFFSET_MARGIN_V

    def moved_by(shift: float) -> list[NullDrift]:
        return [dataclasses.replace(d, offset=d.offset + shift, offset_se=math.nan) if d.taken else d for d in drifts]

    read = {}  # shift -> (the runs so shifted, the curves read from them and the others)

    def misfit(shift: float) -> float:
        trial = [without_drift(run, d) if d.taken else run for run, d in zip(runs, moved_by(shift))]
        read[shift] = trial, fit_flow_curves([*trial, *others], machine, toward_machine=True)
        return read[shift][1].rms

    best = float(minimize_scalar(misfit, bounds=(-reach, reach), method="bounded",
                                 options={"xatol": OFFSET_TOLERANCE_V}).x)
    if best not in read:  # the minimiser returns a point it evaluated; read it should it not
        misfit(best)
    shifted, curves = read[best]
    return shifted, moved_by(best), curves


#: [K] The warm-up that carries a drift into a prediction (:func:`with_drift`): small, so that the oil's viscosity
#: and density barely move (0.5 % and 0.01 %); the drift is the null's alone.
DRIFT_WARM_K = 0.1


def last_drift(tuned: dict) -> NullDrift | None:
    """The null drift the latest commissioning of a tuned file's document read from its last log (the run just
    before, where it was taken out), or None (a file not commissioned, or no drift found). Raises InputError for a
    commissioning entry whose drift is not numbers."""
    entries = tuned.get("commissioning") or []
    found = (entries[-1].get("null_drift") or []) if entries and isinstance(entries[-1], dict) else []
    if not found or not found[-1].get("taken_out"):
        return None
    d = found[-1]
    try:
        return NullDrift(str(d["log"]), float(d["offset_V"]), float(d["rate_V_per_s"]), math.nan,
                         float(d.get("rate_se_V_per_s") or math.nan), float(d["duration_s"]), True)
    except (KeyError, TypeError, ValueError):
        raise InputError(f"the tuned file's commissioning null_drift is not a drift: {d!r}") from None


def with_drift(config: RunConfig, drift: NullDrift, duration: float) -> RunConfig:
    """``config`` with its valve null moving as ``drift`` does, from its offset at the run's start at its rate for
    ``duration`` [s] (a :class:`hexsim.plant.temperature.WarmUp` of :data:`DRIFT_WARM_K` whose null drift gives that
    rate; then held): what hexsim predicts for a run of a machine that drifts as its last commissioned run did."""
    hyd = config.hydraulics
    moved = config.with_machine(hydraulics=hyd.replace(null_offset=hyd.null_offset + drift.offset))
    return dataclasses.replace(moved, warm_up=WarmUp(DRIFT_WARM_K, duration,
                                                     null_drift=drift.rate * duration / DRIFT_WARM_K))


__all__ = ["DRIFT_WARM_K", "MIN_DRIFT_V", "SIGNIFICANCE", "NullDrift", "drifts_taken_out", "judged", "last_drift",
           "read_drift", "with_drift", "without_drift"]
