"""Calibration evidence from transients: the windowed valve replay of a single-actuator log.

Constant-command experiments calibrate what acts in a steady motion (:mod:`hexsim.measured.calibration`:
the valve's flow gain, the supply, the Coulomb friction). What acts while the motion changes, the oil's
bulk modulus with the dead volumes (seed eq. 3.7), the moving mass (3.8), the viscous and static friction
(3.9) and the valve's flow characteristic at small openings (3.3/3.11) where a closed loop spends its
reversals, is seen in the transients of any log: a closed-loop sine as the seed's (3.10), a step, a chirp,
or the switches of an open-loop experiment.

:class:`ReplayEvidence` is one log as the identifier replays it (:class:`hexsim.measured.scoring.Problem`:
0.3 s windows, each started from the measured state and driven by the logged valve setpoints u_v, the
sensors' offsets and scales fitted as nuisance): the even windows are fitted, the odd ones held out. A
window in which the piston comes within :data:`hexsim.measured.scoring.STOP_MARGIN_M` of an end the log
reaches (an end stop, whose stiffness and the transducer's offset there are not the nominal's business) or
a sensor sits at the end of its range is no window of the problem. Residuals are
divided by the log's noise budget (sensor noise and the replay's numerical tolerance, measured once on the
prior machine), so a fit is judged in the same units ``hexsim validate`` judges a log in.
"""

from __future__ import annotations

import dataclasses
import math
import pathlib
from dataclasses import dataclass

import numpy as np

from hexsim.errors import InputError
from hexsim.measured.measurement import MeasurementLog
from hexsim.measured.records import (
    CalibrationReport,
    OwnBudget,
    ReplayErrors,
    WorstWindow,
)
from hexsim.measured.replay import PlantModel, nominal_plant
from hexsim.measured.residuals import effective_n
from hexsim.measured.scoring import (
    WITHIN,
    Budget,
    Problem,
    budget_clusters,
    calibrate_sensors,
    measure_budget,
    residual_vector,
    score,
    within_budget,
)
from hexsim.plant.machine import Machine

#: Fit windows replayed per log at most (spread over the log): a fit's cost stays bounded for long logs;
#: the held-out windows are all scored.
MAX_FIT_WINDOWS = 16
#: Held-out windows of largest cost an own-fit row names (:meth:`ReplayEvidence.errors`).
WORST_WINDOWS = 3


