"""The seed's single actuator written independently of hexsim (no hexsim import): the "real machine" of the
calibrate-then-validate tests on the 3-way valve. Its own equations, integrated by Dormand-Prince 5(4)
under an error control (numba; held to RK4 at 1 µs by tests/test_truths.py):

- spool x_v = (u - u_0) / u_max * x_max (ideal, seed eq. 3.2), or following it as a second-order loop,
  behind a backlash of half width ``play`` [V] on the setpoint; the opening of each edge by ``area``:
  "sharp" pi d max(|x_v| - O_l, 0) (3.3), "quadratic" k_a x_v^2 (3.11 everywhere, as the seed's own
  simulations), "port" min(k_a x_v^2, pi d max(|x_v| - O_l, 0)) (a real spool: the smooth opening until
  the port limits it, with a kink where hexsim blends C¹), or "spool" (none of hexsim's forms: a port of
  ``port_width`` x pi d with a smooth underlap, w s ln(1 + exp((x_v + underlap) / s)) per edge, both edges
  open around null, saturating smoothly where the port is uncovered at ``port_open`` x x_max);
- each edge q = k C_d a sqrt(2 / rho) dp / sqrt(|dp| + 2 kPa) (turbulent; laminar below ~2 kPa, another
  regularisation than hexsim's); a leak C_l (P_s - P1) across the piston into the cap side;
- dP1/dt = E / (A1 y + V_pl) (phi_1 + leak - A1 ydot) (3.7), P1 kept above -0.9 bar; with entrained air
  the oil's and the air's compliances in series, the air's volume polytropic in the absolute pressure;
- a supply that sags through a resistance with the flow drawn (supply edge, leak, rod side), first order;
  or a pressure-compensated pump (its flow limited, turned back over a band below the set pressure) into an
  accumulator, which sags only where the flow drawn exceeds the pump's;
- M yddot = P1 A1 - P_s A2 - F_f(ydot) - M g cos(inclination) (3.8) with the Stribeck curve (3.9, arctan as
  published), stiff end stops outside 0 … L;
- a P controller at 500 Hz on the noisy position (valve saturated at ±10 V), the seed's faded-in sine (3.10)
  as the reference; logged at 1 kHz: position, P1, P_s (its set value; with a sagging supply as a
  transducer reads it), the accelerometer along the axis as the mean specific force over each sample
  interval (Δv/Δt + g cos(inclination)), with noise; the position transducer may lag (y(t - delay)).
"""

from __future__ import annotations

import json
import math
import pathlib
from dataclasses import dataclass, replace

import numba
import numpy as np


@dataclass(frozen=True)
class Actuator:
    bore: float = 0.04
    rod: float = 0.03
    stroke: float = 0.2
    supply: float = 70e5
    tank: float = 0.0
    x_max: float = 1.1e-3
    u_max: float = 10.0
    spool_d: float = 0.01
    area_gain: float = 300.0
    overlap: float = 5e-6
    null_offset: float = 0.0
    area: str = "port"  # "sharp" | "quadratic" | "port" | "spool"
    port_width: float = 0.8  # "spool": the port's width as a fraction of the full perimeter pi d
    underlap: float = 8e-6  # "spool": [m] each edge opens this far before null
    rounding: float = 10e-6  # "spool": [m] the edges' rounding (the softplus's width)
    port_open: float = 0.85  # "spool": the port is uncovered at this fraction of x_max
    flow_gain: float = 1.0  # both edges
    k_at: float = 1.0  # the return edge relative to the supply edge
    cd: float = 0.611
    rho: float = 860.0
    bulk: float = 1.5e9
    v_pl: float = 5e-7
    leak: float = 0.0
    mass: float = 40.0
    viscous: tuple[float, float] = (2200.0, 1800.0)
    coulomb: tuple[float, float] = (65.0, 60.0)
    static: tuple[float, float] = (30.0, 30.0)
    c_s: tuple[float, float] = (0.005, 0.005)
    arctan_k: float = 100.0
    kp: float = 200.0
    spool_hz: float = 0.0  # natural frequency of the spool's position loop (0: ideal, eq. 3.2)
    spool_zeta: float = 0.7
    sensor_delay: float = 0.0  # [s] the position transducer shows y(t - delay)
    play: float = 0.0  # [V] half width of a backlash between the valve setpoint and the spool's
    air: float = 0.0  # volume fraction of undissolved air at atmospheric pressure in the oil
    air_n: float = 1.4  # its polytropic exponent
    supply_resistance: float = 0.0  # [Pa s/m^3] the supply pressure's sag per unit of flow drawn (0: stiff)
    supply_tau: float = 0.02  # [s] the pump and accumulator's time constant of that sag
    # a pressure-compensated pump instead (pump_flow > 0): it delivers pump_flow [m^3/s] at most, its
    # displacement turned back in proportion over the last pump_band [Pa] below the set pressure, into an
    # accumulator of capacitance accumulator [m^3/Pa] that the actuator draws from
    pump_flow: float = 0.0
    pump_band: float = 3e5
    accumulator: float = 5e-11
    inclination_deg: float = 0.0  # the cylinder's axis from vertical
    # a machine that drifts during the run: the valve's null moves at null_rate [V/s]; the oil warms at
    # warm_rate [K/s], its viscosity (the viscous friction) falling as exp(-0.045 dT) (ISO VG 46 between
    # 40 and 50 °C: 46 -> 30 mm^2/s) and its density as 1 - 7e-4 dT
    null_rate: float = 0.0
    warm_rate: float = 0.0

    def replace(self, **kw) -> "Actuator":
        return replace(self, **kw)


