"""One candidate effect fitted on top of a model and judged on held-out windows (:mod:`hexsim.measured.identify`,
steps 3 and 4): the bounded least squares on the fit windows with its standard errors, the joint refit of the
accepted effects, and the acceptance test (significant and material on the held-out windows, no signal
worse, every parameter plausible)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from hexsim.errors import PhysicsError
from hexsim.measured.candidates import (
    AT_EDGE_WORDS,
    CANDIDATES,
    Candidate,
    applier,
    candidate_key,
    parse_key,
    plausibility,
    plausible_bounds,
)
from hexsim.measured.estimates import at_bound
from hexsim.measured.fitting import FAILED_RESIDUAL, bounded_fit
from hexsim.measured.records import EstimateRow
from hexsim.measured.replay import CHANNELS, PlantModel, ReplayProblem
from hexsim.measured.residuals import effective_n
from hexsim.measured.scoring import (
    WITHIN,
    Budget,
    Scored,
    as_signals,
    budget_vector,
    residual_vector,
    score,
    tolerance_cost,
    window_samples,
)
from hexsim.measured.statistics import fit_statistics

#: Level of the one-sided held-out test, shared by the candidates of one round (Bonferroni).
ALPHA = 0.05
#: A candidate makes a channel worse when its held-out RMS grows by more than the channel's budget and
#: by more than this fraction.
WORSE_REL = 0.10
#: A candidate must remove at least this share of the held-out cost its base model leaves beyond the
#: budget (WITHIN budgets^2 per sample): significance alone lets a wrong effect that soaks up a few
#: percent of a large residual pass (null offset 1.73 V on a leaking leg: 4 %, p = 6e-12).
MIN_EXCESS_SHARE = 0.25


@dataclass
class FitResult:
    """One candidate fitted on top of a base model, and the judgement of it."""

    name: str
    on_top_of: tuple[str, ...]
    parameters: dict[str, EstimateRow]  # name -> its Estimate's row (value, std_error, unit, range, status, why)
    x: np.ndarray
    model: PlantModel
    scored: Scored
    nfev: int
    held_out_gain: float = float("nan")  # 1 - held-out cost / the base model's held-out cost
    p_value: float = float("nan")
    accepted: bool = False
    reasons: list[str] = field(default_factory=list)  # why not accepted
    leg: int | None = None  # the leg it acts on alone (hexapod), None: all legs / the single actuator
    # passes every test but has parameters at a bound of their plausible range (those reasons): the effect
    # is there, its form or range does not fit this machine; taken as a partial explanation when nothing passes
    at_edge: list[str] = field(default_factory=list)

    @property
    def key(self) -> str:
        return candidate_key(self.name, self.leg)

    def as_dict(self) -> dict:
        return {"effect": self.name, "leg": self.leg, "on_top_of": list(self.on_top_of), "parameters": self.parameters,
                "held_out_gain": self.held_out_gain, "p_value": self.p_value, "accepted": self.accepted,
                "rejected_because": self.reasons, "at_edge_of_range": self.at_edge, "held_out_rms": self.scored.held_out_rms,
                "calibration": self.scored.calibration, "function_evaluations": self.nfev}


def fit_candidate(problem: ReplayProblem, key: str, base: PlantModel, budget: Budget, on_top_of: tuple[str, ...] = (),
                  starts=None) -> FitResult:
    """Fit one candidate (a :func:`hexsim.measured.candidates.candidate_key`: all legs, or one leg) on top of
    ``base`` (its parameters held) on the fit windows of ``problem``; score it on all of them. The search
    starts from the best of ``starts`` (default the candidate's own). See :func:`_least_squares`."""
    cand, leg = parse_key(key)
    lower, upper = plausible_bounds(cand, problem.log)
    given = cand.starts(problem.log) if starts is None else starts
    starts = [np.clip(np.array(x, dtype=float), lower, upper) for x in given]
    apply = applier(cand, leg)
    x, se, scored, nfev = _least_squares(problem, lambda x: apply(base, x), lower, upper, starts, budget)
    params = _estimates(cand, x, se, lower, upper)
    return FitResult(name=cand.name, on_top_of=on_top_of, parameters=params, x=x, model=apply(base, x),
                     scored=scored, nfev=nfev, leg=leg)


def _estimates(cand: Candidate, x, se, lower, upper) -> dict[str, EstimateRow]:
    """The candidate's parameters as :class:`~hexsim.measured.estimates.Estimate` rows (value, standard error,
    unit, the plausible range fitted in, status fitted or at a bound), by name. Whether a value is a finding
    is the judge's (:func:`judge`)."""
    return {p.key: p.estimate(v, e, bounds=(lo, hi)).as_row()
            for p, v, e, lo, hi in zip(cand.parameters, x, se, lower, upper)}


def refit_jointly(problem: ReplayProblem, fits: list[FitResult], budget: Budget) -> list[FitResult]:
    """All accepted effects refitted together from their values (forward selection refits the whole model
    after each step, so an effect fitted first does not keep what the next one explains). Returns one
    FitResult per effect, each holding the joint model and scores."""
    return refit_on_baseline(problem, fits, budget, Baseline.nominal(problem))[0]


@dataclass(frozen=True)
class Baseline:
    """The model the effects are applied on, with parameters of its own fitted together with theirs: ``make``
    (k,) -> PlantModel, started at ``x0`` (k,) within ``lower``…``upper`` (k,) each. k = 0: a fixed model."""

    make: Callable[[np.ndarray], PlantModel]
    x0: np.ndarray
    lower: np.ndarray
    upper: np.ndarray

    @classmethod
    def nominal(cls, problem: ReplayProblem) -> "Baseline":
        """The problem's nominal model, nothing of its own fitted."""
        empty = np.zeros(0)
        return cls(lambda x: problem.nominal, empty, empty, empty)


def refit_on_baseline(problem: ReplayProblem, fits: list[FitResult], budget: Budget,
                      baseline: Baseline) -> tuple[list[FitResult], np.ndarray, Scored]:
    """The effects of ``fits`` (applied in their order, each from its value) refitted together with the
    ``baseline``'s own parameters, on the baseline's model (:func:`_least_squares`). Returns one FitResult per
    effect (each holding the joint model and scores), the baseline's parameters (k,) and the joint model's scores
    on every window."""
    parsed = [parse_key(f.key) for f in fits]
    bounds = [(baseline.lower, baseline.upper)] + [plausible_bounds(c, problem.log) for c, _ in parsed]
    lower = np.concatenate([b[0] for b in bounds])
    upper = np.concatenate([b[1] for b in bounds])
    sizes = np.cumsum([0, len(baseline.x0)] + [len(c.parameters) for c, _ in parsed])
    appliers = [applier(c, leg) for c, leg in parsed]

    def apply(x):
        model = baseline.make(x[:sizes[1]])
        for i, a in enumerate(appliers, start=1):
            model = a(model, x[sizes[i]:sizes[i + 1]])
        return model

    x0 = np.clip(np.concatenate([baseline.x0, *[f.x for f in fits]]), lower, upper)
    x, se, scored, nfev = _least_squares(problem, apply, lower, upper, [x0], budget)
    model = apply(x)
    out = []
    for i, (f, (c, leg)) in enumerate(zip(fits, parsed), start=1):
        sl = slice(sizes[i], sizes[i + 1])
        params = _estimates(c, x[sl], se[sl], lower[sl], upper[sl])
        out.append(FitResult(name=f.name, on_top_of=f.on_top_of, parameters=params, x=x[sl], model=model,
                             scored=scored, nfev=nfev, held_out_gain=f.held_out_gain, p_value=f.p_value,
                             accepted=f.accepted, reasons=f.reasons, leg=leg))
    return out, x[:sizes[1]], scored


def _least_squares(problem: ReplayProblem, make_model, lower, upper, starts, budget: Budget):
    """:func:`hexsim.measured.fitting.bounded_fit` (trf) inside the bounds on the fit windows, from the best of ``starts``. Standard
    errors from the Jacobian at the optimum, s^2 (J^T J)^-1 with s^2 per independent residual (N_eff,
    Bartlett: residuals of a dynamic model are not white); none for a parameter at a bound
    (:func:`hexsim.measured.estimates.at_bound`). A model that
    cannot run at some parameter value scores as a bad fit there. Returns (x, standard errors, Scored,
    function evaluations)."""
    fitted = problem.fit_windows()  # a single actuator's residual replays its fit windows only
    cache: dict[tuple[bytes, bool], dict[str, np.ndarray] | None] = {}

    def sim_at(x, every_row: bool = False):
        on = problem if every_row else fitted
        key = (np.asarray(x).tobytes(), on is problem)
        if key not in cache:
            try:
                cache[key] = on.simulate(make_model(x))
            except (PhysicsError, FloatingPointError, ValueError):
                cache[key] = None
        return cache[key]

    def resid(x):
        sim = sim_at(x)
        if sim is None:
            n = sum(fitted.measured[ch][fitted.fit_rows, fitted.settle:].size for ch in fitted.channels)
            return np.full(n, FAILED_RESIDUAL)
        return residual_vector(fitted, sim, budget, fitted.fit_rows)

    x0 = min(starts, key=lambda x: float(np.sum(resid(x) ** 2)))
    sol = bounded_fit(resid, [x0], lower, upper, method="trf", diff_step=1e-2, x_scale="jac",
                      max_nfev=12 * len(x0) + 8, xtol=1e-4, ftol=1e-6)
    x = sol.x if sim_at(sol.x) is not None else x0
    scored = score(problem, sim_at(x, every_row=True), budget)
    fit_vec = budget_vector(problem, scored.residuals, budget, problem.fit_rows)  # calibrated on the fit rows
    n_eff = sum(effective_n(scored.residuals[ch][problem.fit_rows, problem.settle:]) for ch in problem.channels)
    # the calibrated fit rows' residuals (not trf's), per independent residual; NaN: no error at a bound
    inside = sol.inside if x is sol.x else np.array([at_bound(v, a, b) is None for v, a, b in zip(x, lower, upper)])
    se = fit_statistics(sol.jac, fit_vec, free=inside, n_independent=n_eff, fill=np.nan).std_errors
    return x, se, scored, int(sol.nfev)


def judge(problem: ReplayProblem, base: Scored, fit: FitResult, budget: Budget, tried: int) -> None:
    """Accept or reject ``fit`` against the model it extends (:mod:`hexsim.measured.identify`, step 4); sets its
    held_out_gain, p_value, accepted and reasons."""
    test = problem.test_rows
    before, after = base.window_cost[test], fit.scored.window_cost[test]
    fit.held_out_gain = float(1.0 - after.sum() / before.sum()) if before.sum() > 0 else 0.0
    # per held-out window: log of the cost ratio, the candidate's cost charged with what the numerical
    # tolerance alone could explain (so a fit of the tolerance is no improvement)
    gain = np.log(before) - np.log(after + tolerance_cost(problem, budget))
    if np.ptp(gain) == 0:
        fit.p_value = 0.0 if gain[0] > 0 else 1.0
    else:
        fit.p_value = float(stats.ttest_1samp(gain, 0.0, alternative="greater").pvalue)
    level = ALPHA / max(tried, 1)
    reasons = []
    if not fit.p_value < level:
        reasons.append(f"held-out improvement beyond the numerical tolerance not significant "
                       f"(p = {fit.p_value:.2g} >= {level:.2g})")
    # material: it must remove a real share of what the base model leaves beyond the budget, or a
    # significant but small improvement (a wrong effect soaking up a little of a large residual) passes
    floor = WITHIN * sum(window_samples(problem, ch) for ch in problem.channels) * len(test)
    excess = float(before.sum()) - floor
    removed = float(before.sum() - after.sum())
    if excess > 0 and removed < MIN_EXCESS_SHARE * excess:
        reasons.append(f"removes only {max(removed, 0.0) / excess:.0%} of the held-out error beyond the budget "
                       f"(at least {MIN_EXCESS_SHARE:.0%} needed): not the explanation")
    b = budget.total
    for ch in problem.channels:  # every signal: a candidate on all legs must not spoil the healthy ones
        labels = signal_labels(problem, ch)
        for j, (was, now) in enumerate(zip(base.held_out_rms_signals[ch], fit.scored.held_out_rms_signals[ch])):
            if now > max((1.0 + WORSE_REL) * was, was + b[ch]):
                where = f"{ch} of {labels[j]}" if len(labels) > 1 else ch
                reasons.append(f"{where} worse: held-out RMS {was:.3g} -> {now:.3g} {CHANNELS[ch][1]}")
    cand = CANDIDATES[fit.name]
    plausible = plausibility(cand, problem.log, fit.x, np.array([fit.parameters[p]["std_error"] for p in cand.names]))
    edge = [r for r in plausible if AT_EDGE_WORDS in r]
    fit.at_edge = edge if not reasons and len(edge) == len(plausible) else []
    fit.reasons = reasons + plausible
    fit.accepted = not fit.reasons


def signal_labels(problem: ReplayProblem, channel: str) -> list[str]:
    """Names of the signals of a channel: ``leg1``…``leg6`` or the accelerometer axes on a hexapod."""
    n = as_signals(problem.measured[channel]).shape[2]
    if n == 1:
        return [channel]
    return [f"axis {a}" for a in "xyz"] if channel == "acceleration" else [f"leg{i + 1}" for i in range(n)]
