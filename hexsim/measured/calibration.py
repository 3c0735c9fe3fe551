"""Calibrating a machine's nominal parameters from calibration experiments: ``hexsim calibrate``.

A data sheet only brackets a real machine's valve flow gain, overlap, edge matching, supply level and
seal friction. Before effects are judged (``hexsim validate``), they are fitted, inside those brackets,
on calibration experiments: open-loop runs at constant valve commands in both directions and at
several commands (as the real servo cylinder's 1, 3 and 5 V runs, ``examples/data/servo_cylinder``).

**Features and model** (:mod:`hexsim.measured.steady`): the steady motions and end-stop plateaus of every
stretch of constant command, and the machine file's steady motion at each.

**Parameters** (:mod:`hexsim.measured.parameters`: :class:`ParameterSet`, :func:`default_parameters`):
machine-file keys, each with bounds, the bounds' source and the experiment that identifies it. A value
edits the machine file by its key, so a calibrated nominal is a machine file like any other.

**Fit** (:func:`calibrate`, the optimizer :mod:`hexsim.measured.fitting`): bounded least squares
(``scipy.optimize.least_squares``) on the features, weighted as :mod:`hexsim.measured.steady` says
(:data:`~hexsim.measured.steady.SPEED_SIGMA_REL`, :data:`~hexsim.measured.steady.SPEED_SIGMA_ABS`,
:data:`~hexsim.measured.steady.PRESSURE_SIGMA`); standard errors and correlations from the Jacobian, s^2 (J^T J)^-1 with s^2 the residual variance (:mod:`hexsim.measured.statistics`). A parameter the data
cannot separate (a standard error above a quarter of its bound range, or a correlation beyond 0.98 with
another, whichever has the larger relative error) is held at its prior and the rest refitted; the report
says why and which experiment would identify it. A fit at a bound is reported as such: a hint that the
model lacks something. Held-out logs are predicted, not fitted; with three or more fitted logs each is
also predicted by a fit on the others (leave one log out).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from hexsim.errors import InputError
from hexsim.measured.acquisition import accelerometer_sampling
from hexsim.measured.curves import (
    curve_report,
    reaches_budget,
    with_curve,
    with_curve_again,
)
from hexsim.measured.envelope import measured_commands
from hexsim.measured.estimates import AT_A_BOUND, FROM_LOGS, HELD, Estimate
from hexsim.measured.fitting import Fit, FitOptions, fit_parameters
from hexsim.measured.measurement import MeasurementLog
from hexsim.measured.parameters import (
    Parameter,
    ParameterSet,
    default_parameters,
    leg_null_parameter,
)
from hexsim.measured.records import CalibrationRecord, CalibrationReport
from hexsim.measured.replay import command_jumps
from hexsim.measured.steady import (
    PRESSURE_SIGMA,
    SPEED_SIGMA_ABS,
    SPEED_SIGMA_REL,
    Feature,
    axis_load,
    feature_errors,
    features,
    predict,
    steady_residual,
)
from hexsim.plant.geometry import Geometry
from hexsim.plant.machine import Machine, with_keys, with_valve
from hexsim.plant.params import FLOW_AREAS

#: Evaluations of one least-squares run on transients (each a replay of the fit windows and a Jacobian of as
#: many replays as parameters): a full calibration, and the screening of a flow-area form (far from an
#: optimum, but it ranked the forms right on every machine measured, docs/calibration.md; the chosen form
#: then goes on from there).
FIT_NFEV, SCREEN_NFEV = 40, 10
#: A fit on replays stops when a step moves the parameters less than XTOL of their brackets' scale or lowers
#: the weighted sum of squares by less than FTOL of itself (scipy's xtol, ftol; its 1e-8 defaults spent half
#: of a calibration's replays on the last 0.01 % of its cost, the refits after a parameter is held nearly all
#: of theirs).
XTOL, FTOL = 1e-4, 1e-6
#: Evaluations of one least-squares run on hexapod logs: each is a closed-loop replay of the whole log (0.8 s
#: for 20 s of the Micro Motion System) and a Jacobian of as many replays as parameters (20); the fit is
#: nearly linear in the legs' flow gains and converges in a few steps (docs/calibration.md).
HEXAPOD_NFEV = 8
#: A hexapod's flow-area forms are screened on the first this many segments of each log (0.25 s each, after
#: the first 0.5 s), with at most this many evaluations each.
HEXAPOD_SCREEN_SEGMENTS, HEXAPOD_SCREEN_NFEV = 24, 3
#: The flow-area forms of seed eq. (3.11) and (3.3) a calibration from transients tries for a valve of that
#: family (the seed's 300 x_v^2 and its port), keeping the one that predicts the held-out windows best.
SEED_FORMS = tuple(form for form in FLOW_AREAS if form not in ("table", "curve"))
#: What ``flow_areas`` names to ask for the valve's curves read from the logs' flows (:mod:`hexsim.measured.curves`;
#: "table" as earlier versions called it).
READ_CURVE = ("curve", "table")
DYNAMICS = ("auto", "always", "never")
def _is_steady(log: MeasurementLog) -> bool:
    """An open-loop constant-command experiment (:func:`features` finds a steady motion in it)."""
    if not log.open_loop:
        return False
    try:
        features(log)
    except InputError:
        return False
    return True


def _forms(machine: Machine, flow_areas: tuple[str, ...] | None) -> tuple[str, ...]:
    """The flow-area forms to calibrate: those asked for, else the machine's own and, for a valve of the
    seed's (3.11) family, the others of :data:`SEED_FORMS`."""
    own = machine.hydraulics.flow_area
    if flow_areas:  # "curve" (or "table" on a machine without one): the curves read from the logs afterwards
        flow_areas = tuple(f for f in flow_areas if f not in READ_CURVE or f == own)
    if flow_areas:
        return tuple(flow_areas)
    if own in SEED_FORMS[:3]:
        return (own, *(f for f in SEED_FORMS if f != own))
    return (own,)


