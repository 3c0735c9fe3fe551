"""The one optimizer of measured/ (:func:`bounded_fit`: bounded least squares of a residual from the best of
its starts; the calibration, the identifier's candidates, friction, the supply's start and the flow curve
call it), and the calibration's use of it: a :class:`~hexsim.measured.parameters.ParameterSet` fitted to a
machine's weighted residual, with the rule that holds a parameter the data cannot identify at its prior.

The residual is a function of a machine (:class:`hexsim.plant.machine.Machine`): the steady features'
(:func:`hexsim.measured.steady.steady_residual`), a log's replay (:class:`hexsim.measured.dynamics.
ReplayEvidence`), or both concatenated. The parameters are searched in normalised coordinates
z = (x − lower) / (upper − lower) ∈ [0, 1] (``scipy.optimize.least_squares``, trf); standard errors and
correlations from :func:`hexsim.measured.statistics.fit_statistics`.

**Held at its prior** (:func:`_unidentified`): a free parameter the residual does not depend on, one whose
standard error exceeds :data:`MAX_SE_SHARE` of its bound range, or the worse known of two correlated
beyond :data:`MAX_CORRELATION`, is held at its prior with the reason, and the rest refitted, until none
breaks the rule. Before the first fit, a parameter no residual entry sees across its whole bracket (at the
prior, and with the others at three quarters of theirs) is held. A parameter the fit drove to a bound is
held too when putting it back at its prior costs less than :data:`MIN_BOUND_GAIN` in the weighted sum of
squares (the others as fitted): a bound reached through a sensitivity the data barely have (the real
cylinder's 10 V table point, seen by its 5 V runs only through a null offset of 0.01 V) is no finding.
A hold whose refit ends more than :data:`MAX_HOLD_RISE` above the fit before it (of that fit's weighted sum
of squares, or of the residual's length where the fit is closer than its weights) is taken back: the data
do separate that parameter (a correlation or standard error read at a point short of the optimum said
otherwise), and the fit before it is the answer, the parameter free with its statistics as they were.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from hexsim.engine.workers import forked_map
from hexsim.errors import InputError, PhysicsError
from hexsim.measured.estimates import AT_BOUND, at_bound
from hexsim.measured.parameters import ParameterSet
from hexsim.measured.statistics import fit_statistics
from hexsim.plant.machine import Machine

#: A parameter whose standard error exceeds this share of its bound range is not identified by the data.
MAX_SE_SHARE = 0.25
#: Two parameters this correlated trade against each other: the one known worse is held at its prior.
MAX_CORRELATION = 0.98
#: A parameter at a bound whose prior costs less than this in the weighted sum of squares (chi^2 with one
#: degree of freedom: 1 is one standard deviation) is not asked for by the data: held at its prior.
MIN_BOUND_GAIN = 1.0
#: A hold (module doc) whose refit's weighted sum of squares ends more than this share above the fit before
#: it (or of the residual's length, for a fit within its weights: a hold there moves it by noise) is taken
#: back. Measured: holding a return edge "correlated +0.992" with the supply edge raised a calibration's cost
#: from 4.75e5 to 6.6e7; the holds the data cannot see change it by under 1 %.
MAX_HOLD_RISE = 0.1
#: A machine the residual cannot be computed for (a physics error, an invalid file) costs this per entry.
FAILED_RESIDUAL = 1e3


@dataclass(frozen=True)
class FitOptions:
    """How :func:`fit_parameters` searches.

    ``diff_step``, ``x_scale``, ``max_nfev``: scipy's (on z; ``max_nfev`` None: scipy's default).
    ``warm``: after a parameter is held, refit from the values the others reached (a replay's cost is not
    convex: from the prior again it can fall into another valley), else from the prior. ``rule`` False: one
    least-squares run of every parameter, no statistics and nothing held (a screening). ``correlated_se``: two
    parameters correlated beyond :data:`MAX_CORRELATION` are both kept while the worse known has a standard
    error within this share of its bracket (thousands of replayed samples separate two parameters correlated at
    0.997 to 1e-4 of their brackets). ``jobs``: processes that evaluate a Jacobian's columns
    (:func:`hexsim.engine.workers.forked_map`; the same result as one). ``clusters``: each residual's
    independent group (a replay window, :meth:`hexsim.measured.calibration._Evidence.clusters`): the standard
    errors and correlations a fit records are then cluster-robust (:mod:`hexsim.measured.statistics`); the
    held-at-prior rule keeps judging on s² (JᵀJ)⁻¹, the data's own resolution of each parameter."""

    diff_step: float = 1e-4
    x_scale: float | str = 1.0
    max_nfev: int | None = None
    warm: bool = False
    rule: bool = True
    correlated_se: float = 0.0
    xtol: float = 1e-8
    ftol: float = 1e-8
    jobs: int = 1
    clusters: np.ndarray | None = field(default=None, compare=False, repr=False)


