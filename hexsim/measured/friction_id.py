"""Friction identification from a log (seed §2.3.3, eq. 2.3–2.4): ``hexsim friction LOG.csv``.

F_f = F_L - M ydd - M g cos(inclination), with F_L = P1 A1 - P_s A2 (seed eq. 2.3) from the pressures of
the 3-way valve, A1 p1 - A2 p2 from both chambers of a 4-way valve (the areas of the log's machine file),
or F_L = ``force_N`` for a drive without pressure sensors (the seed notes the method applies to electric
drives too); a log needs only the columns of one of these and the position. Runs of one experiment
that logged different pressures (the real servo cylinder's pA and pB runs) are merged row by row. The velocity is a Savitzky–Golay derivative of the measured position; M (ydd + g cos θ) is
the logged accelerometer (specific force, ``acc_mps2``; a log holding acceleration without g is
recognised by its mean) where there is one, else the position's second derivative.

The curve fitted is the one the simulator uses (:func:`hexsim.plant.hydraulics.friction_force`, seed eq. 3.9),
F_f = sigma v + s(v) [F_c0 + F_s0 exp(-|v| / c_s)] with s(v) = arctan(k v) (times 2/pi when
``arctan_normalised``), per direction, with ``scipy.optimize.least_squares``; so identification and
simulation recover each other's parameters. (Eq. 2.4 of the seed has sign(v) for s(v); with the
published eq. 3.9, arctan tends to ±pi/2 and the Coulomb level at speed is pi/2 F_c0.) Standard errors
from the Jacobian; a parameter the data cannot separate (at a bound of its range, or a standard error
larger than the value) is reported as unidentifiable with the reason, never as a number.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np
from scipy.optimize import least_squares

from hexsim.errors import InputError
from hexsim.measured.measurement import MeasurementLog
from hexsim.measured.residuals import effective_n
from hexsim.measured.statistics import fit_statistics
from hexsim.plant.model import gravity, moving_mass
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
PARAMS = ("sigma", "F_c0", "F_s0", "c_s")
X_SCALE = (1000.0, 50.0, 20.0, 0.005)  # typical sizes of the parameters (the fit's x_scale)
UNITS = ("N s/m", "N", "N", "m/s")


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


def friction_samples(log: MeasurementLog, hyd: HydraulicParams | None = None
                     ) -> tuple[np.ndarray, np.ndarray, str, str]:
    """(velocity [m/s], friction force [N], source of F_L, source of the acceleration) per sample, the
    samples within :data:`END_MARGIN_M` of the ends of the observed stroke left out. ``hyd``: the areas
    (default the log's machine's). Raises InputError naming the missing columns (:func:`load_force`), or
    if the log is not a single axis."""
    if log.system != "single-actuator":
        raise InputError(f"{log.path}: friction identification needs a single-actuator log (this is {log.system})")
    hyd = hyd or log.machine.hydraulics
    c = log.columns
    f_l, source = load_force(log, hyd)
    fs = log.sample_rate_hz
    mass = log.mass_kg or moving_mass()
    g_axis = gravity() * np.cos(np.deg2rad(log.inclination_deg))
    pos = c["pos_m"]
    inside = (pos > pos.min() + END_MARGIN_M) & (pos < pos.max() - END_MARGIN_M)
    if "acc_mps2" in c:  # M (ydd + g cos θ) measured: no second derivative of the position
        _check_length(log, savgol_length(fs, ACC_WINDOW_S))
        specific = c["acc_mps2"]
        if abs(float(np.mean(specific))) < 0.5 * g_axis:  # the log holds acceleration, not specific force
            specific = specific + g_axis
        vel = savgol(pos, fs, ACC_WINDOW_S, deriv=1)
        return vel[inside], savgol(f_l - mass * specific, fs, ACC_WINDOW_S)[inside], source, "accelerometer (acc_mps2)"
    _check_length(log, savgol_length(fs, DERIVATIVE_WINDOW_S))
    vel = savgol(pos, fs, DERIVATIVE_WINDOW_S, deriv=1)
    acc = savgol(pos, fs, DERIVATIVE_WINDOW_S, deriv=2)
    f_l = savgol(f_l, fs, DERIVATIVE_WINDOW_S)
    return vel[inside], (f_l - mass * acc - mass * g_axis)[inside], source, "second derivative of the position"


def _check_length(log: MeasurementLog, n: int) -> None:
    if len(log.time) < n:
        raise InputError(f"{log.path}: {len(log.time)} samples, fewer than the {n} the derivative filter needs "
                         f"({n / log.sample_rate_hz * 1e3:.0f} ms at {log.sample_rate_hz:g} Hz)")


def _steady_friction(log: MeasurementLog, hyd: HydraulicParams) -> list[dict]:
    """At each steady motion of an open-loop experiment (constant valve command, mid-stroke,
    :func:`hexsim.simulation.metrics.steady_segments`): its speed and the median friction force F_L - M g
    cos θ there (the acceleration is nil). Empty without a valve command column."""
    from hexsim.simulation.metrics import steady_segments

    if "valve_cmd_V" not in log.columns:
        return []
    f_l, _ = load_force(log, hyd)
    g_axis = gravity() * np.cos(np.deg2rad(log.inclination_deg))
    weight = (log.mass_kg or moving_mass()) * g_axis
    rows = steady_segments(log.time, log.columns["valve_cmd_V"], log.columns["pos_m"], {"f_l": f_l})
    return [{"log": log.path.name, "u_V": r["u_V"], "velocity_mps": r["velocity_mps"], "friction_N": r["f_l"] - weight}
            for r in rows]


class _Fit(NamedTuple):
    x: np.ndarray
    fun: np.ndarray
    jac: np.ndarray


def _judge(sol, lo: np.ndarray, hi: np.ndarray, fixed: tuple[str, ...] = ()) -> tuple[dict, dict, np.ndarray]:
    """(parameters with value, standard error, unit and why a value is not identifiable; the
    unidentifiable ones' reasons; standard errors) of a fit ``sol`` (x, fun, jac) within bounds (lo, hi);
    parameters in ``fixed`` were not fitted (their entries are left for the caller)."""
    free = [i for i, p in enumerate(PARAMS) if p not in fixed]
    is_free = np.isin(np.arange(len(PARAMS)), free)
    se = fit_statistics(sol.jac, sol.fun, free=is_free, n_parameters=len(free),  # filtered: correlated
                        n_independent=effective_n(sol.fun[None, :])).std_errors
    # the residual's sensitivity to each parameter over its typical size: a direction the data does not
    # see at all has a zero column, which the pseudo-inverse answers with a standard error of 0
    sensitivity = np.linalg.norm(sol.jac, axis=0) * np.array(X_SCALE)
    blind = sensitivity < 1e-6 * max(float(sensitivity.max()), 1e-300)
    params, unidentifiable = {}, {}
    for i, (p, x, e, u, a, b) in enumerate(zip(PARAMS, sol.x, se, UNITS, lo, hi)):
        params[p] = {"value": float(x), "std_error": float(e), "unit": u}
        if i not in free:
            continue
        reason = None
        if blind[i]:
            reason = "the data does not depend on it (no samples where it changes the friction)"
        elif x <= a + 1e-9 * (b - a) or x >= b - 1e-9 * (b - a):
            reason = f"at the bound {a if x <= a + 1e-9 * (b - a) else b:g} {u} of the fit"
        elif not np.isfinite(e) or e > abs(x):
            reason = (f"the data cannot separate it (standard error {e:.3g} {u} larger than the value "
                      f"{x:.3g}): too few samples at speeds near c_s, where the Stribeck term changes")
        if reason:
            params[p]["unidentifiable"] = unidentifiable[p] = reason
    return params, unidentifiable, se


def identify_friction(logs: MeasurementLog | list) -> dict:
    """Fitted Stribeck parameters per direction with standard errors, the RMS fit error, the samples
    used and, for open-loop experiments, the friction measured at each steady speed against the fit.
    ``logs``: one log, or a list of experiments, each a log or a list of runs of one experiment that
    logged different channels (:func:`merge_runs`); the samples of all are fitted together with the first
    log's machine (its friction curve's arctan gain and the areas). Raises InputError if a direction has
    fewer than 50 samples faster than 0.5 mm/s, or a log lacks what the force needs."""
    groups = [logs] if isinstance(logs, MeasurementLog) else list(logs)
    experiments = [merge_runs(g if isinstance(g, list) else [g]) for g in groups]
    first = experiments[0]
    hyd = first.machine.hydraulics
    parts = [friction_samples(log, hyd) for log in experiments]
    vel = np.concatenate([p[0] for p in parts])
    ff = np.concatenate([p[1] for p in parts])
    source, acc_source = parts[0][2], parts[0][3]
    out = {"log": ", ".join(str(log.path) for log in experiments), "machine": first.machine.label,
           "experiments": len(experiments), "force_source": source, "acceleration_source": acc_source,
           "mass_kg": first.mass_kg or moving_mass(), "inclination_deg": first.inclination_deg,
           "assumed": first.assumed,
           "equation": "seed eq. (3.9), the simulator's friction curve (hexsim.plant.hydraulics.friction_force)"}
    lo, hi = np.array([0.0, 0.0, 0.0, 1e-4]), np.array([1e5, 1e4, 1e4, 0.5])
    fitted = {}
    for side, mask in (("positive", vel > V_MIN), ("negative", vel < -V_MIN)):
        if mask.sum() < 50:
            raise InputError(f"{first.path}: only {int(mask.sum())} samples move in the {side} direction faster "
                             f"than {V_MIN * 1e3:g} mm/s; friction cannot be fitted")
        v, f = vel[mask], ff[mask]
        x0 = np.array([1000.0, 50.0, 20.0, 0.005])  # the shape s(v) carries the direction: magnitudes
        # a robust loss (soft L1 beyond ROBUST_SCALE_N): the few samples of a valve switch, where the
        # pressures ring and the moving mass is uncertain, must not carry the curve
        sol = least_squares(lambda x, v=v, f=f: stribeck(v, x, hyd) - f, x0, bounds=(lo, hi),
                            x_scale=X_SCALE, loss="soft_l1", f_scale=ROBUST_SCALE_N)
        params, unidentifiable, se = _judge(sol, lo, hi)
        if any(p in unidentifiable for p in ("F_s0", "c_s")):
            # no samples near c_s: the hump cannot be told from the viscous slope; fit Coulomb + viscous
            # (F_s0 = 0), the curve the speeds in the data do identify
            x_cv = sol.x.copy()
            x_cv[2] = 0.0
            sol2 = least_squares(lambda y, v=v, f=f: stribeck(v, np.array([y[0], y[1], 0.0, x_cv[3]]), hyd) - f,
                                 np.clip(x_cv[:2], lo[:2] + 1e-6, hi[:2]), bounds=(lo[:2], hi[:2]), x_scale=[1000, 50],
                                 loss="soft_l1", f_scale=ROBUST_SCALE_N)
            sol = _Fit(np.array([*sol2.x, 0.0, x_cv[3]]), sol2.fun, np.hstack([sol2.jac, np.zeros((len(v), 2))]))
            params, _, se = _judge(sol, lo, hi, fixed=("F_s0", "c_s"))
            for p in ("F_s0", "c_s"):
                params[p]["unidentifiable"] = unidentifiable[p] = (
                    "no samples at speeds near c_s, where the Stribeck term changes: fitted Coulomb + viscous with "
                    "F_s0 = 0; run slower motions (a few mm/s) to identify the hump")
        fitted[side] = sol.x
        s2 = float(sol.fun @ sol.fun) / max(effective_n(sol.fun[None, :]) - 4, 1.0)  # filtered: correlated
        out[side] = {"parameters": params, "rms_N": float(np.sqrt(s2)), "samples": int(len(v)),
                     "unidentifiable": unidentifiable}
    steady = [row for log in experiments for row in _steady_friction(log, hyd)]
    for row in steady:
        x = fitted["positive" if row["velocity_mps"] > 0 else "negative"]
        row["fitted_N"] = float(stribeck(np.array([row["velocity_mps"]]), x, hyd)[0])
    out["steady"] = steady
    out["_samples"] = (vel, ff)
    out["_hydraulics"] = hyd  # the friction curve's arctan gain and scale, for the plot
    return out
