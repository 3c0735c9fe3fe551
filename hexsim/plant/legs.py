"""The leg plant, written once: valve, chamber, friction and the effects, as scalar functions that numba
compiles and Python calls.

This module is the single source of the leg physics (seed ch. 3, eq. 3.2–3.4, 3.7–3.9, and the
extensions of :class:`hexsim.plant.effects.Effects`). The compiled runners (:mod:`hexsim.engine.native`) call
:func:`step_legs` inside their loops; the array functions of :mod:`hexsim.plant.hydraulics` (flow curve,
friction curve, statics) map the same scalar functions over arrays; the Python control callback
(``engine="python"``) calls :func:`step_plant`, which runs :func:`step_legs` too. There is no second
translation to keep in step.

Parameters travel as one named record, :class:`LegParams` (a ``NamedTuple`` of floats), built from
:class:`~hexsim.plant.params.HydraulicParams` and :class:`~hexsim.plant.effects.Effects` by :func:`leg_params`; the
leg step reads one record per leg from a structured array (:func:`leg_table`, dtype
:data:`LEG_DTYPE`), so a leg may differ from the others (:class:`~hexsim.plant.effects.LegChange`). The state of n legs is :class:`PlantState`,
a ``NamedTuple`` of five arrays (n,), updated in place by the compiled step.

Sign conventions: piston position y [m] is 0 fully retracted and grows when the leg extends; flow
phi_1 > 0 fills the bottom chamber; the leg force > 0 extends the leg.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np

from hexsim.plant.effects import NOMINAL, Effects, LegChange
from hexsim.plant.params import MAX_CURVE_POINTS, HydraulicParams

#: Laminar–turbulent transition pressure Δp_tr [Pa] of the valve's orifices: below about this pressure
#: difference the flow through an edge is laminar (∝ Δp), above it turbulent (∝ √Δp, seed eq. 3.4).
#: 0.1 bar: the pressure at which a 50 µm spool slot reaches a Reynolds number of about 10 in 35 °C oil.
TRANSITION_DP = 1.0e4
_DP_TR2 = TRANSITION_DP * TRANSITION_DP

_jit = numba.njit(cache=True, fastmath=False)
# the scalar equations are inlined into the loops that call them (numba IR inlining): a call per equation
# would pass the parameter record by value each time. The chamber steps (_chambers, pressure_step,
# rod_pressure_step) are compiled functions of their own: inlined into step_legs as well (three copies of
# every equation) the leg step took 107 s to compile on a cold cache (the first run after an install, and
# each CI worker), 16 s now, for 0-5 % of the run's speed (20 s heave, 30-34x real time either way); replay-heavy
# calibration may have lost more (bench --calibrate, seed actuator closed loop: 94x bare, one repeat, vs 74x).
_inline = numba.njit(cache=True, fastmath=False, inline="always")


class LegParams(NamedTuple):
    """Everything the leg step reads, SI units; one record for all legs (seed app. A by default)."""

    p_s0: float  # supply pressure P_s [Pa] (the pump's set level with a supply model)
    p_t: float  # tank pressure P_t [Pa]
    c_v: float  # orifice constant C_d sqrt(2/rho) [m^1.5/kg^0.5] (eq. 3.4)
    a1: float  # bottom (piston) area A1 [m^2]
    a2: float  # rod-side annulus area A2 [m^2]
    bulk_modulus: float  # E [Pa]
    v_pl: float  # pipeline volume V_pl [m^3]
    u_v_max: float  # valve setpoint range [V]
    x_v_max: float  # spool travel at u_v,max [m]
    overlap: float  # O_l [m] (sharp-edged area, eq. 3.3)
    u_0: float  # null offset: u_v at which the spool is centred [V]
    port_width: float  # pi d, full-perimeter port width [m] (eq. 3.3)
    smooth_gain: float  # area gain of eq. 3.11 [m^2/m^2]
    blend_start: float  # x_a [m]: the smooth area holds up to here (HydraulicParams.smooth_blend; inf: "quadratic")
    blend_end: float  # x_b [m]: the port's sharp-edged opening from here on
    sharp: float  # 1.0: sharp-edged area (eq. 3.3); 2.0: port, min of (3.11) and (3.3); 3.0: rounded, (3.11) up to
    # its corner (blend_end), (3.3) beyond; 0.0: smooth (eq. 3.11)
    arctan_gain: float  # k of eq. 3.9 [s/m]
    arctan_scale: float  # 2/pi if the arctan is normalised to ±1, else 1
    sigma_neg: float  # viscous friction for ydot < 0 [N s/m]
    f_c_neg: float  # Coulomb level for ydot < 0 [N]
    f_s_neg: float  # Stribeck level for ydot < 0 [N]
    c_s_neg: float  # Stribeck velocity for ydot < 0 [m/s]
    sigma_pos: float  # the same four for ydot >= 0
    f_c_pos: float
    f_s_pos: float
    c_s_pos: float
    r_s: float  # supply resistance R_s [Pa s/m^3]; 0: ideal supply
    tau_s: float  # supply time constant [s]
    f_v: float  # spool natural frequency [Hz]; 0: ideal spool (eq. 3.2)
    zeta_v: float  # spool damping [-]
    play: float  # spool play half width h [V]
    c_l: float  # internal leakage C_l [m^3/(s Pa)]
    k_pa: float  # supply-edge gain [-]
    k_at: float  # return-edge gain [-]
    air: float  # entrained air: volume fraction at atmospheric pressure [-]; 0: none
    air_exponent: float  # polytropic exponent of the air [-]
    p_cav: float  # cavitation pressure [Pa, gauge]: the lowest P1 (HydraulicParams.cavitation_pressure)
    four_way: float  # 1.0: 4-way valve, both chambers fed by the valve; 0.0: 3-way, rod side at P_s
    v_pl2: float  # rod-side dead volume V_pl,B [m^3] (4-way)
    stroke: float  # cylinder stroke L_s [m]: rod-side volume (L_s - y) A2 + V_pl,B (4-way)
    k_pb: float  # supply-edge gain P→B [-] (4-way)
    k_bt: float  # return-edge gain B→T [-] (4-way)
    tab_n: float  # points of the opening table (flow_area "table"); 0: no table
    # the table's points (u_v [V], opening fraction of the edge the command opens), closed at and below the
    # first (the origin, or where an underlapped edge opens), unused points the last one repeated
    tu0: float
    tu1: float
    tu2: float
    tu3: float
    tu4: float
    tu5: float
    tu6: float
    tu7: float
    tu8: float
    tu9: float
    tu10: float
    tu11: float
    tf0: float
    tf1: float
    tf2: float
    tf3: float
    tf4: float
    tf5: float
    tf6: float
    tf7: float
    tf8: float
    tf9: float
    tf10: float
    tf11: float
    # flow area "curve": each edge's points (u [V] at the command that opens it, opening fraction, the monotone
    # cubic's slope [1/V]; HydraulicParams.edge_curves), cn_* of them used, the rest the last one repeated
    cn_pa: float
    cu_pa: tuple
    cf_pa: tuple
    cm_pa: tuple
    cn_at: float
    cu_at: tuple
    cf_at: tuple
    cm_at: tuple


def leg_params(hyd: HydraulicParams, eff: Effects = NOMINAL) -> LegParams:
    """The record the compiled leg functions read, from the hydraulic parameters and the effects."""
    neg, pos = hyd.stribeck_table
    return LegParams(
        hyd.supply_pressure, hyd.tank_pressure, hyd.orifice_constant, hyd.area_bottom, hyd.area_rod,
        hyd.bulk_modulus, hyd.pipeline_volume, hyd.u_v_max, hyd.x_v_max, hyd.overlap, hyd.null_offset,
        math.pi * hyd.spool_diameter, hyd.smooth_area_gain,
        *_blend(hyd), {"sharp": 1.0, "port": 2.0, "rounded": 3.0}.get(hyd.flow_area, 0.0), hyd.arctan_gain,
        2.0 / math.pi if hyd.arctan_normalised else 1.0, *map(float, neg), *map(float, pos),
        eff.supply_resistance, eff.supply_time_constant, eff.spool_frequency, eff.spool_damping, eff.spool_play,
        eff.leakage, eff.edge_gain_pa, eff.edge_gain_at, eff.air_fraction, eff.air_exponent, hyd.cavitation_pressure,
        float(hyd.four_way), hyd.pipeline_volume_rod, hyd.stroke, eff.edge_gain_pb, eff.edge_gain_bt,
        *_table_fields(hyd), *_curve_fields(hyd))


def _blend(hyd: HydraulicParams) -> tuple[float, float]:
    """(blend_start, blend_end) of :class:`LegParams`: the smooth area's C^1 blend onto the port, the rounded
    edge's corner twice (:attr:`~hexsim.plant.params.HydraulicParams.rounded_corner`), or infinity ((3.11) at
    every opening; unused by the sharp, port and table areas)."""
    if hyd.flow_area == "rounded":
        return hyd.rounded_corner, hyd.rounded_corner
    return hyd.smooth_blend if hyd.flow_area == "smooth" else (math.inf, math.inf)


def _table_fields(hyd: HydraulicParams) -> tuple[float, ...]:
    """tab_n and the twelve (u, f) points of :class:`LegParams`: the origin unless the table starts at or below
    null (an underlap: the edge opens at that command), the table, the last point repeated."""
    table = [(float(u), float(f)) for u, f in hyd.opening_table]
    points = table if table and table[0][0] <= 0.0 else [(0.0, 0.0), *table]
    n = len(points) - 1
    points += [points[-1]] * (12 - len(points))
    return (float(n), *(u for u, _ in points), *(f for _, f in points))


def _curve_fields(hyd: HydraulicParams) -> tuple:
    """cn, cu, cf, cm of each edge's flow curve (:class:`LegParams`): the points used and three tuples of
    :data:`~hexsim.plant.params.MAX_CURVE_POINTS`, padded with the last point (slope 0 beyond it is not used:
    the curve is extended with its last slope)."""
    out: list = []
    for u, f, m in hyd.edge_curves:
        n = len(u)
        if n == 0:
            u, f, m = np.zeros(1), np.zeros(1), np.zeros(1)
        pad = MAX_CURVE_POINTS - len(u)
        out += [float(n), *(tuple(np.concatenate([a, np.full(pad, a[-1])]).tolist()) for a in (u, f, m))]
    return tuple(out)


#: The flow-curve fields of :class:`LegParams` held as arrays of MAX_CURVE_POINTS in a record.
_CURVE_ARRAYS = ("cu_pa", "cf_pa", "cm_pa", "cu_at", "cf_at", "cm_at")
#: One leg's parameters as a numpy record (the fields of :class:`LegParams`, float64; the flow curves' points
#: as arrays).
LEG_DTYPE = np.dtype([(name, np.float64, (MAX_CURVE_POINTS,)) if name in _CURVE_ARRAYS else (name, np.float64)
                      for name in LegParams._fields])


def leg_table(hyd: HydraulicParams, eff: Effects, n: int, changes: tuple[LegChange, ...] = ()) -> np.ndarray:
    """The parameters of n legs, a structured array (n,) of :data:`LEG_DTYPE`: every leg ``hyd`` and
    ``eff``, legs named in ``changes`` with their own values. The supply fields are read from entry 0
    (shared: :data:`hexsim.plant.effects.SHARED_FIELDS`). Raises InputError for a change of a leg above n."""
    from hexsim.errors import InputError

    table = np.empty(n, dtype=LEG_DTYPE)
    table[:] = tuple(leg_params(hyd, eff))
    for change in changes:
        if change.leg > n:
            raise InputError(f"LegChange of leg{change.leg}: the model has {n} leg{'s' if n > 1 else ''}")
        table[change.leg - 1] = tuple(leg_params(*change.apply(hyd, eff)))
    return table


class PlantState(NamedTuple):
    """Hydraulic state of n legs, arrays (n,), changed in place by :func:`step_legs`: P1 [Pa] (cap side),
    P_s seen by each leg [Pa], spool position x_v [m] and velocity v_v [m/s], setpoint after the spool play
    u_b [V], volume of the cavity in the bottom chamber v_c [m^3] (0 unless P1 is at the cavitation
    pressure), P2 [Pa] (rod side: integrated with a 4-way valve, a copy of P_s with the 3-way valve) and
    the rod side's cavity v_c2 [m^3]."""

    p1: np.ndarray
    p_s: np.ndarray
    x_v: np.ndarray
    v_v: np.ndarray
    u_b: np.ndarray
    v_c: np.ndarray
    p2: np.ndarray
    v_c2: np.ndarray

    @classmethod
    def at_rest(cls, p1, u_v, hyd: HydraulicParams, p_s=None, p2=None) -> "PlantState":
        """Steady state: spool at its setpoint, no play taken up, supply at ``p_s`` (default nominal), rod
        side at ``p2`` (default: P_s, the 3-way valve's; a 4-way caller passes its own, e.g.
        :func:`hexsim.plant.hydraulics.rest_pressures`)."""
        p1 = np.array(p1, dtype=float)
        u_v = np.broadcast_to(np.asarray(u_v, dtype=float), p1.shape).copy()
        p_s = np.full(p1.shape, hyd.supply_pressure) if p_s is None else np.broadcast_to(p_s, p1.shape).astype(float)
        p2 = p_s.copy() if p2 is None else np.broadcast_to(np.asarray(p2, dtype=float), p1.shape).copy()
        return cls(p1=p1, p_s=p_s, x_v=spool_position(u_v, leg_params(hyd)), v_v=np.zeros_like(p1), u_b=u_v,
                   v_c=np.zeros_like(p1), p2=p2, v_c2=np.zeros_like(p1))

    def copy(self) -> "PlantState":
        return PlantState(*(np.array(a, dtype=float) for a in self))