@dataclass
class Fit:
    """The outcome of one fit: values (k,) in the keys' units, standard errors (k,) (0 for a parameter held
    or at a bound), correlation matrix (k, k) (the identity outside the fitted block), the weighted residuals
    at the optimum, and the parameters held at their prior with the reason; ``covariance``: which covariance
    the errors and correlations are (:mod:`hexsim.measured.statistics`), in words."""

    params: ParameterSet
    values: np.ndarray
    std_errors: np.ndarray
    correlation: np.ndarray
    residuals: np.ndarray
    held: dict[str, str]
    covariance: str = "s² (JᵀJ)⁻¹"

    @property
    def free(self) -> list[int]:
        """The indices of the parameters not held at their prior."""
        return _free(self.params, self.held)


def bounded_fit(residual: Callable[[np.ndarray], np.ndarray], starts, lower, upper, **options):
    """Least squares of ``residual`` (x (k,) -> (n,)) inside [``lower``, ``upper``] (each (k,) or a scalar;
    infinite allowed), from the start of ``starts`` (each (k,)) with the lowest sum of squares (one start: no
    evaluation to choose it): ``scipy.optimize.least_squares`` with ``options`` (its method, diff_step,
    x_scale, max_nfev, xtol, ftol, loss, f_scale, jac, workers; its defaults otherwise). A residual that cannot be
    computed at some x (a model that does not run) should return :data:`FAILED_RESIDUAL` per entry there.
    Returns scipy's result (x, fun, jac, nfev, njev, cost, success) with ``inside`` (k,) bool: the parameters
    not at a bound (:func:`hexsim.measured.estimates.at_bound`), those whose standard errors mean something."""
    starts = [np.asarray(s, dtype=float) for s in starts]
    x0 = starts[0] if len(starts) == 1 else min(starts, key=lambda s: float(np.sum(residual(s) ** 2)))
    sol = least_squares(residual, x0, bounds=(lower, upper), **options)
    lo, hi = (np.broadcast_to(np.asarray(b, dtype=float), sol.x.shape) for b in (lower, upper))
    sol.inside = np.array([at_bound(v, a, b) is None for v, a, b in zip(sol.x, lo, hi)], dtype=bool)
    return sol


def _free(params: ParameterSet, held: dict[str, str]) -> list[int]:
    return [i for i, p in enumerate(params) if p.key not in held]


