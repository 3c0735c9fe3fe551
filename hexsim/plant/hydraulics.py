"""Valve, chamber and friction of a valve-controlled asymmetric cylinder: the seed's equations on arrays.

The seed's chapter 3 ("Compensation of the reversal bump", Rexroth-Hydraudyne / TU Eindhoven 2005), one
function per equation, for analysis (flow curves, friction curves, statics, identification). Every
function takes arrays (one entry per leg, shape ``(n,)``; any shape that broadcasts, scalars too) and a
:class:`~hexsim.plant.params.HydraulicParams`, has no side effects and imports nothing from MuJoCo. The
physics itself is written once, as the compiled scalar functions of :mod:`hexsim.plant.legs` that the
simulation steps with; the functions here map those over arrays.

Sign conventions: piston position y [m] is 0 fully retracted and grows when the leg extends; flow
phi_1 > 0 fills the bottom chamber; the leg force > 0 extends the leg.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np

from hexsim import jitcache
from hexsim.plant import legs
from hexsim.plant.effects import NOMINAL, Effects
from hexsim.plant.legs import TRANSITION_DP, leg_params
from hexsim.plant.params import HydraulicParams

__all__ = ["TRANSITION_DP", "spool_position", "flow_areas", "edge_flow", "valve_flow", "valve_flow_dp1", "valve_flow_rod",
           "static_velocity", "steady_state", "SteadyState", "chamber_volume", "pressure_rate", "step_pressure",
           "friction_force", "leg_force", "equilibrium_pressure", "rest_pressures", "eigenfrequency"]

_jit = numba.njit(cache=True)


def _flat(*arrays):
    """The arguments broadcast together, as contiguous float arrays (size,), and their common shape."""
    b = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in arrays))
    return [np.array(a, order="C").ravel() for a in b], b[0].shape


def _shaped(out, shape):
    return out.reshape(shape) if shape else out[0]


@_jit
def _map_areas(x, P, a1, a2):
    for i in range(x.shape[0]):
        a1[i], a2[i] = legs.flow_areas(x[i], P)


@_jit
def _map_orifice(x, p1, p_s, P, phi, dphi):
    for i in range(x.shape[0]):
        phi[i], dphi[i] = legs.orifice(x[i], p1[i], p_s[i], P)


@_jit
def _map_edge(a, dp, P, q):
    for i in range(a.shape[0]):
        q[i] = legs.edge_flow(a[i], dp[i], P)[0]


@_jit
def _map_pressure_step(p1, x, p_s, y, ydot, dt, P, out):
    for i in range(x.shape[0]):
        out[i] = legs.pressure_step(p1[i], 0.0, x[i], p_s[i], y[i], ydot[i], dt, P, p_s[i])[0]


@_jit
def _map_orifice_rod(x, p2, p_s, P, phi, dphi):
    for i in range(x.shape[0]):
        phi[i], dphi[i] = legs.orifice_rod(x[i], p2[i], p_s[i], P)


@_jit
def _map_friction(v, P, out):
    for i in range(v.shape[0]):
        out[i] = legs.friction(v[i], P)


@_jit
def _map_leg_force(p1, p_s, v, P, out):
    for i in range(v.shape[0]):
        out[i] = legs.leg_force(p1[i], p_s[i], v[i], P)


# the array maps compile in the scalar physics of hexsim.plant.legs: drop their cache when that file changes
jitcache.guard((_map_areas, _map_edge, _map_orifice, _map_orifice_rod, _map_pressure_step, _map_friction,
                _map_leg_force),
               legs.__file__)


def spool_position(u_v, p: HydraulicParams):
    """Valve spool position x_v [m] from the valve setpoint u_v [V] (seed eq. 3.2), shaped like u_v.

    The spool's own position loop has a high bandwidth (seed §3.2.1), so
    x_v = (u_v - u_0) x_v,max / u_v,max, with u_0 = ``p.null_offset`` the setpoint at which the spool is
    centred (0 in the seed; it drifts with temperature, seed §5.3). u_v is expected inside ±u_v,max
    (the controller saturates it). (:func:`hexsim.plant.legs.spool_position`, elementwise.)
    """
    return legs.spool_position(np.asarray(u_v, dtype=float), leg_params(p))


def flow_areas(x_v, p: HydraulicParams):
    """Valve openings (a1, a2) [m^2]: a1 supply → chamber (P-A), a2 chamber → tank (A-T).

    ``p.flow_area == "sharp"``: sharp-edged spool with overlap O_l, seed eq. (3.3):
    a1 = pi d (x_v - O_l) for x_v > O_l, a2 = -pi d (x_v + O_l) for x_v < -O_l, else 0.
    ``p.flow_area == "smooth"`` (default): a_i = 300 x_v^2 on the side x_v opens, seed eq. (3.11),
    which the seed adopts because the kink of (3.3) at ±O_l excites the hydraulic eigenfrequency; the
    seed matched its gain to (3.3) over the working range, and past |x_v| = 0.1 mm it would grow beyond
    the port's full-perimeter opening pi d (|x_v| - O_l), 10.5× at full stroke. So it is blended C^1
    onto that line between x_a = 86 µm and x_b = 119 µm (0.78–1.08 V) and follows the line beyond
    (:attr:`~hexsim.plant.params.HydraulicParams.smooth_blend`). ``p.flow_area == "quadratic"``: (3.11) at every
    opening, as the seed simulated. ``p.flow_area == "port"``: the smaller of (3.11) and the port's opening
    (3.3), a kink where they cross (0.90 V with the seed's values) and the overlap
    a dead band (a real spool). ``p.flow_area == "rounded"``: (3.11) from null, no dead band (a rounded metering
    edge passes flow as soon as the spool moves), up to where it meets the port's opening (3.3), the port
    beyond: the same kink, the overlap only placing the port's line
    (:attr:`~hexsim.plant.params.HydraulicParams.rounded_corner`). ``p.flow_area == "table"``: the opening
    table's fraction of pi d x_v,max,
    a1 at the command u = x_v u_v,max / x_v,max and a2 at -u (both open around null where the table starts
    below it: an underlap).

    Returns two arrays shaped like ``x_v`` (:func:`hexsim.plant.legs.flow_areas`, elementwise).
    """
    (x,), shape = _flat(x_v)
    a1, a2 = np.empty_like(x), np.empty_like(x)
    _map_areas(x, leg_params(p), a1, a2)
    return _shaped(a1, shape), _shaped(a2, shape)


def as_curve(p: HydraulicParams, open_earlier_V: float = 0.0) -> HydraulicParams:
    """``p`` with its valve's openings as each edge's curve (flow area "curve"): its own form's P→A opening at
    the command u and A→T opening at -u (:func:`flow_areas`, from 0.2 V below null, or from where the file's curve
    or table opens if lower, to u_v,max, a millivolt apart near null), thinned
    (:func:`hexsim.plant.params.thin_curve`), each edge opening ``open_earlier_V``
    [V] earlier (negative: later; the dead band narrower or wider by twice it, an underlap or more overlap
    than the file's). What a calibration may have got wrong near null, as a machine to try a compensator on
    (:mod:`hexsim.studies.tuning`'s neighbours). The edge gains stay the effects'."""
    from hexsim.plant.params import MAX_CURVE_POINTS, thin_curve

    firsts = ([c[0][0] for c in (p.flow_curve_pa, p.flow_curve_at) if c] if p.flow_area == "curve" else
              [p.opening_table[0][0]] if p.flow_area == "table" and p.opening_table else [])
    lo = min([-0.2, *firsts])  # an underlapped valve's curve read from its flows opens up to 0.5 V before null
    u = np.unique(np.concatenate([np.linspace(lo, 0.5, int(round((0.5 - lo) / 1e-3)) + 1),
                                  np.linspace(0.5, p.u_v_max, 951)]))
    x = u / p.u_v_max * p.x_v_max
    full = np.pi * p.spool_diameter * p.x_v_max
    edges = []
    for a in (flow_areas(x, p)[0], flow_areas(-x, p)[1]):
        value = np.maximum.accumulate(np.maximum(a / full, 0.0))
        points = [[round(v - open_earlier_V, 6), f] for v, f in thin_curve(u, value)]
        if points[-1][0] < p.u_v_max:  # opened earlier: the last point moved below the range's end
            (u0, f0), (u1, f1) = points[-2], points[-1]
            end = [p.u_v_max, f1 + (f1 - f0) / (u1 - u0) * (p.u_v_max - u1)]  # the last segment carried on
            if len(points) < MAX_CURVE_POINTS:
                points.append(end)
            else:  # a file holds at most MAX_CURVE_POINTS: the last point moves to the end on that line
                points[-1] = end
        edges.append(tuple(tuple(q) for q in points))
    return p.replace(flow_area="curve", opening_table=(), flow_curve_pa=edges[0], flow_curve_at=edges[1], overlap=0.0)


@_jit
def _chamber_flow(x_v, q, p_s, P, rod):
    """(phi, d phi/dP) into the cap-side chamber at pressure q (:func:`hexsim.plant.legs.orifice`) or, when
    ``rod``, into the rod side (:func:`~hexsim.plant.legs.orifice_rod`)."""
    return legs.orifice_rod(x_v, q, p_s, P) if rod else legs.orifice(x_v, q, p_s, P)


@_jit
def _chamber_pressure(x_v, target, p_s, P, rod, lo, hi):
    """The chamber pressure in [lo, hi] [Pa] at which the valve's flow into it (:func:`_chamber_flow`) equals
    ``target`` [m^3/s]; NaN if it does not within [lo, hi]. The flow falls monotonically with the pressure
    (d phi/dP <= 0), so Newton's step on the exact derivative, kept inside a bisection bracket, converges to
    1e-6 Pa (as scipy's brentq did here, 20x the cost from Python)."""
    f_lo = _chamber_flow(x_v, lo, p_s, P, rod)[0] - target
    f_hi = _chamber_flow(x_v, hi, p_s, P, rod)[0] - target
    if f_lo == 0.0:
        return lo
    if f_hi == 0.0:
        return hi
    if (f_lo > 0.0) == (f_hi > 0.0):
        return math.nan
    q = 0.5 * (lo + hi)
    for _ in range(200):
        f, df = _chamber_flow(x_v, q, p_s, P, rod)
        f -= target
        if f == 0.0:
            return q
        if (f > 0.0) == (f_lo > 0.0):
            lo = q
        else:
            hi = q
        step = f / df if df < 0.0 else math.inf
        nxt = q - step
        if not (lo < nxt < hi):
            nxt = 0.5 * (lo + hi)
        if abs(nxt - q) < 1e-6 or hi - lo < 1e-6:
            return nxt
        q = nxt
    return q


def edge_flow(area, dp, p: HydraulicParams):
    """Flow [m^3/s] through one valve edge of opening ``area`` [m^2] (edge gain applied by the caller)
    under the pressure difference ``dp`` [Pa] (upstream minus downstream): the orifice equation (seed eq.
    3.4) with its laminar range below :data:`TRANSITION_DP` (:func:`hexsim.plant.legs.edge_flow`,
    elementwise). Arrays broadcast."""
    (a, d), shape = _flat(area, dp)
    q = np.empty_like(a)
    _map_edge(a, d, leg_params(p), q)
    return _shaped(q, shape)


def _orifice(x_v, p1, p: HydraulicParams, p_s, eff: Effects = NOMINAL):
    """phi_1 (seed eq. 3.4) and d phi_1 / d P1, arrays broadcast (:func:`hexsim.plant.legs.orifice`)."""
    p_s = p.supply_pressure if p_s is None else p_s
    (x, q1, qs), shape = _flat(x_v, p1, p_s)
    phi, dphi = np.empty_like(x), np.empty_like(x)
    _map_orifice(x, q1, qs, leg_params(p, eff), phi, dphi)
    return _shaped(phi, shape), _shaped(dphi, shape)


def valve_flow(x_v, p1, p: HydraulicParams, p_s=None, eff: Effects = NOMINAL):
    """Flow phi_1 [m^3/s] into the bottom chamber through the 3-way valve (seed eq. 3.4).

    phi_1 = C_d a1(x_v) sqrt(2 (P_s - P1)/rho) - C_d a2(x_v) sqrt(2 (P1 - P_t)/rho), each edge by
    :func:`edge_flow`: odd in the pressure difference (a reversed difference reverses the flow through
    that edge) and laminar below 0.1 bar. ``p_s`` [Pa] overrides the supply pressure
    (scalar or per leg); default ``p.supply_pressure``. ``eff``: the edge gains k_PA, k_AT. Arrays broadcast.
    """
    return _orifice(x_v, p1, p, p_s, eff)[0]


def valve_flow_dp1(x_v, p1, p: HydraulicParams, p_s=None):
    """d phi_1 / d P1 [m^3/(s Pa)] of :func:`valve_flow`, always <= 0.

    Used by the linearly implicit pressure update; finite at a closed or balanced edge (the laminar
    range of :func:`edge_flow`).
    """
    return _orifice(x_v, p1, p, p_s)[1]


def valve_flow_rod(x_v, p2, p: HydraulicParams, p_s=None, eff: Effects = NOMINAL):
    """Flow phi_2 [m^3/s] into the rod-side chamber B through a 4-way valve at spool position x_v [m] and
    rod-side pressure p2 [Pa]: P→B opens where A→T does, B→T where P→A does (seed eq. 3.4 per edge,
    :func:`hexsim.plant.legs.orifice_rod`; ``eff``: the edge gains k_PB, k_BT). ``p_s`` [Pa] default
    ``p.supply_pressure``. Arrays broadcast."""
    p_s = p.supply_pressure if p_s is None else p_s
    (x, q2, qs), shape = _flat(x_v, p2, p_s)
    phi, dphi = np.empty_like(x), np.empty_like(x)
    _map_orifice_rod(x, q2, qs, leg_params(p, eff), phi, dphi)
    return _shaped(phi, shape)


class SteadyState(NamedTuple):
    """A cylinder moving at constant speed under a constant valve setpoint: velocity [m/s], cap-side P1
    and rod-side P2 [Pa] (P2 = P_s with the 3-way valve), the friction force [N] at that speed."""

    velocity: float
    p1: float
    p2: float
    friction: float


def steady_state(u_v: float, load_force: float, p: HydraulicParams, p_s: float | None = None,
                 eff: Effects = NOMINAL) -> SteadyState:
    """The steady motion at valve setpoint u_v [V] against an external force ``load_force`` [N] along the
    axis (positive retracts the piston: the weight M g cos θ of a load it lifts): the velocity v at which
    flow continuity holds in each chamber (phi_1 = v A1; 4-way also phi_2 = -v A2, seed eq. 3.7 with
    dP/dt = 0) and the piston's forces balance, P1 A1 - P2 A2 - F_f(v) = load_force (seed eq. 3.8 with
    ÿ = 0). Solved by bracketing v (scipy.optimize.brentq) with each chamber's pressure from its own
    continuity equation. ``eff``: the valve's edge gains (k_PA, k_AT, k_PB, k_BT) and null offset are the
    hydraulics'; leakage, spool dynamics and the supply's sag are not in this steady state. Raises
    ValueError if no speed balances (the load is beyond the stall force at that setpoint)."""
    from scipy.optimize import brentq

    p_s = p.supply_pressure if p_s is None else float(p_s)
    x_v = float(spool_position(u_v, p))
    P = leg_params(p, eff)  # once: each speed's chamber solves call the compiled flows many times

    def chamber(rod: bool, target: float) -> float:  # the pressure at which the flow into it is target
        q = _chamber_pressure(x_v, target, p_s, P, rod, p.cavitation_pressure, p_s + 1e7)
        if math.isnan(q):
            raise ValueError(f"no chamber pressure gives {target:g} m^3/s")
        return q

    def pressures(v: float) -> tuple[float, float]:
        p1 = chamber(False, v * p.area_bottom)
        p2 = chamber(True, -v * p.area_rod) if p.four_way else p_s
        return p1, p2

    def imbalance(v: float) -> float:
        p1, p2 = pressures(v)
        return p1 * p.area_bottom - p2 * p.area_rod - legs.friction(v, P) - load_force

    reach = []  # the speeds at which both chambers can still follow (the flow at the pressure limits)
    for rod, area in ((False, p.area_bottom), (True, -p.area_rod))[:2 if p.four_way else 1]:
        ends = [_chamber_flow(x_v, q, p_s, P, rod)[0] / area for q in (p.cavitation_pressure, p_s + 1e7)]
        reach.append((min(ends), max(ends)))
    lo, hi = max(r[0] for r in reach), min(r[1] for r in reach)
    lo, hi = lo + 1e-9 * abs(lo) + 1e-12, hi - 1e-9 * abs(hi) - 1e-12
    try:
        v = brentq(imbalance, lo, hi, xtol=1e-9)
    except ValueError:
        raise ValueError(f"no steady motion at u_v = {u_v:g} V against {load_force:g} N (stalled)") from None
    p1, p2 = pressures(v)
    return SteadyState(v, p1, p2, float(legs.friction(v, P)))


def static_velocity(u_v, p1, p: HydraulicParams, p_s=None):
    """Piston velocity [m/s] at valve setpoint u_v [V] in steady state (dP1/dt = 0, bottom pressure p1 [Pa]):
    phi_1(x_v(u_v), P1) / A1, the static flow curve of seed eq. (5.1). Arrays broadcast."""
    return valve_flow(spool_position(u_v, p), p1, p, p_s) / p.area_bottom


def chamber_volume(y, p: HydraulicParams):
    """Oil volume [m^3] between valve and piston: y A1 + V_pl (seed eq. 3.7), y clipped at 0."""
    return np.maximum(np.asarray(y, dtype=float), 0.0) * p.area_bottom + p.pipeline_volume


def pressure_rate(phi_1, y, ydot, p: HydraulicParams):
    """dP1/dt [Pa/s] of the bottom chamber: E / (y A1 + V_pl) (phi_1 - ydot A1) (seed eq. 3.7).

    Continuity and compressibility (seed eq. 3.6) with no leakage, the pipeline volume lumped into the
    chamber (valid up to ~500 Hz, seed eq. 3.1).
    """
    return p.bulk_modulus / chamber_volume(y, p) * (phi_1 - ydot * p.area_bottom)


def step_pressure(p1, u_v, y, ydot, dt: float, p: HydraulicParams, p_s=None):
    """Bottom-chamber pressure P1 [Pa] after one step of ``dt`` [s] (seed eq. 3.2, 3.4, 3.7).

    Linearly implicit (Rosenbrock-Euler) in P1: P1' = P1 + dt f / (1 - dt df/dP1), with
    f = :func:`pressure_rate`. The valve-chamber pole E/V dphi/dP1 is far faster than dt at large
    openings (about 0.3 ms at u_v = 10 V), where explicit Euler would diverge; where it is slow the
    update equals explicit Euler to first order. The piston velocity ``ydot`` is taken at the start of
    the step; the mechanical side then uses the new P1 (symplectic Euler for the 109 Hz oil spring).
    Arrays broadcast, (n,) in, (n,) out (:func:`hexsim.plant.legs.pressure_step`, elementwise, from a chamber
    without a cavity: P1 does not fall below the cavitation pressure; the effects' version of a whole step,
    with the cavity's volume kept from step to step, is :func:`hexsim.plant.legs.step_legs`).
    """
    p_s = p.supply_pressure if p_s is None else p_s
    (q1, u, qs, yy, yd), shape = _flat(p1, u_v, p_s, y, ydot)
    P = leg_params(p)
    x = spool_position(u, p)
    out = np.empty_like(q1)
    _map_pressure_step(q1, x, qs, yy, yd, float(dt), P, out)
    return _shaped(out, shape)


def friction_force(ydot, p: HydraulicParams):
    """Asymmetric Stribeck friction F_f [N] opposing the piston velocity ydot [m/s] (seed eq. 3.9),
    shaped like ydot.

    F_f = sigma ydot + arctan(k ydot) [F_c0 + F_s0 exp(-|ydot| / c_s)], with the "+" parameters for
    ydot >= 0 and the "-" parameters for ydot < 0 (seed eq. 2.4, app. A). See
    :attr:`HydraulicParams.arctan_normalised` for the scale of arctan: as published it tends to ±pi/2.
    (:func:`hexsim.plant.legs.friction`, elementwise.)
    """
    (v,), shape = _flat(ydot)
    out = np.empty_like(v)
    _map_friction(v, leg_params(p), out)
    return _shaped(out, shape)


def leg_force(p1, ydot, p: HydraulicParams, p_s=None):
    """Hydraulic force on the piston along the leg [N]: P1 A1 - P_s A2 - F_f(ydot) (seed eq. 3.8),
    arrays broadcast (:func:`hexsim.plant.legs.leg_force`, elementwise). For a 4-way valve pass the
    rod-side pressure P2 as ``p_s``.

    Gravity (the -M g of eq. 3.8) is not included: the rigid-body simulator applies it.
    """
    p_s = p.supply_pressure if p_s is None else p_s
    (q1, qs, v), shape = _flat(p1, p_s, ydot)
    out = np.empty_like(v)
    _map_leg_force(q1, qs, v, leg_params(p), out)
    return _shaped(out, shape)


def equilibrium_pressure(load_force, p: HydraulicParams, p_s=None):
    """P1 [Pa] that holds ``load_force`` [N] (the leg force needed at rest) with ydot = 0.

    Solves P1 A1 - P_s A2 = load_force. For the vertical single actuator load_force = M g, which gives
    the seed's initial condition P1(0) = (P_s - P_t) A2/A1 + M g / A1 (seed §3.3) with P_t = 0.
    """
    p_s = p.supply_pressure if p_s is None else p_s
    return (np.asarray(load_force, dtype=float) + p_s * p.area_rod) / p.area_bottom


def rest_pressures(load_force, p: HydraulicParams, p_s=None):
    """(P1, P2) [Pa] of a leg holding ``load_force`` [N] at rest. 3-way: P2 = P_s and P1 from
    :func:`equilibrium_pressure`. 4-way: P1 A1 - P2 A2 = load_force with P1 + P2 = P_s + P_t, the
    null-position sum of a matched, symmetric spool (each chamber between equal P and T edges sits at
    (P_s + P_t)/2 without load; a load shifts the two by the same amount in opposite directions, as the
    spool moves off null to hold it). Arrays broadcast."""
    p_s = p.supply_pressure if p_s is None else p_s
    load = np.asarray(load_force, dtype=float)
    if not p.four_way:
        return equilibrium_pressure(load, p, p_s), np.broadcast_to(np.asarray(p_s, dtype=float), load.shape).copy()
    total = np.asarray(p_s, dtype=float) + p.tank_pressure
    p2 = (total * p.area_bottom - load) / (p.area_bottom + p.area_rod)
    return total - p2, p2


def eigenfrequency(mass: float, p: HydraulicParams, *, stroke: float | None = None, y: float | None = None) -> float:
    """Hydraulic eigenfrequency f_e [Hz] of the oil spring in the bottom chamber with moving mass M [kg].

    With ``stroke`` L_s [m]: the seed's estimate f_e = sqrt(2 E A1 / (M L_s)) / (2 pi) (seed §3.3,
    ≈ 109 Hz for app. A). With ``y`` [m]: the stiffness of eq. (3.7) at that piston position,
    E A1^2 / (y A1 + V_pl). Raises ValueError if neither or both are given.
    """
    if (stroke is None) == (y is None):
        raise ValueError("eigenfrequency needs exactly one of stroke= or y=")
    if y is None:
        stiffness = 2.0 * p.bulk_modulus * p.area_bottom / stroke
    else:
        stiffness = p.bulk_modulus * p.area_bottom**2 / float(chamber_volume(y, p))
    return float(np.sqrt(stiffness / mass) / (2.0 * np.pi))
