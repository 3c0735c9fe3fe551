"""Identifying the effect a measurement log shows and the nominal model lacks (issue 4).

Each candidate of :data:`CANDIDATES` extends the nominal model (seed ch. 3, app. A) by one effect with
one or two free parameters; everything else stays nominal. Each is fitted with
``scipy.optimize.least_squares`` (bounds, 2-point Jacobian) to the valve replay
(:func:`hexsim.replay.replay`) of the *fit* windows (even-numbered) and scored on the *held-out* windows
(odd-numbered). The cost is the sum of squared residuals of every channel the log has, each divided by
its sensor noise estimated from the log (:func:`noise_levels`). A candidate is chosen only if it lowers the held-out cost by at least
:data:`MIN_HELD_OUT_GAIN`; else the answer is ``none`` — a false positive is as wrong as a miss. AIC and
BIC are reported with the number of independent residuals estimated from their autocorrelation
(N_eff = N / (1 + 2 sum rho_k), Bartlett), since residuals of a dynamic model are not white.

Standard errors come from the Jacobian at the optimum, cov = s^2 (J^T J)^-1, inflated by N / N_eff for
the same reason.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from concurrent.futures import as_completed
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from tqdm import tqdm

from hexsim.effects import EFFECT_NAMES, Effects
from hexsim.errors import InputError, PhysicsError
from hexsim.measurement import MeasurementLog
from hexsim.params import HydraulicParams
from hexsim.replay import CHANNELS, PlantModel, Windows, measured_velocity, replay, supply_from_log
from hexsim.signals import zero_crossings
from hexsim.workers import worker_pool

#: A candidate must lower the held-out cost by this fraction to be chosen.
MIN_HELD_OUT_GAIN = 0.05
#: Valve-replay window [s]: long enough to see a flow offset integrate, short enough not to drift away.
WINDOW_S = 0.45
#: Start of each window left out of the cost [s]: the initial state taken from the measurements
#: (velocity from a filtered derivative, P1 with its sensor noise) is not exact, and the 100 Hz oil
#: spring rings the difference out over some 10–40 ms.
SETTLE_S = 0.05
BAR_PER_LPM = 1e5 / (1e-3 / 60)  # [Pa s/m^3] of 1 bar per L/min


@dataclass(frozen=True)
class Candidate:
    """One effect: parameter names with units, start, bounds, and how they change the model."""

    name: str
    parameters: tuple[str, ...]
    units: tuple[str, ...]
    starts: Callable[[MeasurementLog], tuple[tuple[float, ...], ...]]  # the fit starts from the best of these
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    apply: Callable[[PlantModel, np.ndarray], PlantModel]
    physics: str


def _eff(model: PlantModel, **kw) -> PlantModel:
    return PlantModel(model.hydraulics, model.effects.replace(**kw))


def _hyd(model: PlantModel, **kw) -> PlantModel:
    return PlantModel(model.hydraulics.replace(**kw), model.effects)


def _supply_set(log: MeasurementLog) -> float:
    """Start of the set pressure [bar]: the 99th percentile of the logged P_s (the supply sags below it
    whenever oil is drawn), or the seed's 70 bar without a P_s column."""
    return float(np.quantile(log.columns["ps_Pa"], 0.99)) / 1e5 if "ps_Pa" in log.columns else 70.0


def _friction(model: PlantModel, x) -> PlantModel:
    h = model.hydraulics
    return _hyd(model, coulomb_pos=h.coulomb_pos * x[0], coulomb_neg=h.coulomb_neg * x[0],
                static_pos=h.static_pos * x[0], static_neg=h.static_neg * x[0],
                viscous_pos=h.viscous_pos * x[1], viscous_neg=h.viscous_neg * x[1])