# ---------------------------------------------------------------------------------------------------
# scalar physics, one function per equation


@_inline
def spool_position(u_v, P):
    """x_v [m] of an ideal spool at setpoint u_v [V]: (u_v - u_0) x_v,max / u_v,max (seed eq. 3.2)."""
    return (u_v - P.u_0) * (P.x_v_max / P.u_v_max)


@_inline
def flow_areas(x_v, P):
    """Openings (a1 P→A, a2 A→T) [m^2] at spool position x_v [m]: sharp edges with overlap (seed eq.
    3.3), or on the side x_v opens the smooth 300 x_v^2 (eq. 3.11) up to |x_v| = x_a, blended C^1 onto
    the sharp-edged port's pi d (|x_v| - O_l) at x_b and that line beyond, the geometric limit
    (:attr:`hexsim.plant.params.HydraulicParams.smooth_blend`; x_a = inf for ``flow_area="quadratic"``); or the
    smaller of (3.11) and the port's opening, a kink where they cross (``flow_area="port"``: a real spool, its
    overlap a dead band); or (3.11) from null up to where it meets the port's opening, the port beyond
    (``flow_area="rounded"``: a rounded metering edge, no dead band); or
    the opening table's fraction of the full opening pi d x_v,max, each edge at the command that opens it
    (P→A at u = x_v u_v,max / x_v,max, A→T at -u: both open around null where the table starts below it,
    an underlap; :func:`table_opening`); or each edge's flow curve, a monotone cubic through its points
    (``flow_area="curve"``: P→A at u, A→T at -u; :func:`curve_opening`); edge gains not applied."""
    if P.tab_n > 0.5:
        u = x_v * (P.u_v_max / P.x_v_max)
        full = P.port_width * P.x_v_max
        return full * table_opening(u, P), full * table_opening(-u, P)
    if P.cn_pa > 0.5:
        u = x_v * (P.u_v_max / P.x_v_max)
        full = P.port_width * P.x_v_max
        return (full * curve_opening(u, P.cn_pa, P.cu_pa, P.cf_pa, P.cm_pa),
                full * curve_opening(-u, P.cn_at, P.cu_at, P.cf_at, P.cm_at))
    if P.sharp > 2.5:  # rounded: (3.11) from null (no dead band) up to its corner, the port's opening (3.3) beyond
        x = abs(x_v)
        a = P.smooth_gain * x * x if x <= P.blend_end else P.port_width * (x - P.overlap)
        a1 = a if x_v > 0.0 else 0.0
        return a1, a - a1
    if P.sharp > 1.5:  # port: the smaller of (3.11) and the port's opening (3.3), a kink where they cross
        a = min(P.smooth_gain * x_v * x_v, P.port_width * max(abs(x_v) - P.overlap, 0.0))
        a1 = a if x_v > 0.0 else 0.0
        return a1, a - a1
    if P.sharp > 0.5:
        return P.port_width * max(x_v - P.overlap, 0.0), P.port_width * max(-x_v - P.overlap, 0.0)
    x = abs(x_v)
    if x <= P.blend_start:
        a = P.smooth_gain * x_v * x_v
    elif x < P.blend_end:
        a = P.port_width * (x - P.overlap) - P.smooth_gain * (x - P.blend_end) ** 2
    else:
        a = P.port_width * (x - P.overlap)
    a1 = a if x_v > 0.0 else 0.0
    return a1, a - a1


