"""Faults injected into a run (issue 6): what a motion system must survive without a silent wrong answer.

Kinds (``hexsim run … --fault KIND:key=value,…``):

* ``valve_stuck`` (``leg``, ``t``, ``value`` [V]): the valve of ``leg`` ignores the controller from
  ``t`` on and holds u_v = ``value`` (a stuck spool / a frozen amplifier output);
* ``supply_loss`` (``t``, ``ramp`` [s], default 0.5): the supply pressure P_s ramps linearly from its
  value to the tank pressure over ``ramp`` (pump trip); the platform sinks onto its end stops;
* ``sensor_frozen`` (``leg``, ``t``): the position the controller sees for ``leg`` stays at its value at
  ``t``;
* ``sensor_dropout`` (``leg``, ``t``): the position transducer of ``leg`` reads 0 (fully retracted)
  from ``t`` on, so the controller drives the leg out;
* ``end_stop`` (``leg``, ``t``, ``value`` [m], default 0.02): the setpoint of ``leg`` jumps ``value``
  beyond the end of the stroke at ``t`` (a wrong setpoint reaching the leg).

Faults act at the controller's sample instants (500 Hz), in both engines. The run reports each fault
with its time and leg and what followed: the extreme piston positions (how far the soft end stops of
the MJCF let the piston past the stroke), the lowest P_s, the largest connect violation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hexsim.errors import InputError

KINDS = ("valve_stuck", "supply_loss", "sensor_frozen", "sensor_dropout", "end_stop")
_KEYS = {"valve_stuck": ("leg", "t", "value"), "supply_loss": ("t", "ramp"), "sensor_frozen": ("leg", "t"),
         "sensor_dropout": ("leg", "t"), "end_stop": ("leg", "t", "value")}
_REQUIRED = {"valve_stuck": ("leg", "t", "value"), "supply_loss": ("t",), "sensor_frozen": ("leg", "t"),
             "sensor_dropout": ("leg", "t"), "end_stop": ("leg", "t")}


@dataclass(frozen=True)
class Fault:
    """One fault: ``kind`` (see :data:`KINDS`), ``leg`` (1-based, None for the supply), start time ``t``
    [s] and ``value`` (V for valve_stuck, m beyond the stroke for end_stop, ramp time s for supply_loss)."""

    kind: str
    t: float
    leg: int | None = None
    value: float | None = None

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise InputError(f"fault kind {self.kind!r} is unknown; choose one of {', '.join(KINDS)}")
        if not (math.isfinite(self.t) and self.t >= 0):
            raise InputError(f"fault {self.kind}: t must be a time >= 0 s, got {self.t!r}")
        if "leg" in _REQUIRED[self.kind] and (self.leg is None or self.leg < 1):
            raise InputError(f"fault {self.kind}: needs leg=1…6, got {self.leg!r}")
        if self.value is not None and not math.isfinite(self.value):
            raise InputError(f"fault {self.kind}: value must be finite, got {self.value!r}")
        if self.kind == "supply_loss" and self.value is not None and self.value <= 0:
            raise InputError(f"fault supply_loss: ramp must be > 0 s, got {self.value!r}")

    @classmethod
    def parse(cls, text: str) -> "Fault":
        """``KIND:key=value,…`` as given to ``--fault`` (keys leg, t, value; supply_loss: t, ramp)."""
        kind, _, rest = text.partition(":")
        kind = kind.strip().replace("-", "_")
        if kind not in KINDS:
            raise InputError(f"--fault {text!r}: unknown kind {kind!r}; choose one of {', '.join(KINDS)}")
        values: dict[str, float] = {}
        for item in filter(None, (p.strip() for p in rest.split(","))):
            key, sep, raw = item.partition("=")
            key = key.strip()
            if not sep or key not in _KEYS[kind]:
                raise InputError(f"--fault {text!r}: {item!r} is not one of {', '.join(k + '=…' for k in _KEYS[kind])}")
            try:
                values[key] = float(raw)
            except ValueError:
                raise InputError(f"--fault {text!r}: {key} = {raw.strip()!r} is not a number") from None
        missing = [k for k in _REQUIRED[kind] if k not in values]
        if missing:
            raise InputError(f"--fault {text!r}: missing {missing[0]}=…")
        leg = values.get("leg")
        if leg is not None and leg != int(leg):
            raise InputError(f"--fault {text!r}: leg = {leg:g} is not a leg number")
        value = values.get("ramp") if kind == "supply_loss" else values.get("value")
        return cls(kind, values["t"], None if leg is None else int(leg), value)

    def as_dict(self) -> dict:
        out = {"kind": self.kind, "t_s": self.t, "leg": self.leg}
        if self.kind == "valve_stuck":
            out["u_v_V"] = self.value
        elif self.kind == "end_stop":
            out["beyond_stroke_m"] = self.default_value
        elif self.kind == "supply_loss":
            out["ramp_s"] = self.default_value
        return out

    @property
    def default_value(self) -> float:
        if self.value is not None:
            return self.value
        return {"end_stop": 0.02, "supply_loss": 0.5}.get(self.kind, 0.0)


class FaultInjector:
    """Applies a list of faults at the controller samples of a run with ``n_legs`` legs whose stroke is
    ``stroke`` (n, 2) [m]. Raises InputError for a leg the model does not have."""

    def __init__(self, faults: tuple[Fault, ...], n_legs: int, stroke: np.ndarray, supply_pressure: float,
                 tank_pressure: float) -> None:
        for f in faults:
            if f.leg is not None and f.leg > n_legs:
                raise InputError(f"fault {f.kind}: leg {f.leg} does not exist (the model has {n_legs} legs)")
        self.faults = faults
        self.stroke = stroke
        self.p_s0, self.p_t = supply_pressure, tank_pressure
        self._frozen: dict[int, float] = {}

    def __bool__(self) -> bool:
        return bool(self.faults)

    def setpoint(self, t: float, r: np.ndarray) -> np.ndarray:
        """The piston setpoints (n,) [m] the legs receive at time ``t``."""
        for f in self.faults:
            if f.kind == "end_stop" and t >= f.t:
                r = r.copy()
                r[f.leg - 1] = self.stroke[f.leg - 1, 1] + f.default_value
        return r

    def measured(self, t: float, y: np.ndarray) -> np.ndarray:
        """The positions (n,) [m] the controller sees at ``t``."""
        for f in self.faults:
            if t < f.t:
                continue
            i = f.leg - 1 if f.leg is not None else 0
            if f.kind == "sensor_frozen":
                y = y.copy()
                y[i] = self._frozen.setdefault(i, float(y[i]))
            elif f.kind == "sensor_dropout":
                y = y.copy()
                y[i] = 0.0
        return y

    def valve(self, t: float, u_v: np.ndarray) -> np.ndarray:
        """The valve setpoints (n,) [V] that reach the valves at ``t``."""
        for f in self.faults:
            if f.kind == "valve_stuck" and t >= f.t:
                u_v = u_v.copy()
                u_v[f.leg - 1] = f.value
        return u_v

    def supply(self, t: float) -> float | None:
        """P_s [Pa] imposed at ``t`` by a supply loss, or None."""
        level = None
        for f in self.faults:
            if f.kind == "supply_loss" and t >= f.t:
                frac = max(0.0, 1.0 - (t - f.t) / f.default_value)
                level = self.p_t + frac * (self.p_s0 - self.p_t)
        return level
