"""The steady evidence of calibration experiments: open-loop runs at constant valve commands in both directions
and at several commands (as the real servo cylinder's 1, 3 and 5 V runs, ``examples/data/servo_cylinder``),
read as features and predicted by the machine file (:mod:`hexsim.measured.calibration` fits them).

**Features** (:func:`features`, measured on each log with the same functions a simulated run is read
with): every stretch of constant command (|u_v| > 0.05 V) gives

* a *steady motion* in the middle of the stroke (:func:`hexsim.studies.metrics.steady_segments`): the
  speed and the median of each logged chamber pressure (p1, p2; ps if logged);
* an *end-stop plateau* where the command holds the piston against a stop: the chamber the valve
  connects to the supply reads P_s, the other the tank (4-way valve; the 3-way valve's cap side reads
  P_s or the tank).

**Model** (:func:`predict`): the steady motion of the machine file at that command against the load
along the axis (:func:`hexsim.plant.hydraulics.steady_state`: flow continuity in each chamber, seed eq.
3.4/3.7 with dP/dt = 0, and the piston's force balance, eq. 3.8 with the friction of eq. 3.9); at an
end stop P_s and P_t.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from hexsim.errors import InputError
from hexsim.measured.measurement import MeasurementLog
from hexsim.plant import hydraulics
from hexsim.plant.machine import Machine
from hexsim.plant.model import gravity
from hexsim.studies.metrics import steady_segments

#: Weight of a steady speed: 1 % of it plus 0.5 mm/s (a line fit over a stretch of 1 kHz positions is far
#: more precise; the weight says how closely the steady model is asked to follow, not the sensor).
SPEED_SIGMA_REL = 0.01
SPEED_SIGMA_ABS = 5e-4
#: Weight of a median pressure [Pa]: 0.3 bar (the real rig's transducer noise; offsets of that size are common).
PRESSURE_SIGMA = 3e4
#: End-stop plateau: the last share of a stretch, slower than END_SPEED [m/s], its median within END_MARGIN_M
#: [m] of the observed end of the travel.
END_SHARE, END_SPEED, END_MARGIN_M = 0.4, 1e-3, 2e-3
@dataclass(frozen=True)
class Feature:
    """One measured quantity of a calibration experiment: which log, the stretch's command u_V [V] and
    time span, ``kind`` ("steady" or "end stop"), ``quantity`` ("velocity", "p1", "p2", "ps"), the measured
    value (m/s or Pa) and its weight ``sigma`` (same unit)."""

    log: str
    kind: str
    u_V: float
    t_start_s: float
    t_end_s: float
    quantity: str
    measured: float
    sigma: float


_PRESSURES = (("p1", "p1_Pa"), ("p2", "p2_Pa"), ("ps", "ps_Pa"))


def features(log: MeasurementLog) -> list[Feature]:
    """The calibration features of an open-loop constant-command log (module doc). Raises InputError for a
    log without a valve command or without a stretch of constant command that moves the piston."""
    if log.system != "single-actuator":
        raise InputError(f"{log.path}: calibration reads single-actuator logs (this is {log.system})")
    c = log.columns
    t, u, y = log.time, c["valve_cmd_V"], c["pos_m"]
    pressures = {name: c[col] for name, col in _PRESSURES if col in c}
    name = log.path.name
    out = []
    for row in steady_segments(t, u, y, pressures):
        v = row["velocity_mps"]
        out.append(Feature(name, "steady", row["u_V"], row["t_start_s"], row["t_end_s"], "velocity", v,
                           SPEED_SIGMA_REL * abs(v) + SPEED_SIGMA_ABS))
        out += [Feature(name, "steady", row["u_V"], row["t_start_s"], row["t_end_s"], q, row[q], PRESSURE_SIGMA)
                for q in pressures]
    lo, hi = float(np.min(y)), float(np.max(y))
    change = np.flatnonzero(np.diff(u) != 0) + 1
    bounds = np.concatenate([[0], change, [len(t)]])
    fs = log.sample_rate_hz
    for a, b in zip(bounds[:-1], bounds[1:]):
        if abs(u[a]) <= 0.05 or b - a < 0.2 * fs:
            continue
        tail = np.arange(int(b - END_SHARE * (b - a)), b)
        stop = hi if u[a] > 0 else lo
        speed = abs(np.polynomial.polynomial.polyfit(t[tail], y[tail], 1)[1])
        if speed > END_SPEED or abs(float(np.median(y[tail])) - stop) > END_MARGIN_M:
            continue
        out += [Feature(name, "end stop", float(u[a]), float(t[tail[0]]), float(t[tail[-1]]), q,
                        float(np.median(p[tail])), PRESSURE_SIGMA) for q, p in pressures.items()]
    if not any(f.kind == "steady" for f in out):
        raise InputError(f"{log.path}: no stretch of constant valve command moves the piston through mid-stroke; "
                         f"calibration needs open-loop runs at constant commands (docs/calibration.md)")
    return out


def axis_load(log: MeasurementLog) -> tuple[float | None, float]:
    """(the moving mass the log's sidecar declares [kg] or None, g cos(inclination) along its axis
    [m/s^2]): what :func:`predict` needs of a log to compute the weight the piston lifts."""
    return log.mass_kg, gravity() * math.cos(math.radians(log.inclination_deg))


def load_force(machine: Machine, load: tuple[float | None, float]) -> float:
    """M g cos(inclination) [N] with M the mass the log declares (that experiment's stated condition),
    else the machine's (the one being calibrated), else the model's."""
    declared, g_axis = load
    return (declared if declared is not None else machine.moving_mass_kg) * g_axis


def predict(feats: list[Feature], machine: Machine, loads: dict[str, float]) -> np.ndarray:
    """The model's value of each feature (same order, same units) on ``machine``; ``loads``: each log's
    :func:`axis_load` (the weight along the axis is the machine's mass on it). A stretch the valve cannot move against its load predicts
    no motion (velocity 0, pressures at their limits)."""
    hyd, eff = machine.hydraulics, machine.effects
    cache: dict[tuple[str, float], hydraulics.SteadyState | None] = {}
    out = np.empty(len(feats))
    for i, f in enumerate(feats):
        if f.kind == "end stop":
            feeds = "p1" if f.u_V > 0 else "p2"
            if f.quantity == "ps":
                out[i] = hyd.supply_pressure
            elif not hyd.four_way:
                out[i] = hyd.supply_pressure if f.u_V > 0 else hyd.tank_pressure
            else:
                out[i] = hyd.supply_pressure if f.quantity == feeds else hyd.tank_pressure
            continue
        key = (f.log, f.u_V)
        if key not in cache:
            try:
                cache[key] = hydraulics.steady_state(f.u_V, load_force(machine, loads[f.log]), hyd, eff=eff)
            except ValueError:
                cache[key] = None
        s = cache[key]
        if s is None:
            out[i] = 0.0 if f.quantity == "velocity" else hyd.supply_pressure
        else:
            out[i] = {"velocity": s.velocity, "p1": s.p1, "p2": s.p2, "ps": hyd.supply_pressure}[f.quantity]
    return out


def steady_residual(feats: list[Feature], loads: dict) -> Callable[[Machine], np.ndarray]:
    """The weighted residual (predicted - measured) / sigma of the steady ``feats`` as a function of the machine."""
    measured = np.array([f.measured for f in feats])
    sigma = np.array([f.sigma for f in feats])
    return lambda m: (predict(feats, m, loads) - measured) / sigma


def feature_errors(feats: list[Feature], predicted: np.ndarray) -> dict:
    """Speed errors (relative) and pressure errors [Pa] of predictions against the features."""
    speed = [abs(p / f.measured - 1.0) for f, p in zip(feats, predicted) if f.quantity == "velocity" and f.measured]
    press = [abs(p - f.measured) for f, p in zip(feats, predicted) if f.quantity != "velocity"]
    return {"speeds": len(speed), "speed_error_mean": float(np.mean(speed)) if speed else None,
            "speed_error_max": float(np.max(speed)) if speed else None, "pressures": len(press),
            "pressure_error_mean_Pa": float(np.mean(press)) if press else None,
            "pressure_error_max_Pa": float(np.max(press)) if press else None}