@_inline
def _lerp(u, ua, fa, ub, fb):
    if ub <= ua:
        return fb
    return fa + (fb - fa) * (u - ua) / (ub - ua)


@_inline
def table_opening(u, P):
    """The opening fraction of an edge at the command u [V] that opens it: closed at and below the table's
    first point (tu0, tf0 = 0) of :class:`LegParams`, linear between its points, beyond the last its value."""
    us = (P.tu0, P.tu1, P.tu2, P.tu3, P.tu4, P.tu5, P.tu6, P.tu7, P.tu8, P.tu9, P.tu10, P.tu11)
    fs = (P.tf0, P.tf1, P.tf2, P.tf3, P.tf4, P.tf5, P.tf6, P.tf7, P.tf8, P.tf9, P.tf10, P.tf11)
    if u <= us[0]:
        return 0.0
    for i in range(1, 12):
        if u <= us[i]:
            return _lerp(u, us[i - 1], fs[i - 1], us[i], fs[i])
    return fs[11]


@_jit
def curve_opening(u, n, us, fs, ms):
    """The opening fraction of an edge at the command u [V] that opens it, from its flow curve's n points
    (us [V], fs [-], slopes ms [1/V]; :class:`LegParams` cu/cf/cm): closed at and below the first point, the
    cubic Hermite polynomial between points (a monotone PCHIP, its slopes from
    :attr:`hexsim.plant.params.HydraulicParams.edge_curves`), the last slope beyond the last point. Called, not
    inlined: inlined into each of the leg step's callers it added 11 s (30 %) to the first run's compile."""
    k = int(n) - 1
    if u <= us[0]:
        return 0.0
    if u >= us[k]:
        return fs[k] + ms[k] * (u - us[k])
    lo, hi = 0, k
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if u < us[mid]:
            hi = mid
        else:
            lo = mid
    h = us[hi] - us[lo]
    t = (u - us[lo]) / h
    t2 = t * t
    t3 = t2 * t
    return ((2.0 * t3 - 3.0 * t2 + 1.0) * fs[lo] + (t3 - 2.0 * t2 + t) * h * ms[lo]
            + (-2.0 * t3 + 3.0 * t2) * fs[hi] + (t3 - t2) * h * ms[hi])