def _pack(s: Actuator) -> np.ndarray:
    a1 = math.pi / 4 * s.bore**2
    return np.array([a1, a1 - math.pi / 4 * s.rod**2, s.stroke, s.supply, s.tank, s.x_max, s.u_max, s.spool_d,
                     s.area_gain, s.overlap, s.null_offset, {"sharp": 0.0, "quadratic": 1.0, "port": 2.0, "spool": 3.0}[s.area],
                     s.flow_gain, s.k_at, s.cd, s.rho, s.bulk, s.v_pl, s.leak, s.mass, *s.viscous, *s.coulomb,
                     *s.static, *s.c_s, s.arctan_k, 2 * math.pi * s.spool_hz, s.spool_zeta, s.air, s.air_n,
                     s.supply_resistance, s.supply_tau, math.cos(math.radians(s.inclination_deg)),
                     s.pump_flow, s.pump_band, s.accumulator, s.port_width * math.pi * s.spool_d, s.underlap,
                     s.rounding, s.port_open * s.x_max])


@numba.njit(cache=True)
def spool_edge(c, x):
    """The opening [m^2] of an edge of the "spool" valve at spool position x [m] (positive opens it)."""
    w, lap, s, x_open = c[39], c[40], c[41], c[42]
    z = (x + lap) / s
    e = w * s * (z + math.log1p(math.exp(-z)) if z > 0 else math.log1p(math.exp(z)))
    return e / (1.0 + (e / (w * x_open)) ** 4) ** 0.25


@numba.njit(cache=True)
def _rhs(y, v, p1, xv, vv, ps, u, c):
    """The state's derivatives (ẏ, v̇, Ṗ1, ẋ_v, v̇_v, Ṗ_s) as a tuple (no array)."""
    m = c[19]
    x_set = (u - c[10]) / c[6] * c[5]
    w = c[29]
    if w > 0:  # second-order spool loop
        x, dxv, dvv = xv, vv, w * w * (x_set - xv) - 2.0 * c[30] * w * vv
    else:
        x, dxv, dvv = x_set, 0.0, 0.0
    dp1, force, drawn = leg_at(c, y, v, p1, x, ps)
    if c[36] > 0:  # pressure-compensated pump into an accumulator
        dps = (c[36] * min(max((c[3] - ps) / c[37], 0.0), 1.0) - drawn) / c[38]
    else:
        dps = (c[3] - c[33] * drawn - ps) / c[34] if c[33] > 0 else 0.0
    return v, (force - m * 9.81 * c[35]) / m, dp1, dxv, dvv, dps


