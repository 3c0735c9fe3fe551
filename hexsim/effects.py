"""Effects the nominal seed model lacks, and the per-step leg plant that includes them.

The seed's model (ch. 3) has an ideal supply (P_s constant), an ideal spool (x_v follows u_v at once,
eq. 3.2), no leakage and an exact position sensor. On the real Micro Motion System the seed itself saw
the supply pressure move, gravity not along the actuator and hysteresis in the flow curve (ch. 4) and
left them open. :class:`Effects` switches such extensions on; every field's zero value is the seed's
model, so ``Effects()`` reproduces the nominal plant exactly. Null offset, bulk modulus and friction are
fields of :class:`~hexsim.params.HydraulicParams`; mass and inclination of the actuator are rigid-body
facts and change the MuJoCo model (:func:`hexsim.model.apply_load`).

:func:`step_plant` is a pure function on arrays of one entry per leg, like :mod:`hexsim.hydraulics`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from hexsim import hydraulics
from hexsim.errors import InputError
from hexsim.params import HydraulicParams, _check_nonnegative

#: Names of the candidate effects of the identifier (issue 4), in the order they are tried.
EFFECT_NAMES = ("supply_pressure", "spool_dynamics", "null_offset", "hysteresis", "leakage", "load", "friction",
                "bulk_modulus", "sensor_delay", "edge_asymmetry")


@dataclass(frozen=True)
class Effects:
    """Extensions of the nominal leg model; the defaults (all zero / None) are the seed's model.

    Supply: a pump with an accumulator behind a supply line; P_s sags by R_s phi_s with the flow phi_s
    drawn from the manifold and follows with time constant tau_s (a first-order pump/accumulator model,
    e.g. Merritt, *Hydraulic Control Systems*, §4.13; Jelali & Kroll, *Hydraulic Servo-systems*, §3.7):
    dP_s/dt = (P_s0 - R_s phi_s - P_s) / tau_s, phi_s = sum over the legs on the manifold of
    (phi_PA + phi_leak - A2 ydot) (the rod side is connected to the supply, seed Fig. 3.1).

    Spool: a second-order spool position loop, x_v'' = w_v^2 (x_v,set - x_v) - 2 zeta w_v x_v' with
    w_v = 2 pi f_v (valve datasheets give the -90° frequency; Jelali & Kroll §3.4), x_v limited to
    ±x_v,max. Spool play: the setpoint passes a backlash of half width h [V] before the spool (the
    hysteresis of the flow curve the seed measured, §4.2). Leakage: internal across the piston,
    C_l (P_s - P1) into the bottom chamber. Sensor delay: the position the controller and the log see
    is y(t - tau_y). Edge asymmetry: the supply (P→A) and return (A→T) edges of the spool pass k_PA and
    k_AT times the flow of eq. (3.4) (ground edges differ by manufacturing tolerance and wear; the seed's
    measured flow curve is not symmetric either, §4.2).
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
    mass_kg: float | None = None  # moving mass M [kg] of the single actuator; None: the MJCF's
    inclination_deg: float | None = None  # actuator axis from vertical [deg]; None: vertical (the MJCF)

    def __post_init__(self) -> None:
        _check_nonnegative(self, "supply_resistance", "supply_time_constant", "spool_frequency", "spool_damping",
                           "spool_play", "leakage", "sensor_delay", "edge_gain_pa", "edge_gain_at")
        if self.supply_resistance > 0 and self.supply_time_constant <= 0:
            raise InputError("Effects.supply_time_constant must be > 0 when supply_resistance > 0")
        if self.mass_kg is not None and not (math.isfinite(self.mass_kg) and self.mass_kg > 0):
            raise InputError(f"Effects.mass_kg must be a finite positive number, got {self.mass_kg!r}")
        if self.inclination_deg is not None and not (math.isfinite(self.inclination_deg)
                                                     and 0.0 <= self.inclination_deg <= 90.0):
            raise InputError(f"Effects.inclination_deg must be within 0…90, got {self.inclination_deg!r}")

    def replace(self, **changes) -> "Effects":
        """A copy with ``changes`` applied (validated again)."""
        return replace(self, **changes)


NOMINAL = Effects()