@_inline
def edge_flow(a, dp, P):
    """(q, dq/d dp): flow [m^3/s] through one valve edge of opening a [m^2] under the pressure difference
    dp [Pa], and its derivative: the orifice equation (seed eq. 3.4), q = C_d a sqrt(2/rho) sqrt(dp) for
    dp >> Δp_tr, with the two-regime form of Ellman & Piché (ASME J. Dyn. Syst. Meas. Control 121(4),
    1999), q = C_d a sqrt(2/rho) dp / (dp^2 + Δp_tr^2)^(1/4): laminar (∝ dp) below the transition
    pressure :data:`TRANSITION_DP`, turbulent above (relative difference 3e-6 at 30 bar), smooth and odd
    in dp, so a reversed pressure difference reverses the flow and the derivative is finite at dp = 0."""
    r2 = dp * dp + _DP_TR2
    r = math.sqrt(math.sqrt(r2))
    return P.c_v * a * dp / r, P.c_v * a * (0.5 * dp * dp + _DP_TR2) / (r2 * r)


@_inline
def orifice(x_v, p1, p_s, P):
    """(phi_1, d phi_1/d P1): flow into the bottom chamber [m^3/s] through both edges (seed eq. 3.4 per
    edge, :func:`edge_flow`; edge gains k_PA, k_AT) and its exact derivative."""
    a1, a2 = flow_areas(x_v, P)
    q1, dq1 = edge_flow(a1 * P.k_pa, p_s - p1, P)
    q2, dq2 = edge_flow(a2 * P.k_at, p1 - P.p_t, P)
    return q1 - q2, -dq1 - dq2


