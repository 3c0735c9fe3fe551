"""What one step of the measured-data chain hands the next, typed: the calibration record a validation reads
(:class:`CalibrationRecord`, from a machine file's ``calibration`` block as :func:`hexsim.measured.calibration.
calibrate` writes it), the verdict (:data:`Verdict`) and the validation report (:class:`ValidationReport`, the
JSON document ``hexsim validate`` writes and :func:`hexsim.measured.validation.validate` returns) and the
discovery's account (:class:`Discovery`, :func:`hexsim.measured.discovery.discover`). The advice a
validation gives on an uncalibrated machine is :class:`hexsim.measured.advice.CalibrationAdvice`; the
identification's outcome :class:`hexsim.measured.identify.Identification`.

The block is read here and only here: the budget's calibration uncertainty and model floor
(:mod:`hexsim.measured.scoring`) and the validation's "beyond the calibrated curve" read the record's fields.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Literal, TypedDict, get_args

import numpy as np

from hexsim.errors import InputError
from hexsim.measured.estimates import Estimate
from hexsim.plant.machine import Machine, get_key, with_keys

#: Models drawn from a calibration's uncertainty for a prediction (:meth:`CalibrationRecord.plausible`).
PLAUSIBLE_DRAWS = 8

#: What a log says of the model: ``none`` (the nominal reproduces every channel within its budget),
#: ``explained`` (the accepted effects bring every channel within it), ``partial`` (effects accepted,
#: structure left, or an accepted effect at the edge of its plausible range), ``unexplained`` (no library
#: effect passes).
Verdict = Literal["none", "explained", "partial", "unexplained"]
VERDICTS: tuple[str, ...] = get_args(Verdict)
#: The verdicts that leave the model short of the log: discovery runs, validate advises calibration.
UNSETTLED: tuple[Verdict, ...] = ("partial", "unexplained")


class EstimateRow(TypedDict, total=False):
    """One parameter's :class:`~hexsim.measured.estimates.Estimate` as a report holds it
    (:meth:`~hexsim.measured.estimates.Estimate.as_row`): ``why`` for every status but fitted."""

    key: str
    unit: str
    value: float
    std_error: float
    lower: float
    upper: float
    status: str
    why: str


class WorstWindow(TypedDict):
    """A held-out replay window of large cost (:class:`ReplayErrors`): its start [s], its share of the log's
    held-out cost, the valve command's range in it [V] (low, high)."""

    start_s: float
    share: float
    command_V: list[float]


@dataclass(frozen=True)
class ReplayErrors:
    """How a machine replays one log's windows (:meth:`hexsim.measured.dynamics.ReplayEvidence.errors`): the log,
    how many windows were fitted and held out, each channel's held-out RMS in budgets and its budget, the
    held-out cost (the sum of the held-out windows' squared residuals in budgets) and, for a single actuator's
    windows, the worst held-out windows. :meth:`record` is the form a calibration report (JSON) holds."""

    log: str
    windows_fitted: int
    windows_held_out: int
    held_out_rms_in_budgets: dict[str, float]
    held_out_cost: float
    budget: dict[str, float]
    worst_windows: list[WorstWindow] | None = None

    def record(self) -> dict:
        """The report's row: the fields by name, ``worst_windows`` only where there are any."""
        row = {"log": self.log, "windows_fitted": self.windows_fitted, "windows_held_out": self.windows_held_out,
               "held_out_rms_in_budgets": dict(self.held_out_rms_in_budgets), "held_out_cost": self.held_out_cost,
               "budget": dict(self.budget)}
        if self.worst_windows is not None:
            row["worst_windows"] = [dict(w) for w in self.worst_windows]
        return row


class ParameterRow(EstimateRow, total=False):
    """One parameter of a calibration report (:func:`hexsim.measured.calibration.calibrate`): its estimate with
    ``prior`` (the machine file's value before calibration), ``bounds_source`` (where its bracket comes from)
    and ``experiment`` (what would identify it)."""

    prior: float
    bounds_source: str
    experiment: str


class OwnBudget(TypedDict, total=False):
    """How the calibrated model fits its own logs (:func:`hexsim.measured.dynamics.own_budget`): ``reached``
    (every channel's held-out RMS within 1.4 budgets), each channel's largest held-out RMS over the logs in budgets,
    the channels ``short`` of the budget, those ``worse_than_prior`` (channel -> [prior's, calibrated's]) on a log
    (``worse_than_prior_on``: channel -> the log's file name) and, where it is short, the ``sentence`` the report
    prints."""

    reached: bool
    held_out_rms_in_budgets: dict[str, float]
    short: dict[str, float]
    worse_than_prior: dict[str, list[float]]
    worse_than_prior_on: dict[str, str]
    sentence: str


