"""Valve, chamber and friction of a valve-controlled asymmetric cylinder: pure functions on arrays.

The seed's chapter 3 ("Compensation of the reversal bump", Rexroth-Hydraudyne / TU Eindhoven 2005), one
function per equation. Every function takes arrays with one entry per leg (shape ``(n,)``; scalars work
too) and a :class:`~hexsim.params.HydraulicParams`, has no side effects and imports nothing from MuJoCo,
so a compiled kernel can replace the per-step loop without changing the physics.

Sign conventions: piston position y [m] is 0 fully retracted and grows when the leg extends; flow
phi_1 > 0 fills the bottom chamber; the leg force > 0 extends the leg.
"""

from __future__ import annotations

import numpy as np

from hexsim.params import HydraulicParams

#: Pressure difference [Pa] below which the Jacobian of the orifice flow is evaluated as if it were this
#: large. Only the linearly implicit integrator uses the Jacobian; the flow itself is exact.
JACOBIAN_DP_FLOOR = 1.0e4


def spool_position(u_v, p: HydraulicParams):
    """Valve spool position x_v [m] from the valve setpoint u_v [V] (seed eq. 3.2).

    The spool's own position loop has a high bandwidth (seed §3.2.1), so
    x_v = (u_v - u_0) x_v,max / u_v,max, with u_0 = ``p.null_offset`` the setpoint at which the spool is
    centred (0 in the seed; it drifts with temperature, seed §5.3). u_v is expected inside ±u_v,max
    (the controller saturates it).
    """
    return (np.asarray(u_v, dtype=float) - p.null_offset) * (p.x_v_max / p.u_v_max)


def flow_areas(x_v, p: HydraulicParams):
    """Valve openings (a1, a2) [m^2]: a1 supply → chamber (P-A), a2 chamber → tank (A-T).

    ``p.flow_area == "sharp"``: sharp-edged spool with overlap O_l, seed eq. (3.3):
    a1 = pi d (x_v - O_l) for x_v > O_l, a2 = -pi d (x_v + O_l) for x_v < -O_l, else 0.
    ``p.flow_area == "smooth"`` (default): a_i = 300 x_v^2 on the side x_v opens, seed eq. (3.11),
    which the seed adopts because the kink of (3.3) at ±O_l excites the hydraulic eigenfrequency.

    Returns two arrays shaped like ``x_v``.
    """
    x_v = np.asarray(x_v, dtype=float)
    if p.flow_area == "sharp":
        w = np.pi * p.spool_diameter
        return w * np.maximum(x_v - p.overlap, 0.0), w * np.maximum(-x_v - p.overlap, 0.0)
    a = p.smooth_area_gain * x_v * x_v
    a1 = a * (x_v > 0.0)
    return a1, a - a1


def _orifice(x_v, p1, p: HydraulicParams, p_s, edge_gains=(1.0, 1.0)):
    """phi_1 (seed eq. 3.4) and d phi_1 / d P1, computed together from one evaluation of the areas;
    ``edge_gains`` (k_PA, k_AT) scale the two edges' openings (:class:`hexsim.effects.Effects`)."""
    p_s = p.supply_pressure if p_s is None else p_s
    a1, a2 = flow_areas(x_v, p)
    a1, a2 = a1 * edge_gains[0], a2 * edge_gains[1]
    dp1 = p_s - p1
    dp2 = p1 - p.tank_pressure
    s1 = np.sqrt(np.abs(dp1))
    s2 = np.sqrt(np.abs(dp2))
    k = p.orifice_constant
    phi = k * (a1 * np.copysign(s1, dp1) - a2 * np.copysign(s2, dp2))
    floor = np.sqrt(JACOBIAN_DP_FLOOR)
    dphi = -0.5 * k * (a1 / np.maximum(s1, floor) + a2 / np.maximum(s2, floor))
    return phi, dphi


def valve_flow(x_v, p1, p: HydraulicParams, p_s=None):
    """Flow phi_1 [m^3/s] into the bottom chamber through the 3-way valve (seed eq. 3.4).

    phi_1 = C_d a1(x_v) sqrt(2 (P_s - P1)/rho) - C_d a2(x_v) sqrt(2 (P1 - P_t)/rho).
    The square root is taken signed (sqrt|dp| sign dp) so a reversed pressure difference reverses the
    flow through that edge instead of producing NaN. ``p_s`` [Pa] overrides the supply pressure
    (scalar or per leg); default ``p.supply_pressure``.
    """
    return _orifice(x_v, p1, p, p_s)[0]