#: Atmospheric pressure [Pa]: the model's pressures are gauge (P_t = 0), the air's law is absolute.
P_ATM = 101325.0


@_inline
def bulk_modulus(p1, P):
    """Effective bulk modulus [Pa] of the oil at gauge pressure p1 [Pa]: E without entrained air; with an
    air volume fraction a at atmospheric pressure (polytropic exponent n), oil and air springs in series,
    E_eff = E (1 + r) / (1 + r E / (n p)), r = a (p_atm / p)^(1/n), p the absolute pressure (floored at
    1 kPa) — the entrained-air model of hydraulic simulators (e.g. MapleSim's Hydraulics library,
    "Constant Volume"; Gholizadeh, Burton & Schoenau, Int. J. Fluid Power 12(3), 2011)."""
    if P.air <= 0.0:
        return P.bulk_modulus
    p = max(p1 + P_ATM, 1e3)
    r = P.air * (P_ATM / p) ** (1.0 / P.air_exponent)
    return P.bulk_modulus * (1.0 + r) / (1.0 + r * P.bulk_modulus / (P.air_exponent * p))


@_inline
def chamber_step(p, v_c, net, dnet, volume, dt, P):
    """(p [Pa], cavity volume v_c [m^3]) of one chamber after a step dt [s]: seed eq. (3.7) for a chamber
    of oil volume ``volume`` [m^3] whose net inflow (valve, leakage, minus the piston's displacement rate)
    is ``net`` [m^3/s] with derivative ``dnet`` = d net / dp [m^3/(s Pa)]; ``net`` at p, or at the
    cavitation pressure p_cav while a cavity is open (v_c > 0).

    Without a cavity: dp/dt = E / V net, linearly implicit (Rosenbrock–Euler) in p (E =
    :func:`bulk_modulus` at the step's start p). Cavitation: oil cannot be stretched below p_cav (air
    release, vapour; :attr:`hexsim.plant.params.HydraulicParams.cavitation_pressure`). If the step would take
    p below p_cav, p stays at p_cav and a cavity opens with the volume the oil would have had to expand
    by, (p_cav - p') V / E; while it is open the net inflow (at p_cav) fills it; once it is full the rest
    of the step's inflow compresses the oil from p_cav. Flow continuity is kept: every volume that leaves
    the chamber is either the oil's expansion or the cavity's."""
    if v_c > 0.0:
        v_c -= dt * net
        if v_c >= 0.0:
            return P.p_cav, v_c
        return P.p_cav - v_c * bulk_modulus(P.p_cav, P) / volume, 0.0
    stiff = bulk_modulus(p, P) / volume
    p_new = p + dt * stiff * net / (1.0 - dt * stiff * dnet)
    if p_new < P.p_cav:
        return P.p_cav, (P.p_cav - p_new) / stiff
    return p_new, 0.0