@numba.njit(cache=True)
def leg_at(c, y, v, p1, x, ps):
    """(dP1/dt [Pa/s], the force on the load [N]: pressures, friction and end stops, the flow drawn from the
    supply [m^3/s]: the supply edge, the leak and the rod side's displacement, connected to the supply) of
    one cylinder ``c`` (:func:`_pack`) at piston position y, velocity v, cap pressure p1, spool position x
    and supply pressure ps [Pa]."""
    a1, a2, stroke, _, pt, x_max, u_max, d, ka, ol, u0, form, kq, kat, cd, rho, bulk, vpl, leak, m = c[:20]
    port = math.pi * d * max(abs(x) - ol, 0.0)
    smooth = ka * x * x
    a = port if form == 0.0 else (smooth if form == 1.0 else min(smooth, port))
    orifice = cd * a * math.sqrt(2.0 / rho)
    phi_in = 0.0
    if form == 3.0:  # both edges open around null
        dps, dpt = ps - p1, p1 - pt
        phi_in = kq * cd * spool_edge(c, x) * math.sqrt(2.0 / rho) * dps / math.sqrt(abs(dps) + 2e3)
        phi = phi_in - kq * kat * cd * spool_edge(c, -x) * math.sqrt(2.0 / rho) * dpt / math.sqrt(abs(dpt) + 2e3)
    elif x > 0:
        dp = ps - p1
        phi = kq * orifice * dp / math.sqrt(abs(dp) + 2e3)
    else:
        dp = p1 - pt
        phi = -kq * kat * orifice * dp / math.sqrt(abs(dp) + 2e3)
    if c[31] > 0:  # entrained air: oil and air volumes compressed in series, the air polytropically
        pa = max(p1 + 1.01325e5, 1e3)
        ratio = c[31] * (1.01325e5 / pa) ** (1.0 / c[32])  # air volume per oil volume at pa
        bulk = (1.0 + ratio) / (1.0 / bulk + ratio / (c[32] * pa))
    dp1 = bulk / (a1 * max(y, 0.0) + vpl) * (phi + leak * (ps - p1) - a1 * v)
    if p1 < -0.9e5 and dp1 < 0:
        dp1 = 0.0
    i = 0 if v >= 0 else 1
    friction = c[20 + i] * v + math.atan(c[28] * v) * (c[22 + i] + c[24 + i] * math.exp(-abs(v) / c[26 + i]))
    stop = 0.0
    if y < 0:
        stop = -2e8 * y - 2e4 * v
    elif y > stroke:
        stop = -2e8 * (y - stroke) - 2e4 * v
    drawn = phi_in if form == 3.0 else (phi if x > 0 else 0.0)
    return dp1, p1 * a1 - ps * a2 - friction + stop, drawn + leak * (ps - p1) - a2 * v


@numba.njit(cache=True)
def _advance_rk4(z, u, c, h, n):
    """n classical Runge-Kutta steps of h [s] with the valve setpoint u held (the state z (6,) in, a new array
    out; scalars in between): the fixed-step reference tests/test_truths.py holds :func:`_advance` to."""
    y, v, p1, xv, vv, ps = z[0], z[1], z[2], z[3], z[4], z[5]
    for _ in range(n):
        a1, a2, a3, a4, a5, a6 = _rhs(y, v, p1, xv, vv, ps, u, c)
        g = 0.5 * h
        b1, b2, b3, b4, b5, b6 = _rhs(y + g * a1, v + g * a2, p1 + g * a3, xv + g * a4, vv + g * a5, ps + g * a6, u, c)
        c1, c2, c3, c4, c5, c6 = _rhs(y + g * b1, v + g * b2, p1 + g * b3, xv + g * b4, vv + g * b5, ps + g * b6, u, c)
        d1, d2, d3, d4, d5, d6 = _rhs(y + h * c1, v + h * c2, p1 + h * c3, xv + h * c4, vv + h * c5, ps + h * c6, u, c)
        k = h / 6.0
        y += k * (a1 + 2 * b1 + 2 * c1 + d1)
        v += k * (a2 + 2 * b2 + 2 * c2 + d2)
        p1 += k * (a3 + 2 * b3 + 2 * c3 + d3)
        xv += k * (a4 + 2 * b4 + 2 * c4 + d4)
        vv += k * (a5 + 2 * b5 + 2 * c5 + d5)
        ps += k * (a6 + 2 * b6 + 2 * c6 + d6)
    return np.array([y, v, p1, xv, vv, ps])