def _wants_curve(ev: "_Evidence", machine: Machine, flow_areas: tuple[str, ...] | None) -> bool | None:
    """Whether a calibration goes on to read the valve's curves from the logs' flows (:mod:`hexsim.measured.curves`):
    True where ``flow_areas`` asks for them (:data:`READ_CURVE`) on a machine whose valve is a form, None where it
    may (no form named: when the chosen form misses its own logs' budget, single-actuator transients with
    ``p1_Pa`` in every log), False otherwise. Raises InputError where it is asked for and cannot be read: steady
    features only, hexapod logs, or a log without ``p1_Pa`` (named)."""
    own = machine.hydraulics.flow_area
    asked = bool(flow_areas) and any(f in READ_CURVE and f != own for f in flow_areas)
    readable = bool(ev.replays) and not ev.hexapod and all("p1_Pa" in r.log.columns for r in ev.replays)
    if not asked:
        return None if not flow_areas and readable and own not in ("table", "curve") else False
    if not ev.replays or ev.hexapod:
        raise InputError("--flow-area curve reads the valve's curves from single-actuator transients (closed-loop "
                         "motions, steps); these logs give " + ("hexapod replays" if ev.hexapod else "steady features"))
    lacking = [r.log.path.name for r in ev.replays if "p1_Pa" not in r.log.columns]
    if lacking:
        raise InputError(f"--flow-area curve reads the valve's curves from the chamber's flow: {', '.join(lacking)} "
                         f"has no p1_Pa column")
    return True


def with_flow_area(machine: Machine, form: str) -> Machine:
    """``machine`` with its valve's flow-area form set to ``form`` (checked as any machine file: an underlap
    needs the sharp area). Raises InputError for a form the machine's valve cannot take."""
    return with_valve(machine, flow_area=form, **({} if form == "table" else {"opening_table": []}),
                      **({} if form == "curve" else {"flow_curve_PA": [], "flow_curve_AT": []}))