@dataclass
class ReplayEvidence:
    """One single-actuator log as calibration evidence (module doc): its replay problem with the fit and
    held-out windows away from the stops, and the noise budget measured on the prior machine."""

    log: MeasurementLog
    problem: Problem
    budget: Budget
    fitted: Problem  # the fit windows alone: a residual replays only them

    @classmethod
    def of(cls, log: MeasurementLog, machine: Machine, every_window: bool = False) -> "ReplayEvidence":
        """The evidence of ``log`` judged against ``machine`` (``every_window``: all windows held out, for a
        log that is predicted, not fitted). A hexapod log is replayed in closed loop as ``hexsim validate``
        replays it (:meth:`_hexapod`). Raises InputError for a single-actuator log without the valve command
        or position, or one with fewer than four replay windows away from the stops (:class:`Problem`); for
        a hexapod log as :class:`hexsim.measured.hexapod_replay.HexapodProblem`."""
        if log.system == "hexapod":
            return cls._hexapod(log, machine, every_window)
        missing = [c for c in ("valve_cmd_V", "pos_m") if c not in log.columns]
        if missing:
            raise InputError(f"{log.path}: calibration from transients needs the column(s) {', '.join(missing)}")
        log = dataclasses.replace(log, machine=machine)
        problem = Problem(log)  # its windows keep away from the end stops and clipped sensors
        if every_window:
            problem.test_rows = np.sort(np.concatenate([problem.fit_rows, problem.test_rows]))
        return cls.of_problem(problem, measure_budget(problem, problem.simulate(problem.nominal)))

    @classmethod
    def of_problem(cls, problem: Problem, budget: Budget) -> "ReplayEvidence":
        """The evidence of a single-actuator log whose replay ``problem`` and ``budget`` (measured on the
        nominal, :func:`hexsim.measured.scoring.measure_budget`) are already built, e.g. by the identification
        of ``hexsim validate`` (:attr:`hexsim.measured.identify.Identification.nominal_budget`): the same
        windows, at most :data:`MAX_FIT_WINDOWS` of its fit windows replayed by the residual."""
        fitted = problem.fit_rows[np.unique(np.linspace(0, len(problem.fit_rows) - 1, MAX_FIT_WINDOWS).round().astype(int))]
        return cls(problem.log, problem, budget, problem.only(fitted))

    @classmethod
    def _hexapod(cls, log: MeasurementLog, machine: Machine, every_window: bool) -> "ReplayEvidence":
        """A hexapod log's evidence: its closed-loop replay (:class:`hexsim.measured.hexapod_replay.HexapodProblem`,
        one run of the whole log: the even segments fitted, the odd held out; ``every_window``: all held out).
        Each leg's position offset is calibrated freely here (a leg's static tracking error is its valve's null,
        set after the fit: :func:`hexsim.measured.calibration.leg_null_offsets`)."""
        from hexsim.measured.hexapod_replay import HexapodProblem

        log = dataclasses.replace(log, machine=machine)
        problem = HexapodProblem(log)
        problem.position_offset_limit = math.inf  # each leg's offset free: the legs' nulls take it afterwards
        if every_window:
            problem.test_rows = np.arange(problem.segments)
        budget = measure_budget(problem, problem.simulate(problem.nominal))
        return cls(log, problem, budget, problem)

    def prefix(self, segments: int) -> "ReplayEvidence":
        """A hexapod log's evidence on its first ``segments`` segments only (the replay cut short there: a
        cheaper residual to screen on); a single actuator's is its own (its windows are replayed alone)."""
        if not self.problem.screens or segments >= self.problem.segments:
            return self
        short = self.problem.prefix(segments)
        return ReplayEvidence(self.log, short, self.budget, short)

    def model(self, machine: Machine) -> PlantModel:
        """The replay model of ``machine`` for this log (the log's declared mass, inclination and supply kept)."""
        return nominal_plant(dataclasses.replace(self.log, machine=machine))

    def residual(self, machine: Machine, plant: PlantModel | None = None) -> np.ndarray:
        """The replay's calibrated residuals over the budget, one vector, on the fit windows (at most
        :data:`MAX_FIT_WINDOWS`), of ``machine`` (or the replay model ``plant`` where given: effects a machine file
        does not carry as the identification fitted them). Raises PhysicsError where the machine cannot run this
        log."""
        p = self.fitted
        return residual_vector(p, p.simulate(plant or self.model(machine)), self.budget, p.fit_rows)

    @property
    def clusters(self) -> np.ndarray:
        """The fit window of each entry of :meth:`residual` (:func:`hexsim.measured.scoring.budget_clusters`)."""
        p = self.fitted
        return budget_clusters(p, p.fit_rows)

    @property
    def residual_size(self) -> int:
        """Entries of :meth:`residual` (every channel's scored samples of the fit windows), without a replay."""
        p = self.fitted
        return sum(p.measured[ch][p.fit_rows, p.settle:].size for ch in p.channels)

    def effective_share(self, machine: Machine) -> float:
        """Independent samples per residual of the fit windows (:func:`hexsim.measured.residuals.effective_n`):
        the replay's residuals are not white, and a standard error from all samples would be too small."""
        p = self.fitted
        res, _ = calibrate_sensors(p, p.simulate(self.model(machine)), p.fit_rows)
        n = sum(res[ch][:, p.settle:].size for ch in p.channels)
        n_eff = sum(effective_n(res[ch][:, p.settle:]) for ch in p.channels)
        return n_eff / n if n else 1.0

    def errors(self, machine: Machine, plant: PlantModel | None = None) -> ReplayErrors:
        """How ``machine`` (or the replay model ``plant``, as :meth:`residual`) replays this log's held-out windows
        (the windows not fitted): each channel's RMS in budgets, its budget, the held-out cost and, for a single
        actuator's windows, the :data:`WORST_WINDOWS` held-out windows of largest cost. Raises PhysicsError where
        the machine cannot run this log."""
        p = self.problem
        scored = score(p, p.simulate(plant or self.model(machine)), self.budget)
        cost = scored.window_cost
        held_out_cost = float(np.sum(cost[p.test_rows]))
        worst = None
        if p.windowed and held_out_cost > 0:
            u = p.windows.take(self.log.columns["valve_cmd_V"])
            worst = [WorstWindow(start_s=float(self.log.time[p.windows.starts[i]]),
                                 share=float(cost[i]) / held_out_cost,
                                 command_V=[float(u[i].min()), float(u[i].max())])
                     for i in p.test_rows[np.argsort(cost[p.test_rows])[::-1][:WORST_WINDOWS]]]
        return ReplayErrors(
            log=str(self.log.path), windows_fitted=int(len(p.fit_rows)), windows_held_out=int(len(p.test_rows)),
            held_out_rms_in_budgets={ch: float(np.sqrt(v)) for ch, v in within_budget(scored, self.budget).items()},
            held_out_cost=held_out_cost, budget={ch: float(b) for ch, b in self.budget.total.items()},
            worst_windows=worst)