def fit_parameters(residual_of: Callable[[Machine], np.ndarray], machine: Machine, params: ParameterSet,
                   held: dict[str, str] | None = None, *, options: FitOptions = FitOptions(),
                   independent_share: Callable[[Machine], float] | None = None, initial: Machine | None = None,
                   notify: Callable[[str], None] = lambda text: None) -> Fit:
    """Fit ``params`` of ``machine`` (the nominal, whose values are the priors) to the weighted residual
    ``residual_of(machine)`` (n,) under ``options`` (module doc), those in ``held`` (key: why) at their prior.
    ``independent_share``: independent samples per residual at a machine (replay residuals are not white;
    default all). ``initial``: a machine whose values of ``params`` the search starts from (clipped into the
    brackets), instead of the prior's. ``notify``: progress lines."""
    held = dict(held or {})
    n_res = len(residual_of(machine))

    def safe(values: np.ndarray) -> np.ndarray:
        try:
            return residual_of(params.apply(machine, values))
        except (InputError, PhysicsError, FloatingPointError, ValueError):
            return np.full(n_res, FAILED_RESIDUAL)

    prior, lo, span = params.priors(machine), params.lower, params.span
    start = prior.copy() if initial is None else np.clip(params.priors(initial), lo, lo + span)
    if options.rule:
        held |= _blind(safe, params, prior, held)
    before: tuple[Fit, str] | None = None  # the fit before the last hold, and the key held
    while True:
        free = _free(params, held)
        x = prior.copy()
        if not free:
            return Fit(params, x, np.zeros(len(params)), np.eye(len(params)), residual_of(machine), held)

        def residual(z, free=free):
            x[free] = lo[free] + z * span[free]
            return safe(x)

        # from the previous fit's values (the prior the first time): holding one parameter should not throw
        # away where the others went
        z0 = np.clip((start[free] - lo[free]) / span[free], 0.0, 1.0)
        sol = bounded_fit(residual, [z0], 0.0, 1.0, diff_step=options.diff_step, x_scale=options.x_scale,
                          max_nfev=options.max_nfev, xtol=options.xtol, ftol=options.ftol,
                          workers=forked_map(options.jobs) if options.jobs > 1 else None)
        notify(f"fitted {len(free)} parameters: {sol.nfev} evaluations, {sol.njev} Jacobians, cost {2 * sol.cost:.4g}")
        if before is not None:
            cost = float(np.sum(before[0].residuals ** 2))
            if 2 * sol.cost - cost > MAX_HOLD_RISE * max(cost, n_res):
                notify(f"kept free: {before[1]} (held, the cost rose {cost:.4g} -> {2 * sol.cost:.4g})")
                return before[0]
        x[free] = lo[free] + sol.x * span[free]
        if options.warm:
            start = x.copy()
        if not options.rule:
            return Fit(params, x, np.zeros(len(params)), np.eye(len(params)), sol.fun, held)
        share = 1.0 if independent_share is None else independent_share(params.apply(machine, x))
        fit, worst, why = _judged(sol, residual, params, free, x, prior, held, share, options)
        if worst is None:
            return fit
        notify(f"held at its prior: {params[free[worst]].key} ({why})")
        before = (fit, params[free[worst]].key)
        held[params[free[worst]].key] = why


def _judged(sol, residual: Callable[[np.ndarray], np.ndarray], params: ParameterSet, free: list[int], x: np.ndarray,
            prior: np.ndarray, held: dict[str, str], share: float, options: FitOptions) -> tuple[Fit, int | None, str]:
    """The :class:`Fit` of the solution ``sol`` on the ``free`` parameters (scaled to their brackets; ``x`` the
    values, ``share`` the independent samples per residual) with its standard errors and correlations
    (:func:`hexsim.measured.statistics.fit_statistics`), and the free parameter to hold next: its index in
    ``free`` and why (weak at a bound, :func:`_weak_at_bound`, else unidentified, :func:`_unidentified`), or
    None."""
    lo, span = params.lower, params.span
    stats = fit_statistics(sol.jac, sol.fun, free=_inside(sol), n_independent=share * len(sol.fun))
    se_z, corr = stats.std_errors, stats.correlation
    worst, why = _weak_at_bound(sol, residual, (prior[free] - lo[free]) / span[free])
    x[free] = lo[free] + sol.x * span[free]  # the residual's closure wrote its trial values there
    if worst is None:
        worst, why = _unidentified(sol, se_z, corr, [params[i].key for i in free], options.correlated_se)
    covariance = "s² (JᵀJ)⁻¹"
    if options.clusters is not None and len(options.clusters) == len(sol.fun):
        robust = fit_statistics(sol.jac, sol.fun, free=_inside(sol), n_independent=share * len(sol.fun),
                                clusters=options.clusters)  # (too few effective windows: the s² (JᵀJ)⁻¹ above)
        se_z, corr = robust.std_errors, robust.correlation
        windows, used = len(np.unique(options.clusters)), int(np.count_nonzero(robust.free))
        covariance = (f"cluster-robust over {windows} replay windows ({robust.effective_groups:.1f} in effect)"
                      if robust.clustered else
                      f"s² (JᵀJ)⁻¹: the {windows} replay windows count as {robust.effective_groups:.1f} in effect, "
                      f"not more than the {used} free parameters a cluster-robust covariance needs")
    se = np.zeros(len(params))
    se[free] = se_z * span[free]
    full = np.eye(len(params))
    full[np.ix_(free, free)] = corr
    return Fit(params, x.copy(), se, full, sol.fun, dict(held), covariance), worst, why