@dataclass
class _Evidence:
    """What a calibration fits, read from its logs: the steady features of the constant-command experiments
    (``feats``, from the ``steady`` logs; ``loads`` per log file name) and the replays of the others
    (``replays``: :class:`hexsim.measured.dynamics.ReplayEvidence`); ``hexapod`` for hexapod logs."""

    steady: list[MeasurementLog]
    feats: list[Feature]
    loads: dict
    replays: list
    hexapod: bool

    def residual(self, replays: list | None = None) -> Callable[[Machine], np.ndarray]:
        """The weighted residual of a machine: the steady features' and each replay's (default all of them;
        the screening passes their prefixes)."""
        steady_of = steady_residual(self.feats, self.loads)
        replays = self.replays if replays is None else replays
        return lambda m: np.concatenate([steady_of(m), *(ev.residual(m) for ev in replays)])

    def clusters(self) -> np.ndarray:
        """Each entry of :meth:`residual`'s independent group: a steady feature its own, each replay's fit
        windows theirs (:attr:`hexsim.measured.dynamics.ReplayEvidence.clusters`)."""
        out, start = [np.arange(len(self.feats))], len(self.feats)
        for ev in self.replays:
            ids = ev.clusters
            out.append(start + ids)
            start += int(ids.max()) + 1 if ids.size else 0
        return np.concatenate(out)

    def independent_share(self, m: Machine) -> float:
        """Independent samples per residual entry at machine ``m`` (features: each; replays: their own)."""
        sizes = [len(self.feats)] + [ev.residual_size for ev in self.replays]
        shares = [1.0] + [ev.effective_share(m) for ev in self.replays]
        return float(np.dot(sizes, shares) / max(sum(sizes), 1))

    @property
    def jumps(self) -> bool:
        """Whether a replayed single-actuator log's valve command jumps (a step): what shows when its sensors
        were read (:mod:`hexsim.measured.acquisition`)."""
        return not self.hexapod and any(command_jumps(ev.log).size for ev in self.replays)


def _gather(logs: list[MeasurementLog], held_out: list[MeasurementLog], machine: Machine, dynamics: str,
            built: tuple = ()) -> _Evidence:
    """The evidence of ``logs`` (see :func:`calibrate`); ``built``: replay evidence already built for some of
    them (:class:`hexsim.measured.dynamics.ReplayEvidence`, matched by the log's path). Raises InputError for an unknown ``dynamics``, logs of a
    hexapod and a single actuator together, a hexapod with ``dynamics`` "never", or two logs of one file name."""
    from hexsim.measured.dynamics import ReplayEvidence

    if dynamics not in DYNAMICS:
        raise InputError(f"dynamics {dynamics!r}: expected one of {', '.join(DYNAMICS)}")
    systems = {log.system for log in (*logs, *held_out)}
    if len(systems) > 1:
        raise InputError("hexapod and single-actuator logs together: a calibration reads the logs of one machine")
    hexapod = systems == {"hexapod"}
    if hexapod and dynamics == "never":
        raise InputError("a hexapod is calibrated from its logs' transients (its closed-loop replay); dynamics "
                         "'never' reads only single-actuator constant-command experiments")
    steady = list(logs) if dynamics == "never" else [log for log in logs if _is_steady(log)]
    moving = [] if dynamics == "never" else list(logs) if dynamics == "always" else [
        log for log in logs if log not in steady]
    loads = {log.path.name: axis_load(log) for log in (*logs, *held_out)}
    if len(loads) < len(logs) + len(held_out):
        raise InputError("two logs of the same file name: calibration names features by their log's file name")
    ready = {ev.log.path: ev for ev in built}
    return _Evidence(steady, [f for log in steady for f in features(log)], loads,
                     [ready.get(log.path) or ReplayEvidence.of(log, machine) for log in moving], hexapod)