# Dormand & Prince's RK5(4)7M (J. Comput. Appl. Math. 6, 1980; Hairer, Norsett & Wanner, Solving ODEs I, II.5):
# the stages' coefficients A (row i: stage i+1 from stages 1..i; its last row the 5th-order weights B, so the last
# stage is the next step's first) and B minus the embedded 4th-order weights, E (the local error's estimate).
_DP_A = np.array([[0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                  [1 / 5, 0.0, 0.0, 0.0, 0.0, 0.0],
                  [3 / 40, 9 / 40, 0.0, 0.0, 0.0, 0.0],
                  [44 / 45, -56 / 15, 32 / 9, 0.0, 0.0, 0.0],
                  [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0.0, 0.0],
                  [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656, 0.0],
                  [35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84]])
_DP_E = np.array([71 / 57600, 0.0, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40])
#: The absolute tolerances of the state (y [m], v [m/s], P1 [Pa], x_v [m], v_v [m/s], P_s [Pa]): v to 1e-9 m/s, so
#: the logged acceleration (v's change over a millisecond) is 1e-6 m/s^2 off at most per step, far below the
#: 0.02 m/s^2 of accelerometer noise and the 1e-3 m/s^2 of the smallest compensated reversal bump; P1 to 1 Pa
#: (a transducer's noise is 2 kPa). Relative tolerance 1e-8 on top.
_ATOL = np.array([1e-10, 1e-9, 1.0, 1e-10, 1e-7, 1.0])
_RTOL = 1e-8


@numba.njit(cache=True)
def _advance(z, u, c, span, h):
    """Integrate over ``span`` [s] with the valve setpoint u held, by Dormand-Prince 5(4) with local
    extrapolation and the step controlled to :data:`_ATOL`/:data:`_RTOL` (the step stays small where the
    chamber is stiff: a wide-open valve near the supply pressure, a short oil column), starting with the step
    h [s]. Returns (the state (6,), the step to start the next span with); a state that cannot be advanced
    (the step below 1e-12 s) comes back NaN."""
    z = z.copy()
    k = np.empty((7, 6))
    zt = np.empty(6)
    t = 0.0
    k[0, :] = _rhs(z[0], z[1], z[2], z[3], z[4], z[5], u, c)
    while t < span:
        step = min(h, span - t)
        last = step < h
        for i in range(1, 7):
            for j in range(6):
                acc = 0.0
                for m in range(i):
                    acc += _DP_A[i, m] * k[m, j]
                zt[j] = z[j] + step * acc
            k[i, :] = _rhs(zt[0], zt[1], zt[2], zt[3], zt[4], zt[5], u, c)
        err = 0.0
        for j in range(6):  # zt is the 5th-order solution (the last stage's point: B is A's last row)
            e = 0.0
            for m in range(7):
                e += _DP_E[m] * k[m, j]
            err = max(err, abs(step * e) / (_ATOL[j] + _RTOL * max(abs(z[j]), abs(zt[j]))))
        if not math.isfinite(err):
            err = 1e10
        factor = min(5.0, max(0.2, 0.9 * err ** -0.2)) if err > 0 else 5.0
        if err <= 1.0:
            t += step
            z[:] = zt
            k[0, :] = k[6, :]  # first same as last
            if not last:
                h = min(step * factor, 1e-4)
        else:
            h = step * factor
            if h < 1e-12:
                z[:] = np.nan
                return z, h
    return z, h


def _drifted(c0: np.ndarray, s: Actuator, t: float) -> np.ndarray:
    """The packed cylinder at time t [s] of a drifting run (null, viscosity, density)."""
    c = c0.copy()
    warm = s.warm_rate * t
    c[10] = s.null_offset + s.null_rate * t
    c[15] = s.rho * (1.0 - 7e-4 * warm)
    c[20:22] = np.asarray(s.viscous) * math.exp(-0.045 * warm)
    return c


def motion(s: Actuator, duration: float, frequency: float, amplitude: float, rng: np.random.Generator,
           noise: tuple[float, float, float] = (2e-6, 2e3, 0.02), compensate=None,
           reference: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """A closed-loop run of ``duration`` s tracking amplitude sin(2 pi f t) faded in over one period around
    mid-stroke (seed eq. 3.10), or ``reference`` [m] (one setpoint a millisecond: a chirp, steps; frequency and
    amplitude then unused): the log's columns at 1 kHz, noise (position m, pressure Pa, acceleration
    m/s^2) on the measured channels (the controller sees the noisy position). Integrated by :func:`_advance`.
    ``compensate(u_p, y, r, r_dot, r_ddot, r_dddot, p1) -> U_c`` [V], called at each controller sample with
    the P output, the measured position, the reference and its derivatives (central differences at the
    controller rate) and the measured cap pressure, adds U_c to the valve setpoint (before saturation);
    its sum is logged as ``comp_V``."""
    c0 = c = _pack(s)
    a1, a2 = c[0], c[1]
    g = 9.81
    dt = 1e-3
    t = np.arange(0.0, duration, dt)
    if reference is not None:
        ref = np.asarray(reference, dtype=float)[:len(t)]
    else:
        period = 1.0 / frequency
        ref = s.stroke / 2 + amplitude * np.sin(2 * np.pi * frequency * t) * np.clip(t / period, 0.0, 1.0)
    g_axis = g * math.cos(math.radians(s.inclination_deg))  # gravity along the cylinder's axis
    z = np.array([s.stroke / 2, 0.0, (s.supply * a2 + s.mass * g_axis) / a1, -s.null_offset / s.u_max * s.x_max,
                  0.0, s.supply])
    out = {k: np.empty(len(t)) for k in ("pos", "p1", "u", "acc", "ps", "uc")}
    y_meas = rng.normal(0.0, noise[0], len(t))
    p1_noise = rng.normal(0.0, noise[1], len(t))
    derivatives = [np.gradient(ref[::2], 2 * dt)]
    for _ in range(2):
        derivatives.append(np.gradient(derivatives[-1], 2 * dt))
    u = spool_u = u_c = 0.0
    v_prev = 0.0
    h = 1e-6
    for j in range(len(t)):
        out["pos"][j] = z[0]
        y_meas[j] += float(np.interp(t[j] - s.sensor_delay, t[:j + 1], out["pos"][:j + 1])) if s.sensor_delay else z[0]
        if j % 2 == 0:  # the 500 Hz controller on the measured position
            if s.null_rate or s.warm_rate:
                c = _drifted(c0, s, t[j])
            u_p = s.kp * (ref[j] - y_meas[j])
            if compensate is not None:
                d1, d2, d3 = (d[j // 2] for d in derivatives)
                u_c = float(compensate(u_p, y_meas[j], ref[j], d1, d2, d3, z[2] + p1_noise[j]))
            u = float(np.clip(u_p + u_c, -s.u_max, s.u_max))
            spool_u = min(max(spool_u, u - s.play), u + s.play)  # the play operator (backlash)
        out["p1"][j], out["u"][j], out["ps"][j], out["uc"][j] = z[2], u, z[5], u_c
        out["acc"][j] = (z[1] - v_prev) / dt + g_axis if j else g_axis
        v_prev = z[1]
        z, h = _advance(z, spool_u, c, dt, h)
        assert np.all(np.isfinite(z)), f"non-finite state at t = {t[j]:.3f} s"
    p1 = out["p1"] + p1_noise
    acc = out["acc"] + rng.normal(0.0, noise[2], len(t))
    sags = s.supply_resistance > 0 or s.pump_flow > 0
    ps = out["ps"] + rng.normal(0.0, noise[1], len(t)) if sags else out["ps"]
    columns = {"time_s": t, "ref_m": ref, "valve_cmd_V": out["u"], "pos_m": y_meas, "p1_Pa": p1, "ps_Pa": ps,
               "acc_mps2": acc}
    if compensate is not None:
        columns["comp_V"] = out["uc"]
    return columns


def write(columns: dict[str, np.ndarray], path: pathlib.Path, description: str, kp: float = 200.0,
          system: str = "single-actuator") -> pathlib.Path:
    """The measurement-log CSV + sidecar (docs/measurement-log.md) of ``columns``, written by numpy."""
    names = list(columns)
    np.savetxt(path, np.column_stack([columns[k] for k in names]), delimiter=",", header=",".join(names),
               comments="", fmt="%.10g")
    path.with_suffix(".json").write_text(json.dumps({
        "system": system, "sample_rate_hz": 1000.0,
        "controller": {"type": "P", "kp_V_per_m": kp, "rate_hz": 500.0}, "description": description}))
    return path
