"""A closed-loop servo axis written independently of hexsim (no hexsim import): a 4-way proportional valve driving a
300 mm differential cylinder on a vertical axis, 123 kg, under P control at 500 Hz — the "real machine" of
``examples/four_way_axis.py``. Its own equations, integrated by scipy's LSODA between controller samples:

- the valve: a second-order spool (60 Hz, zeta 0.7, in volts of command); its opening a fraction of the full
  port with a 0.1 V overlap and a knee at 3 V where the flow gain halves (a progressive metering notch meeting
  the port); each of the four edges P->A, A->T, P->B, B->T its own gain (matched within grinding tolerance);
- each edge: q = k C_d a sqrt(2 / rho) dp / sqrt(|dp| + 2 kPa) (turbulent, laminar only below ~2 kPa);
- chambers: dp1/dt = E / (A1 y + V_A) (q_A + q_L - A1 v), dp2/dt = E / (A2 (L - y) + V_B) (q_B - q_L + A2 v),
  q_L = C_L (p2 - p1) across the piston seal; pressures kept above -0.9 bar;
- piston: M dv/dt = p1 A1 - p2 A2 - F_f(v) - M g + end stops (stiff springs with damping at 0 and L), F_f = (F_c +
  F_s exp(-|v| / v_s)) tanh(v / 0.5 mm/s) + sigma v, each direction its own F_c, F_s;
- the loop: u = sat(K_p (r - y_m) + U_c, +-10 V) at 500 Hz, held between samples, y_m the position with the
  transducer's noise, U_c a compensator's output where one is hooked in (``run(..., compensate=...)``, called as
  hexsim's P controller calls one);
- the valve's null may drift (``null_rate`` [V/s], from ``null_offset`` at t = 0);
- the log at 1 kHz: time_s, ref_m, valve_cmd_V, pos_m, p1_Pa, p2_Pa, ps_Pa with 5 um and 0.045 bar of white
  noise (a supply held at its set pressure).
"""

from __future__ import annotations

import json
import math
import pathlib
from dataclasses import dataclass, replace

import numpy as np
from scipy.integrate import odeint

#: Log rate [Hz] and samples per controller sample (500 Hz).
LOG_HZ = 1000.0


@dataclass(frozen=True)
class Axis:
    bore: float = 0.040
    rod: float = 0.025
    stroke: float = 0.300
    mass: float = 123.0
    supply: float = 100e5
    tank: float = 1.0e5
    rated_flow: float = 4e-4  # per edge at 35 bar and the full command [m^3/s] (24 L/min)
    knee_v: float = 3.0  # [V] where the flow gain halves
    knee_f: float = 0.5  # the opening's fraction there
    overlap_v: float = 0.1  # [V]
    null_offset: float = 0.0  # [V]
    null_rate: float = 0.0  # [V/s]
    spool_hz: float = 60.0
    spool_zeta: float = 0.7
    k_pa: float = 1.0
    k_at: float = 0.97
    k_pb: float = 1.03
    k_bt: float = 0.95
    bulk: float = 1.4e9
    v_a: float = 1.2e-4
    v_b: float = 1.0e-4
    coulomb: tuple[float, float] = (178.0, 142.0)  # [N] moving out (+), in (-)
    static: tuple[float, float] = (60.0, 50.0)  # [N] above the Coulomb level at rest
    stribeck_v: float = 0.005
    viscous: float = 1500.0
    leakage: float = 0.0  # C_L [m^3/(s Pa)] from the rod side to the cap side
    kp: float = 800.0  # [V/m]
    rate: float = 500.0  # [Hz]
    pos_noise: float = 5e-6
    p_noise: float = 4500.0

    def replace(self, **kw) -> "Axis":
        return replace(self, **kw)


def opening(ax: Axis, u: float) -> float:
    """The fraction of the full opening at a spool position of u [V] of command (either direction)."""
    a = abs(u) - ax.overlap_v
    if a <= 0.0:
        return 0.0
    knee = ax.knee_v - ax.overlap_v
    if a < knee:
        return ax.knee_f * a / knee
    return min(ax.knee_f + (1.0 - ax.knee_f) * (a - knee) / (10.0 - ax.knee_v), 1.0)