def _choose_form(ev: _Evidence, machine: Machine, params: ParameterSet | None, flow_areas: tuple[str, ...] | None,
                 notify: Callable[[str], None], fixed: tuple[str, ...] = (), jobs: int = 1,
                 curve_passes: int = 1) -> tuple[dict, list[dict]]:
    """Calibrate each flow-area form (default :func:`_forms`; with transients only, else the machine's own),
    each from the prior (a form's calibrated values are another form's far valley): with more than one, a
    screening (a few evaluations, no held-at-prior rule; a hexapod's on its logs' first segments, each replay
    being the whole log's), then the form that predicts the held-out windows best calibrated in full from
    where its screening ended; the keys ``fixed`` are not fitted (the logs state them). Returns (the chosen:
    ``flow_area``, ``start`` machine, ``params``, ``fit``,
    ``machine``; every form tried, with its held-out cost or why it was refused); the curves read up to
    ``curve_passes`` times while the calibration misses its own logs' budget (:func:`with_curve_again`). Raises
    InputError if no form could be calibrated."""
    forms = _forms(machine, flow_areas) if ev.replays else (machine.hydraulics.flow_area,)
    curve = _wants_curve(ev, machine, flow_areas)  # refused before any fit where it cannot be read
    options = FitOptions(diff_step=1e-3, x_scale="jac", warm=True, correlated_se=0.01, xtol=XTOL, ftol=FTOL,
                         max_nfev=HEXAPOD_NFEV if ev.hexapod else FIT_NFEV, jobs=jobs,
                         clusters=ev.clusters()) if ev.replays else FitOptions()
    share = ev.independent_share if ev.replays else None
    screen = len(forms) > 1
    judged = ([r.prefix(HEXAPOD_SCREEN_SEGMENTS) for r in ev.replays] if ev.hexapod else ev.replays) if screen \
        else ev.replays
    screening = replace(options, max_nfev=HEXAPOD_SCREEN_NFEV if ev.hexapod else SCREEN_NFEV, rule=False)
    tried: list[dict] = []
    for form in forms:
        try:
            start = machine if form == machine.hydraulics.flow_area else with_flow_area(machine, form)
        except InputError as exc:
            tried.append({"flow_area": form, "refused": str(exc)})
            continue
        form_params = ParameterSet(p for p in (params if params is not None else default_parameters(
            start, dynamics=bool(ev.replays), hexapod=ev.hexapod, timing=ev.jumps)) if p.key not in fixed)
        notify(f"{'screening' if screen else 'calibrating'} {len(form_params)} parameters with the {form} flow area")
        fit = fit_parameters(ev.residual(judged), start, form_params, independent_share=share, notify=notify,
                             options=screening if screen else options)
        result = form_params.apply(start, fit.values)
        tried.append({"flow_area": form, "held_out_cost": sum(r.errors(result).held_out_cost for r in judged),
                      "start": start, "params": form_params, "fit": fit, "machine": result})
    usable = [t for t in tried if "fit" in t]
    if not usable:
        raise InputError(f"{machine.label}: no flow-area form could be calibrated ({tried[0]['refused']})")
    best = dict(min(usable, key=lambda t: t["held_out_cost"]))
    if screen:
        notify(f"calibrating {len(best['params'])} parameters with the {best['flow_area']} flow area")
        best["fit"] = fit_parameters(ev.residual(), best["start"], best["params"], independent_share=share,
                                     initial=best["machine"], options=options, notify=notify)
        best["machine"] = best["params"].apply(best["start"], best["fit"].values)
    if curve or (curve is None and not reaches_budget(ev.replays, best["machine"])):
        best = with_curve(ev.replays, ev.residual(), best, tried, options, share, notify)
        for _ in range(curve_passes - 1):
            if "curve" not in best or reaches_budget(ev.replays, best["machine"]):
                break
            best = with_curve_again(ev.replays, ev.residual(), best, tried, options, share, notify)
    return best, tried


@dataclass(frozen=True)
class Calibration:
    """What :func:`calibrate` returns: the calibrated ``machine`` (its ``calibration`` block the report without
    the feature rows, its sources each fitted key's value ± standard error and prior) and the ``report``."""

    machine: Machine
    report: CalibrationReport

    @property
    def record(self) -> CalibrationRecord:
        """The report as a validation reads a calibrated file's block (:class:`CalibrationRecord`)."""
        return CalibrationRecord.of(self.report)