@dataclass
class PlantState:
    """Hydraulic state of n legs, arrays (n,): P1 [Pa], P_s seen by each leg [Pa], spool position x_v [m]
    and velocity [m/s], setpoint after the spool play u_b [V]."""

    p1: np.ndarray
    p_s: np.ndarray
    x_v: np.ndarray
    v_v: np.ndarray
    u_b: np.ndarray

    @classmethod
    def at_rest(cls, p1, u_v, hyd: HydraulicParams, p_s=None) -> "PlantState":
        """Steady state: spool at its setpoint, no play taken up, supply at ``p_s`` (default nominal)."""
        p1 = np.array(p1, dtype=float)
        u_v = np.broadcast_to(np.asarray(u_v, dtype=float), p1.shape).copy()
        p_s = np.full(p1.shape, hyd.supply_pressure) if p_s is None else np.broadcast_to(p_s, p1.shape).astype(float)
        return cls(p1=p1, p_s=p_s, x_v=hydraulics.spool_position(u_v, hyd), v_v=np.zeros_like(p1), u_b=u_v)

    def copy(self) -> "PlantState":
        return PlantState(*(a.copy() for a in (self.p1, self.p_s, self.x_v, self.v_v, self.u_b)))


def step_plant(state: PlantState, u_v, y, ydot, dt: float, hyd: HydraulicParams, eff: Effects,
               groups: np.ndarray | None = None) -> PlantState:
    """Advance the leg hydraulics by ``dt`` [s] with valve setpoints u_v [V] (n,), piston positions y [m]
    and velocities ydot [m/s] (n,) taken at the start of the step. Returns a new state.

    Order: spool play (backlash), spool dynamics (semi-implicit Euler), bottom-chamber pressure
    (linearly implicit, :func:`hexsim.hydraulics.step_pressure`, seed eq. 3.4/3.7, with leakage), supply
    pressure (exact first-order update with the step's flow). ``groups`` (n,) ints: legs sharing a supply
    manifold (the hexapod: all zeros); default each leg its own supply. With ``Effects()`` this is exactly
    :func:`hexsim.hydraulics.step_pressure`.
    """
    if eff is NOMINAL or eff == NOMINAL:  # the seed's plant: one call, as the reference step
        p1 = hydraulics.step_pressure(state.p1, u_v, y, ydot, dt, hyd, state.p_s)
        return PlantState(p1=p1, p_s=state.p_s, x_v=state.x_v, v_v=state.v_v, u_b=state.u_b)
    u_v = np.asarray(u_v, dtype=float)
    u_b = state.u_b
    if eff.spool_play > 0:
        u_b = np.clip(u_b, u_v - eff.spool_play, u_v + eff.spool_play)
    else:
        u_b = u_v
    x_set = hydraulics.spool_position(u_b, hyd)
    if eff.spool_frequency > 0:
        w = 2.0 * np.pi * eff.spool_frequency
        v_v = state.v_v + dt * (w * w * (x_set - state.x_v) - 2.0 * eff.spool_damping * w * state.v_v)
        x_v = state.x_v + dt * v_v
        limited = np.abs(x_v) > hyd.x_v_max
        x_v = np.clip(x_v, -hyd.x_v_max, hyd.x_v_max)
        v_v = np.where(limited, 0.0, v_v)
    else:
        x_v, v_v = x_set, state.v_v
    gains = (eff.edge_gain_pa, eff.edge_gain_at)
    p1 = hydraulics.step_pressure(state.p1, u_v, y, ydot, dt, hyd, state.p_s, x_v=x_v, leakage=eff.leakage,
                                  edge_gains=gains)
    p_s = state.p_s
    if eff.supply_resistance > 0:
        a1 = hydraulics.flow_areas(x_v, hyd)[0] * eff.edge_gain_pa
        dp = state.p_s - p1
        phi_pa = hyd.orifice_constant * a1 * np.copysign(np.sqrt(np.abs(dp)), dp)
        phi_s = phi_pa + eff.leakage * dp - ydot * hyd.area_rod
        groups = np.arange(len(p1)) if groups is None else groups
        demand = np.bincount(groups, weights=phi_s)[groups]
        target = hyd.supply_pressure - eff.supply_resistance * demand
        p_s = target + (state.p_s - target) * math.exp(-dt / eff.supply_time_constant)
        p_s = np.maximum(p_s, hyd.tank_pressure)
    return PlantState(p1=p1, p_s=p_s, x_v=x_v, v_v=v_v, u_b=u_b)
