"""A valve's flow curve read from its logs' own flows: the opening against command, point by point.

A closed-loop log of a valve-controlled cylinder measures the flow through the valve at every sample, by
continuity (seed eq. 3.6, 3.7): phi_1 = A1 ydot + V1(y) / E dP1/dt (+ the leakage C_l (P_s - P1) the chamber
receives across the piston), and with a 4-way valve phi_2 = -A2 ydot + V2(y) / E dP2/dt. The valve's side of
the same flow is the orifice equation of each edge (seed eq. 3.4): with the opening of an edge a table T of
the signed command u that opens it (:func:`hexsim.plant.legs.table_opening`, linear between its points, P→A
at u, A→T at -u), phi_1 = k_PA pi d x_v,max T(u) q(P_s - P1) - k_AT pi d x_v,max T(-u) q(P1 - P_t), q the
flow of a unit opening (:func:`hexsim.plant.hydraulics.edge_flow`). That is *linear* in the table's values,
so the curve is a bounded linear least-squares problem (openings rising from the first point: every answer
a valve's) whose answer does not depend on where a search starts, unlike a replay's fit of the same points
(:mod:`hexsim.measured.calibration`). The return edge's gain k_AT is the one nonlinear parameter, found by a
bounded scalar search around it (separable least squares: Golub & Pereyra, SIAM J. Numer. Anal. 10(2),
1973). A robust loss (scipy's soft-L1) keeps the reversals, where dP1/dt is largest and noisiest, from
steering the curve.

The points the logs do not reach are held near a prior curve (the chosen flow-area form's, sampled) by a
regularisation whose weight the held-out windows choose: each log is cut into :data:`FOLDS` contiguous
windows, the curve fitted without one window at a time and judged on it (blocked cross-validation, e.g.
Bergmeir & Benítez, Information Sciences 191, 2012), and the weight with the smallest held-out flow error kept.

The derivatives are Savitzky-Golay's (:func:`scipy.signal.savgol_filter`, zero phase, a cubic over
:data:`WINDOW_S`), the same filter on every channel so that the samples stay aligned.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.signal import lti, lsim, savgol_filter
from scipy.stats import median_abs_deviation

from hexsim.errors import InputError
from hexsim.measured.fitting import bounded_fit
from hexsim.measured.measurement import MeasurementLog
from hexsim.plant import hydraulics
from hexsim.plant.legs import bulk_modulus, leg_params
from hexsim.plant.machine import Machine

#: Span [s] of the Savitzky-Golay cubic that smooths and differentiates the channels (10 ms: short against the
#: ~0.1 s of a reversal, long against the 1 ms sampling whose pressure noise dP/dt would amplify).
WINDOW_S = 0.011
#: Samples this close to either end of the stroke [m] are left out (the stops' forces are not the valve's).
STOP_MARGIN = 0.002
#: Contiguous windows per log for the blocked cross-validation of the regularisation weight.
FOLDS = 5
#: Regularisation weights tried (:func:`_solve`): a point's deviation from the prior curve by its scale costs
#: this fraction of the data's robust sum of squares.
WEIGHTS = (1e-4, 1e-3, 1e-2, 1e-1, 1.0)
#: The return edge's gain is searched within this range of the prior's.
EDGE_GAIN_RANGE = (0.5, 1.5)


@dataclass(frozen=True)
class FlowSamples:
    """A log's flow balance, sample by sample (all (n,), n the samples kept): ``u`` the signed command at the
    spool [V] (u_v - u_0, through the spool's loop where the machine has one), ``supply`` and ``ret`` the flow
    [m^3/s] a full opening pi d x_v,max of the supply and the return edge would pass at the logged pressures
    (edge gains applied; into the chamber positive), ``mirror`` True for the rod side (its supply edge opens
    at -u), ``flow`` the piston's displacement flow [m^3/s] (A1 ydot less the leakage, or -A2 ydot),
    ``stored_swept`` and ``stored_dead`` the compressibility flow's factors [m^3 Pa/s] and [Pa/s]: V dP/dt of
    the swept volume and dP/dt (the dead volume's, cap side; the rod side's dead volume is the machine's, in
    ``stored_swept``), ``block`` the cross-validation window of each sample (0 … :data:`FOLDS` - 1)."""

    u: np.ndarray
    supply: np.ndarray
    ret: np.ndarray
    mirror: bool
    flow: np.ndarray
    stored_swept: np.ndarray
    stored_dead: np.ndarray
    block: np.ndarray


@dataclass(frozen=True)
class FlowCurve:
    """A fitted flow curve: ``commands`` (k,) [V] and ``openings`` (k,) [-] (fraction of pi d x_v,max, the
    first at or below null and 0), the return edge's gain ``edge_gain_at`` [-] (with a 4-way valve the rod
    side's k_BT scaled alike), the oil's ``bulk_modulus`` [Pa] and the cap side's dead volume
    ``pipeline_volume`` [m^3] (from the compressibility flow), the ``weight`` the held-out windows chose, their
    flow error at each weight tried (``held_out``: weight -> rms [m^3/s]) and the rms flow error of the fit
    (``rms``, [m^3/s]) against the measured flow's rms (``flow_rms``), and the commands the logs reached
    (``reached``: lowest, highest [V], at the spool: beyond them the curve is the prior's)."""

    commands: np.ndarray
    openings: np.ndarray
    edge_gain_at: float
    bulk_modulus: float
    pipeline_volume: float
    weight: float
    held_out: dict
    rms: float
    flow_rms: float
    reached: tuple[float, float]

    def table(self) -> list[list[float]]:
        """The machine file's ``valve.opening_table`` rows [[u V, opening], …]."""
        return [[round(float(u), 6), round(float(f), 6)] for u, f in zip(self.commands, self.openings)]


def _smooth(x: np.ndarray, rate: float, deriv: int = 0) -> np.ndarray:
    """The Savitzky-Golay cubic over :data:`WINDOW_S` of ``x`` sampled at ``rate`` [Hz] (its ``deriv``-th derivative)."""
    n = max(5, int(round(WINDOW_S * rate)) | 1)
    return savgol_filter(x, n, 3, deriv=deriv, delta=1.0 / rate, mode="interp")


def _spool_command(u_v: np.ndarray, time: np.ndarray, machine: Machine) -> np.ndarray:
    """The signed command at the spool [V]: u_v - u_0 (seed eq. 3.2), through the machine's second-order spool
    loop where it has one (:class:`hexsim.plant.effects.Effects` ``spool_frequency``)."""
    u = u_v - machine.hydraulics.null_offset
    eff = machine.effects
    if eff.spool_frequency <= 0:
        return u
    w = 2.0 * math.pi * eff.spool_frequency
    return lsim(lti([w * w], [1.0, 2.0 * eff.spool_damping * w, w * w]), u, time - time[0], X0=None)[1]


def flow_samples(log: MeasurementLog, machine: Machine) -> list[FlowSamples]:
    """The flow balance of a single-actuator ``log`` on ``machine``: the cap side's (and with a 4-way valve and a
    logged ``p2_Pa`` the rod side's) :class:`FlowSamples`. Raises InputError (naming the log) for a hexapod log
    or one without ``p1_Pa``."""
    if log.system != "single-actuator":
        raise InputError(f"{log.path.name}: a flow curve is read from single-actuator logs (this one is {log.system})")
    if "p1_Pa" not in log.columns:
        raise InputError(f"{log.path.name}: a flow curve needs the chamber pressure (column p1_Pa)")
    hyd, eff = machine.hydraulics, machine.effects
    rate, cols = log.sample_rate_hz, log.columns
    y = _smooth(cols["pos_m"], rate)
    ydot = _smooth(cols["pos_m"], rate, 1)
    u = _smooth(_spool_command(cols["valve_cmd_V"], log.time, machine), rate)
    p_s = _smooth(cols["ps_Pa"], rate) if "ps_Pa" in cols else np.full_like(y, hyd.supply_pressure)
    keep = (y > STOP_MARGIN) & (y < log.stroke_m - STOP_MARGIN)
    block = np.minimum((np.arange(len(y)) * FOLDS) // len(y), FOLDS - 1)
    across = _smooth(cols["p2_Pa"], rate) if hyd.four_way and "p2_Pa" in cols else p_s  # the leak's far side
    P = leg_params(hyd, eff)
    full = P.port_width * hyd.x_v_max
    stiffness = lambda p: np.array([bulk_modulus(float(v), P) for v in p]) if eff.air_fraction > 0 else hyd.bulk_modulus

    def side(p_col: str, area: float, swept: np.ndarray, k_in: float, k_out: float, mirror: bool) -> FlowSamples:
        p = _smooth(cols[p_col], rate)
        dp = _smooth(cols[p_col], rate, 1) * hyd.bulk_modulus / stiffness(p)  # entrained air: E_eff's share
        flow = area * ydot - (0.0 if mirror else eff.leakage * (across - p))
        supply = k_in * full * hydraulics.edge_flow(1.0, p_s - p, hyd)
        ret = -k_out * full * hydraulics.edge_flow(1.0, p - hyd.tank_pressure, hyd)
        dead = np.zeros_like(dp) if mirror else dp
        return FlowSamples(*(a[keep] for a in (u, supply, ret)), mirror,
                           *(a[keep] for a in (flow, swept * dp, dead, block)))

    out = [side("p1_Pa", hyd.area_bottom, np.maximum(y, 0.0) * hyd.area_bottom, eff.edge_gain_pa, eff.edge_gain_at,
                False)]
    if hyd.four_way and "p2_Pa" in cols:
        v2 = np.maximum(log.stroke_m - y, 0.0) * hyd.area_rod + hyd.pipeline_volume_rod
        out.append(side("p2_Pa", -hyd.area_rod, v2, eff.edge_gain_pb, eff.edge_gain_bt, True))
    return out


def _basis(u: np.ndarray, commands: np.ndarray) -> np.ndarray:
    """(n, k - 1): the opening at ``u`` per unit rise of the table above each point after the first (linear
    between points, closed at and below the first, flat beyond the last): column j is the opening of a table
    that rises by 1 from point j on (:func:`hexsim.plant.legs.table_opening`)."""
    eye = np.eye(len(commands))
    hats = np.column_stack([np.interp(u, commands, e, left=0.0, right=e[-1]) for e in eye[1:]])
    return np.cumsum(hats[:, ::-1], axis=1)[:, ::-1]  # a rise at point j lifts every point from j on


def _design(samples: list[FlowSamples], commands: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The linear system of the unknowns (the k - 1 rises, 1/E, V_pl/E): (A (n, k + 1), R (n, k + 1), b (n,)),
    A the supply edges' flow less the compressibility flow, R the return edges' flow (the prior's gains), so that
    with the return edges' gains ``g`` times the prior's (A + g R) x = b, the displacement flow."""
    supply, ret, flows = [], [], []
    for s in samples:
        at_in, at_out = (-s.u, s.u) if s.mirror else (s.u, -s.u)
        supply.append(np.column_stack([_basis(at_in, commands) * s.supply[:, None], -s.stored_swept, -s.stored_dead]))
        ret.append(np.column_stack([_basis(at_out, commands) * s.ret[:, None], np.zeros((len(s.u), 2))]))
        flows.append(s.flow)
    return np.vstack(supply), np.vstack(ret), np.concatenate(flows)


@dataclass(frozen=True)
class _Prior:
    """What the fit is held towards (:func:`_solve`): the unknowns' map to the penalised quantities ``lift``
    (q, m) (the openings above the first point, 1/E, V_pl/E), their ``value`` (q,) and ``sigma`` (q,)."""

    lift: np.ndarray
    value: np.ndarray
    sigma: np.ndarray

    @classmethod
    def of(cls, openings: np.ndarray, machine: Machine) -> "_Prior":
        k = len(openings) - 1
        lift = np.zeros((k + 2, k + 2))
        lift[:k, :k] = np.tril(np.ones((k, k)))
        lift[k, k] = lift[k + 1, k + 1] = 1.0
        beta = 1.0 / machine.hydraulics.bulk_modulus
        gamma = machine.hydraulics.pipeline_volume * beta
        value = np.concatenate([openings[1:], [beta, gamma]])
        sigma = np.concatenate([0.5 * openings[1:] + 0.02, [0.5 * beta, 0.5 * gamma + 0.5e-6 * beta]])
        return cls(lift, value, sigma)

    def start(self) -> np.ndarray:
        k = len(self.value) - 2
        return np.concatenate([np.maximum(np.diff(np.concatenate([[0.0], self.value[:k]])), 0.0), self.value[k:]])


#: Bounds of 1/E [1/Pa]: a bulk modulus within 0.1 … 3 GPa (aerated oil … stiff mineral oil in steel).
_BETA = (1.0 / 3.0e9, 1.0 / 1.0e8)


def _solve(A: np.ndarray, b: np.ndarray, prior: _Prior, weight: float, scale: float) -> np.ndarray:
    """The unknowns (m,) (rises >= 0, 1/E within :data:`_BETA`, V_pl/E >= 0) minimising the soft-L1 flow error
    (scale ``scale`` [m^3/s]) plus the weighted deviation from ``prior`` (sum of squares by its sigma, times
    ``weight`` times the samples)."""
    pen = math.sqrt(weight * len(b)) / prior.sigma
    jac = np.vstack([A / scale, pen[:, None] * prior.lift])
    fun = lambda x: np.concatenate([(A @ x - b) / scale, pen * (prior.lift @ x - prior.value)])
    m = A.shape[1]
    lo = np.concatenate([np.zeros(m - 2), [_BETA[0], 0.0]])
    hi = np.concatenate([np.full(m - 2, np.inf), [_BETA[1], np.inf]])
    x0 = np.clip(prior.start(), lo, hi)
    return bounded_fit(fun, [x0], lo, hi, jac=lambda x: jac, loss="soft_l1", f_scale=1.0, method="trf",
                       x_scale="jac").x


def _gain(A: np.ndarray, R: np.ndarray, b: np.ndarray, prior: "_Prior", scale: float) -> float:
    """The return edges' gain factor g of the system (A + g R) x = b (:func:`_design`): a bounded scalar search
    of the soft-L1 flow error, the unknowns solved (:func:`_solve`, the smallest regularisation weight) at each
    trial."""
    def cost(g: float) -> float:
        e = ((A + g * R) @ _solve(A + g * R, b, prior, WEIGHTS[0], scale) - b) / scale
        return float(np.sum(2.0 * (np.sqrt(1.0 + e * e) - 1.0)))

    return float(minimize_scalar(cost, bounds=EDGE_GAIN_RANGE, method="bounded", options={"xatol": 2e-3}).x)


def fit_flow_curve(logs: list[MeasurementLog], machine: Machine, commands: np.ndarray,
                   prior: np.ndarray) -> FlowCurve:
    """The valve's opening table at ``commands`` (k,) [V] (the first at or below null, its opening 0) read from
    ``logs``' flow balance on ``machine`` (its areas, null offset, supply edge gain k_PA and spool loop; see the
    module), held near ``prior`` (k,) [-] (and ``machine``'s bulk modulus and dead volume) where the logs do not
    reach, with the weight the held-out windows choose; the return edge's gain (relative to ``machine``'s), the
    bulk modulus and the dead volume fitted with it.

    Raises InputError (naming the log) for a log without p1_Pa or of a hexapod, or if fewer than 200 samples
    away from the stops remain."""
    samples = [s for log in logs for s in flow_samples(log, machine)]
    if sum(len(s.flow) for s in samples) < 200:
        raise InputError("a flow curve needs at least 200 samples away from the stroke's ends; the logs have fewer")
    supply, ret, b = _design(samples, commands)
    scale = max(0.05 * float(median_abs_deviation(b, scale="normal")), 1e-9)
    block = np.concatenate([s.block for s in samples])
    held = _Prior.of(np.asarray(prior, float), machine)
    g = _gain(supply, ret, b, held, scale)
    A = supply + g * ret
    held_out = {}
    for weight in WEIGHTS:
        err = [(A[block == k] @ _solve(A[block != k], b[block != k], held, weight, scale) - b[block == k]) ** 2
               for k in range(FOLDS)]
        held_out[weight] = float(np.sqrt(np.mean(np.concatenate(err))))
    weight = min(held_out, key=held_out.get)
    x = _solve(A, b, held, weight, scale)
    return FlowCurve(np.asarray(commands, float), np.concatenate([[0.0], np.cumsum(x[:-2])]),
                     g * machine.effects.edge_gain_at, 1.0 / x[-2], x[-1] / x[-2], weight, held_out,
                     float(np.sqrt(np.mean((A @ x - b) ** 2))), float(np.sqrt(np.mean(b * b))),
                     (float(min(s.u.min() for s in samples)), float(max(s.u.max() for s in samples))))