class CalibrationReport(TypedDict, total=False):
    """A calibration's report (:func:`hexsim.measured.calibration.calibrate`; a calibrated machine file's
    ``calibration`` block is it without ``rows``); docs/calibration.md describes the fields. Errors per channel
    are RMS in budgets (transients) or in the features' units (steady motions)."""

    machine: str  # the prior's label
    system: str  # "single-actuator" | "hexapod": the logs'
    system_note: str  # where the calibrated file's kind differs from the prior's
    logs: list[str]
    method: str
    weights: dict
    covariance: str  # which covariance the standard errors and correlation are (hexsim.measured.statistics)
    parameters: list[ParameterRow]
    correlation: dict  # "keys" of the fitted parameters, their "matrix"
    flow_area: dict  # the form chosen, each tried with its held-out cost, the curves read from the flows
    transients: list[dict]  # per replayed log: "before" and "after" (held-out RMS in budgets, budget)
    commands_measured_V: list[float]  # a single actuator's: the commands the logs dwelt on (hexsim.measured.envelope)
    replayed: list[dict]  # a steady calibration's logs replayed in windows
    own_budget: OwnBudget
    acquisition: dict  # how the accelerometer sampled, from the logs' timing
    held_out: dict  # the held-out logs' errors, prior and calibrated
    leave_one_log_out: list[dict]
    fit: dict  # the steady features' errors "before" and "after"
    rows: list[dict]  # the steady features, each with its error before and after


class AddedEffect(TypedDict):
    """An effect the identification accepted: the candidate's name, the hexapod leg it acts on alone (None:
    every leg, or the single actuator) and its parameters' estimates by name."""

    name: str
    leg: int | None
    parameters: dict[str, EstimateRow]


class DiscoveredTerm(TypedDict):
    """One term the discovery's sparse fit kept (:func:`hexsim.measured.discovery.discover`): its equation
    (``flow``, ``rod_flow``, ``force``), its name, the hexapod leg (None: the single actuator), coefficient and
    standard error in ``unit``, what it means in words, and the equation's held-out error before and after it."""

    equation: str
    term: str
    leg: int | None
    coefficient: float
    std_error: float
    unit: str
    meaning: str
    equation_error_held_out: dict[str, float]


@dataclass(frozen=True)
class Discovery:
    """The discovery's account (:func:`hexsim.measured.discovery.discover`): whether it ran (``done``; else
    ``why`` not), the ``method``, the ``terms`` found, those ``added_to_model`` (``equation:term``, on a
    hexapod ``legN:equation:term``) and, where they were kept, the held-out RMS per channel before and after
    [SI], the share of the held-out cost they recover and the model's effects (single actuator) or leg changes
    (hexapod) with them; ``why`` nothing was kept; the area terms ``not_asked`` (why), the terms found that map
    onto no parameter (``not_representable``), the hexapod legs whose equation is far off, the model it ran
    ``on`` (a partial verdict's choice) and the kept replay's score (``scored``, a
    :class:`hexsim.measured.scoring.Scored`; not in the JSON)."""

    done: bool
    why: str = ""
    method: str = ""
    terms: list[DiscoveredTerm] = field(default_factory=list)
    added_to_model: list[str] = field(default_factory=list)
    held_out_rms_before: dict[str, float] | None = None
    held_out_rms_after: dict[str, float] | None = None
    held_out_cost_recovered: float | None = None
    effects_after: dict[str, float] | None = None
    leg_changes: list[dict] | None = None
    not_asked: dict[str, str] = field(default_factory=dict)
    not_representable: list[str] | None = None
    far_off_legs: list[int] = field(default_factory=list)
    on: str = ""
    scored: Any = None

    def kept(self, applied: list[str], before, after, cost_before: float, cost_after: float) -> Discovery:
        """This account with the terms ``applied`` kept: the held-out RMS of the replays ``before`` and
        ``after`` them (:class:`hexsim.measured.scoring.Scored`), the share of the held-out cost
        ``cost_before`` that ``cost_after`` recovers, and ``after`` as the kept replay's score."""
        return replace(self, added_to_model=applied, held_out_rms_before=before.held_out_rms,
                       held_out_rms_after=after.held_out_rms, scored=after,
                       held_out_cost_recovered=1.0 - cost_after / cost_before if cost_before > 0 else 0.0)

    def record(self) -> dict:
        """The account as the validation's JSON holds it (``discovery``): the fields that apply, no score."""
        if not self.done:
            return {"done": False, "why": self.why}
        out = {"done": True, "method": self.method, "terms": list(self.terms), "added_to_model": list(self.added_to_model)}
        optional = {"not_asked": self.not_asked or None, "not_representable": self.not_representable,
                    "far_off_legs": self.far_off_legs or None, "why": self.why or None,
                    "held_out_rms_before": self.held_out_rms_before, "held_out_rms_after": self.held_out_rms_after,
                    "held_out_cost_recovered": self.held_out_cost_recovered, "effects_after": self.effects_after,
                    "leg_changes": self.leg_changes, "on": self.on or None}
        return out | {k: v for k, v in optional.items() if v is not None}


