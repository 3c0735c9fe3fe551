"""A 4-way valve-controlled differential cylinder written independently of hexsim (no hexsim import): the
"real machine" of the calibration tests. Its own equations, integrated by scipy's stiff solver:

- spool x_v = (u - u_0) / u_max * x_max (an ideal spool); openings a = w max(|x_v| - O_l, 0) on the side x_v opens;
- each control edge: q = k C_d a sqrt(2 / rho) dp / sqrt(|dp| + 2 kPa) (turbulent, laminar only below ~2 kPa:
  another regularisation than hexsim's, whose laminar range reaches 0.1 bar);
- chambers: dp1/dt = E / (A1 y + V_A) (q_PA - q_AT + q_L - A1 v), dp2/dt = E / (A2 (L - y) + V_B) (q_PB - q_BT
  - q_L + A2 v), q_L = C_L (p2 - p1) the leakage across the piston seal; pressures kept above -0.9 bar;
- piston: M dv/dt = p1 A1 - p2 A2 - F_c± tanh(v / 1 mm/s) - M g cos(inclination) + end stops (stiff springs
  with damping at 0 and L);
- logs in the measurement-log format written by numpy (time_s, valve_cmd_V, pos_m, p1_Pa, p2_Pa), with noise.
"""

from __future__ import annotations

import json
import math
import pathlib
from dataclasses import dataclass, replace

import numpy as np
from scipy.integrate import solve_ivp


@dataclass(frozen=True)
class Rig:
    bore: float = 0.016
    rod: float = 0.010
    stroke: float = 0.2
    supply: float = 44.5e5
    tank: float = 0.0
    rated_flow: float = 1.05e-4  # per edge at 35 bar and full command
    x_max: float = 1.1e-3
    overlap: float = 1.2e-5
    null_offset: float = 0.0
    k_pa: float = 1.0
    k_at: float = 1.0
    k_pb: float = 1.0
    k_bt: float = 1.0
    cd: float = math.pi / (math.pi + 2)
    rho: float = 860.0
    bulk: float = 1.5e9
    v_a: float = 2e-5
    v_b: float = 2e-5
    coulomb_pos: float = 66.7
    coulomb_neg: float = 76.1
    mass: float = 1.0
    inclination_deg: float = 90.0
    leakage: float = 0.0  # C_L [m^3/(s Pa)] across the piston seal, from the rod side to the cap side
    # a valve whose opening is not linear in the command: (|u| V, fraction of the full opening) points,
    # interpolated from (0, 0); None: linear beyond the overlap
    curve: tuple[tuple[float, float], ...] | None = None

    def replace(self, **kw) -> "Rig":
        return replace(self, **kw)

    @property
    def width(self) -> float:
        """Port width w [m] of the rated flow (its definition: Q_N through one edge at 35 bar, full stroke)."""
        return self.rated_flow / (self.cd * (self.x_max - self.overlap) * math.sqrt(2 * 35e5 / self.rho))


def _edge(k, cd, a, dp, rho):
    """Turbulent orifice flow, made laminar below ~2 kPa by dp / sqrt(|dp| + 2 kPa) (this plant's own
    regularisation; sqrt(|dp|) has an infinite slope at 0 that stalls a stiff solver)."""
    return k * cd * a * math.sqrt(2.0 / rho) * dp / math.sqrt(abs(dp) + 2e3)


