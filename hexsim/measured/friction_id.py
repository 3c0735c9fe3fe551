"""Friction identification from a log (seed §2.3.3, eq. 2.3–2.4): ``hexsim friction LOG.csv``.

F_f = F_L - M ydd - M g cos(inclination), with F_L = P1 A1 - P_s A2 (seed eq. 2.3) from the pressures,
or F_L = ``force_N`` for a drive without pressure sensors (the seed notes the method applies to electric
drives too). The velocity is a Savitzky–Golay derivative of the measured position; M (ydd + g cos θ) is
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

import pathlib

import numpy as np
from scipy.optimize import least_squares

from hexsim.errors import InputError
from hexsim.measured.measurement import MeasurementLog
from hexsim.measured.residuals import effective_n
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
UNITS = ("N s/m", "N", "N", "m/s")


def stribeck(v: np.ndarray, x: np.ndarray, hyd: HydraulicParams | None = None) -> np.ndarray:
    """The simulator's friction curve for one direction (seed eq. 3.9), x = (sigma, F_c0, F_s0, c_s);
    the arctan gain k and its normalisation from ``hyd`` (default the seed's)."""
    hyd = hyd or HydraulicParams()
    shape = np.arctan(hyd.arctan_gain * v) * (2.0 / np.pi if hyd.arctan_normalised else 1.0)
    return x[0] * v + shape * (x[1] + x[2] * np.exp(-np.abs(v) / x[3]))


def friction_samples(log: MeasurementLog, hyd: HydraulicParams | None = None
                     ) -> tuple[np.ndarray, np.ndarray, str, str]:
    """(velocity [m/s], friction force [N], source of F_L, source of the acceleration) per sample. Raises InputError naming the
    missing columns if the log has neither p1_Pa + ps_Pa nor force_N, or is not a single axis."""
    if log.system != "single-actuator":
        raise InputError(f"{log.path}: friction identification needs a single-actuator log (this is {log.system})")
    hyd = hyd or HydraulicParams()
    c = log.columns
    if "force_N" in c:
        f_l, source = c["force_N"], "force_N"
    elif "p1_Pa" in c and "ps_Pa" in c:
        f_l, source = c["p1_Pa"] * hyd.area_bottom - c["ps_Pa"] * hyd.area_rod, "P1 A1 - P_s A2 (seed eq. 2.3)"
    else:
        raise InputError(f"{log.path}: friction identification needs columns 'p1_Pa' and 'ps_Pa', or 'force_N'")
    fs = log.sample_rate_hz
    mass = log.mass_kg or moving_mass()
    g_axis = gravity() * np.cos(np.deg2rad(log.inclination_deg))
    if "acc_mps2" in c:  # M (ydd + g cos θ) measured: no second derivative of the position
        _check_length(log, savgol_length(fs, ACC_WINDOW_S))
        specific = c["acc_mps2"]
        if abs(float(np.mean(specific))) < 0.5 * g_axis:  # the log holds acceleration, not specific force
            specific = specific + g_axis
        vel = savgol(c["pos_m"], fs, ACC_WINDOW_S, deriv=1)
        return vel, savgol(f_l - mass * specific, fs, ACC_WINDOW_S), source, "accelerometer (acc_mps2)"
    _check_length(log, savgol_length(fs, DERIVATIVE_WINDOW_S))
    vel = savgol(c["pos_m"], fs, DERIVATIVE_WINDOW_S, deriv=1)
    acc = savgol(c["pos_m"], fs, DERIVATIVE_WINDOW_S, deriv=2)
    f_l = savgol(f_l, fs, DERIVATIVE_WINDOW_S)
    return vel, f_l - mass * acc - mass * g_axis, source, "second derivative of the position"


def _check_length(log: MeasurementLog, n: int) -> None:
    if len(log.time) < n:
        raise InputError(f"{log.path}: {len(log.time)} samples, fewer than the {n} the derivative filter needs "
                         f"({n / log.sample_rate_hz * 1e3:.0f} ms at {log.sample_rate_hz:g} Hz)")


def identify_friction(log: MeasurementLog) -> dict:
    """Fitted Stribeck parameters per direction with standard errors, the RMS fit error and the samples
    used. Raises InputError if a direction has fewer than 50 samples faster than 2 mm/s."""
    vel, ff, source, acc_source = friction_samples(log)
    out = {"log": str(log.path), "force_source": source, "acceleration_source": acc_source, "mass_kg": log.mass_kg or moving_mass(),
           "inclination_deg": log.inclination_deg, "assumed": log.assumed,
           "equation": "seed eq. (3.9), the simulator's friction curve (hexsim.plant.hydraulics.friction_force)"}
    lo, hi = np.array([0.0, 0.0, 0.0, 1e-4]), np.array([1e5, 1e4, 1e4, 0.5])
    for side, mask in (("positive", vel > V_MIN), ("negative", vel < -V_MIN)):
        if mask.sum() < 50:
            raise InputError(f"{log.path}: only {int(mask.sum())} samples move in the {side} direction faster "
                             f"than {V_MIN * 1e3:g} mm/s; friction cannot be fitted")
        v, f = vel[mask], ff[mask]
        x0 = np.array([1000.0, 50.0, 20.0, 0.005])  # the shape s(v) carries the direction: magnitudes
        sol = least_squares(lambda x, v=v, f=f: stribeck(v, x) - f, x0, bounds=(lo, hi),
                            x_scale=[1000, 50, 20, 0.005])
        s2 = float(sol.fun @ sol.fun) / max(effective_n(sol.fun[None, :]) - 4, 1.0)  # filtered: correlated
        se = np.sqrt(np.clip(np.diag(np.linalg.pinv(sol.jac.T @ sol.jac)) * s2, 0, None))
        params, unidentifiable = {}, {}
        for p, x, e, u, a, b in zip(PARAMS, sol.x, se, UNITS, lo, hi):
            reason = None
            if x <= a + 1e-9 * (b - a) or x >= b - 1e-9 * (b - a):
                reason = f"at the bound {a if x <= a + 1e-9 * (b - a) else b:g} {u} of the fit"
            elif not np.isfinite(e) or e > abs(x):
                reason = (f"the data cannot separate it (standard error {e:.3g} {u} larger than the value "
                          f"{x:.3g}): too few samples at speeds near c_s, where the Stribeck term changes")
            if reason and p == "c_s":  # the only parameter that is shape, not level: report it as such
                unidentifiable[p] = reason
            params[p] = {"value": float(x), "std_error": float(e), "unit": u}
            if reason:
                params[p]["unidentifiable"] = reason
        out[side] = {"parameters": params, "rms_N": float(np.sqrt(s2)), "samples": int(len(v)),
                     "unidentifiable": unidentifiable}
    out["_samples"] = (vel, ff)
    return out


def plot_map(result: dict, path: pathlib.Path) -> None:
    from matplotlib.figure import (
        Figure,  # no pyplot: the user's backend is never switched
    )

    from hexsim.outputs.plotting import save_figure

    vel, ff = result["_samples"]
    fig = Figure(figsize=(7, 4.5), layout="tight")
    ax = fig.subplots()
    ax.plot(vel, ff, ",", color="0.5", label="F_f = F_L - M ydd - M g cos θ (seed eq. 2.3)")
    for side, sgn in (("positive", 1), ("negative", -1)):
        x = np.array([result[side]["parameters"][p]["value"] for p in PARAMS])
        v = sgn * np.linspace(V_MIN, max(np.abs(vel).max(), 2 * V_MIN), 200)
        ax.plot(v, stribeck(v, x), color="C0" if sgn > 0 else "C3", label=f"Stribeck fit, {side} (seed eq. 3.9)")
    ax.set_xlabel("velocity [m/s]")
    ax.set_ylabel("friction force [N]")
    ax.set_title(f"friction-velocity map: {pathlib.Path(result['log']).name}")
    ax.legend(fontsize=8, markerscale=20)
    save_figure(fig, path, dpi=100)