class ValidationReport(TypedDict, total=False):
    """The validation's JSON document (``validation.json``, ``hexsim validate --json``), as
    :func:`hexsim.measured.validation.summary` builds it and :func:`hexsim.measured.validation.validate` completes
    it; docs/calibration.md and docs/validation.md describe the fields. Channel-keyed maps use the replay's
    channels (``position``, ``p1``, ``acceleration``, …); errors are NRMSE, RMS in the channels' SI units."""

    log: str
    machine: str
    system: str
    verdict: Verdict
    added_effect: str | None
    added_effects: list[AddedEffect]
    parameters: dict[str, EstimateRow]  # the first accepted effect's
    calibration: dict  # the sensors' calibration of the nominal and final models (offset, scale per channel)
    budget: dict
    held_out_rms_in_budgets: dict[str, float]
    held_out_rms_per_signal: dict[str, dict[str, dict[str, float]]]
    error_before: dict[str, float]
    error_after: dict[str, float]
    error_definition: str
    replay: str
    rms_before: dict[str, float]
    rms_after: dict[str, float]
    units: dict[str, str]
    candidates: list[dict]
    screening: list[dict]
    selection: str
    conclusions: list[str]
    payload_from_statics: dict | None
    discovery: dict | None
    residuals_leg: int | None
    residuals_before: dict
    residuals_after: dict
    windows: dict
    not_checked: list[str]
    assumed: list[str]
    left_out: list[str]  # validate's additions
    model: str
    nominal_check: dict
    beyond_calibrated_curve: dict
    software: dict  # the versions, as every JSON file hexsim writes carries them (hexsim.tables.write_json)


@dataclass(frozen=True)
class OwnFit:
    """How the calibrated model fits one of its own calibration logs' held-out windows (or, after a steady
    calibration, every window of a constant-command log): held-out RMS per channel in budgets and each
    channel's budget [SI]."""

    held_out_rms_in_budgets: dict[str, float]
    budget: dict[str, float]