def simulate(rig: Rig, t: np.ndarray, u: np.ndarray, y0: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions, p1, p2 (each like t) under the command u (held between samples) from rest at y0."""
    a1 = math.pi / 4 * rig.bore**2
    a2 = math.pi / 4 * (rig.bore**2 - rig.rod**2)
    g = 9.81 * math.cos(math.radians(rig.inclination_deg))
    w = rig.width

    def rhs(time, s, cmd):
        y, v, p1, p2 = s
        x = (cmd - rig.null_offset) / 10.0 * rig.x_max
        if rig.curve is None:
            open_pos = w * max(x - rig.overlap, 0.0)  # P->A and B->T
            open_neg = w * max(-x - rig.overlap, 0.0)  # A->T and P->B
        else:
            full = w * (rig.x_max - rig.overlap) * float(np.interp(abs(x) / rig.x_max * 10.0, curve_u, curve_f))
            open_pos, open_neg = (full, 0.0) if x > 0 else (0.0, full)
        q_a = _edge(rig.k_pa, rig.cd, open_pos, rig.supply - p1, rig.rho) - _edge(rig.k_at, rig.cd, open_neg, p1 - rig.tank, rig.rho)
        q_b = _edge(rig.k_pb, rig.cd, open_neg, rig.supply - p2, rig.rho) - _edge(rig.k_bt, rig.cd, open_pos, p2 - rig.tank, rig.rho)
        q_leak = rig.leakage * (p2 - p1)
        dp1 = rig.bulk / (a1 * max(y, 0.0) + rig.v_a) * (q_a + q_leak - a1 * v)
        dp2 = rig.bulk / (a2 * max(rig.stroke - y, 0.0) + rig.v_b) * (q_b - q_leak + a2 * v)
        if p1 < -0.9e5 and dp1 < 0:
            dp1 = 0.0
        if p2 < -0.9e5 and dp2 < 0:
            dp2 = 0.0
        friction = (rig.coulomb_pos if v >= 0 else rig.coulomb_neg) * math.tanh(v / 1e-3)
        stop = 0.0
        if y < 0.0:
            stop = -2e7 * y - 4e3 * v
        elif y > rig.stroke:
            stop = -2e7 * (y - rig.stroke) - 4e3 * v
        dv = (p1 * a1 - p2 * a2 - friction - rig.mass * g + stop) / rig.mass
        return [v, dv, dp1, dp2]

    load = rig.mass * g
    if rig.curve is not None:
        curve_u = [0.0, *(u for u, _ in rig.curve)]
        curve_f = [0.0, *(f for _, f in rig.curve)]
    p2_0 = ((rig.supply + rig.tank) * a1 - load) / (a1 + a2)
    state = [y0, 0.0, rig.supply + rig.tank - p2_0, p2_0]
    out = np.empty((4, len(t)))
    switch = np.concatenate([[0], np.flatnonzero(np.diff(u) != 0) + 1, [len(t)]])
    for a, b in zip(switch[:-1], switch[1:]):  # each constant command on its own: no step across a switch
        end = t[b] if b < len(t) else t[-1]
        sol = solve_ivp(rhs, (t[a], end), state, t_eval=t[a:b], args=(float(u[a]),), method="LSODA", rtol=1e-6,
                        atol=[1e-9, 1e-7, 1.0, 1.0], dense_output=True)
        assert sol.success, sol.message
        out[:, a:b] = sol.y
        state = sol.sol(end)
    return out[0], out[2], out[3]


def experiment(rig: Rig, volts: float | tuple[float, ...], folder: pathlib.Path, name: str,
               rng: np.random.Generator) -> pathlib.Path:
    """The real rig's calibration experiment at ``volts``: 0 V for 0.1 s, +U until the piston has rested
    at the far stop for 0.6 s, -U likewise (several U: one after the other), logged at 1 kHz with 0.3 mm and
    0.3 bar of noise."""
    a1 = math.pi / 4 * rig.bore**2
    levels = [0.0]
    for v in np.atleast_1d(volts):
        speed = 0.8 * (v / 10.0) * rig.width * rig.x_max * rig.cd * math.sqrt(2 * 30e5 / rig.rho) / a1
        hold = int(round((rig.stroke / speed + 0.6) * 1000))
        levels += [v] * hold + [-v] * hold
    u = np.repeat(np.array(levels), [100] + [1] * (len(levels) - 1))
    t = np.arange(u.size) * 1e-3
    y, p1, p2 = simulate(rig, t, u, 0.005)
    path = folder / f"{name}.csv"
    cols = np.column_stack([t, u, y + rng.normal(0, 3e-4, t.size), p1 + rng.normal(0, 3e4, t.size),
                            p2 + rng.normal(0, 3e4, t.size)])
    np.savetxt(path, cols, delimiter=",", header="time_s,valve_cmd_V,pos_m,p1_Pa,p2_Pa", comments="", fmt="%.9g")
    path.with_suffix(".json").write_text(json.dumps({
        "system": "single-actuator", "sample_rate_hz": 1000.0, "controller": {"type": "none"}, "valve": "4-way",
        "cylinder": {"bore_m": rig.bore, "rod_m": rig.rod, "stroke_m": rig.stroke},
        "description": f"independent 4-way cylinder, {' then '.join(f'{v:g}' for v in np.atleast_1d(volts))} V"}))
    return path
