"""Friction identification from a log (seed §2.3.3, eq. 2.3–2.4): ``hexsim friction LOG.csv``.

F_f = F_L - M ydd - M g cos(inclination), with F_L = P1 A1 - P_s A2 (seed eq. 2.3) from the pressures of
the 3-way valve, A1 p1 - A2 p2 from both chambers of a 4-way valve (the areas of the log's machine file),
or F_L = ``force_N`` for a drive without pressure sensors (the seed notes the method applies to electric
drives too); a log needs only the columns of one of these and the position.

Which samples: an open-loop experiment (constant valve commands) is read in its steady windows only
(:func:`steady_windows`: after the command settles, away from the end stops, at a constant speed), where
the acceleration is nil and is left out, each sample at its window's straight-line speed; runs of one
experiment that logged different pressures (the real servo cylinder's pA and pB runs) are merged row by
row where both move steadily (two runs reach a stop at different times). A log without steady motions
(closed loop) is read sample by sample away from the stops, the velocity and the acceleration from a
zero-phase (symmetric) Savitzky–Golay filter of the position, or M (ydd + g cos θ) from the logged
accelerometer (specific force, ``acc_mps2``; a log holding acceleration without g is recognised by its
mean).

The curve fitted is the one the simulator uses (:func:`hexsim.plant.hydraulics.friction_force`, seed eq. 3.9),
F_f = sigma v + s(v) [F_c0 + F_s0 exp(-|v| / c_s)] with s(v) = arctan(k v) (times 2/pi when
``arctan_normalised``), per direction, with ``scipy.optimize.least_squares``; so identification and
simulation recover each other's parameters. (Eq. 2.4 of the seed has sign(v) for s(v); with the
published eq. 3.9, arctan tends to ±pi/2 and the Coulomb level at speed is pi/2 F_c0.) Standard errors
from the Jacobian; a parameter the data cannot separate (at a bound of its range, or a standard error
larger than the value) is reported as unidentifiable with the reason, never as a number. The model is
as rich as the speeds in the data: one speed per direction gives its level alone. The loss is robust
(soft L1 beyond :data:`ROBUST_SCALE_N`); a direction with too few usable samples, a force that aids the
motion, or a scatter larger than its level answers "cannot fit" with the reason instead of a number.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple, TypedDict

import numpy as np
from scipy.stats import median_abs_deviation

from hexsim.errors import InputError
from hexsim.measured.estimates import FITTED, HELD, UNIDENTIFIABLE, Estimate, at_bound
from hexsim.measured.fitting import bounded_fit
from hexsim.measured.measurement import MeasurementLog
from hexsim.measured.parameters import Parameter
from hexsim.measured.residuals import effective_n
from hexsim.measured.statistics import fit_statistics
from hexsim.plant.model import gravity
from hexsim.plant.params import HydraulicParams
from hexsim.signals import savgol, savgol_length

#: [s] Savitzky–Golay window (cubic) with a logged accelerometer: the velocity and F_L - M (ydd + g)
#: need no second derivative, so the window only has to smooth the sensor noise while keeping the
#: Stribeck hump (|v| < ~3 c_s, ~15 ms around a reversal on the seed's sine). hexsim's own exact 20 s
#: actuator log: every parameter within 3.8 % (with the position's second derivative and 51 ms: F_s0+
#: 10 % low); 6 s logs with sensor noise: sigma and F_c0 within 0.6 %, F_s0 and c_s (which trade along
#: the hump) within 17 %.
ACC_WINDOW_S = 0.031
#: [s] the window without an accelerometer: long enough to smooth the oil-spring ringing out of ydd.
DERIVATIVE_WINDOW_S = 0.051
V_MIN = 0.0005  # [m/s]: samples slower than this are left out (sign of v uncertain below ~0.1 mm/s)
_LIMITS = "physical limits (a force opposes motion), far beyond any seal's"
#: The parameters of one direction's curve, in the order of x in :func:`stribeck`: their units, the fit's
#: bounds (physical limits, not brackets) and their typical sizes (the fit's x_scale, and what "at a bound"
#: is measured against, :func:`hexsim.measured.estimates.at_bound`).
PARAMETERS = (Parameter("sigma", 0.0, 1e5, _LIMITS, unit="N s/m", scale=1000.0),
              Parameter("F_c0", 0.0, 1e4, _LIMITS, unit="N", scale=50.0),
              Parameter("F_s0", 0.0, 1e4, _LIMITS, unit="N", scale=20.0),
              Parameter("c_s", 1e-4, 0.5, "a Stribeck speed of 0.1 mm/s to 0.5 m/s", unit="m/s", scale=0.005))
PARAMS = tuple(p.key for p in PARAMETERS)
X_SCALE = np.array([p.scale for p in PARAMETERS])
LOWER, UPPER = np.array([p.lower for p in PARAMETERS]), np.array([p.upper for p in PARAMETERS])


def stribeck(v: np.ndarray, x: np.ndarray, hyd: HydraulicParams | None = None) -> np.ndarray:
    """The simulator's friction curve for one direction (seed eq. 3.9), x = (sigma, F_c0, F_s0, c_s);
    the arctan gain k and its normalisation from ``hyd`` (default the seed's)."""
    hyd = hyd or HydraulicParams()
    shape = np.arctan(hyd.arctan_gain * v) * (2.0 / np.pi if hyd.arctan_normalised else 1.0)
    return x[0] * v + shape * (x[1] + x[2] * np.exp(-np.abs(v) / x[3]))


#: [N] Residual beyond which the fit's loss grows linearly, not quadratically (scipy's soft_l1): a
#: few times the force noise of a pressure-measured friction (0.3 bar on 2 cm^2 is 6 N).
ROBUST_SCALE_N = 10.0
#: [m] Samples this close to the ends of the observed piston range are left out: at an end stop the
#: pressures build up against the stop, not against friction.
END_MARGIN_M = 0.003
#: [s] After the valve command of an open-loop experiment changes, its samples are left out this long:
#: the piston accelerates and the chamber pressures ring (the oil spring's mode, tens of Hz) first.
SETTLE_S = 0.05
#: [-] A steady window's samples move within this share of the window's own speed (the speed from a
#: straight line through the window's positions): the rest of a constant command is still accelerating.
STEADY_SPEED_SHARE = 0.2
#: Usable samples a direction needs before a curve is fitted to it.
MIN_SAMPLES = 50
#: [-] Speeds of one direction spanning less than this ratio (95th over 5th percentile) cannot tell a
#: viscous slope from the Coulomb level: the level alone is fitted there.
MIN_SPEED_RATIO = 1.5


def merge_runs(logs: list[MeasurementLog]) -> MeasurementLog:
    """One experiment from several runs of it that logged different channels (a pA run with ``p1_Pa``, a
    pB run with ``p2_Pa``, as the real servo cylinder's): the first log with the others' columns it
    lacks, row by row, cut to the shortest. Raises InputError for runs of different sample rates or
    systems."""
    base = logs[0]
    if len(logs) == 1:
        return base
    n = min(len(log.time) for log in logs)
    cols = {k: v[:n] for k, v in base.columns.items()}
    for other in logs[1:]:
        if other.sample_rate_hz != base.sample_rate_hz or other.system != base.system:
            raise InputError(f"{other.path}: cannot pair with {base.path.name} (sample rate {other.sample_rate_hz:g} vs "
                             f"{base.sample_rate_hz:g} Hz, {other.system} vs {base.system})")
        for k, v in other.columns.items():
            cols.setdefault(k, v[:n])
    return dataclasses.replace(base, columns=cols)


def load_force(log: MeasurementLog, hyd: HydraulicParams) -> tuple[np.ndarray, str]:
    """(F_L (N,) [N], its source): ``force_N``; or A1 p1 - A2 p2 from ``p1_Pa`` and ``p2_Pa`` (a 4-way
    valve: both chambers measured) with the machine's areas; or A1 p1 - A2 P_s from ``p1_Pa`` and
    ``ps_Pa`` (the 3-way valve, rod side at supply, seed eq. 2.3). Raises InputError naming the columns
    needed when the log has none of these."""
    c = log.columns
    if "force_N" in c:
        return c["force_N"], "force_N"
    if "p1_Pa" in c and "p2_Pa" in c:
        return c["p1_Pa"] * hyd.area_bottom - c["p2_Pa"] * hyd.area_rod, "A1 p1 - A2 p2 (both chambers)"
    if "p1_Pa" in c and "ps_Pa" in c and not hyd.four_way:
        return c["p1_Pa"] * hyd.area_bottom - c["ps_Pa"] * hyd.area_rod, "P1 A1 - P_s A2 (seed eq. 2.3)"
    have = ", ".join(k for k in c if k != "time_s")
    need = ("'p1_Pa' and 'p2_Pa' (a 4-way valve; runs of one experiment that logged one each pair as A.csv+B.csv)"
            if hyd.four_way else "'p1_Pa' and 'ps_Pa' (the 3-way valve), or 'p1_Pa' and 'p2_Pa'")
    raise InputError(f"{log.path}: friction identification needs column 'force_N', or {need}; the log has {have}")


def _stops_mask(pos: np.ndarray) -> np.ndarray:
    """(N,) bool: samples further than :data:`END_MARGIN_M` from both ends of the observed range."""
    return (pos > pos.min() + END_MARGIN_M) & (pos < pos.max() - END_MARGIN_M)


def steady_windows(log: MeasurementLog) -> np.ndarray:
    """(N,) int: the steady window each sample of an open-loop experiment belongs to (-1: none). A window
    is a stretch of constant valve command (|u_v| > 0.05 V) less its first :data:`SETTLE_S`, away from the
    end stops (:data:`END_MARGIN_M`), whose speed (zero-phase Savitzky–Golay, :data:`ACC_WINDOW_S`) is
    within :data:`STEADY_SPEED_SHARE` of the window's median speed. All -1 for a log without a valve
    command or a command that never holds (a closed-loop log)."""
    window = np.full(len(log.time), -1)
    if "valve_cmd_V" not in log.columns or len(log.time) < savgol_length(log.sample_rate_hz, ACC_WINDOW_S):
        return window
    u, pos, fs = log.columns["valve_cmd_V"], log.columns["pos_m"], log.sample_rate_hz
    vel = savgol(pos, fs, ACC_WINDOW_S, deriv=1)
    away = _stops_mask(pos)
    settle = int(round(SETTLE_S * fs))
    bounds = np.concatenate([[0], np.flatnonzero(np.diff(u) != 0) + 1, [len(u)]])
    for k, (a, b) in enumerate(zip(bounds[:-1], bounds[1:])):
        if abs(u[a]) <= 0.05 or b - a - settle < MIN_SAMPLES // 5:
            continue
        idx = np.arange(a + settle, b)[away[a + settle:b]]
        if len(idx) < 5:
            continue
        typical = float(np.median(vel[idx]))
        idx = idx[np.abs(vel[idx] - typical) <= STEADY_SPEED_SHARE * abs(typical)]
        window[idx] = k
    return window


@dataclasses.dataclass(frozen=True)
class FrictionSamples:
    """The samples friction is fitted to. ``velocity`` (N,) [m/s]; ``force`` (N,) [N] the friction force
    F_f = F_L - M (ydd + g cos θ); ``window`` (N,) the steady window of each sample (-1: a sample of a
    moving log, its acceleration from the filter named in ``acceleration_source``); ``force_source``:
    where F_L came from."""

    velocity: np.ndarray
    force: np.ndarray
    window: np.ndarray
    force_source: str
    acceleration_source: str


def _window_speeds(t: np.ndarray, pos: np.ndarray, window: np.ndarray) -> np.ndarray:
    """(N,) each steady sample's speed [m/s]: the slope of a straight line through its window's
    positions (the noise of a derivative left out); NaN outside the windows."""
    speed = np.full(len(t), np.nan)
    for k in np.unique(window[window >= 0]):
        idx = window == k
        speed[idx] = np.polynomial.polynomial.polyfit(t[idx], pos[idx], 1)[1]
    return speed


def friction_samples(runs: MeasurementLog | list[MeasurementLog], hyd: HydraulicParams | None = None
                     ) -> FrictionSamples:
    """The samples of one experiment that friction can be read from (:class:`FrictionSamples`).

    ``runs``: a log, or runs of one experiment that logged different channels (merged row by row,
    :func:`merge_runs`: the real servo cylinder's pA and pB runs). An open-loop experiment with steady
    motions (:func:`steady_windows`; of every run, so two runs that reach a stop at different times
    pair only where both move steadily) gives its steady samples, the acceleration left out and each
    sample at its window's speed (a direction without steady motion then has no samples). Otherwise (a
    closed-loop log, or a command that never holds) every
    sample away from the stops, the velocity and M ydd from a zero-phase Savitzky–Golay filter (cubic,
    :data:`ACC_WINDOW_S` with a logged accelerometer, else :data:`DERIVATIVE_WINDOW_S` on the position).
    ``hyd``: the areas (default the log's machine's). Raises InputError naming the missing columns
    (:func:`load_force`), or if the log is not a single axis, or its machine is a user's hexapod file (which
    gives no leg's moving mass) and the sidecar declares no ``mass_kg``."""
    runs = [runs] if isinstance(runs, MeasurementLog) else list(runs)
    log = merge_runs(runs)
    if log.system != "single-actuator":
        raise InputError(f"{log.path}: friction identification needs a single-actuator log (this is {log.system})")
    if log.machine.system != log.system and log.machine.path is not None and "mass_kg" not in log.sidecar:
        # the built-in hexapod's leg is the seed's actuator (40 kg, app. A); a user's hexapod file has no
        # moving mass of one leg
        raise InputError(f"{log.path}: a single-actuator log, but the machine {log.machine.label} is a "
                         f"{log.machine.system}, which gives no leg's moving mass: pass the actuator's machine file "
                         f"(--machine) or declare mass_kg in the log's sidecar")
    hyd = hyd or log.machine.hydraulics
    c = log.columns
    f_l, source = load_force(log, hyd)
    fs = log.sample_rate_hz
    mass = log.moving_mass_kg
    g_axis = gravity() * np.cos(np.deg2rad(log.inclination_deg))
    pos = c["pos_m"]
    n = len(log.time)
    window = steady_windows(runs[0])[:n]
    for other in runs[1:]:
        window = np.where(steady_windows(other)[:n] == window, window, -1)
    if np.sum(window >= 0) >= MIN_SAMPLES:  # steady motions: no derivative of the position enters the force
        speeds = _window_speeds(log.time, pos, window)
        steady = window >= 0
        return FrictionSamples(speeds[steady], (f_l - mass * g_axis)[steady], window[steady], source,
                               "left out: steady windows (speed constant to "
                               f"{STEADY_SPEED_SHARE:.0%}, each at its straight-line speed)")
    inside = _stops_mask(pos)
    if "acc_mps2" in c:  # M (ydd + g cos θ) measured: no second derivative of the position
        _check_length(log, savgol_length(fs, ACC_WINDOW_S))
        specific = c["acc_mps2"]
        if abs(float(np.mean(specific))) < 0.5 * g_axis:  # the log holds acceleration, not specific force
            specific = specific + g_axis
        vel = savgol(pos, fs, ACC_WINDOW_S, deriv=1)
        force = savgol(f_l - mass * specific, fs, ACC_WINDOW_S)
        return FrictionSamples(vel[inside], force[inside], np.full(int(inside.sum()), -1), source,
                               f"accelerometer (acc_mps2), zero-phase Savitzky-Golay {ACC_WINDOW_S * 1e3:.0f} ms")
    _check_length(log, savgol_length(fs, DERIVATIVE_WINDOW_S))
    vel = savgol(pos, fs, DERIVATIVE_WINDOW_S, deriv=1)
    acc = savgol(pos, fs, DERIVATIVE_WINDOW_S, deriv=2)
    force = savgol(f_l, fs, DERIVATIVE_WINDOW_S) - mass * acc - mass * g_axis
    return FrictionSamples(vel[inside], force[inside], np.full(int(inside.sum()), -1), source,
                           f"second derivative of the position, zero-phase Savitzky-Golay "
                           f"{DERIVATIVE_WINDOW_S * 1e3:.0f} ms")


def _check_length(log: MeasurementLog, n: int) -> None:
    if len(log.time) < n:
        raise InputError(f"{log.path}: {len(log.time)} samples, fewer than the {n} the derivative filter needs "
                         f"({n / log.sample_rate_hz * 1e3:.0f} ms at {log.sample_rate_hz:g} Hz)")


class SteadyFriction(TypedDict):
    """The friction measured at one steady speed of an open-loop experiment (:func:`_steady_friction`): the
    log's file name, the command [V], the speed [m/s], the friction [N], and the fitted curve's there (None
    where its direction has none)."""

    log: str
    u_V: float
    velocity_mps: float
    friction_N: float
    fitted_N: float | None


def _steady_friction(log: MeasurementLog, hyd: HydraulicParams) -> list[SteadyFriction]:
    """At each steady motion of an open-loop experiment (constant valve command, mid-stroke,
    :func:`hexsim.studies.metrics.steady_segments`): its speed and the median friction force F_L - M g
    cos θ there (the acceleration is nil; ``fitted_N`` None until a curve is fitted). Empty without a valve
    command column."""
    from hexsim.studies.metrics import steady_segments

    if "valve_cmd_V" not in log.columns:
        return []
    f_l, _ = load_force(log, hyd)
    g_axis = gravity() * np.cos(np.deg2rad(log.inclination_deg))
    weight = log.moving_mass_kg * g_axis
    rows = steady_segments(log.time, log.columns["valve_cmd_V"], log.columns["pos_m"], {"f_l": f_l})
    return [SteadyFriction(log=log.path.name, u_V=r["u_V"], velocity_mps=r["velocity_mps"],
                           friction_N=r["f_l"] - weight, fitted_N=None) for r in rows]


class _Fit(NamedTuple):
    x: np.ndarray
    fun: np.ndarray
    jac: np.ndarray


def _judge(sol, held: dict[str, str] | None = None, n_independent: float | None = None,
           weighted: bool = False) -> tuple[dict[str, Estimate], dict[str, str], np.ndarray]:
    """(each parameter's :class:`~hexsim.measured.estimates.Estimate`, status unidentifiable or held with
    why where the data cannot give it; those reasons by name; standard
    errors) of a fit ``sol`` (x, fun, jac) within the :data:`PARAMETERS`' bounds; ``held`` (name: why): the
    parameters not fitted, held at their start's value. ``n_independent``: the independent
    samples behind the residual (default: the residual's effective count, filtered samples being correlated;
    steady windows: one per window and not more than the samples say)."""
    held = held or {}
    free = [i for i, p in enumerate(PARAMS) if p not in held]
    is_free = np.isin(np.arange(len(PARAMS)), free)
    n_eff = effective_n(sol.fun[None, :])
    stats = fit_statistics(sol.jac, sol.fun, free=is_free, n_parameters=len(free),
                           n_independent=n_eff if n_independent is None else min(n_independent, n_eff))
    se = stats.std_errors
    # the residual's sensitivity to each parameter over its typical size: a direction the data does not
    # see at all has a zero column, which the pseudo-inverse answers with a standard error of 0
    sensitivity = np.linalg.norm(sol.jac, axis=0) * X_SCALE
    blind = sensitivity < 1e-6 * max(float(sensitivity.max()), 1e-300)
    params, unidentifiable = {}, {}
    if weighted:  # residuals in units of their standard errors: a reduced chi-square below 1 is no better data
        jf = sol.jac[:, is_free]
        se = np.zeros(len(PARAMS))
        se[is_free] = np.sqrt(np.clip(np.diag(np.linalg.pinv(jf.T @ jf)), 0.0, None) * max(1.0, stats.s2))
    for i, (param, x, e) in enumerate(zip(PARAMETERS, sol.x, se)):
        est = Estimate(param.key, float(x), float(e), param.unit, lower=param.lower, upper=param.upper)
        params[param.key] = est
        if i not in free:  # held at the start's value (0 for a slope or a hump the speeds cannot show)
            params[param.key] = dataclasses.replace(est, status=HELD, why=held[param.key])
            unidentifiable[param.key] = held[param.key]
            continue
        reason = None
        bound = at_bound(x, param.lower, param.upper, param.scale)  # limits (>= 0), not brackets: its typical size
        if blind[i]:
            reason = "the data does not depend on it (no samples where it changes the friction)"
        elif bound is not None:
            reason = f"at the bound {bound:g} {param.unit} of the fit"
        elif not np.isfinite(e) or e > abs(x):
            where = ("the speeds in the data do not separate a slope from the level" if param.key == "sigma" else
                     "too few samples at speeds near c_s, where the Stribeck term changes")
            reason = (f"the data cannot separate it (standard error {e:.3g} {param.unit} larger than the value "
                      f"{x:.3g}): {where}")
        if reason:
            params[param.key] = dataclasses.replace(est, status=UNIDENTIFIABLE, why=reason)
            unidentifiable[param.key] = reason
    return params, unidentifiable, se


#: the parameters each model frees: the level alone, Coulomb + viscous, the whole Stribeck curve
MODELS = {"level": ("F_c0",), "coulomb+viscous": ("sigma", "F_c0"), "stribeck": PARAMS}
HUMP_REASON = ("no samples at speeds near c_s, where the Stribeck term changes: fitted Coulomb + viscous with "
               "F_s0 = 0; run slower motions (a few mm/s) to identify the hump")


def _fit_curve(v: np.ndarray, f: np.ndarray, weight: np.ndarray, free: tuple[str, ...], x0: np.ndarray,
               hyd: HydraulicParams, robust: bool) -> _Fit:
    """Least squares of (stribeck(v) - f) weight over the ``free`` parameters, the others held at ``x0``;
    the Jacobian (n, 4) with zero columns for the held ones. ``robust``: soft L1 beyond
    :data:`ROBUST_SCALE_N` (samples), else plain (window medians, already robust)."""
    idx = [PARAMS.index(p) for p in free]

    def full(y):
        x = x0.copy()
        x[idx] = y
        return x

    sol = bounded_fit(lambda y: (stribeck(v, full(y), hyd) - f) * weight,
                      [np.clip(x0[idx], LOWER[idx] + 1e-9, UPPER[idx])], LOWER[idx], UPPER[idx],
                      x_scale=X_SCALE[idx], **({"loss": "soft_l1", "f_scale": ROBUST_SCALE_N} if robust else {}))
    jac = np.zeros((len(v), len(PARAMS)))
    jac[:, idx] = sol.jac
    return _Fit(full(sol.x), sol.fun, jac)


def _windows(v: np.ndarray, f: np.ndarray, window: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each steady window as one measurement: its speed [m/s], median force [N] and the median's standard
    error [N] (1.25 x the robust scatter, scipy's normal-scaled MAD, over the root of its samples)."""
    ids = np.unique(window)
    speed = np.array([v[window == k][0] for k in ids])
    force = np.array([np.median(f[window == k]) for k in ids])
    error = np.array([1.2533 * median_abs_deviation(f[window == k], scale="normal") / np.sqrt(np.sum(window == k))
                      for k in ids])
    return speed, force, np.maximum(error, 1e-3)


def _model_for(speed: np.ndarray, n_points: int | None, along: float) -> tuple[str, dict[str, str], np.ndarray]:
    """The richest model (a :data:`MODELS` key) the speeds [m/s] of one direction identify, the parameters
    it holds with why, and its start x0 (``along``: the level the force reads [N]). ``n_points``: the steady
    windows (None: samples of a moving log). One speed (within :data:`MIN_SPEED_RATIO`): the level alone;
    two to four windows: Coulomb + viscous; else the whole Stribeck curve."""
    ratio = float(np.percentile(speed, 95) / max(np.percentile(speed, 5), 1e-12))
    if ratio < MIN_SPEED_RATIO:
        why = (f"the data span one speed ({np.percentile(speed, 5) * 1e3:.3g}-{np.percentile(speed, 95) * 1e3:.3g} "
               "mm/s): a viscous slope or a Stribeck hump cannot be told from the Coulomb level; fitted the level "
               "alone (run two or more speeds)")
        return "level", dict.fromkeys(("sigma", "F_s0", "c_s"), why), np.array([0.0, along, 0.0, 0.005])
    if n_points is not None and n_points < 5:
        why = (f"{n_points} steady speeds cannot show a Stribeck hump (it needs five or more, some of a few mm/s): "
               "fitted Coulomb + viscous with F_s0 = 0")
        return "coulomb+viscous", dict.fromkeys(("F_s0", "c_s"), why), np.array([0.0, along, 0.0, 0.005])
    return "stribeck", {}, np.array([1000.0, along, 20.0, 0.005])


@dataclasses.dataclass(frozen=True)
class FrictionSide:
    """One direction's friction fit (:func:`identify_friction`): its ``side`` (positive: extending), the
    ``samples`` used; the ``parameters`` (:data:`PARAMS` order, each an
    :class:`~hexsim.measured.estimates.Estimate`: value, standard error, unit, status and why where the data
    cannot give it), the ``rms_N`` and robust ``scatter_N`` [N] of the samples about the curve, the steady
    ``windows`` fitted (None: samples of a moving log) and ``x``, the curve's (sigma, F_c0, F_s0, c_s) as
    :func:`stribeck` takes them; or ``cannot_fit``, the reason the data cannot support a curve (the fit's
    figures kept when it is the scatter)."""

    side: str
    samples: int
    parameters: dict[str, Estimate] = dataclasses.field(default_factory=dict)
    rms_N: float | None = None
    scatter_N: float | None = None
    windows: int | None = None
    cannot_fit: str | None = None
    x: np.ndarray | None = None

    @property
    def fitted(self) -> bool:
        """Whether the direction has a curve (no ``cannot_fit``)."""
        return self.cannot_fit is None

    @property
    def unidentifiable(self) -> dict[str, str]:
        """The parameters the data cannot give (held or unidentifiable), each with why."""
        return {k: e.why for k, e in self.parameters.items() if e.status != FITTED}

    def friction(self, v: np.ndarray, hyd: HydraulicParams | None = None) -> np.ndarray:
        """The fitted curve's friction force [N] at the velocities ``v`` [m/s] (any shape; :func:`stribeck`).
        Raises ValueError for a direction that could not be fitted."""
        if not self.fitted:
            raise ValueError(f"the {self.side} direction has no friction curve: {self.cannot_fit}")
        return stribeck(v, self.x, hyd)

    def record(self) -> dict:
        """The direction as ``hexsim friction --json`` writes it: each parameter's row (key, unit, value,
        std_error, bounds, status; why and ``unidentifiable`` where the data cannot give it), rms_N,
        scatter_N, samples, the reasons by name, windows (steady logs); or ``cannot_fit`` and samples."""
        if not self.parameters:
            return {"cannot_fit": self.cannot_fit, "samples": self.samples}
        rows = {k: e.as_row() | ({"unidentifiable": e.why} if e.status != FITTED else {})
                for k, e in self.parameters.items()}
        out = {"parameters": rows, "rms_N": self.rms_N, "scatter_N": self.scatter_N, "samples": self.samples,
               "unidentifiable": self.unidentifiable}
        out |= {"windows": self.windows} if self.windows is not None else {}
        return out | ({"cannot_fit": self.cannot_fit} if self.cannot_fit else {})


@dataclasses.dataclass(frozen=True)
class FrictionMap:
    """What :func:`identify_friction` returns: the ``log`` (its files, comma-separated), the ``machine``'s
    label, the number of ``experiments``; where the force and the acceleration came from
    (``force_source``, ``acceleration_source``), the moving mass [kg] and inclination [deg] used and what was
    ``assumed``; the ``positive`` and ``negative`` directions' fits (:class:`FrictionSide`); the ``steady``
    points; the samples fitted (``velocity`` [m/s] and ``force`` [N], (n,) each) and the ``hydraulics``
    whose friction curve (its arctan gain) the fit used."""

    log: str
    machine: str
    experiments: int
    force_source: str
    acceleration_source: str
    mass_kg: float
    inclination_deg: float
    assumed: list
    positive: FrictionSide
    negative: FrictionSide
    steady: list[SteadyFriction]
    velocity: np.ndarray
    force: np.ndarray
    hydraulics: HydraulicParams

    EQUATION = "seed eq. (3.9), the simulator's friction curve (hexsim.plant.hydraulics.friction_force)"

    def side(self, name: str) -> FrictionSide:
        """The direction ``name``: "positive" (extending) or "negative". Raises KeyError for another name."""
        if name not in ("positive", "negative"):
            raise KeyError(f"no friction direction {name!r} (positive or negative)")
        return self.positive if name == "positive" else self.negative

    def record(self) -> dict:
        """The identification as ``hexsim friction --json`` writes it (the samples left out)."""
        return {"log": self.log, "machine": self.machine, "experiments": self.experiments,
                "force_source": self.force_source, "acceleration_source": self.acceleration_source,
                "mass_kg": self.mass_kg, "inclination_deg": self.inclination_deg, "assumed": self.assumed,
                "equation": self.EQUATION, "positive": self.positive.record(), "negative": self.negative.record(),
                "steady": [dict(row) for row in self.steady]}


def _fit_direction(v: np.ndarray, f: np.ndarray, window: np.ndarray, hyd: HydraulicParams,
                   side: str) -> FrictionSide:
    """One direction's fit (:class:`FrictionSide`): parameters (value, standard error, unit, why not
    identifiable), the RMS and robust scatter of the samples about it [N], the samples; or ``cannot_fit``
    with the reason where the data cannot support a curve (too few samples, a force that aids the motion, a scatter larger than the
    level). Steady windows (``window`` >= 0) are fitted as one measurement each (:func:`_windows`,
    standard errors scaled by the reduced chi-square where it exceeds 1); other samples one by one with a
    robust loss. The model is as rich as the data: one speed (one window, or speeds within
    :data:`MIN_SPEED_RATIO`) gives the level alone, two to four windows Coulomb + viscous, more and
    samples near c_s the Stribeck hump."""
    if len(v) < MIN_SAMPLES:
        return FrictionSide(side, len(v), cannot_fit=(
            f"only {len(v)} usable samples move in the {side} direction (steady where the command holds, away from "
            f"the stops, faster than {V_MIN * 1e3:g} mm/s); {MIN_SAMPLES} are needed"))
    along = float(np.median(f * np.sign(v)))
    if along <= 0.0:
        return FrictionSide(side, len(v), cannot_fit=(
            f"the force read along the {side} motion aids it (median {along:.3g} N); friction opposes motion: "
            "check the areas, the moving mass and inclination (M g cos θ) and which runs were paired"))
    steady = bool(np.all(window >= 0))
    if steady:
        pv, pf, pe = _windows(v, f, window)
        weight, n_points = 1.0 / pe, len(pv)
    else:
        pv, pf, weight, n_points = v, f, np.ones(len(v)), None
    model, held, x0 = _model_for(np.abs(pv), n_points, along)
    sol = _fit_curve(pv, pf, weight, MODELS[model], x0, hyd, robust=not steady)
    if model == "stribeck":
        _, unidentifiable, _ = _judge(sol)
        if any(p in unidentifiable for p in ("F_s0", "c_s")):
            # no samples near c_s: the hump cannot be told from the viscous slope; fit Coulomb + viscous
            # (F_s0 = 0), the curve the speeds in the data do identify
            x0 = sol.x.copy()
            x0[2] = 0.0
            sol = _fit_curve(pv, pf, weight, MODELS["coulomb+viscous"], x0, hyd, robust=not steady)
            held = dict.fromkeys(("F_s0", "c_s"), HUMP_REASON)
    params, _, _ = _judge(sol, held, n_independent=n_points, weighted=steady)
    residual = stribeck(v, sol.x, hyd) - f
    scatter = float(median_abs_deviation(residual, scale="normal"))
    level = float(abs(np.median(stribeck(v, sol.x, hyd))))
    cannot = None
    if scatter > level:
        cannot = (f"the friction force scatters by {scatter:.3g} N (robust) about a level of {level:.3g} N: the data "
                  "cannot support a curve (are the pressures of one experiment, the position inside the stroke, the "
                  "moving mass right?)")
    return FrictionSide(side, len(v), params, float(np.sqrt(np.mean(residual**2))), scatter,
                        n_points if steady else None, cannot, sol.x)


def identify_friction(logs: MeasurementLog | list) -> FrictionMap:
    """Fitted Stribeck parameters per direction with standard errors, the RMS fit error, the samples
    used and, for open-loop experiments, the friction measured at each steady speed against the fit
    (:class:`FrictionMap`). ``logs``: one log, or a list of experiments, each a log or a list of runs of one
    experiment that logged different channels (:func:`friction_samples`); the samples of all are fitted
    together with the first log's machine (its friction curve's arctan gain and the areas). A direction the
    data cannot support has ``cannot_fit`` (the reason) instead of a curve. Raises InputError if a log lacks
    what the force needs, or is not a single axis (:func:`friction_samples`), or neither direction can be
    fitted."""
    groups = [logs] if isinstance(logs, MeasurementLog) else list(logs)
    runs = [g if isinstance(g, list) else [g] for g in groups]
    experiments = [merge_runs(r) for r in runs]
    first = experiments[0]
    hyd = first.machine.hydraulics
    parts = [friction_samples(r, hyd) for r in runs]
    vel = np.concatenate([p.velocity for p in parts])
    ff = np.concatenate([p.force for p in parts])
    # steady windows numbered across the experiments (-1 stays: a sample of a moving log)
    offsets = np.cumsum([0] + [int(p.window.max()) + 1 for p in parts[:-1]])
    windows = np.concatenate([np.where(p.window >= 0, p.window + o, -1) for p, o in zip(parts, offsets)])
    positive, negative = (_fit_direction(vel[mask], ff[mask], windows[mask], hyd, side)
                          for side, mask in (("positive", vel > V_MIN), ("negative", vel < -V_MIN)))
    if not (positive.fitted or negative.fitted):
        raise InputError(f"{first.path}: friction cannot be fitted: positive: {positive.cannot_fit}; "
                         f"negative: {negative.cannot_fit}")
    steady = [row for log in experiments for row in _steady_friction(log, hyd)]
    for row in steady:
        side = positive if row["velocity_mps"] > 0 else negative
        row["fitted_N"] = float(side.friction(np.array([row["velocity_mps"]]), hyd)[0]) if side.fitted else None
    return FrictionMap(", ".join(str(log.path) for log in experiments), first.machine.label, len(experiments),
                       parts[0].force_source, parts[0].acceleration_source, first.moving_mass_kg,
                       first.inclination_deg, first.assumed, positive, negative, steady, vel, ff, hyd)