def run(ax: Axis, ref: np.ndarray, seed: int, compensate=None, states: dict | None = None) -> np.ndarray:
    """The axis following ``ref`` (n,) [m] at 1 kHz from rest at ref[0]: the log's columns (n, 7).

    ``compensate(u_p, y, r, r_dot, r_ddot, r_dddot, p1) -> U_c`` [V] is called at each controller sample with the P
    output, the measured position, the reference and its derivatives (central differences of the 500 Hz setpoints)
    and the measured cap pressure, as hexsim's P controller calls a compensator; U_c is added before the
    saturation. ``states``, where given, receives the run without sensor noise at the log's samples: ``acc_mps2``
    (the piston's acceleration averaged over the millisecond before each sample, as an accelerometer sampled at
    1 kHz gives it), ``velocity_mps``, ``comp_V`` (U_c)."""
    a1 = math.pi / 4 * ax.bore**2
    a2 = a1 - math.pi / 4 * ax.rod**2
    cd, rho, g = 0.61, 860.0, 9.81
    full = ax.rated_flow / (cd * math.sqrt(2 * 35e5 / rho))  # the full opening [m^2] of the rated flow
    w = 2 * math.pi * ax.spool_hz

    def edge(k, area, dp):
        return k * cd * area * math.sqrt(2.0 / rho) * dp / math.sqrt(abs(dp) + 2e3)

    def rhs(t, s, cmd):
        y, v, p1, p2, xs, vs = s
        f = full * opening(ax, xs)
        pos, neg = (f, 0.0) if xs > 0 else (0.0, f)
        q_a = edge(ax.k_pa, pos, ax.supply - p1) - edge(ax.k_at, neg, p1 - ax.tank)
        q_b = edge(ax.k_pb, neg, ax.supply - p2) - edge(ax.k_bt, pos, p2 - ax.tank)
        q_l = ax.leakage * (p2 - p1)
        dp1 = ax.bulk / (a1 * max(y, 0.0) + ax.v_a) * (q_a + q_l - a1 * v)
        dp2 = ax.bulk / (a2 * max(ax.stroke - y, 0.0) + ax.v_b) * (q_b - q_l + a2 * v)
        if p1 < -0.9e5 and dp1 < 0:
            dp1 = 0.0
        if p2 < -0.9e5 and dp2 < 0:
            dp2 = 0.0
        side = 0 if v >= 0 else 1
        friction = ((ax.coulomb[side] + ax.static[side] * math.exp(-abs(v) / ax.stribeck_v)) * math.tanh(v / 5e-4)
                    + ax.viscous * v)
        stop = 0.0
        if y < 0.0:
            stop = -5e7 * y - 2e4 * v
        elif y > ax.stroke:
            stop = -5e7 * (y - ax.stroke) - 2e4 * v
        dv = (p1 * a1 - p2 * a2 - friction - ax.mass * g + stop) / ax.mass
        null = ax.null_offset + ax.null_rate * t
        return [v, dv, dp1, dp2, vs, w * w * (cmd - null - xs) - 2 * ax.spool_zeta * w * vs]

    rng = np.random.default_rng(seed)
    n = ref.size
    p1_0 = (ax.mass * g + 0.5 * ax.supply * a2) / a1  # at rest, the rod side at half the supply
    state = np.array([float(ref[0]), 0.0, p1_0, 0.5 * ax.supply, 0.0, 0.0])
    out = np.empty((n, 4))
    cmds, comp = np.empty(n), np.zeros(n)
    per = int(round(LOG_HZ / ax.rate))
    derivatives, p_noise = [], None
    if compensate is not None:  # the reference's derivatives at the controller rate, the cap pressure's noise
        derivatives = [np.gradient(ref[::per], per / LOG_HZ)]
        for _ in range(2):
            derivatives.append(np.gradient(derivatives[-1], per / LOG_HZ))
        p_noise = rng.normal(0.0, ax.p_noise, n)
    # LSODA (ODEPACK's, through odeint: solve_ivp's LSODA wraps the same solver in Python at each step, and took
    # 2.3x the time) from each controller sample to the next, the valve's command held
    tol = dict(rtol=1e-6, atol=[1e-9, 1e-7, 1.0, 1.0, 1e-6, 1e-3], tfirst=True)
    for k in range(0, n, per):
        e = rng.normal(0.0, ax.pos_noise)
        u_p, u_c = ax.kp * (ref[k] - state[0] - e), 0.0
        if compensate is not None:
            d1, d2, d3 = (d[k // per] for d in derivatives)
            u_c = float(compensate(u_p, state[0] + e, ref[k], d1, d2, d3, state[2] + p_noise[k]))
        cmd = float(np.clip(u_p + u_c, -10.0, 10.0))
        t0, t1 = k / LOG_HZ, (k + per) / LOG_HZ
        rows = np.arange(k, min(k + per, n))
        times = [t0, *(rows[1:] / LOG_HZ), t1]  # rows[0] is at t0
        sol, info = odeint(rhs, state, times, args=(cmd,), full_output=True, **tol)
        assert info["message"] == "Integration successful.", info["message"]
        out[rows] = sol[:rows.size, :4]
        cmds[rows], comp[rows] = cmd, u_c
        state = sol[-1]
    t = np.arange(n) / LOG_HZ
    if states is not None:
        v = out[:, 1]
        states.update(velocity_mps=v.copy(), comp_V=comp, acc_mps2=np.concatenate([[0.0], np.diff(v) * LOG_HZ]))
    noise = rng.normal(0.0, 1.0, (n, 4)) * [ax.pos_noise, ax.p_noise, ax.p_noise, ax.p_noise]
    return np.column_stack([t, ref, cmds, out[:, 0] + noise[:, 0], out[:, 2] + noise[:, 1], out[:, 3] + noise[:, 2],
                            ax.supply + noise[:, 3]])


def write(ax: Axis, ref: np.ndarray, path: pathlib.Path, seed: int, description: str, compensate=None,
          accelerometer: float = 0.0) -> pathlib.Path:
    """The log of ``ax`` following ``ref`` at ``path`` (.csv) with its sidecar (.json): a closed loop, a 4-way valve
    and the cylinder declared; the mass and inclination left to the machine file (a user does not weigh a load).
    ``compensate`` as :func:`run`'s; ``accelerometer`` > 0 [m/s^2] adds ``acc_mps2``, an accelerometer on the piston
    (specific force: the 1 ms mean acceleration plus g) with that white noise, drawn from a stream of its own."""
    states = {}
    cols = run(ax, ref, seed, compensate=compensate, states=states)
    header = "time_s,ref_m,valve_cmd_V,pos_m,p1_Pa,p2_Pa,ps_Pa"
    if accelerometer > 0:
        noise = np.random.default_rng(seed + 1000).normal(0.0, accelerometer, len(cols))
        cols, header = np.column_stack([cols, states["acc_mps2"] + 9.81 + noise]), header + ",acc_mps2"
    np.savetxt(path, cols, delimiter=",", header=header, comments="", fmt="%.9g")
    path.with_suffix(".json").write_text(json.dumps({
        "system": "single-actuator", "sample_rate_hz": LOG_HZ,
        "controller": {"type": "P", "kp_V_per_m": ax.kp, "rate_hz": ax.rate},
        "valve": "4-way", "cylinder": {"bore_m": ax.bore, "rod_m": ax.rod, "stroke_m": ax.stroke},
        "description": description}, indent=1))
    return path


def chirp(duration: float = 20.0, f0: float = 0.2, f1: float = 2.0, mid: float = 0.15, amp: float = 0.03) -> np.ndarray:
    """A linear chirp f0 -> f1 [Hz] about ``mid`` [m], its amplitude falling from ``amp`` to half (the valve's
    speed kept), faded in over 1 s; at 1 kHz."""
    t = np.arange(int(duration * LOG_HZ)) / LOG_HZ
    phase = 2 * np.pi * (f0 * t + 0.5 * (f1 - f0) / duration * t**2)
    return mid + np.clip(t, 0.0, 1.0) * amp * np.sin(phase) * (1.0 - 0.5 * t / duration)


def steps(duration: float = 20.0, seed: int = 5) -> np.ndarray:
    """Steps to random positions in 40…260 mm, one a second, from 150 mm; at 1 kHz."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(duration * LOG_HZ)) / LOG_HZ
    levels = np.concatenate([[0.15], rng.uniform(0.04, 0.26, int(duration))])
    return levels[np.minimum(t.astype(int), levels.size - 1)]


def sine(duration: float = 20.0, f: float = 0.5, mid: float = 0.15, amp: float = 0.08) -> np.ndarray:
    """A sine of ``amp`` [m] at ``f`` [Hz] about ``mid``, faded in over 1 s; at 1 kHz."""
    t = np.arange(int(duration * LOG_HZ)) / LOG_HZ
    return mid + np.clip(t, 0.0, 1.0) * amp * np.sin(2 * np.pi * f * t)