CANDIDATES: dict[str, Candidate] = {c.name: c for c in (
    Candidate("supply_pressure", ("R_s", "tau_s", "P_s0"), ("bar/(L/min)", "ms", "bar"),
              lambda log: tuple((r, tau, _supply_set(log)) for r, tau in ((0.2, 20.0), (2.0, 20.0), (2.0, 200.0))),
              (0.0, 1.0, 1.0), (20.0, 1000.0, 400.0),
              lambda m, x: PlantModel(m.hydraulics.replace(supply_pressure=x[2] * 1e5),
                                      m.effects.replace(supply_resistance=x[0] * BAR_PER_LPM,
                                                        supply_time_constant=x[1] * 1e-3)),
              "pump + accumulator behind a supply line: P_s sags from the set pressure P_s0 by R_s phi_s, "
              "time constant tau_s"),
    Candidate("spool_dynamics", ("f_v", "zeta_v"), ("Hz", "-"), lambda log: ((20.0, 0.7), (50.0, 0.7), (120.0, 0.7), (300.0, 0.7)), (5.0, 0.1), (1000.0, 3.0),
              lambda m, x: _eff(m, spool_frequency=x[0], spool_damping=x[1]),
              "second-order spool position loop (natural frequency f_v, damping zeta_v)"),
    Candidate("null_offset", ("u_0",), ("V",), lambda log: ((-0.2,), (0.0,), (0.2,)), (-2.0,), (2.0,),
              lambda m, x: _hyd(m, null_offset=x[0]),
              "valve setpoint u_0 that centres the spool is not 0 (seed §5.3: drifts with temperature)"),
    Candidate("hysteresis", ("h",), ("V",), lambda log: ((0.02,), (0.1,), (0.3,), (1.0,)), (0.0,), (2.0,),
              lambda m, x: _eff(m, spool_play=x[0]),
              "spool play: backlash of half width h between setpoint and spool (seed §4.2, hysteresis of the flow curve)"),
    Candidate("leakage", ("C_l",), ("1e-12 m^3/(s Pa)",), lambda log: ((0.5,), (5.0,), (50.0,)), (0.0,), (200.0,),
              lambda m, x: _eff(m, leakage=x[0] * 1e-12),
              "internal leakage across the piston, C_l (P_s - P1) into the bottom chamber"),
    Candidate("load", ("M", "inclination"), ("kg", "deg"),
              lambda log: ((log.mass_kg or 40.0, max(log.inclination_deg, 1.0)),
                          (1.5 * (log.mass_kg or 40.0), 30.0)), (5.0, 0.0), (400.0, 89.0),
              lambda m, x: _eff(m, mass_kg=x[0], inclination_deg=x[1]),
              "moving mass and inclination of the axis differ from the declared (seed ch. 4: gravity not along the actuator)"),
    Candidate("friction", ("k_c", "k_sigma"), ("-", "-"), lambda log: ((1.0, 1.0), (0.5, 1.0), (2.5, 1.0)), (0.0, 0.0), (10.0, 10.0),
              _friction, "Stribeck friction (seed eq. 3.9) with Coulomb + static levels scaled by k_c, viscous by k_sigma"),
    Candidate("bulk_modulus", ("E",), ("GPa",), lambda log: ((0.3,), (1.0,), (2.5,)), (0.05,), (5.0,),
              lambda m, x: _hyd(m, bulk_modulus=x[0] * 1e9),
              "effective bulk modulus of the oil (entrained air lowers it; seed eq. 3.7)"),
    Candidate("sensor_delay", ("tau_y",), ("ms",), lambda log: ((1.0,), (5.0,), (20.0,)), (0.0,), (50.0,),
              lambda m, x: _eff(m, sensor_delay=x[0] * 1e-3),
              "the position measurement lags the piston by tau_y"),
)}
assert tuple(CANDIDATES) == EFFECT_NAMES


def available_channels(log: MeasurementLog) -> list[str]:
    return [ch for ch, (col, _, _) in CHANNELS.items() if col in log.columns]


def channel_scales(log: MeasurementLog) -> dict[str, float]:
    """Scale of each channel: the standard deviation of the measured signal, floored (so a constant
    supply pressure is judged against 0.1 bar, not against its sensor noise)."""
    return {ch: max(float(np.std(log.columns[CHANNELS[ch][0]])), CHANNELS[ch][2]) for ch in available_channels(log)}


def noise_levels(log: MeasurementLog) -> dict[str, float]:
    """Sensor noise (rms) of each channel estimated from the log itself (:func:`_noise_of`)."""
    return {ch: _noise_of(log.columns[CHANNELS[ch][0]], ch) for ch in available_channels(log)}