def calibrate(logs: list[MeasurementLog], machine: Machine, *, held_out: list[MeasurementLog] = (),
              params: ParameterSet | None = None, cross_validate: bool = True, dynamics: str = "auto",
              flow_areas: tuple[str, ...] | None = None, evidence: tuple = (), notify=None,
              jobs: int = 1, curve_passes: int = 1) -> Calibration:
    """Fit ``params`` (default :func:`default_parameters`) of ``machine`` to the evidence of ``logs`` (module
    doc); predict ``held_out``. Evidence: the steady features of open-loop constant-command experiments, and
    the transients of every other single-actuator log (:class:`hexsim.measured.dynamics.ReplayEvidence`:
    closed-loop motions, steps), or of hexapod logs (their closed-loop replay); ``dynamics`` "always" adds
    the transients of the constant-command experiments too, "never" reads steady features only. With
    transients the valve's flow-area form is chosen among ``flow_areas`` (default :func:`_forms`) by the
    held-out windows' cost (:func:`_choose_form`). ``evidence``: the replays of some of ``logs`` already built
    (:meth:`hexsim.measured.dynamics.ReplayEvidence.of_problem`: a validation's problem and budget), used
    instead of replaying those logs' nominal again. ``jobs``: processes that evaluate the replays' Jacobians
    (:class:`hexsim.measured.fitting.FitOptions`; the same calibration as one). ``curve_passes``: how many times
    the valve's curves are read from the flows while the calibration misses its own logs (:func:`_choose_form`).

    Returns the :class:`Calibration`: the calibrated machine (its ``calibration`` the report without the feature
    rows) and the report (:class:`~hexsim.measured.records.CalibrationReport`): per parameter prior, value,
    standard error, bounds and their source, status (fitted, at a bound, held at its prior: why, and the
    experiment that would identify it), the correlations of the fitted ones,
    the errors before/after on the fitted features and held-out windows, on each held-out log and
    (``cross_validate``, three or more steady logs) on each log left out of a refit, and the feature rows.
    Raises InputError for a log that is not evidence of either kind, or an unknown ``dynamics``."""
    notify = notify or (lambda text: None)
    machine, supply = supply_from_logs(logs, machine)
    ev = _gather(logs, held_out, machine, dynamics, evidence)
    machine, sampling = accelerometer_sampling(ev.replays, machine) if ev.jumps else (machine, None)
    best, tried = _choose_form(ev, machine, params, flow_areas, notify, fixed=(supply["key"],) if supply else (),
                               jobs=jobs, curve_passes=curve_passes)
    nulls = []
    if ev.hexapod:
        best["machine"], nulls = leg_null_offsets(ev.replays, best["machine"])
    best["machine"], noise = sensor_noise_from_logs(logs, best["machine"])
    report = _report(ev, machine, best, tried, logs)
    if sampling:
        report["acquisition"] = sampling
    report["parameters"] += nulls + ([supply] if supply else []) + ([noise] if noise else [])
    if held_out:
        report["held_out"] = _held_out(held_out, machine, best["machine"], ev.loads)
    if cross_validate and len(ev.steady) >= 3 and not ev.replays:
        report["leave_one_log_out"] = _leave_one_log_out(ev, best)
    if ev.feats:
        steady_names = {log.path.name for log in ev.steady}
        before, after = predict(ev.feats, machine, ev.loads), predict(ev.feats, best["machine"], ev.loads)
        report["rows"] = [{**f.__dict__, "before": float(b), "after": float(a)}
                          for f, b, a in zip(ev.feats, before, after) if f.log in steady_names]
    return Calibration(_with_provenance(best["machine"], machine, report, best["flow_area"], len(logs)), report)


def supply_from_logs(logs: list[MeasurementLog], machine: Machine) -> tuple[Machine, dict | None]:
    """The supply pressure as the logs state it: where every log carries ``ps_Pa``, the machine's
    ``supply.pressure_Pa`` is the median of all their samples (the level every replay already runs at,
    :func:`hexsim.measured.replay.supply_from_log`), an operating condition measured, not a parameter to fit
    (fitted, it moves no replay and would be "held at its prior"). Returns the machine with it set and its
    report row (status ``from the logs``); the machine unchanged and None where a log lacks ``ps_Pa``."""
    from scipy.stats import median_abs_deviation

    if not logs or any("ps_Pa" not in log.columns for log in logs):
        return machine, None
    samples = np.concatenate([log.columns["ps_Pa"] for log in logs])
    level = float(np.median(samples))
    spread = float(median_abs_deviation(samples, scale="normal"))
    logged = Parameter("supply.pressure_Pa", float(np.min(samples)), float(np.max(samples)),
                       "the logged supply pressure's range", "ps_Pa logged")
    est = Estimate(logged.key, level, spread / math.sqrt(len(samples)), logged.unit, FROM_LOGS,
                   f"every log carries ps_Pa: the median of its {len(samples)} samples (it ranges "
                   f"{logged.lower / 1e5:.4g}…{logged.upper / 1e5:.4g} bar), the level every replay runs at",
                   logged.lower, logged.upper)
    row = logged.row(est) | {"prior": float(machine.hydraulics.supply_pressure)}
    return with_keys(machine, {"supply.pressure_Pa": level}), row


