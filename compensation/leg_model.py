"""The leg model a model-based compensator inverts, and what the motion computer hands it each sample.

A :class:`LegModel` is what a feedforward (:mod:`compensation.model_based`) knows of the machine, per leg: the
static flow curve u_v -> ẏ at the rest pressure (seed eq. 5.1; with an underlapped 3-way valve each edge's
share), the chamber's constants (seed eq. 3.7), the friction curve (seed eq. 3.9) and the legs' inertia. It
is built by hexsim from a machine file (:func:`hexsim.control.feedforward.leg_model`) or read from a tuned
file (``hexsim tune``; :data:`FILE_FORMAT`), never the simulator's truth; :func:`check_model` refuses one
whose inverse would give an extreme or unstable compensation. A :class:`Reference` is the piston setpoints
and their derivatives (and the measured p1) a compensator observes at each controller sample.
"""

from __future__ import annotations

import math
from dataclasses import MISSING, dataclass, fields
from typing import NamedTuple

import numpy as np

from compensation.settings import SettingsError

#: Version of the tuned-compensator file (:meth:`LegModel.to_dict`).
FILE_FORMAT = "hexsim-compensator/1"


class Reference(NamedTuple):
    """What the motion computer knows of each leg at a controller sample, arrays (n_legs,): the piston
    setpoint r [m] and its first three time derivatives [m/s, m/s², m/s³] (from the setpoint table by
    central differences: a one-sample preview, 2 ms at 500 Hz), and the measured bottom-chamber pressure
    p1 [Pa] where a pressure transducer is fitted (None otherwise)."""

    r: np.ndarray
    r_dot: np.ndarray
    r_ddot: np.ndarray
    r_dddot: np.ndarray
    p1: np.ndarray | None = None


@dataclass(frozen=True)
class LegModel:
    """The calibrated leg as a feedforward sees it, per leg i of n (what a tuned file holds).

    u: valve setpoints of the flow curve [V], (G,), increasing over ±u_v,max;
    velocity: the static flow curve F_i(u) [m/s] at the rest pressure, (n, G), non-decreasing
        (seed eq. 5.1; its overlap is the flat part around null);
    p_rest: the bottom-chamber pressure holding the leg's rest load [Pa], (n,);
    supply_pressure, tank_pressure: P_s, P_t [Pa] (seed app. A);
    area_bottom: A1 [m²]; bulk_modulus: E [Pa]; pipeline_volume: V_pl [m³] (seed eq. 3.7);
    mass: the legs' inertia matrix M [kg], (n, n): the leg forces that accelerate the legs by ÿ are M ÿ
        (the platform's inertia seen along the legs, coupled: a heave moves every leg);
    friction_v, friction_f: the friction curve F_f(ẏ) [m/s -> N] as a table, (F,) each (seed eq. 3.9);
    pressure_scaling: scale the flow curve to P1_ref by the orifice law (3-way valves; off for 4-way,
        whose two chambers share the load);
    slope: s_i, the linear curve's slope [m/(s V)], (n,): the machine's chord at ±u_ref;
    kp: K_p [V/m], the P gain the compensator runs beside (the machine file's controller; 0: unknown, the
        adaptive one reads it off the P output and the tracking error);
    source: where the model came from (machine file, tuned file);
    velocity_at: the return edge's (A→T) share of ``velocity`` [m/s], (n, G), >= 0, where the valve's two
        edges pass flow together (an underlapped or rounded 3-way spool: the curve at rest is the supply
        edge's flow less the return edge's, velocity = v_PA - v_AT); None (the default, and an overlapped
        spool's) where only one edge is open at a time. With it the inverse scales each edge by its own
        pressure drop (seed eq. 3.4 per edge), where without it the edge the target's sign opens is scaled.
    """

    u: np.ndarray
    velocity: np.ndarray
    p_rest: np.ndarray
    supply_pressure: float
    tank_pressure: float
    area_bottom: float
    bulk_modulus: float
    pipeline_volume: float
    mass: np.ndarray
    friction_v: np.ndarray
    friction_f: np.ndarray
    slope: np.ndarray
    pressure_scaling: bool = True
    kp: float = 0.0
    source: str = ""
    velocity_at: np.ndarray | None = None

    def __post_init__(self) -> None:
        check_model(self)

    @property
    def n_legs(self) -> int:
        return len(self.p_rest)

    def friction(self, v: np.ndarray) -> np.ndarray:
        """F_f(v) [N], v (n,) [m/s], from the table (held constant beyond its ends)."""
        return np.interp(v, self.friction_v, self.friction_f)

    def to_dict(self) -> dict:
        """The model as JSON-ready data (arrays as lists), :data:`FILE_FORMAT`."""
        out = {"format": FILE_FORMAT}
        for f in fields(self):
            value = getattr(self, f.name)
            out[f.name] = value.tolist() if isinstance(value, np.ndarray) else value
        return out

    @classmethod
    def from_dict(cls, doc: dict, where: str = "compensator file") -> "LegModel":
        """The model of :meth:`to_dict`. Raises SettingsError naming the missing or bad entry."""
        if not isinstance(doc, dict) or doc.get("format") != FILE_FORMAT:
            got = doc.get("format") if isinstance(doc, dict) else type(doc).__name__
            raise SettingsError(f"{where}: format must be {FILE_FORMAT!r}, got {got!r}")
        values = {}
        for f in fields(cls):
            if f.name not in doc:
                if f.default is not MISSING:
                    continue
                raise SettingsError(f"{where}: missing {f.name!r}")
            value = doc[f.name]
            if isinstance(value, list):
                try:
                    value = np.asarray(value, dtype=float)
                except (TypeError, ValueError):
                    raise SettingsError(f"{where}: {f.name} must be numbers") from None
            values[f.name] = value
        return cls(**values)


