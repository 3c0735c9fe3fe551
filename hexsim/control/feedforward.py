"""The leg model a model-based compensator inverts, built from a machine file (never the simulator's truth).

:func:`leg_model` evaluates the machine's static flow curve (seed eq. 5.1, with the machine's flow area,
overlap, null offset, edge gains and leakage), its friction curve (seed eq. 3.9) and its chamber
(seed eq. 3.7) into a :class:`compensation.leg_model.LegModel`, the record a tuned compensator file
holds and :class:`~compensation.model_based.FeedforwardCompensator` inverts.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d

from compensation.leg_model import LegModel, open_together, refined_grid
from compensation.settings import SettingsError
from hexsim.plant import hydraulics
from hexsim.plant.effects import NOMINAL, Effects
from hexsim.plant.params import HydraulicParams

#: Points of the flow curve over ±u_v,max (5 mV apart at ±10 V; the seed's overlap is 45 mV wide), before
#: :func:`compensation.leg_model.refined_grid` adds points where the curve bends (an edge opening, a port's corner).
GRID_POINTS = 4001
#: Points of the 4-way valve's steady-state curve (each a root search), denser near null.
GRID_POINTS_4WAY = 401
#: Points of the friction table over ± the flow curve's largest speed.
FRICTION_POINTS = 4001


def static_flow_curve(u: np.ndarray, p_rest: np.ndarray, hyd: HydraulicParams, eff: Effects = NOMINAL,
                      load: np.ndarray | None = None) -> np.ndarray:
    """Static piston velocity [m/s], (n_legs, len(u)), at valve setpoints u [V] (G,). 3-way valve: the
    bottom chamber's flow at the leg's rest pressure p_rest (n_legs,) [Pa] plus the leakage into it, over A1
    (seed eq. 5.1). 4-way valve: the steady motion against the leg's rest ``load`` [N] (both chambers'
    continuity and the force balance, :func:`hexsim.plant.hydraulics.steady_state`)."""
    if not hyd.four_way:
        x_v = hydraulics.spool_position(u[None, :], hyd)
        p1 = np.asarray(p_rest, dtype=float)[:, None]
        flow = hydraulics.valve_flow(x_v, p1, hyd, eff=eff) + eff.leakage * (hyd.supply_pressure - p1)
        return flow / hyd.area_bottom
    rows = []
    for f in np.asarray(load, dtype=float):
        row = []
        for v in u:
            try:
                row.append(hydraulics.steady_state(float(v), float(f), hyd, eff=eff).velocity)
            except ValueError:  # stalled: no motion at this command against this load
                row.append(0.0)
        rows.append(np.maximum.accumulate(row))
    return np.asarray(rows)


def leg_model(hyd: HydraulicParams, p_rest: np.ndarray, inertia: np.ndarray, *, eff: Effects = NOMINAL,
              load: np.ndarray | None = None, u_ref: float = 1.0, kp: float = 0.0, source: str = "") -> LegModel:
    """The :class:`~compensation.leg_model.LegModel` of a machine: ``hyd`` and ``eff`` its hydraulics and
    effects (a machine file's), ``p_rest`` (n,) [Pa] each leg's bottom-chamber pressure at rest,
    ``inertia`` (n, n) [kg] the legs' inertia matrix (leg forces = inertia @ leg accelerations; the
    inverse of :func:`hexsim.engine.config.leg_mobility`'s A), ``load`` (n,) [N] the rest loads (4-way
    valves), ``u_ref`` [V] where the linear curve meets the flow curve (its slope is the mean chord at
    ±u_ref, as the oracle's), ``kp`` [V/m] the P gain the compensator runs beside (0: unknown). A 3-way valve's
    curve whose edges pass flow together is split into the return edge's share (:func:`return_edge_share`) and,
    where the openings are curves read from flows (flow area "curve"), smoothed within :data:`ROUNDED_V` of null
    (:func:`rounded_near_null`). Raises SettingsError (a ValueError) for a model whose inverse
    :func:`compensation.leg_model.check_model` refuses."""
    u_max = hyd.u_v_max
    if hyd.four_way:
        s = np.linspace(-1.0, 1.0, GRID_POINTS_4WAY)
        u = u_max * np.sign(s) * s**2  # dense near null, where the overlap is
        velocity = static_flow_curve(u, p_rest, hyd, eff, load)
    else:
        u, velocity = refined_grid(lambda x: static_flow_curve(x, p_rest, hyd, eff),
                                   np.linspace(-u_max, u_max, GRID_POINTS))
    at = None if hyd.four_way else return_edge_share(u, p_rest, velocity, hyd, eff)
    if at is not None and hyd.flow_area == "curve":  # curves read from flows, both edges open around null
        velocity, at = rounded_near_null(u, velocity, increasing=True), rounded_near_null(u, at)
    ends = np.stack([np.interp([-u_ref, u_ref], u, row) for row in velocity])
    slope = (ends[:, 1] - ends[:, 0]) / (2 * u_ref)
    v_max = 1.2 * float(np.max(np.abs(velocity[:, [0, -1]])))
    friction_v = np.linspace(-v_max, v_max, FRICTION_POINTS)
    return LegModel(u=u, velocity=velocity, p_rest=np.asarray(p_rest, dtype=float),
                    supply_pressure=float(hyd.supply_pressure), tank_pressure=float(hyd.tank_pressure),
                    area_bottom=float(hyd.area_bottom), bulk_modulus=float(hyd.bulk_modulus),
                    pipeline_volume=float(hyd.pipeline_volume), mass=np.atleast_2d(np.asarray(inertia, dtype=float)),
                    friction_v=friction_v, friction_f=np.asarray(hydraulics.friction_force(friction_v, hyd)),
                    slope=slope, pressure_scaling=not hyd.four_way, kp=float(kp), source=source, velocity_at=at)


#: Within ROUNDED_V [V] of null, the flow curve of a 3-way valve whose edges pass flow together (an underlapped or
#: rounded spool) and whose openings are each edge's curve (flow area "curve": read from its logs' flows by a
#: calibration or commissioning) is inverted smoothed by a Gaussian of ROUNDED_SIGMA_V [V] (:func:`rounded_near_null`;
#: a form's corners, e.g. the sharp form's at an underlap's edges, are the file's and stay). A curve
#: read from a machine's flows (:mod:`hexsim.measured.flow_curve`) places its corners with an l1 penalty, and near
#: null, where the two edges' sum hardly shows in the flows, it places them where the valve has none: the
#: ``underlap`` machine's calibrated P→A slope doubles within 20 mV at -0.06 V, its spool's own rounded edges
#: change theirs by under 2 % per 5 mV. The flows cannot place a corner finer than the commands a 10 ms interval of
#: the balance spans where a motion crosses null (a chirp's: 30 mV median, 6-64 mV from the 10th to the 90th
#: percentile). A compensator inverting such a corner steps the flow at every crossing of it and the oil column
#: rings: in the ``underlap`` machine's own loop its tuned feedforward left 0.0725 m/s² at the reversals, 0.0458
#: with the curve inverted smoothed (89.8 % of the bump removed, from 83.9 %), and hexsim's prediction of that run,
#: its plant keeping the corners, went from 0.0244 to 0.0589 (``examples/proof_on_the_machine.py``;
#: docs/compensation.md). The machine file keeps the curve as read: a replay and a validation see what the flows
#: gave.
ROUNDED_V, ROUNDED_SIGMA_V = 0.5, 0.02


def rounded_near_null(u: np.ndarray, curve: np.ndarray, increasing: bool = False) -> np.ndarray:
    """``curve`` (n, G) on the valve setpoints ``u`` (G,) [V], smoothed within :data:`ROUNDED_V` of null by a
    Gaussian of :data:`ROUNDED_SIGMA_V` (scipy.ndimage.gaussian_filter1d on a 1 mV grid, the curve held at its
    ends beyond the grid) and unchanged beyond it; ``increasing``: each row kept non-decreasing (a net velocity
    curve, whose inverse must be unique: a kink of the curve at ROUNDED_V leaves the smoothed part above the curve
    just beyond it). A new array, shape of ``curve``.

    Fading the smoothing out over its last 40 mV instead was tried: on the ``underlap`` machine the sine's largest
    commands (0.51 V) fell in the fade, and ``hexsim tune --check`` on its tuned run read the peaks between
    reversals 1.20× the prediction (1.10-1.30), where they are 1.11× (1.00-1.23) with the smoothing held to
    ROUNDED_V."""
    step = 1e-3
    margin = 4.0 * ROUNDED_SIGMA_V
    dense = np.arange(-ROUNDED_V - margin, ROUNDED_V + margin + 0.5 * step, step)
    inside = np.abs(u) <= ROUNDED_V
    out = np.array(curve, dtype=float, copy=True)
    for row in out:
        smooth = gaussian_filter1d(np.interp(dense, u, row), ROUNDED_SIGMA_V / step, mode="nearest")
        row[inside] = np.interp(u[inside], dense, smooth)
        if increasing:
            row[:] = np.maximum.accumulate(row)
    return out


#: The second pressure, as a share of the supply edge's drop at rest, at which
#: :func:`return_edge_share` reads the flow curve again.
SPLIT_STEP = 0.05


def return_edge_share(u: np.ndarray, p_rest: np.ndarray, velocity: np.ndarray, hyd: HydraulicParams,
                      eff: Effects = NOMINAL) -> np.ndarray | None:
    """The return edge's (A→T) share v_AT [m/s], (n_legs, len(u)), of a 3-way valve's flow curve ``velocity``
    (:func:`static_flow_curve` at ``p_rest``): the curve read again at p_rest + dp, and the two readings split
    by the orifice law of each edge (seed eq. 3.4: v = v_PA sqrt((P_s - P1) / (P_s - P_rest)) - v_AT
    sqrt((P1 - P_t) / (P_rest - P_t)), two equations in v_PA and v_AT at each u), whatever the machine's flow
    area (a form, curves or a table) and effects. None where the two edges never pass flow together (an
    overlapped or zero-lapped spool: v_AT is -velocity below null and nil above it, which the curve says)."""
    p_rest = np.asarray(p_rest, dtype=float)
    drop_s, drop_t = hyd.supply_pressure - p_rest, p_rest - hyd.tank_pressure
    dp = SPLIT_STEP * drop_s
    again = static_flow_curve(u, p_rest + dp, hyd, eff)
    g_s, g_t = np.sqrt((drop_s - dp) / drop_s)[:, None], np.sqrt((drop_t + dp) / drop_t)[:, None]
    at = np.maximum((velocity * g_s - again) / (g_t - g_s), 0.0)
    return at if np.any(open_together(velocity, at)) else None


#: Largest K_p s / f_c of the P loop through the inverse: the discrete loop's pole 1 - K_p s / f_c stays
#: within 0.5…1 (a well-damped integrator; at 2 it is unstable).
LOOP_GAIN_LIMIT = 0.5


def check_loop(model: LegModel, kp: float, rate_hz: float) -> None:
    """Refuse a leg model on which the P loop through the inverse would ring: K_p s_i / f_c above
    :data:`LOOP_GAIN_LIMIT` (K_p [V/m], s_i the linear curve's slope [m/(s V)], f_c the controller rate
    [Hz]). Raises SettingsError naming the leg and the figure."""
    ratio = kp * np.asarray(model.slope) / rate_hz
    if np.any(ratio > LOOP_GAIN_LIMIT):
        i = int(np.argmax(ratio))
        raise SettingsError(f"leg{i + 1}: K_p s / f_c = {ratio[i]:.2f} (K_p {kp:g} V/m, s {model.slope[i]:.3g} m/(s V)): "
                            f"above {LOOP_GAIN_LIMIT}, the P loop through the model's inverse would ring")


def setpoint_derivatives(setpoints: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ṙ, r̈, r⃛) [m/s, m/s², m/s³], each shaped like ``setpoints`` (n_ticks, n_legs) [m] sampled every ``dt``
    [s]: central differences (``numpy.gradient``, second order at the ends), the derivatives a motion
    computer has with a one-sample preview of its reference. Zeros for a table of fewer than 3 rows."""
    if len(setpoints) < 3:
        z = np.zeros_like(setpoints, dtype=float)
        return z, z.copy(), z.copy()
    d1 = np.gradient(setpoints, dt, axis=0, edge_order=2)
    d2 = np.gradient(d1, dt, axis=0, edge_order=2)
    return d1, d2, np.gradient(d2, dt, axis=0, edge_order=2)


#: [s] Time constant of the live reference's acceleration and jerk (:class:`LiveDerivatives`): a host's 100 Hz
#: packets, played on a straight line between them, change the setpoint's slope every 10 ms.
LIVE_SMOOTHING_S = 0.01


class LiveDerivatives:
    """(ṙ, r̈, r⃛) of setpoint rows written while the run goes (``hexsim serve``, the FMUs), one controller
    sample every ``dt`` [s] for ``n`` legs, causal: what a motion computer without a preview has. ṙ is the
    backward difference (exact on a host's straight line between its packets); r̈ is the derivative of ṙ
    through a critically damped second-order low pass of time constant ``smoothing_s`` (its state-variable form,
    discretised exactly: the slope's steps at the host's packets do not turn into spikes of a sample), r⃛ the
    backward difference of r̈. The first row gives zeros. :func:`setpoint_derivatives` is the batch run's
    (central differences of the whole table)."""

    def __init__(self, n: int, dt: float, smoothing_s: float = LIVE_SMOOTHING_S) -> None:
        from scipy.linalg import expm

        w = 1.0 / smoothing_s
        a = np.array([[0.0, 1.0], [-w * w, -2.0 * w]])
        self.Ad = expm(a * dt)
        self.Bd = np.linalg.solve(a, (self.Ad - np.eye(2)) @ np.array([0.0, w * w]))
        self.dt = dt
        self.last: np.ndarray | None = None
        self.z = np.zeros((2, n))  # the filtered velocity and its derivative

    def __call__(self, r: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """This sample's setpoints ``r`` (n,) [m] -> (ṙ, r̈, r⃛), each (n,)."""
        r = np.asarray(r, dtype=float)
        d1 = np.zeros_like(r) if self.last is None else (r - self.last) / self.dt
        self.last = r.copy()
        before = self.z[1].copy()
        self.z = self.Ad @ self.z + np.outer(self.Bd, d1)
        return d1, self.z[1].copy(), (self.z[1] - before) / self.dt