def sensor_noise_from_logs(logs: list[MeasurementLog], machine: Machine) -> tuple[Machine, dict | None]:
    """The position sensor's noise as the logs show it: the median over the logs (and a hexapod's legs) of
    each position channel's white-noise rms (:func:`hexsim.measured.residuals.noise_of`: the second
    difference's MAD, blind to the motion), written to ``sensors.position_noise_m``. The P controller turns
    this noise into valve dither, K_p times it, at every reversal: a file that keeps a data sheet's 2 µm for a
    transducer that reads 5 µm predicts a reversal bump 30-40 % low. Returns the machine with it set and its
    report row (status ``from the logs``); unchanged and None for logs without a position column."""
    from hexsim.measured.residuals import noise_of

    levels = [noise_of(log.columns[c], "position") for log in logs for c in log.columns
              if c == "pos_m" or (c.startswith("leg") and c.endswith("_pos_m"))]
    if not levels:
        return machine, None
    level = float(np.median(levels))
    logged = Parameter("sensors.position_noise_m", float(min(levels)), float(max(levels)),
                       "the position channels' noise over the logs", "pos_m logged")
    est = Estimate(logged.key, level, float(np.std(levels)) / math.sqrt(len(levels)), logged.unit, FROM_LOGS,
                   f"the median white-noise rms of the {len(levels)} logged position channel(s) (second differences' "
                   f"MAD; they range {min(levels) * 1e6:.3g}…{max(levels) * 1e6:.3g} µm): runs dither the valve "
                   f"with it, as the machine does", logged.lower, logged.upper)
    row = logged.row(est) | {"prior": float(machine.controller.position_noise)}
    return with_keys(machine, {"sensors.position_noise_m": level}), row


def leg_null_offsets(replays: list, machine: Machine) -> tuple[Machine, list[dict]]:
    """Each hexapod leg's valve null offset from its static tracking error, after the other parameters are
    fitted: in closed loop a null offset u_0 holds the piston u_0 / K_p off its setpoint wherever the valve's
    flow is linear in u_v - u_0 (seed eq. 3.2-3.4 with the P control of §2.3.2), while a transducer's offset
    does not show between log and replay (the controller holds the measured position on the setpoint on the
    machine as in the model). So u_0,leg = u_0,prior - K_p d_leg, d_leg the mean of measured minus replayed
    position over the fit segments of the ``replays`` (:class:`hexsim.measured.dynamics.ReplayEvidence`, their
    position offsets calibrated freely) less the legs' median of it, averaged over the logs. The common
    part stays with the sensors, as ``hexsim validate`` leaves it
    (:func:`hexsim.measured.scoring.calibrate_sensors`): all six nulls shifted alike are not told from the
    model's common mismatch (an unmodelled spool lag on a heave offsets all six legs alike), so each null is
    found relative to the legs' median; its standard error from the residual's independent samples
    (:func:`hexsim.measured.residuals.effective_n`). Without
    it, ``hexsim validate`` (whose closed-loop replay leaves a leg's offset standing out of the others' in the
    residual, :data:`hexsim.measured.hexapod_replay.CLOSED_LOOP_OFFSET_M`) would take every valve's
    zero-point tolerance for a drifted null.

    Returns the machine with ``legs.legN.valve.null_offset_V`` set (clipped to its bracket,
    :func:`hexsim.measured.parameters.leg_null_parameter`: beyond it the report says "at a bound") and the
    parameter rows for the report."""
    from hexsim.measured.residuals import effective_n
    from hexsim.measured.scoring import position_offsets

    offsets, variances = [], []
    for r in replays:
        p = r.problem
        sim = p.simulate(r.model(machine))["position"]
        mean = position_offsets(p, sim, p.fit_rows)
        offsets.append(r.log.kp * (mean - np.median(mean)))  # [V] per leg, off the legs' common offset
        d = (p.measured["position"] - sim)[p.fit_rows, p.settle:]  # (rows, n, 6) [m]
        variances.append([(r.log.kp * float(np.std(d[..., j]))) ** 2 / max(effective_n(d[..., j]), 1.0)
                          for j in range(d.shape[2])])
    shift = np.mean(offsets, axis=0)
    se = np.sqrt(np.sum(variances, axis=0)) / len(replays)
    priors = [dict(dict(machine.legs).get(leg, ())).get("null_offset", machine.hydraulics.null_offset)
              for leg in range(1, len(shift) + 1)]
    rows, values = [], {}
    for leg, (prior, du, e) in enumerate(zip(priors, shift, se), start=1):
        param = leg_null_parameter(machine, leg)
        value = float(np.clip(prior - du, param.lower, param.upper))
        values[param.key] = value
        est = param.estimate(value, e)
        if est.status == AT_A_BOUND:
            est = replace(est, why="the leg's static tracking error asks for more than a valve's zero-point "
                                   "tolerance: a leak or a sensor of that leg, not its null")
        rows.append(param.row(est) | {"prior": float(prior)})
    return with_keys(machine, values), rows


