"""The flow balance of a valve-controlled cylinder's log, interval by interval (seed eq. 3.6, 3.7 integrated):
what :mod:`hexsim.measured.flow_curve` reads each valve edge's curve from, with the sensors' skew the
acquisition read (:mod:`hexsim.measured.acquisition`) applied at the intervals' ends.

Over each interval of :data:`INTERVAL_S` the volume that entered the chamber (from the piston's positions and the
chamber's pressures at the interval's ends) equals the valve's flow summed over its samples, each command held
over its period as the controller holds it (the equation error in integral form, Young, Automatica 17(1), 1981):
no measured signal is differentiated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.signal import lsim, lti, savgol_filter

from hexsim.errors import InputError
from hexsim.measured.measurement import MeasurementLog
from hexsim.measured.replay import near_jumps
from hexsim.plant import hydraulics
from hexsim.plant.legs import backlash_history, bulk_modulus, leg_params
from hexsim.plant.machine import Machine

#: Span [s] of the Savitzky-Golay cubic that smooths the position at the intervals' ends (zero phase; 11 ms,
#: short against a motion, long against the transducer's sample-to-sample noise).
WINDOW_S = 0.011
#: Length [s] of the intervals over which continuity is integrated (:func:`flow_samples`): long against the
#: position transducer's noise at its ends, short against the motion (each sample's command keeps its own
#: place on the curve inside it).
INTERVAL_S = 0.01
#: Samples this close to either end of the stroke [m] are left out (the stops' forces are not the valve's).
STOP_MARGIN = 0.002
#: Contiguous windows per log for the blocked cross-validation of the smoothness weight.
FOLDS = 5


@dataclass(frozen=True)
class FlowSamples:
    """One chamber's flow balance in a log, interval by interval: per sample i of the intervals kept (all (n,)),
    ``u`` the signed command at the spool [V] (u_v - u_0, through the valve's play and the spool's loop where the
    machine has them), ``supply`` and ``ret`` the volume [m^3] a full opening pi d x_v,max of the supply and the
    return edge would pass over the sample's period at the logged pressures (into the chamber positive),
    ``interval`` the interval it belongs to (0 … k - 1); per interval j (all (k,)) ``displaced`` the volume [m^3]
    the piston displaced into the chamber over it less the leakage, ``swept_dp`` and ``dead_dp`` the compressed
    volume's factors: the chamber's swept volume times its pressure's change [m^3 Pa] and that change [Pa] (the
    dead volume's, cap side; the rod side's dead volume is the machine's, in ``swept_dp``), so that the volume that
    entered is displaced + swept_dp / E + dead_dp V_pl / E, ``block`` its cross-validation window (0 …
    :data:`FOLDS` - 1);
    ``mirror`` True for the rod side (its supply edge opens at -u); ``time`` (n,) [s] each sample's time in the log
    (None where a caller built the samples without it)."""

    u: np.ndarray
    supply: np.ndarray
    ret: np.ndarray
    interval: np.ndarray
    displaced: np.ndarray
    swept_dp: np.ndarray
    dead_dp: np.ndarray
    block: np.ndarray
    mirror: bool
    time: np.ndarray | None = None


def _smooth(x: np.ndarray, rate: float) -> np.ndarray:
    """The Savitzky-Golay cubic over :data:`WINDOW_S` of ``x`` sampled at ``rate`` [Hz] (zero phase)."""
    n = max(5, int(round(WINDOW_S * rate)) | 1)
    return savgol_filter(x, n, 3, mode="interp")


def _spool_command(u_v: np.ndarray, time: np.ndarray, machine: Machine) -> np.ndarray:
    """The signed command at the spool [V]: u_v - u_0 (seed eq. 3.2), through the valve's play where it has one
    (:class:`hexsim.plant.effects.Effects` ``spool_play``, seed §4.4: the backlash of half width h each sample's
    command passes, :func:`hexsim.plant.legs.backlash`) and its second-order spool loop where it has one
    (``spool_frequency``)."""
    u = u_v - machine.hydraulics.null_offset
    eff = machine.effects
    if eff.spool_play > 0:
        h = eff.spool_play
        u = np.clip(backlash_history(np.ascontiguousarray(u, dtype=float), h), u - h, u + h)  # past the play
    if eff.spool_frequency <= 0:
        return u
    w = 2.0 * math.pi * eff.spool_frequency
    return lsim(lti([w * w], [1.0, 2.0 * eff.spool_damping * w, w * w]), u, time - time[0], X0=None)[1]


def flow_samples(log: MeasurementLog, machine: Machine, skew: float = 0.0) -> list[FlowSamples]:
    """The flow balance of a single-actuator ``log`` on ``machine`` in the integral form of continuity (seed eq.
    3.6, 3.7 integrated over each interval of :data:`INTERVAL_S`: the volume that entered the chamber, from the
    piston's positions and the chamber's pressures at the interval's ends, equals the valve's flow summed over
    its samples, each command held over its period as the controller holds it): no derivative of a measured
    signal, so a step's fast pressure jump is measured as well as a slow motion (the equation error in integral
    form, Young, Automatica 17(1), 1981). The cap side's (and with a 4-way valve and a logged ``p2_Pa`` the rod
    side's) :class:`FlowSamples`, the edges' gains those of ``machine``; intervals that come within
    :data:`STOP_MARGIN` of either end of the stroke are left out. The piston's positions are the transducer's
    readings tau_y later where ``machine`` has a lagging transducer (:class:`hexsim.plant.effects.Effects`
    ``sensor_delay``: it shows y(t - tau_y), as the replay has it), the intervals of the log's last tau_y left out;
    the commands pass the valve's play and spool loop (:func:`_spool_command`). ``skew`` [s], within a sample either
    way: the state was read that long after its row's command took effect (:mod:`hexsim.measured.acquisition`), so an
    interval gains that share of the next row's flow and loses it of its first row's (negative: the rows
    before each end). Raises InputError (naming the log) for a hexapod log or one without ``p1_Pa``."""
    hyd, eff = machine.hydraulics, machine.effects
    rate, cols = log.sample_rate_hz, log.columns
    dt = 1.0 / rate
    step = max(1, int(round(INTERVAL_S * rate)))
    n = (len(log.time) - 1) // step
    edges = np.arange(n + 1) * step  # sample index of each interval's ends
    y = _end_positions(log, eff.sensor_delay)
    u = _spool_command(cols["valve_cmd_V"], log.time, machine)
    p_s = cols["ps_Pa"] if "ps_Pa" in cols else np.full_like(y, hyd.supply_pressure)
    # within the stroke, and not in the log's last tau_y, whose positions the lagging transducer has not shown yet
    inside = (y > STOP_MARGIN) & (y < log.stroke_m - STOP_MARGIN) & (log.time + eff.sensor_delay <= log.time[-1])
    keep = np.array([inside[a:b + 1].all() for a, b in zip(edges[:-1], edges[1:])], dtype=bool)
    block = np.minimum((np.arange(n) * FOLDS) // max(n, 1), FOLDS - 1)
    across = cols["p2_Pa"] if hyd.four_way and "p2_Pa" in cols else p_s  # the leak's far side
    P = leg_params(hyd, eff)
    full = P.port_width * hyd.x_v_max
    samples = np.arange(edges[-1]).reshape(n, step)[keep].ravel()  # the samples of the kept intervals
    interval = np.repeat(np.arange(int(keep.sum())), step)
    a, b = edges[:-1][keep], edges[1:][keep]  # each kept interval's ends
    samples, interval, weight = _skewed(samples, interval, a, b, float(np.clip(skew * rate, -0.999, 0.999)),
                                        len(log.time))

    def side(p_col: str, area: float, volume_at, k_in: float, k_out: float, mirror: bool) -> FlowSamples:
        p = cols[p_col]
        mid = 0.5 * (p[samples] + p[samples + 1])  # the period's mean pressure at each held command
        p_supply = 0.5 * (p_s[samples] + p_s[samples + 1])
        supply = k_in * full * hydraulics.edge_flow(1.0, p_supply - mid, hyd) * dt * weight
        ret = -k_out * full * hydraulics.edge_flow(1.0, mid - hyd.tank_pressure, hyd) * dt * weight
        p_mid = 0.5 * (p[a] + p[b])
        air = np.array([hyd.bulk_modulus / bulk_modulus(float(v), P) for v in p_mid]) if eff.air_fraction > 0 else 1.0
        dp = (p[b] - p[a]) * air  # entrained air: the effective bulk modulus's share
        displaced = area * (y[b] - y[a])
        if not mirror and eff.leakage:
            starts = np.flatnonzero(np.r_[True, np.diff(interval) != 0])
            displaced -= eff.leakage * np.add.reduceat((across - p)[samples] * dt * weight, starts)
        return FlowSamples(u[samples], supply, ret, interval, displaced, volume_at(0.5 * (y[a] + y[b])) * dp,
                           np.zeros_like(dp) if mirror else dp, block[keep], mirror, log.time[samples])

    out = [side("p1_Pa", hyd.area_bottom, lambda ym: np.maximum(ym, 0.0) * hyd.area_bottom,
                eff.edge_gain_pa, eff.edge_gain_at, False)]
    if hyd.four_way and "p2_Pa" in cols:
        out.append(side("p2_Pa", -hyd.area_rod,
                        lambda ym: np.maximum(log.stroke_m - ym, 0.0) * hyd.area_rod + hyd.pipeline_volume_rod,
                        eff.edge_gain_pb, eff.edge_gain_bt, True))
    return out


def _end_positions(log: MeasurementLog, delay: float = 0.0) -> np.ndarray:
    """(n,) [m]: the piston's positions as the intervals' ends read them, the transducer's noise smoothed (zero
    phase, :func:`_smooth`) except where the smoothing would reach over the kink of a command's jump (the raw
    position there); a transducer lagging ``delay`` [s] (it shows y(t - delay)) read that much later (the last
    ``delay`` of the log held at its last reading). Raises InputError (naming the log) for a hexapod log or one
    without ``p1_Pa``."""
    if log.system != "single-actuator":
        raise InputError(f"{log.path.name}: a flow curve is read from single-actuator logs (this one is {log.system})")
    if "p1_Pa" not in log.columns:
        raise InputError(f"{log.path.name}: a flow curve needs the chamber pressure (column p1_Pa)")
    y = _smooth(log.columns["pos_m"], log.sample_rate_hz)
    kinked = near_jumps(log, WINDOW_S)
    y[kinked] = log.columns["pos_m"][kinked]
    return np.interp(log.time + delay, log.time, y) if delay > 0 else y


def _skewed(samples: np.ndarray, interval: np.ndarray, a: np.ndarray, b: np.ndarray, share: float, n: int
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The samples of the intervals from rows ``a`` to ``b`` (each (k,)) with each sample's weight in its
    interval's flow, when the state was read ``share`` of a row after its command took effect (:func:`flow_samples`):
    an interval gains that share of the row at its end and loses it of its first row (negative: of the rows before
    each). ``samples`` and ``interval`` (m,) as they were, the extra rows (clipped to the ``n`` samples' range)
    sorted in; returns (samples, interval, weight)."""
    weight = np.ones(len(samples))
    if share == 0.0:
        return samples, interval, weight
    gained, lost = (b, a) if share > 0 else (a - 1, b - 1)
    ends = np.clip(np.concatenate([gained, lost]), 0, n - 2)
    ids = np.concatenate([interval, np.tile(np.arange(len(a)), 2)])
    order = np.argsort(ids, kind="stable")
    weight = np.concatenate([weight, np.full(len(a), abs(share)), np.full(len(a), -abs(share))])
    return np.concatenate([samples, ends])[order], ids[order], weight[order]