def worst_windows_text(errors: list[dict]) -> str:
    """Where the calibrated model misses its own logs most, one sentence ("" where no log has windows): the
    log of largest held-out cost among ``errors`` (:meth:`~hexsim.measured.records.ReplayErrors.record` rows, as a
    report holds them) and its worst windows, their start, the valve command's range and their share of that
    log's held-out cost."""
    rows = [e for e in errors if e.get("worst_windows")]
    if not rows:
        return ""
    worst = max(rows, key=lambda e: e["held_out_cost"])
    windows = worst["worst_windows"]
    where = ", ".join(f"{w['start_s']:.2f} s ({w['command_V'][0]:.3g}…{w['command_V'][1]:.3g} V)" for w in windows)
    share = sum(w["share"] for w in windows)
    return (f"Most of it is in {pathlib.Path(worst['log']).name}'s held-out windows from {where}: {share:.0%} of "
            f"that log's held-out cost in {len(windows)} of its {worst['windows_held_out']} windows.")


#: A calibrated model whose held-out error on a channel of one of its own logs exceeds the prior's on that log by
#: this factor (and misses the budget) is worse than the file it started from there: ``hexsim calibrate`` writes no
#: file.
WORSE_THAN_PRIOR = 1.1


def own_budget(report: CalibrationReport) -> OwnBudget:
    """Whether the calibrated model reaches its own calibration logs' budget: the worst held-out RMS in
    budgets per channel over the logs' windows after the calibration (``transients`` or ``replayed``),
    ``reached`` when every channel's is within sqrt(:data:`hexsim.measured.scoring.WITHIN`), else
    ``short`` (channel -> budgets) and a ``sentence`` saying what that means for a validation on this machine:
    the model leaves structure of its own (form the calibration cannot fit), which ``hexsim validate`` counts
    as the model's floor (:func:`hexsim.measured.scoring.model_floor`) and judges effects against;
    ``worse_than_prior`` (channel -> [prior's, calibrated's] budgets, of the log where the ratio is largest): the
    channels it misses by more than :data:`WORSE_THAN_PRIOR` times (and beyond the budget) what the prior missed
    them by on the same log's windows."""
    from hexsim.measured.envelope import windows_beyond_text

    rows = [*report.get("transients", []), *report.get("replayed", [])]
    afters = [row["after"] for row in rows if "after" in row]
    worst: dict[str, float] = {}
    for after in afters:
        for ch, v in after.get("held_out_rms_in_budgets", {}).items():
            worst[ch] = max(worst.get(ch, 0.0), float(v))
    short = {ch: v for ch, v in worst.items() if v > math.sqrt(WITHIN)}
    worse: dict[str, list[float]] = {}  # per log, on its own windows: another log's larger miss hides nothing
    on: dict[str, str] = {}
    for row in rows:
        b, a = (row.get(k, {}).get("held_out_rms_in_budgets", {}) for k in ("before", "after"))
        for ch in (ch for ch in a if ch in b and a[ch] > math.sqrt(WITHIN) and a[ch] > WORSE_THAN_PRIOR * b[ch]):
            if ch not in worse or a[ch] / b[ch] > worse[ch][1] / worse[ch][0]:
                worse[ch], on[ch] = [b[ch], a[ch]], pathlib.Path(row["after"].get("log", "")).name
    out = {"reached": not short, "held_out_rms_in_budgets": worst, "short": short, "worse_than_prior": worse,
           "worse_than_prior_on": on}
    if short:
        out["sentence"] = (
            "The calibrated model does not reach its own logs' budget: held-out " + ", ".join(
                f"{ch} {v:.3g}" for ch, v in short.items()) + f" budgets (reached: within {math.sqrt(WITHIN):.2g}). "
            "What it leaves is model form the calibration cannot fit (a valve curve between the forms, a dynamic "
            "the model lacks): hexsim validate counts it as this machine's floor and judges effects against it; "
            "small effects on this machine are not resolved below it. " + worst_windows_text(afters) + " "
            + windows_beyond_text(report)).strip()
    return out