def _report(ev: _Evidence, machine: Machine, best: dict, tried: list[dict], logs: list[MeasurementLog]
            ) -> CalibrationReport:
    """The calibration's report without the held-out logs, the leave-one-out refits and the feature rows
    (:func:`calibrate` adds them)."""
    fit, calibrated = best["fit"], best["machine"]
    methods = []
    if ev.feats:
        methods.append("steady motions and end-stop pressures")
    if ev.replays:
        methods.append("transients (closed-loop replay of the whole log, hexsim.measured.hexapod_replay)"
                       if ev.hexapod else "transients (windowed valve replay, hexsim.measured.dynamics)")
    report = {"machine": machine.label, "system": "hexapod" if ev.hexapod else "single-actuator",
              "logs": [str(log.path) for log in logs],
              "method": "bounded least squares of " + " and ".join(methods) + " (hexsim.measured.calibration)",
              "weights": {"speed": f"{SPEED_SIGMA_REL:.0%} + {SPEED_SIGMA_ABS * 1e3:g} mm/s",
                          "pressure_Pa": PRESSURE_SIGMA, "transients": "each channel's noise budget"},
              "covariance": fit.covariance,
              "parameters": _parameter_rows(fit),
              "correlation": {"keys": [fit.params[i].key for i in fit.free],
                              "matrix": _free_block(fit).round(4).tolist()}}
    if ev.replays:
        after = [r.errors(calibrated).record() for r in ev.replays]  # each log replayed once for the report
        report["flow_area"] = {"chosen": best["flow_area"], "prior": machine.hydraulics.flow_area,
                               "held_out_cost": sum(e["held_out_cost"] for e in after),
                               "tried": [{"flow_area": t["flow_area"], **({"held_out_cost": t["held_out_cost"]}
                                         if "held_out_cost" in t else {"refused": t["refused"]})} for t in tried]}
        if "curve" in best:
            report["flow_area"]["curve"] = curve_report(best["curve"], best["form"], calibrated)
        report["transients"] = [{"before": r.errors(machine).record(), "after": a}
                                for r, a in zip(ev.replays, after)]
        if not ev.hexapod:  # where the logs dwelt: a validation beyond is the calibration's envelope
            report["commands_measured_V"] = [round(v, 4) for v in measured_commands([r.log for r in ev.replays],
                                                                                  calibrated.hydraulics.null_offset)]
    elif ev.steady:
        report["replayed"] = _replayed(ev.steady, machine, calibrated)
    _add_priors(report, best.get("prior", best["start"]), best["params"])
    if ev.replays or ev.steady:
        from hexsim.measured.dynamics import own_budget

        report["own_budget"] = own_budget(report)
    if ev.feats:
        report["fit"] = {"before": feature_errors(ev.feats, predict(ev.feats, machine, ev.loads)),
                         "after": feature_errors(ev.feats, predict(ev.feats, calibrated, ev.loads))}
    return report


def _replayed(logs: list[MeasurementLog], prior: Machine, calibrated: Machine) -> list[dict]:
    """A steady calibration's own logs replayed in windows as ``hexsim validate`` replays a log, none of them
    fitted (``before``/``after``: the prior's and the calibrated machine's RMS per channel in budgets): what
    the calibrated nominal still misses on the logs it was calibrated on, between the steady motions, enters
    every later validation's budget (:func:`hexsim.measured.scoring.model_floor`). A log with fewer than four
    windows away from its end stops is left out (``refused``: why)."""
    from hexsim.measured.dynamics import ReplayEvidence

    rows = []
    for log in logs:
        try:
            ev = ReplayEvidence.of(log, prior, every_window=True)
        except InputError as exc:
            rows.append({"log": str(log.path), "refused": str(exc)})
            continue
        rows.append({"log": str(log.path), "before": ev.errors(prior).record(),
                     "after": ev.errors(calibrated).record()})
    return rows


def _leave_one_log_out(ev: _Evidence, best: dict) -> list[dict]:
    """Each steady log's features predicted by a refit on the others' (the held parameters held again)."""
    rows = []
    params, calibrated = best["params"], best["machine"]
    for log in ev.steady:
        rest = [f for f in ev.feats if f.log != log.path.name]
        mine = [f for f in ev.feats if f.log == log.path.name]
        refit = fit_parameters(steady_residual(rest, ev.loads), calibrated, params, best["fit"].held)
        predicted = predict(mine, params.apply(calibrated, refit.values), ev.loads)
        rows.append({"log": str(log.path), **feature_errors(mine, predicted)})
    return rows