@dataclass(frozen=True)
class CalibrationRecord:
    """A calibrated machine's record: its parameters' estimates (by key), the correlation matrix of those it
    fitted (``correlated``: keys, (k, k) matrix), the calibrated model's fit of its own logs (``own_fits``)
    and, where the valve's flow curve was read from the logs, the commands [V] those logs reached
    (``curve_commands_V``) and the form the curve was held towards (``curve_form``); the commands [V] a
    single actuator's logs measured the curve over (``commands_measured_V``, :mod:`hexsim.measured.envelope`)."""

    estimates: dict[str, Estimate]
    correlated: tuple[str, ...]
    correlation: np.ndarray
    own_fits: tuple[OwnFit, ...]
    curve_commands_V: tuple[float, float] | None = None
    curve_form: str = "prior"
    commands_measured_V: tuple[float, float] | None = None

    @classmethod
    def of(cls, block: dict | None, where: str = "calibration") -> CalibrationRecord | None:
        """The record of a machine file's ``calibration`` block (None: not calibrated). Raises InputError naming
        ``where`` and the entry for a malformed parameter row, a correlation matrix that is not k x k for its
        k keys, an own-fit row without budgets, or measured commands that are not two numbers."""
        if block is None:
            return None
        estimates = {}
        for row in block.get("parameters", []):
            est = Estimate.from_row(row, f"{where}.parameters")
            estimates[est.key] = est
        corr = block.get("correlation", {})
        keys = tuple(corr.get("keys", []))
        try:
            matrix = np.array(corr.get("matrix", np.eye(len(keys))), dtype=float).reshape(len(keys), len(keys))
        except ValueError:
            matrix = None
        if matrix is None or (keys and not np.all(np.isfinite(matrix))):
            raise InputError(f"{where}.correlation: the matrix is not a finite {len(keys)} x {len(keys)} one for its "
                             f"{len(keys)} keys")
        fits = []
        for t in (*block.get("transients", []), *block.get("replayed", [])):
            after = t.get("after") if isinstance(t, dict) else None
            if not after:
                continue
            try:
                fits.append(OwnFit({ch: float(v) for ch, v in after.get("held_out_rms_in_budgets", {}).items()},
                                   {ch: float(v) for ch, v in after.get("budget", {}).items()}))
            except (TypeError, ValueError, AttributeError) as exc:
                raise InputError(f"{where}: an own-fit row of {t.get('log', '?')}: {exc}") from None
        curve = (block.get("flow_area") or {}).get("curve") or {}
        reached = curve.get("commands_measured_V")
        dwelt = block.get("commands_measured_V")
        try:
            dwelt = None if dwelt is None else (float(dwelt[0]), float(dwelt[1]))
        except (TypeError, ValueError, IndexError):
            raise InputError(f"{where}.commands_measured_V: expected [lowest, highest] in V, got {dwelt!r:.60}") from None
        return cls(estimates, keys, matrix, tuple(fits),
                   None if reached is None else (float(reached[0]), float(reached[1])),
                   str(curve.get("from_form", "prior")), dwelt)

    def identified(self) -> list[str]:
        """The correlated keys whose estimates are identified (:attr:`Estimate.identified`), in order: those
        whose uncertainty a replay propagates."""
        return [k for k in self.correlated if k in self.estimates and self.estimates[k].identified]

    @property
    def misfit(self) -> float:
        """The largest held-out RMS in budgets of the calibrated model on its own logs, over their channels (at least
        1): how much more than its noise the model misses the logs it was fitted to."""
        return max([1.0, *(r for fit in self.own_fits for r in fit.held_out_rms_in_budgets.values())])

    def plausible(self, machine: Machine, n: int = PLAUSIBLE_DRAWS, seed: int = 0) -> list[Machine]:
        """``n`` machines drawn from what the calibration leaves uncertain of ``machine`` (whose ``calibration``
        this record is): its identified parameters (:meth:`identified`) about their values in ``machine`` (a
        commissioning may have moved them, :func:`value_in`), normal with the standard errors and correlation
        of the fit, the errors scaled by :attr:`misfit` (a fit that misses its own logs by r budgets has
        standard errors at least r too small: the Birge ratio, R. T. Birge, Phys. Rev. 40, 1932; the Particle
        Data Group's scale factor) and clipped to the ranges they were fitted in; with ``seed`` the same draws
        every time. Empty when nothing is identified. What a compensator tuned on the nominal leaves of the
        reversal bump is the model's error, which the nominal cannot show: the draws can (docs/compensation.md,
        "What hexsim predicts")."""
        keys = self.identified()
        if not keys or n < 1:
            return []
        doc = machine.document()
        at = [self.correlated.index(k) for k in keys]
        est = [self.estimates[k] for k in keys]
        centre = np.array([value_in(doc, k, e.value) for k, e in zip(keys, est)])
        se = self.misfit * np.array([e.std_error for e in est])
        # the report rounds the correlations: the nearest positive semi-definite matrix (eigenvalues clipped at 0)
        w, v = np.linalg.eigh(self.correlation[np.ix_(at, at)])
        root = v * np.sqrt(np.clip(w, 0.0, None))
        z = np.random.default_rng(seed).standard_normal((n, len(keys))) @ root.T
        lower, upper = np.array([e.lower for e in est]), np.array([e.upper for e in est])
        draws = np.clip(centre + z * se, lower, upper)
        return [with_keys(machine, dict(zip(keys, map(float, row)))) for row in draws]


def plausible_machines(machine: Machine, n: int = PLAUSIBLE_DRAWS, seed: int = 0) -> list[Machine]:
    """``n`` machines drawn from what ``machine``'s calibration leaves uncertain
    (:meth:`CalibrationRecord.plausible`); none for a machine without a calibration (a built-in, a hand-written
    file) or for ``n`` = 0. Raises InputError as :meth:`CalibrationRecord.of` for a malformed calibration block."""
    record = CalibrationRecord.of(machine.calibration, f"{machine.label}: calibration")
    return record.plausible(machine, n, seed) if record is not None else []


def value_in(doc: dict, key: str, calibrated: float) -> float:
    """``key``'s value in the machine file ``doc`` (it may have moved on from the calibration: a commissioning's curve
    carries the edge gains, so they read 1 where the calibration fitted 0.95), else the ``calibrated`` value."""
    try:
        value = get_key(doc, key)
    except (KeyError, IndexError, TypeError):
        return calibrated
    return float(value) if isinstance(value, (int, float)) else calibrated