@_jit
def pressure_step(p1, v_c, x_v, p_s, y, ydot, dt, P, p_rod):
    """(P1 [Pa], cavity volume v_c [m^3]) after a step dt [s] of the bottom (cap-side) chamber; ydot is
    the piston velocity at the start of the step, ``p_rod`` [Pa] the rod side's pressure the internal
    leakage crosses the piston from (P_s with the 3-way valve, P2 with the 4-way).

    Eq. (3.7): dP1/dt = E / (y A1 + V_pl) (phi_1 + C_l (p_rod - P1) - ydot A1), by :func:`chamber_step`
    (linearly implicit; cavitation at p_cav)."""
    volume = max(y, 0.0) * P.a1 + P.v_pl
    if v_c > 0.0:
        phi, _ = orifice(x_v, P.p_cav, p_s, P)
        return chamber_step(p1, v_c, phi + P.c_l * (p_rod - P.p_cav) - ydot * P.a1, 0.0, volume, dt, P)
    phi, dphi = orifice(x_v, p1, p_s, P)
    if P.c_l != 0.0:
        phi += P.c_l * (p_rod - p1)
        dphi -= P.c_l
    return chamber_step(p1, v_c, phi - ydot * P.a1, dphi, volume, dt, P)


@_inline
def orifice_rod(x_v, p2, p_s, P):
    """(phi_2, d phi_2/d P2): flow into the rod-side chamber B [m^3/s] through the 4-way valve and its
    derivative. The spool opening a1(x_v) that connects P→A connects B→T, a2(x_v) (A→T) connects P→B
    (a matched spool; each edge's gain k_PB, k_BT):
    phi_2 = k_PB C_d a2 sqrt(2 (P_s - P2)/rho) - k_BT C_d a1 sqrt(2 (P2 - P_t)/rho) (seed eq. 3.4 per edge)."""
    a1, a2 = flow_areas(x_v, P)
    q_in, dq_in = edge_flow(a2 * P.k_pb, p_s - p2, P)
    q_out, dq_out = edge_flow(a1 * P.k_bt, p2 - P.p_t, P)
    return q_in - q_out, -dq_in - dq_out


@_jit
def rod_pressure_step(p2, v_c2, x_v, p_s, p1, y, ydot, dt, P):
    """(P2 [Pa], cavity volume [m^3]) of the rod-side chamber after a step dt [s] (4-way valve): eq. (3.7)
    for chamber B, dP2/dt = E / ((L_s - y) A2 + V_pl,B) (phi_2 - C_l (P2 - P1) + ydot A2), by
    :func:`chamber_step`; ``p1`` [Pa] the cap side's pressure at the step's start (internal leakage)."""
    volume = max(P.stroke - y, 0.0) * P.a2 + P.v_pl2
    p = P.p_cav if v_c2 > 0.0 else p2
    phi, dphi = orifice_rod(x_v, p, p_s, P)
    return chamber_step(p2, v_c2, phi - P.c_l * (p - p1) + ydot * P.a2, dphi - P.c_l, volume, dt, P)