def _with_provenance(calibrated: Machine, prior: Machine, report: dict, form: str, n_logs: int) -> Machine:
    """The calibrated machine with its provenance: the report (without the feature rows) as its
    ``calibration``, each fitted key's source (value ± standard error, the prior), the chosen flow-area form's
    if it changed."""
    sources = dict(calibrated.sources)
    if form != prior.hydraulics.flow_area:
        sources["valve.flow_area"] = (f"hexsim calibrate from {n_logs} log(s): {form} predicts the held-out windows "
                                      f"best (prior {prior.hydraulics.flow_area})")
    curve = report.get("flow_area", {}).get("curve")
    if curve:
        for edge in ("PA", "AT"):
            sources[f"valve.flow_curve_{edge}"] = (
                f"hexsim calibrate from {n_logs} log(s): read from the logs' flows (continuity against the orifice "
                f"equation) to {curve['reach_V'][edge]:.3g} V, the {curve['from_form']} form's shape beyond")
    for row in report["parameters"]:
        if row["status"] != HELD:
            key, _, index = row["key"].partition("[")  # a table point's source is its table's
            text = (f"{'point ' + index[:-1] + ': ' if index else ''}{row['value']:.6g} ± {row['std_error']:.2g} "
                    f"{row['unit']} (prior {row['prior']:.6g})")
            earlier = sources.get(key, "") if index else ""
            sources[key] = (f"{earlier}; {text}" if earlier.startswith("hexsim calibrate") else
                            f"hexsim calibrate from {n_logs} log(s): {text}")
    calibrated = as_logged_system(calibrated, report)
    provenance = {k: v for k, v in report.items() if k != "rows"}
    return dataclasses.replace(calibrated, calibration=provenance, sources=tuple(sources.items()),
                               description=(calibrated.description + " Calibrated by hexsim calibrate.").strip())


def as_logged_system(machine: Machine, report: dict) -> Machine:
    """``machine`` as the kind of system its calibration logs come from: a hexapod file (the built-in default)
    calibrated on single-actuator logs describes one actuator, so it becomes a single-actuator file (its
    hexapod section and legs dropped; the load's mass and inclination the logs' axis has), and the report
    says so (``system``). A machine of the logs' own kind is returned unchanged."""
    logs_system = report.get("system", machine.system)
    if machine.system == logs_system or logs_system != "single-actuator":
        return machine
    report["system_note"] = (f"the logs are a single actuator's: the calibrated file describes one actuator "
                             f"(the prior {machine.label} is a {machine.system})")
    return dataclasses.replace(machine, system="single-actuator", geometry=Geometry(), legs=(),
                               name=f"{machine.name}_actuator")


def _held_out(logs: list[MeasurementLog], prior: Machine, calibrated: Machine, loads: dict) -> dict:
    """Held-out logs predicted by the prior and the calibrated machine: the steady features of the
    constant-command experiments (``before``/``after``), every window of the others
    (``transients``: held-out RMS in budgets)."""
    from hexsim.measured.dynamics import ReplayEvidence

    steady = [log for log in logs if _is_steady(log)]
    out: dict = {"logs": [str(log.path) for log in logs]}
    if steady:
        out_feats = [f for log in steady for f in features(log)]
        out["before"] = feature_errors(out_feats, predict(out_feats, prior, loads))
        out["after"] = feature_errors(out_feats, predict(out_feats, calibrated, loads))
    moving = [ReplayEvidence.of(log, prior, every_window=True) for log in logs if log not in steady]
    if moving:
        out["transients"] = [{"before": ev.errors(prior).record(), "after": ev.errors(calibrated).record()}
                             for ev in moving]
    return out


def _free_block(fit: Fit) -> np.ndarray:
    return fit.correlation[np.ix_(fit.free, fit.free)]


def _parameter_rows(fit: Fit) -> list[dict]:
    """Each parameter's :class:`~hexsim.measured.estimates.Estimate` (held at its prior, at its physical limit,
    at a bound or fitted: :meth:`~hexsim.measured.parameters.Parameter.estimate`) as a report row, with where
    its bounds come from and the experiment that identifies it (:meth:`~hexsim.measured.parameters.Parameter.row`)."""
    return [p.row(p.estimate(value, se, held=fit.held.get(p.key)))
            for p, value, se in zip(fit.params, fit.values, fit.std_errors)]


def _add_priors(report: dict, machine: Machine, params: ParameterSet) -> None:
    """Each parameter row's prior (the machine's value before calibration), in place."""
    for row, value in zip(report["parameters"], params.priors(machine)):
        row["prior"] = float(value)