def _noise_of(x: np.ndarray, channel: str) -> float:
    """1.4826 MAD of the second difference / sqrt(6) (white noise of variance s^2 gives a second
    difference of variance 6 s^2; the signal's own second difference is small at the log rate).
    Floors: 0.1 µm, 100 Pa, 1e-3 m/s^2."""
    floors = {"position": 1e-7, "p1": 100.0, "p_s": 100.0, "acceleration": 1e-3}
    d2 = np.diff(x, 2)
    mad = float(np.median(np.abs(d2 - np.median(d2))))
    return max(1.4826 * mad / math.sqrt(6.0), floors[channel])


class Problem:
    """The log, its windows and scales; evaluates residuals of a model on them."""

    def __init__(self, log: MeasurementLog, window_s: float = WINDOW_S) -> None:
        self.log = log
        length = int(round(window_s * log.sample_rate_hz))
        self.windows = Windows.tile(len(log.time), length)
        self.fit_rows = np.arange(0, len(self.windows.starts), 2)
        self.test_rows = np.arange(1, len(self.windows.starts), 2)
        if len(self.test_rows) == 0:
            raise InputError(f"{log.path}: the log is shorter than two replay windows of {window_s} s")
        self.settle = int(round(SETTLE_S * log.sample_rate_hz))
        self.channels = available_channels(log)
        self.scales = channel_scales(log)
        self.weights = noise_levels(log)
        self.measured = {ch: self.windows.take(log.columns[CHANNELS[ch][0]]) for ch in self.channels}
        self.nominal = PlantModel(supply_from_log(log, HydraulicParams()), Effects())

    def residuals(self, model: PlantModel) -> dict[str, np.ndarray]:
        """Simulated minus measured, channel -> (k, length), physical units."""
        out = replay(self.log, model, self.windows)
        return {ch: out[ch] - self.measured[ch] for ch in self.channels}

    def vector(self, res: dict[str, np.ndarray], rows: np.ndarray) -> np.ndarray:
        """Residuals of ``rows`` of the windows divided by each channel's noise level (the maximum-likelihood
        weighting for white sensor noise), the first :data:`SETTLE_S` of each window left out."""
        return np.concatenate([(res[ch][rows, self.settle:] / self.weights[ch]).ravel() for ch in self.channels])

    def nrmse(self, res: dict[str, np.ndarray], rows: np.ndarray | None = None) -> dict[str, float]:
        """RMS residual / scale per channel (on ``rows`` of the windows, default all)."""
        rows = slice(None) if rows is None else rows
        return {ch: float(np.sqrt(np.mean(res[ch][rows] ** 2)) / self.scales[ch]) for ch in self.channels}

    # what the report needs (hexsim.validation), the same for every kind of problem
    replay_mode = ("valve replay: the logged u_v drives the model open loop in windows, each started from "
                   "the measured state")
    scored = "windows after their settling time"

    @property
    def units(self) -> dict[str, str]:
        return {ch: CHANNELS[ch][1] for ch in self.channels}

    @property
    def window_doc(self) -> dict:
        fs = self.log.sample_rate_hz
        return {"count": int(len(self.windows.starts)), "length_s": self.windows.length / fs,
                "settle_s": self.settle / fs, "fit": "even windows", "held_out": "odd windows"}

    def analysis_view(self, res: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Residuals (k, n) per channel as the residual analysis takes them: windows without the settling."""
        return {ch: r[:, self.settle:] for ch, r in res.items()}

    def motion_state(self):
        """(u_v, velocity, position, near a reversal), each (k, n) like :meth:`analysis_view`."""
        log = self.log
        pos = log.columns["pos_m"]
        vel = measured_velocity(log, pos)
        near = near_reversals(log.time, vel)
        take = lambda x: self.windows.take(x)[:, self.settle:]  # noqa: E731
        return take(log.columns["valve_cmd_V"]), take(vel), take(pos), take(near)

    def sample_times(self) -> np.ndarray:
        """Log times [s] of the samples of :meth:`analysis_view` (k, n)."""
        fs = self.log.sample_rate_hz
        return self.log.time[self.windows.starts][:, None] + np.arange(self.settle, self.windows.length)[None, :] / fs


def near_reversals(t: np.ndarray, velocity: np.ndarray, half_width: float = 0.05) -> np.ndarray:
    """(N,) True within ``half_width`` [s] of a velocity reversal."""
    near = np.zeros(len(t), bool)
    for tr in zero_crossings(t, velocity):
        near |= np.abs(t - tr) < half_width
    return near


def effective_n(res: dict[str, np.ndarray]) -> float:
    """Independent residuals: sum over channels of N / (1 + 2 sum_k rho_k), rho from the windows'
    autocorrelation up to the first non-positive lag (Bartlett / Bayley–Hammersley)."""
    total = 0.0
    for r in res.values():
        x = r - r.mean(axis=1, keepdims=True)
        var = float(np.mean(x * x))
        if var <= 0:
            continue
        s = 0.0
        for lag in range(1, x.shape[1] // 2):
            rho = float(np.mean(x[:, lag:] * x[:, :-lag])) / var
            if rho <= 0:
                break
            s += rho
        total += x.size / (1.0 + 2.0 * s)
    return total


@dataclass
class FitResult:
    name: str
    parameters: dict[str, dict[str, float]]  # name -> {value, std_error, unit}
    cost_fit: float
    cost_held_out: float
    held_out_gain: float  # 1 - cost_held_out / nominal held-out cost
    aic: float
    bic: float
    nfev: int
    model: PlantModel | None = None

    def as_dict(self) -> dict:
        return {"effect": self.name, "parameters": self.parameters, "cost_fit": self.cost_fit,
                "cost_held_out": self.cost_held_out, "held_out_gain": self.held_out_gain, "aic": self.aic,
                "bic": self.bic, "function_evaluations": self.nfev}


def _criteria(cost: float, n_eff: float, n_total: int, k: int) -> tuple[float, float]:
    # Gaussian log-likelihood over N_eff independent residuals with the variance estimated (2 cost / N)
    sigma2 = max(2.0 * cost / n_total, 1e-300)
    aic = n_eff * math.log(sigma2) + 2 * k
    bic = n_eff * math.log(sigma2) + k * math.log(n_eff)
    return aic, bic


def fit_candidate(problem: Problem, name: str) -> FitResult:
    """Fit one candidate (least_squares, trf, bounds) on the fit windows and score it on the held-out."""
    cand = CANDIDATES[name]
    log = problem.log
    lower, upper = np.array(cand.lower), np.array(cand.upper)
    cache: dict[bytes, dict[str, np.ndarray]] = {}

    def resid(x):
        key = np.asarray(x).tobytes()
        if key not in cache:
            try:
                cache[key] = problem.residuals(cand.apply(problem.nominal, x))
            except (PhysicsError, FloatingPointError, ValueError):  # the model cannot run there: a bad fit
                cache[key] = {ch: np.full_like(problem.measured[ch], 1e3 * problem.scales[ch])
                              for ch in problem.channels}
        return problem.vector(cache[key], problem.fit_rows)

    starts = [np.clip(np.array(x, dtype=float), lower, upper) for x in cand.starts(log)]
    x0 = min(starts, key=lambda x: float(np.sum(resid(x) ** 2)))
    sol = least_squares(resid, x0, bounds=(lower, upper), method="trf", diff_step=1e-2, x_scale="jac",
                        max_nfev=12 * len(x0) + 8, xtol=1e-4, ftol=1e-6)
    resid(sol.x)  # the optimum is normally in the cache already
    res = cache[np.asarray(sol.x).tobytes()]
    fit_vec = problem.vector(res, problem.fit_rows)
    test_vec = problem.vector(res, problem.test_rows)
    n_fit = fit_vec.size
    n_eff = effective_n({ch: res[ch][problem.fit_rows] for ch in problem.channels})
    dof = max(n_eff - len(x0), 1.0)
    s2 = float(fit_vec @ fit_vec) / dof * (n_eff / n_fit)
    try:
        cov = np.linalg.inv(sol.jac.T @ sol.jac) * s2 * (n_fit / n_eff)
        se = np.sqrt(np.clip(np.diag(cov), 0, None))
    except np.linalg.LinAlgError:
        se = np.full(len(x0), np.nan)
    aic, bic = _criteria(0.5 * float(fit_vec @ fit_vec), n_eff, n_fit, len(x0))
    params = {p: {"value": float(v), "std_error": float(e), "unit": u}
              for p, v, e, u in zip(cand.parameters, sol.x, se, cand.units)}
    return FitResult(name=name, parameters=params, cost_fit=0.5 * float(fit_vec @ fit_vec),
                     cost_held_out=0.5 * float(test_vec @ test_vec), held_out_gain=float("nan"), aic=aic, bic=bic,
                     nfev=int(sol.nfev), model=cand.apply(problem.nominal, sol.x))


def make_problem(log: MeasurementLog):
    """The identification problem of a log: windowed valve replay for a single actuator
    (:class:`Problem`), closed-loop replay in segments for a hexapod
    (:class:`hexsim.hexapod_replay.HexapodProblem`)."""
    if log.system == "hexapod":
        from hexsim.hexapod_replay import HexapodProblem

        return HexapodProblem(log)
    return Problem(log)


#: Candidates that apply to a hexapod log: the load (mass, inclination) is a single-axis fact.
HEXAPOD_CANDIDATES = tuple(n for n in EFFECT_NAMES if n != "load")


def _fit_in_worker(log: MeasurementLog, name: str) -> FitResult:
    return fit_candidate(make_problem(log), name)


@dataclass
class Identification:
    """Outcome of :func:`identify`: the nominal and the chosen model's residuals and the candidate table."""

    problem: Problem
    nominal_residuals: dict[str, np.ndarray]
    nominal_cost_fit: float
    nominal_cost_held_out: float
    nominal_aic: float
    nominal_bic: float
    candidates: list[FitResult]
    chosen: FitResult | None
    chosen_residuals: dict[str, np.ndarray]

    @property
    def added_effect(self) -> str:
        return self.chosen.name if self.chosen else "none"

    @property
    def error_before(self) -> dict[str, float]:
        return self.problem.nrmse(self.nominal_residuals)

    @property
    def error_after(self) -> dict[str, float]:
        return self.problem.nrmse(self.chosen_residuals)


def identify(log: MeasurementLog, *, candidates: tuple[str, ...] | None = None, jobs: int = 2,
             progress: bool = False) -> Identification:
    """Replay the log with the nominal model, fit every candidate effect and choose (see the module doc).

    ``candidates``: default every effect that applies to the log's system. ``jobs`` worker processes
    fit candidates in parallel (1: in this process). Raises InputError for a log the replay cannot use.
    """
    problem = make_problem(log)
    if candidates is None:
        candidates = HEXAPOD_CANDIDATES if log.system == "hexapod" else EFFECT_NAMES
    nominal = problem.residuals(problem.nominal)
    fit_vec = problem.vector(nominal, problem.fit_rows)
    test_vec = problem.vector(nominal, problem.test_rows)
    n_eff = effective_n({ch: nominal[ch][problem.fit_rows] for ch in problem.channels})
    base_aic, base_bic = _criteria(0.5 * float(fit_vec @ fit_vec), n_eff, fit_vec.size, 0)
    base_test = 0.5 * float(test_vec @ test_vec)
    results: list[FitResult] = []
    def progress_bar():
        return tqdm(total=len(candidates), desc="fitting effects", unit="effect", disable=not progress, leave=False)

    if jobs > 1:
        with worker_pool(jobs) as pool:
            futures = [pool.submit(_fit_in_worker, log, name) for name in candidates]
            bar = progress_bar()  # after the workers started (hexsim.workers)
            for fut in as_completed(futures):
                results.append(fut.result())
                bar.set_postfix_str(results[-1].name)
                bar.update()
    else:
        bar = progress_bar()
        for name in candidates:
            results.append(fit_candidate(problem, name))
            bar.set_postfix_str(name)
            bar.update()
    bar.close()
    order = {n: i for i, n in enumerate(candidates)}
    results.sort(key=lambda r: order[r.name])
    for r in results:
        r.held_out_gain = 1.0 - r.cost_held_out / base_test if base_test > 0 else 0.0
    best = max(results, key=lambda r: r.held_out_gain, default=None)
    chosen = best if best is not None and best.held_out_gain >= MIN_HELD_OUT_GAIN and best.bic < base_bic else None
    chosen_res = problem.residuals(chosen.model) if chosen else nominal
    return Identification(problem=problem, nominal_residuals=nominal, nominal_cost_fit=0.5 * float(fit_vec @ fit_vec),
                          nominal_cost_held_out=base_test, nominal_aic=base_aic, nominal_bic=base_bic,
                          candidates=results, chosen=chosen, chosen_residuals=chosen_res)