@_inline
def friction(v, P):
    """Asymmetric Stribeck friction F_f [N] at piston velocity v [m/s] (seed eq. 3.9):
    sigma v + arctan(k v) [F_c + F_s exp(-|v| / c_s)], the "+" set for v >= 0."""
    shape = math.atan(P.arctan_gain * v) * P.arctan_scale
    if v >= 0.0:
        return P.sigma_pos * v + shape * (P.f_c_pos + P.f_s_pos * math.exp(-abs(v) / P.c_s_pos))
    return P.sigma_neg * v + shape * (P.f_c_neg + P.f_s_neg * math.exp(-abs(v) / P.c_s_neg))


@_inline
def leg_force(p1, p_rod, ydot, P):
    """Hydraulic force on the piston along the leg [N]: P1 A1 - p_rod A2 - F_f(ydot) (seed eq. 3.8
    without the -M g, which the rigid-body simulator applies), p_rod [Pa] the rod side's pressure (P_s
    with the 3-way valve, P2 with the 4-way)."""
    return p1 * P.a1 - p_rod * P.a2 - friction(ydot, P)


@_inline
def backlash(u_b, u, h):
    """The valve's play (hysteresis, seed §4.4) of half width h [V]: the spool's effective setpoint u_b [V]
    follows the setpoint u [V] only where |u - u_b| > h; returns the new u_b."""
    return min(max(u_b, u - h), u + h)


@_jit
def backlash_history(u, h):
    """The play's state before each sample of a setpoint sequence u (n,) [V] of half width h [V]:
    u_b[0] = u[0], u_b[j] = :func:`backlash` (u_b[j-1], u[j-1], h) (the recursion a replay starts each
    window from)."""
    out = np.empty_like(u)
    prev = u[0]
    for j in range(u.shape[0]):
        out[j] = prev
        prev = backlash(prev, u[j], h)
    return out


@_inline
def _spool_step(i, u, dt, S, P):
    """Spool play (backlash of half width h) and the second-order spool loop (semi-implicit Euler,
    x_v limited to ±x_v,max) of leg i, in place in the state S."""
    u_b = backlash(S.u_b[i], u, P.play) if P.play > 0.0 else u
    S.u_b[i] = u_b
    x_set = spool_position(u_b, P)
    if P.f_v > 0.0:
        w = 2.0 * math.pi * P.f_v
        v_v = S.v_v[i] + dt * (w * w * (x_set - S.x_v[i]) - 2.0 * P.zeta_v * w * S.v_v[i])
        x_v = S.x_v[i] + dt * v_v
        if abs(x_v) > P.x_v_max:
            x_v = math.copysign(P.x_v_max, x_v)
            v_v = 0.0
        S.v_v[i] = v_v
        S.x_v[i] = x_v
    else:
        S.x_v[i] = x_set


