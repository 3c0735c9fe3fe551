"""Effects the nominal seed model lacks, and the per-step leg plant that includes them.

The seed's model (ch. 3) has an ideal supply (P_s constant), an ideal spool (x_v follows u_v at once,
eq. 3.2), no leakage and an exact position sensor. On the real Micro Motion System the seed itself saw
the supply pressure move, gravity not along the actuator and hysteresis in the flow curve (ch. 4) and
left them open. :class:`Effects` switches such extensions on; every field's zero value is the seed's
model, so ``Effects()`` reproduces the nominal plant exactly. Null offset, bulk modulus and friction are
fields of :class:`~hexsim.plant.params.HydraulicParams`; mass and inclination of the actuator and a payload on
the hexapod's platform are rigid-body facts and edit the MuJoCo spec before it is compiled
(:func:`hexsim.plant.model.apply_load`).

The equations of the effects are written once, in the leg step of :mod:`hexsim.plant.legs`; how the
identifier fits each effect (its parameters, plausible ranges and sources) is declared once, in
:data:`hexsim.measured.candidates.CANDIDATES`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

from hexsim.errors import InputError
from hexsim.plant.params import _check_nonnegative


@dataclass(frozen=True)
class Effects:
    """Extensions of the nominal leg model; the defaults (all zero / None) are the seed's model.

    Supply: a pump with an accumulator behind a supply line; P_s sags by R_s phi_s with the flow phi_s
    drawn from the manifold and follows with time constant tau_s (a first-order pump/accumulator model,
    e.g. Merritt, *Hydraulic Control Systems*, §4.13; Jelali & Kroll, *Hydraulic Servo-systems*, §3.7):
    dP_s/dt = (P_s0 - R_s phi_s - P_s) / tau_s, phi_s = sum over the legs on the manifold of
    (phi_PA + phi_leak - A2 ydot) (the rod side is connected to the supply, seed Fig. 3.1).

    Spool: a second-order spool position loop, x_v'' = w_v^2 (x_v,set - x_v) - 2 zeta w_v x_v' with
    w_v = 2 pi f_v (valve datasheets give the -90° frequency; Jelali & Kroll §3.4), x_v limited to ±x_v,max.
    Spool play: the setpoint passes a backlash of half width h [V] before the spool (the hysteresis of the flow
    curve the seed measured, §4.2). Leakage: internal across the piston, C_l (P_s - P1) into the bottom chamber
    (a 4-way valve: C_l (P2 - P1), out of the rod side). Sensor delay: the position the controller and the log
    see is y(t - tau_y). Edge asymmetry: the supply (P→A) and return (A→T) edges of the spool pass k_PA and k_AT
    times the flow of eq. (3.4), and with a 4-way valve the rod side's P→B and B→T edges k_PB and k_BT (ground
    edges differ by manufacturing tolerance and wear; the seed's measured flow curve is not symmetric
    either, §4.2). Entrained air: a volume fraction a of undissolved air at atmospheric pressure makes the oil
    softer the lower the pressure (:func:`hexsim.plant.legs.bulk_modulus`). Payload (hexapod): a point mass m_p
    at c_p on the platform (platform frame, origin at the platform body), added to the platform's mass, centre
    of mass and inertia (parallel-axis theorem); the seed's 600 kg is the Micro Motion System's maximum payload.
    """

    supply_resistance: float = 0.0  # R_s [Pa s/m^3], P_s sag per unit supply flow; 0: ideal supply
    supply_time_constant: float = 0.02  # tau_s [s], pump + accumulator response (used if R_s > 0)
    spool_frequency: float = 0.0  # f_v [Hz], natural frequency of the spool loop; 0: ideal spool (seed 3.2)
    spool_damping: float = 0.7  # zeta_v [-], damping of the spool loop (used if f_v > 0)
    spool_play: float = 0.0  # h [V], half width of the backlash between setpoint and spool
    leakage: float = 0.0  # C_l [m^3/(s Pa)], internal leakage across the piston
    sensor_delay: float = 0.0  # tau_y [s], delay of the position measurement
    edge_gain_pa: float = 1.0  # k_PA [-], flow gain of the supply edge P→A relative to eq. (3.4); 1: seed
    edge_gain_at: float = 1.0  # k_AT [-], flow gain of the return edge A→T relative to eq. (3.4); 1: seed
    edge_gain_pb: float = 1.0  # k_PB [-], the 4-way valve's supply edge P→B, relative to eq. (3.4)
    edge_gain_bt: float = 1.0  # k_BT [-], the 4-way valve's return edge B→T, relative to eq. (3.4)
    mass_kg: float | None = None  # moving mass M [kg] of the single actuator; None: the MJCF's
    inclination_deg: float | None = None  # actuator axis from vertical [deg]; None: vertical (the MJCF)
    air_fraction: float = 0.0  # a [-], entrained (undissolved) air per volume of oil at atmospheric pressure
    air_exponent: float = 1.4  # n [-], polytropic exponent of that air (1: isothermal, 1.4: adiabatic)
    payload_kg: float = 0.0  # hexapod: mass added to the platform [kg] (< 0: a lighter platform); 0: the MJCF's
    payload_at_m: tuple[float, float, float] = (0.0, 0.0, 0.0)  # its centre of gravity, platform frame [m]

    def __post_init__(self) -> None:
        _check_nonnegative(self, "supply_resistance", "supply_time_constant", "spool_frequency", "spool_damping",
                           "spool_play", "leakage", "sensor_delay", "edge_gain_pa", "edge_gain_at", "edge_gain_pb",
                           "edge_gain_bt", "air_fraction")
        if not (math.isfinite(self.air_exponent) and 1.0 <= self.air_exponent <= 1.4):
            raise InputError(f"Effects.air_exponent must be within 1 (isothermal) … 1.4 (adiabatic), got "
                             f"{self.air_exponent!r}")
        if self.supply_resistance > 0 and self.supply_time_constant <= 0:
            raise InputError("Effects.supply_time_constant must be > 0 when supply_resistance > 0")
        if self.mass_kg is not None and not (math.isfinite(self.mass_kg) and self.mass_kg > 0):
            raise InputError(f"Effects.mass_kg must be a finite positive number, got {self.mass_kg!r}")
        if not (math.isfinite(self.payload_kg) and len(self.payload_at_m) == 3
                and all(math.isfinite(v) for v in self.payload_at_m)):
            raise InputError(f"Effects.payload_kg / payload_at_m must be finite (a mass and x, y, z), got "
                             f"{self.payload_kg!r} at {self.payload_at_m!r}")
        if self.inclination_deg is not None and not (math.isfinite(self.inclination_deg)
                                                     and 0.0 <= self.inclination_deg <= 90.0):
            raise InputError(f"Effects.inclination_deg must be within 0…90, got {self.inclination_deg!r}")

    def replace(self, **changes) -> "Effects":
        """A copy with ``changes`` applied (validated again)."""
        return replace(self, **changes)


NOMINAL = Effects()

#: Parameters one leg cannot have on its own: the supply and tank are one manifold, the sensor delay is
#: the motion computer's, the load a rigid-body fact, the valve range the controller's saturation.
SHARED_FIELDS = frozenset({"supply_pressure", "tank_pressure", "supply_resistance", "supply_time_constant",
                           "sensor_delay", "mass_kg", "inclination_deg", "payload_kg", "payload_at_m", "u_v_max"})


@dataclass(frozen=True)
class LegChange:
    """Parameters of one leg that differ from the others' (a worn valve edge, a leaking seal, a drifted
    null point): ``leg`` 1…n and ``values`` ((field, value), …) of
    :class:`~hexsim.plant.params.HydraulicParams` or :class:`Effects` fields, SI units. Fields of
    :data:`SHARED_FIELDS` are refused. Build with ``LegChange.of(3, leakage=3e-12, null_offset=0.1)``.
    Raises InputError for an unknown or shared field or a leg below 1 (the upper limit is checked
    against the model by the runner)."""

    leg: int
    values: tuple[tuple[str, float], ...]

    @classmethod
    def of(cls, leg: int, **values: float) -> "LegChange":
        return cls(int(leg), tuple(values.items()))

    def __post_init__(self) -> None:
        """Names checked first, then the values made floats, sorted by name (a shared vector, the payload's
        position, is refused by its name, not by a failed conversion)."""
        from hexsim.plant.params import HydraulicParams

        known = {f.name for f in fields(HydraulicParams)} | {f.name for f in fields(Effects)}
        if self.leg < 1:
            raise InputError(f"LegChange: leg must be 1 or more, got {self.leg}")
        for name, _ in self.values:
            if name not in known:
                raise InputError(f"LegChange of leg{self.leg}: unknown parameter {name!r}")
            if name in SHARED_FIELDS:
                raise InputError(f"LegChange of leg{self.leg}: {name} is shared by all legs, not one leg's")
        object.__setattr__(self, "values", tuple(sorted((k, _number(self.leg, k, v)) for k, v in self.values)))

    def apply(self, hyd, eff: Effects):
        """(hydraulics, effects) of this leg: ``hyd`` and ``eff`` with the values replaced (validated)."""
        own = {f.name for f in fields(Effects)}
        return (hyd.replace(**{k: v for k, v in self.values if k not in own}),
                eff.replace(**{k: v for k, v in self.values if k in own}))


def _number(leg: int, name: str, value) -> float:
    """``value`` as a float; InputError naming the leg and the parameter if it is not a number."""
    try:
        return float(value)
    except (TypeError, ValueError):
        raise InputError(f"LegChange of leg{leg}: {name} must be a number, got {value!r}") from None


def merge_leg_changes(first: tuple[LegChange, ...], then: tuple[LegChange, ...]) -> tuple[LegChange, ...]:
    """One change per leg: the values of ``first`` (a machine file's legs) with those of ``then`` (a run's or a
    candidate's) on top, the same field of the same leg taken from ``then``."""
    merged: dict[int, dict[str, float]] = {}
    for change in (*first, *then):
        merged.setdefault(change.leg, {}).update(change.values)
    return tuple(LegChange.of(leg, **values) for leg, values in sorted(merged.items()))