def check_model(m: LegModel) -> None:
    """Refuse a model whose inverse would give an extreme or unstable compensation, naming the leg and the
    reason: a flow curve that falls, does not cross zero, or whose dead band (the overlap seen from the
    flow curve) is wider than 2 V; a slope not positive; a rest pressure outside tank…supply; a negative
    mass, friction that does not oppose motion, a non-positive area or bulk modulus."""
    u, v = np.asarray(m.u, dtype=float), np.atleast_2d(np.asarray(m.velocity, dtype=float))
    n = len(np.atleast_1d(m.p_rest))
    if u.ndim != 1 or len(u) < 3 or np.any(np.diff(u) <= 0):
        raise SettingsError("flow curve: u must be at least 3 increasing valve setpoints [V]")
    if v.shape != (n, len(u)) or not np.all(np.isfinite(v)):
        raise SettingsError(f"flow curve: velocity must be finite, shape ({n}, {len(u)}), got {v.shape}")
    for name in ("area_bottom", "bulk_modulus"):
        if not (math.isfinite(getattr(m, name)) and getattr(m, name) > 0):
            raise SettingsError(f"{name} must be positive, got {getattr(m, name)!r}")
    if not m.supply_pressure > m.tank_pressure:
        raise SettingsError(f"supply pressure {m.supply_pressure:g} Pa must exceed the tank's {m.tank_pressure:g} Pa")
    for i in range(n):
        leg = f"leg{i + 1}"
        row = v[i]
        if np.any(np.diff(row) < -1e-9 * np.ptp(row)):
            k = int(np.argmin(np.diff(row)))
            raise SettingsError(f"{leg}: the flow curve falls at u_v = {u[k]:.3f} V: its inverse is not unique")
        if not (row[0] < 0 < row[-1]):
            raise SettingsError(f"{leg}: the flow curve does not cross zero velocity (from {row[0]:.3g} to "
                                f"{row[-1]:.3g} m/s): the valve cannot reverse the leg")
        band = u[np.abs(row) <= 1e-6 * max(abs(row[0]), row[-1])]
        if band.size and band[-1] - band[0] > 2.0:
            raise SettingsError(f"{leg}: the flow curve's dead band is {band[-1] - band[0]:.2f} V wide (more than "
                                "2 V): its inverse would jump the valve across it at every reversal")
        if not m.slope[i] > 0:
            raise SettingsError(f"{leg}: slope of the linear flow curve must be positive, got {m.slope[i]!r}")
        if not m.tank_pressure < m.p_rest[i] < m.supply_pressure:
            raise SettingsError(f"{leg}: rest pressure {m.p_rest[i] / 1e5:.1f} bar outside tank…supply")
        if m.mass.shape != (n, n) or not np.all(np.isfinite(m.mass)) or m.mass[i, i] < 0:
            raise SettingsError(f"{leg}: the inertia matrix must be finite, ({n}, {n}), with a non-negative "
                                f"diagonal, got shape {m.mass.shape}")
    fv, ff = np.asarray(m.friction_v), np.asarray(m.friction_f)
    if fv.shape != ff.shape or len(fv) < 2 or np.any(np.diff(fv) <= 0):
        raise SettingsError("friction table: friction_v must increase and match friction_f")
    if np.any(ff * fv < 0):
        raise SettingsError("friction table: friction must oppose the motion (F_f(v) v >= 0)")
    if m.velocity_at is not None:
        at = np.asarray(m.velocity_at, dtype=float)
        if at.shape != v.shape or not np.all(np.isfinite(at)) or np.any(at < 0):
            raise SettingsError(f"velocity_at (the return edge's share of the flow curve) must be finite, >= 0, "
                                f"shape {v.shape}, got shape {at.shape}")
        if not m.pressure_scaling:
            raise SettingsError("velocity_at is a 3-way valve's return edge; this model has no pressure scaling")