@_jit
def step_legs(P, dt, u, y, ydot, S, force, groups, supply_flow):
    """One step dt [s] of n legs, in place: parameters P (:func:`leg_table`, (n,) records; the supply's
    from P[0]), valve setpoints u (n,) [V], piston positions y and velocities ydot (n,) at the start of
    the step, state S (:class:`PlantState`), leg forces out ``force`` (n,) [N]; ``groups`` (n,) ints:
    the supply manifold of each leg; ``supply_flow`` (n,) out: the flow phi_s [m^3/s] drawn from
    manifold g in entry g (computed with a supply model, R_s > 0).

    Order: spool play, spool dynamics, P1 (:func:`pressure_step`) and, with a 4-way valve, P2
    (:func:`rod_pressure_step`, from P1 at the step's start), then the supply pressure of each manifold
    (exact first-order update, dP_s/dt = (P_s0 - R_s phi_s - P_s) / tau_s, with the step's supply flow
    phi_s = sum of phi_PA + C_l (P_s - P1) - ydot A2 (3-way) or phi_PA + phi_PB (4-way)), then the leg
    force with the new P1 and P_s or P2 (:func:`leg_force`). With the 3-way valve P2 is set to P_s.

    Timing: the force from the new P1 acts over the mechanics step that follows (MuJoCo's semi-implicit
    Euler), so P1 is staggered half a step from y, ydot (leapfrog: P1 steps from t - h/2 to t + h/2 with
    the flow at t). An ideal spool (f_v = 0) jumps at the controller sample t_k, the middle of that
    interval: the step's flow is half at the old opening and half at the new (two half steps of
    :func:`pressure_step`). Taking the new opening for the whole step put every valve change half a step
    early: on the default heave at 1e-4 s, against 1e-5 s, the worst single buffered reversal peak was
    2.13 % off, 0.44 % with the split (roll/pitch/yaw/surge/sway: 1.5–4.2 % before, 0.5–1.7 % after).
    A spool with dynamics (f_v > 0) moves every step; its flow uses the step's end position."""
    p1, p_s, p2, x_v = S.p1, S.p_s, S.p2, S.x_v
    n = p1.shape[0]
    supply = P[0]
    if supply.r_s > 0.0:
        supply_flow[:] = 0.0
    for i in range(n):
        Pi = P[i]
        x_old = x_v[i]
        _spool_step(i, u[i], dt, S, Pi)
        if Pi.f_v == 0.0 and x_v[i] != x_old:  # the valve switched at this step's start: see Timing
            _chambers(i, x_old, y[i], ydot[i], 0.5 * dt, S, Pi)
            _chambers(i, x_v[i], y[i], ydot[i], 0.5 * dt, S, Pi)
        else:
            _chambers(i, x_v[i], y[i], ydot[i], dt, S, Pi)
        if supply.r_s > 0.0:
            areas = flow_areas(S.x_v[i], Pi)
            dps = S.p_s[i] - S.p1[i]
            phi_pa = edge_flow(areas[0] * Pi.k_pa, dps, Pi)[0]
            if Pi.four_way > 0.5:
                supply_flow[groups[i]] += phi_pa + edge_flow(areas[1] * Pi.k_pb, S.p_s[i] - p2[i], Pi)[0]
            else:
                supply_flow[groups[i]] += phi_pa + Pi.c_l * dps - ydot[i] * Pi.a2
    if supply.r_s > 0.0:
        decay = math.exp(-dt / supply.tau_s)
        for i in range(n):
            target = supply.p_s0 - supply.r_s * supply_flow[groups[i]]
            S.p_s[i] = max(target + (S.p_s[i] - target) * decay, supply.p_t)
    for i in range(n):
        if P[i].four_way > 0.5:
            force[i] = leg_force(p1[i], p2[i], ydot[i], P[i])
        else:
            p2[i] = p_s[i]
            force[i] = leg_force(p1[i], p_s[i], ydot[i], P[i])


@_jit
def _chambers(i, x_v, y, ydot, dt, S, P):
    """Leg i's chamber pressures over dt [s] at spool position x_v [m], in place in the state S: P1
    (:func:`pressure_step`) and, with a 4-way valve, P2 (:func:`rod_pressure_step`), both from the
    pressures at the step's start."""
    if P.four_way > 0.5:
        p1_old = S.p1[i]
        S.p1[i], S.v_c[i] = pressure_step(p1_old, S.v_c[i], x_v, S.p_s[i], y, ydot, dt, P, S.p2[i])
        S.p2[i], S.v_c2[i] = rod_pressure_step(S.p2[i], S.v_c2[i], x_v, S.p_s[i], p1_old, y, ydot, dt, P)
    else:
        S.p1[i], S.v_c[i] = pressure_step(S.p1[i], S.v_c[i], x_v, S.p_s[i], y, ydot, dt, P, S.p_s[i])


def step_plant(state: PlantState, u_v, y, ydot, dt: float, hyd: HydraulicParams, eff: Effects,
               groups: np.ndarray | None = None, changes: tuple[LegChange, ...] = ()) -> tuple[PlantState, np.ndarray]:
    """Advance n legs by ``dt`` [s] from Python: valve setpoints u_v [V] (n,) or scalar, piston positions
    y [m] and velocities ydot [m/s] (n,) at the start of the step. Returns (new state, leg forces (n,) [N]);
    ``state`` is left unchanged. ``groups`` (n,) ints: legs sharing a supply manifold (the hexapod: all
    zeros); default each leg its own supply. ``changes``: legs whose parameters differ
    (:func:`leg_table`). Runs :func:`step_legs`, the compiled runners' step."""
    return advance_legs(state, u_v, y, ydot, dt, leg_table(hyd, eff, state.p1.shape[0], changes), groups)


def advance_legs(state: PlantState, u_v, y, ydot, dt: float, table: np.ndarray,
                 groups: np.ndarray | None = None) -> tuple[PlantState, np.ndarray]:
    """:func:`step_plant` with the parameters already as a :func:`leg_table` (n,)."""
    new = state.copy()
    n = new.p1.shape[0]
    u = np.broadcast_to(np.asarray(u_v, dtype=float), (n,)).copy()
    groups = np.arange(n) if groups is None else np.asarray(groups, dtype=np.intp)
    force = np.empty(n)
    step_legs(table, float(dt), u, np.asarray(y, dtype=float), np.asarray(ydot, dtype=float), new, force, groups,
              np.zeros(n))
    return new, force