def valve_flow_dp1(x_v, p1, p: HydraulicParams, p_s=None):
    """d phi_1 / d P1 [m^3/(s Pa)] of :func:`valve_flow`, always <= 0.

    Used by the linearly implicit pressure update; the pressure difference is floored at
    :data:`JACOBIAN_DP_FLOOR` so the derivative stays finite at a closed or balanced edge.
    """
    return _orifice(x_v, p1, p, p_s)[1]


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


def step_pressure(p1, u_v, y, ydot, dt: float, p: HydraulicParams, p_s=None, *, x_v=None, leakage=0.0,
                  edge_gains=(1.0, 1.0)):
    """Bottom-chamber pressure P1 [Pa] after one step of ``dt`` [s] (seed eq. 3.2, 3.4, 3.7).

    Linearly implicit (Rosenbrock-Euler) in P1: P1' = P1 + dt f / (1 - dt df/dP1), with
    f = :func:`pressure_rate`. The valve-chamber pole E/V dphi/dP1 is far faster than dt at large
    openings (about 30 µs at u_v = 10 V), where explicit Euler would diverge; where it is slow the
    update equals explicit Euler to first order. The piston velocity ``ydot`` is taken at the start of
    the step; the mechanical side then uses the new P1 (symplectic Euler for the 109 Hz oil spring).

    ``x_v`` [m] overrides the spool position computed from u_v (a spool with its own dynamics,
    :mod:`hexsim.effects`); ``leakage`` C_l [m^3/(s Pa)] adds the internal leakage across the piston
    C_l (P_s - P1) to phi_1 (the rod side is at P_s), zero in the seed; ``edge_gains`` (k_PA, k_AT)
    scale the supply and return edges (1, 1 in the seed). Arrays of shape (n,) in, (n,) out.
    """
    x_v = spool_position(u_v, p) if x_v is None else x_v
    phi, dphi = _orifice(x_v, p1, p, p_s, edge_gains)
    if leakage:  # a scalar C_l
        phi = phi + leakage * ((p.supply_pressure if p_s is None else p_s) - p1)
        dphi = dphi - leakage
    stiffness = p.bulk_modulus / chamber_volume(y, p)
    return p1 + dt * stiffness * (phi - ydot * p.area_bottom) / (1.0 - dt * stiffness * dphi)


def friction_force(ydot, p: HydraulicParams):
    """Asymmetric Stribeck friction F_f [N] opposing the piston velocity ydot [m/s] (seed eq. 3.9).

    F_f = sigma ydot + arctan(k ydot) [F_c0 + F_s0 exp(-|ydot| / c_s)], with the "+" parameters for
    ydot >= 0 and the "-" parameters for ydot < 0 (seed eq. 2.4, app. A). See
    :attr:`HydraulicParams.arctan_normalised` for the scale of arctan: as published it tends to ±pi/2.
    """
    ydot = np.asarray(ydot, dtype=float)
    sigma, f_c, f_s, c_s = p.stribeck_table[(ydot >= 0.0).astype(np.intp)].T
    shape = np.arctan(p.arctan_gain * ydot)
    if p.arctan_normalised:
        shape = shape * (2.0 / np.pi)
    return sigma * ydot + shape * (f_c + f_s * np.exp(-np.abs(ydot) / c_s))


def leg_force(p1, ydot, p: HydraulicParams, p_s=None):
    """Hydraulic force on the piston along the leg [N]: P1 A1 - P_s A2 - F_f(ydot) (seed eq. 3.8).

    Gravity (the -M g of eq. 3.8) is not included: the rigid-body simulator applies it.
    """
    p_s = p.supply_pressure if p_s is None else p_s
    return p1 * p.area_bottom - p_s * p.area_rod - friction_force(ydot, p)


def equilibrium_pressure(load_force, p: HydraulicParams, p_s=None):
    """P1 [Pa] that holds ``load_force`` [N] (the leg force needed at rest) with ydot = 0.

    Solves P1 A1 - P_s A2 = load_force. For the vertical single actuator load_force = M g, which gives
    the seed's initial condition P1(0) = (P_s - P_t) A2/A1 + M g / A1 (seed §3.3) with P_t = 0.
    """
    p_s = p.supply_pressure if p_s is None else p_s
    return (np.asarray(load_force, dtype=float) + p_s * p.area_rod) / p.area_bottom


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