#: Share of the flow curve's largest speed above which an edge counts as open (:func:`open_together`).
OPEN_FRACTION = 1e-4


def open_together(velocity: np.ndarray, velocity_at: np.ndarray) -> np.ndarray:
    """Where both edges of a 3-way valve pass flow at rest, (n, G) bool: the supply edge's share (``velocity`` +
    ``velocity_at``) and the return edge's (``velocity_at``), each (n, G) [m/s], both above :data:`OPEN_FRACTION`
    of the leg's largest speed."""
    v = np.atleast_2d(velocity)
    return np.minimum(v + velocity_at, velocity_at) > OPEN_FRACTION * np.max(np.abs(v), axis=1, keepdims=True)


#: Largest error [m/s] of a flow curve's linear interpolation between the points of the grid an inverse reads it on
#: (:func:`refined_grid`). A feedforward that reads a curve 0.14 mm/s wrong for one 2 ms tick, where an
#: overlapped edge starts to open (its flow rises 0.44 mm/s within 3 mV), rang a calibrated Micro Motion System
#: actuator's oil column at 0.13 m/s^2 at every reversal on that side (docs/compensation.md, "Why `corner`'s
#: prediction was high"); 10 µm/s would ring it at some 0.01 m/s^2.
CURVE_TOLERANCE = 1e-5

#: Halvings :func:`refined_grid` may make of a grid's interval (5 mV / 2^12 = 1.2 µV).
REFINE_LEVELS = 12


def refined_grid(curve, u: np.ndarray, tolerance: float = CURVE_TOLERANCE,
                 levels: int = REFINE_LEVELS) -> tuple[np.ndarray, np.ndarray]:
    """A grid of valve setpoints on which a flow curve's linear interpolation holds to ``tolerance`` [m/s], and the
    curve on it: ``u`` [V] (G,) increasing, ``curve(u) -> (n, len(u))`` [m/s] (a leg's static flow curve, seed
    eq. 5.1). Each interval whose midpoint the chord misses by more than ``tolerance`` (on any leg) is halved, up
    to ``levels`` times: the points gather where an edge opens, at a port's corner or a table's knee, and a smooth
    curve keeps its grid. Returns (u (G',), curve (n, G')), G' >= G."""
    u = np.asarray(u, dtype=float)
    v = np.atleast_2d(curve(u))
    check = np.ones(len(u) - 1, dtype=bool)  # the intervals to test: at first all, then the halves just made
    for _ in range(levels):
        k = np.flatnonzero(check)
        if k.size == 0:
            break
        mid = 0.5 * (u[k] + u[k + 1])
        v_mid = np.atleast_2d(curve(mid))
        miss = np.max(np.abs(v_mid - 0.5 * (v[:, k] + v[:, k + 1])), axis=0) > tolerance
        if not miss.any():
            break
        k, mid, v_mid = k[miss], mid[miss], v_mid[:, miss]
        u = np.insert(u, k + 1, mid)
        v = np.insert(v, k + 1, v_mid, axis=1)
        check = np.zeros(len(u) - 1, dtype=bool)
        new = k + 1 + np.arange(len(k))  # where the midpoints landed
        check[new - 1] = check[new] = True
    return u, v


__all__ = ["CURVE_TOLERANCE", "FILE_FORMAT", "OPEN_FRACTION", "LegModel", "Reference", "check_model", "open_together",
           "refined_grid"]