def _blind(safe: Callable[[np.ndarray], np.ndarray], params: ParameterSet, prior: np.ndarray,
           held: dict[str, str]) -> dict[str, str]:
    """The parameters (not already ``held``) no residual entry sees across their whole bracket (a table
    point beyond every command of the experiments, the mass of a horizontal axis): at the prior, and with the
    others at three quarters of their brackets (a payload's centre of gravity moves nothing while its mass is
    the prior's 0). ``safe``: the residual (n,) at values (k,)."""
    lo, span = params.lower, params.span
    blind = {}
    for i, p in enumerate(params):
        if p.key in held:
            continue
        for others in (prior, lo + 0.75 * span):
            ends = []
            for value in (p.lower, p.upper):
                x = others.copy()
                x[i] = value
                ends.append(safe(x))
            if np.max(np.abs(ends[1] - ends[0])) >= 1e-3:
                break
        else:
            blind[p.key] = "the features do not depend on it across its bracket"
    return blind


def _inside(sol) -> np.ndarray:
    """(k,) bool: the parameters the fit left inside their bounds (normalised coordinates). scipy's trf
    returns the Jacobian column of a parameter at an active bound zeroed: it is not a free variable there."""
    return sol.inside


def _weak_at_bound(sol, residual: Callable[[np.ndarray], np.ndarray], z_prior: np.ndarray) -> tuple[int | None, str]:
    """The free parameter at a bound the data barely ask for, and why: of those the fit moved from their
    prior (``z_prior`` (f,), normalised) to a bound, the one whose return to the prior (the others as
    fitted) raises the weighted sum of squares least, if by less than :data:`MIN_BOUND_GAIN`; (None, "")
    if none. ``residual``: of the normalised free values. A prior at the bound (a tank pressure of 0, a
    physical limit) is no move."""
    best, gain = None, MIN_BOUND_GAIN
    for j in np.flatnonzero(~_inside(sol) & (np.abs(sol.x - z_prior) > AT_BOUND)):  # a prior at its bound stays
        z = sol.x.copy()
        z[j] = z_prior[j]
        g = float(np.sum(residual(z) ** 2) - np.sum(sol.fun ** 2))
        if g < gain:
            best, gain = int(j), g
    if best is None:
        return None, ""
    return best, (f"the fit ran to a bound the data barely ask for: its prior costs {max(gain, 0.0):.2g} in the "
                  f"weighted sum of squares (less than {MIN_BOUND_GAIN:g})")


def _unidentified(sol, se_z: np.ndarray, corr: np.ndarray, keys: list[str],
                  correlated_se: float = 0.0) -> tuple[int | None, str]:
    """The free parameter the features cannot identify, and why (module doc: no sensitivity, a standard
    error above MAX_SE_SHARE of its bracket, or a correlation beyond MAX_CORRELATION, the worse known of
    the two, if its standard error is above ``correlated_se`` of its bracket); (None, "") if every one is
    identified. ``se_z`` (f,): standard errors as shares of the brackets; ``keys``: the free parameters'."""
    inside = _inside(sol)
    norms = np.linalg.norm(sol.jac, axis=0)
    blind = inside & (norms < 1e-9 * max(float(norms.max()), 1e-300))
    if blind.any():
        return int(np.argmax(blind)), "the features do not depend on it"
    if inside.any():
        j = int(np.argmax(se_z))  # the standard error as a share of the bound range
        if se_z[j] > MAX_SE_SHARE:
            return j, f"its standard error is {se_z[j]:.0%} of its bound range"
    if inside.sum() > 1:
        c = np.abs(corr - np.eye(len(keys)))
        a, b = np.unravel_index(int(np.argmax(c)), c.shape)
        if c[a, b] > MAX_CORRELATION and max(se_z[a], se_z[b]) > correlated_se:
            worst = a if se_z[a] >= se_z[b] else b
            other = b if worst == a else a
            return worst, (f"it trades against {keys[other]} (correlation {corr[a, b]:+.3f}): the features cannot "
                           f"separate the two")
    return None, ""
