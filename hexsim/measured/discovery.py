"""Discovering the term a model lacks when no library effect explains a log (issue 13).

When the verdict is ``partial`` or ``unexplained``, the residual is traced to the model's own equations
on the measured signals of a single-actuator log (equation error, as in SINDy: Brunton, Proctor & Kutz,
PNAS 2016):

- **flow** (seed eq. 3.6-3.7): r_Q = (y A1 + V_pl)/E dP1/dt + A1 ydot - phi_1,model [m^3/s],
- **force** (seed eq. 3.8): r_F = M ydd - (P1 A1 - P_s A2 - F_f(ydot) - M g cos(theta)) [N],

and on a 4-way valve (both chambers fed by the valve) the cap side's flow equation with the leakage across
the piston C_l (P2 - P1) when P2 is logged, the rod side's when P2 is logged, r_Q2 = (A2 (L_s - y) +
V_pl,B)/E dP2/dt - A2 ydot - phi_2,model (:data:`ROD_FLOW_TERMS`: the edges P→B and B→T), and the force
equation with P2 A2 in place of P_s A2 when both pressures are logged,

with ydot, ydd, dP1/dt Savitzky–Golay derivatives and every term smoothed by the same filter. Each
residual is regressed on a dictionary of physically meaningful features (:data:`FLOW_TERMS`,
:data:`FORCE_TERMS`: the two valve edges' flows, the leakage pressure difference, velocity, a smooth sign
of velocity, position, constants) by the Lasso path with the BIC choosing the sparsity
(``sklearn.linear_model.LassoLarsIC``: a well-kept implementation, and the BIC needs no random
cross-validation folds), refitted by least squares on the chosen terms, and pruned to the terms whose
coefficient is at least :data:`MIN_T` standard errors from zero (standard errors inflated by the
residual's autocorrelation) and that remove at least :data:`MIN_SHARE` of the equation error on the
held-out windows. The fit uses the samples of the identifier's fit windows only. The piston area's term is
not asked when the position's derivative noise is a material part of the equation error
(:data:`AREA_NOISE_SHARE`): the error holds that noise through its own A ydot, and the equation's own terms
at -1 would fit it.

Terms that map onto a model parameter (edge gains, leakage, viscous and Coulomb friction) are added to
the model — all together and each alone, keeping what lowers the replay's held-out error most, and
nothing if none does; the held-out error before and after is reported with the term in physical words.
The others are reported only.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from scipy.signal import savgol_coeffs, savgol_filter

from hexsim.measured.records import DiscoveredTerm, Discovery
from hexsim.measured.replay import PlantModel, ReplayProblem
from hexsim.measured.residuals import effective_n, noise_of
from hexsim.measured.scoring import score
from hexsim.measured.statistics import fit_statistics
from hexsim.plant import hydraulics
from hexsim.plant.model import gravity

SMOOTH_S = 0.021  # [s] Savitzky–Golay window (cubic) of the derivatives and of every term
MIN_T = 4.0  # a term is kept when |coefficient| >= MIN_T standard errors
MIN_SHARE = 0.05  # ... and when it removes at least this share of the held-out equation error (mean square)
V_COULOMB = 1e-3  # [m/s] width of the smooth sign tanh(ydot / V_COULOMB)
#: The piston area's column A ydot carries the position's derivative noise, and so does the flow equation's
#: error itself (through its own A ydot): when that noise is this share of the error's rms or more, the
#: regression fits the noise with the equation's own terms at -1 (errors in variables; seen on a 4-way
#: cylinder logged with 0.3 mm of position noise: every log "far off"), and the area is not asked.
AREA_NOISE_SHARE = 0.2


@dataclass(frozen=True)
class Term:
    """One dictionary feature: name, equation (flow | force), unit of its coefficient, and the sentence
    that says what a coefficient c means."""

    name: str
    equation: str
    unit: str
    words: str  # format string with {c} (the coefficient) and {pct} (100 |c|) and {more} (more/less)
    limit: float | None = None  # largest |c| that is a correction of the model's own term (relative terms)


FLOW_TERMS = (
    Term("phi_PA", "flow", "-", "the supply edge P→A passes {pct:.0f} % {more} flow than eq. (3.4)", 0.5),
    Term("phi_AT", "flow", "-", "the return edge A→T passes {pct:.0f} % {more} flow than eq. (3.4)", 0.5),
    Term("p_s - p1", "flow", "m^3/(s Pa)", "a flow of {c:.3g} m^3/(s Pa) times (P_s - P1) into the bottom chamber "
         "(leakage across the piston)"),
    Term("1", "flow", "m^3/s", "a constant flow of {c:.3g} m^3/s into the bottom chamber (a null offset or an "
         "external leak)"),
    Term("A1 ydot", "flow", "-", "the bottom chamber takes {pct:.1f} % {more} oil per metre of stroke than A1 "
         "(effective area)", 0.2),
)
#: The 4-way valve's cap side: the leakage across the piston comes from the rod side (P2 - P1, logged).
FLOW_TERMS_4WAY = (
    *FLOW_TERMS[:2],
    Term("p2 - p1", "flow", "m^3/(s Pa)", "a flow of {c:.3g} m^3/(s Pa) times (P2 - P1) into the cap side "
         "(leakage across the piston)"),
    *FLOW_TERMS[3:],
)
#: The 4-way valve's rod side B (its pressure P2 logged).
ROD_FLOW_TERMS = (
    Term("phi_PB", "flow_rod", "-", "the supply edge P→B passes {pct:.0f} % {more} flow than eq. (3.4)", 0.5),
    Term("phi_BT", "flow_rod", "-", "the return edge B→T passes {pct:.0f} % {more} flow than eq. (3.4)", 0.5),
    Term("p1 - p2", "flow_rod", "m^3/(s Pa)", "a flow of {c:.3g} m^3/(s Pa) times (P1 - P2) into the rod side "
         "(leakage across the piston)"),
    Term("1", "flow_rod", "m^3/s", "a constant flow of {c:.3g} m^3/s into the rod side (a null offset or an "
         "external leak)"),
    Term("A2 ydot", "flow_rod", "-", "the rod side gives {pct:.1f} % {more} oil per metre of stroke than A2 "
         "(effective area)", 0.2),
)
FORCE_TERMS = (
    Term("ydot", "force", "N s/m", "a viscous force of {c:.4g} N s/m times the velocity (along the motion if > 0)"),
    Term("tanh(ydot/1 mm/s)", "force", "N", "a Coulomb-like force of {c:.3g} N (along the motion if > 0)"),
    Term("1", "force", "N", "a constant force of {c:+.3g} N along the axis (load, inclination)"),
)
#: Asked only when no term of :data:`FLOW_TERMS` stands out on any leg (a hexapod log): the flow's time
#: derivative, whose coefficient is a lag -tau of the valve's flow behind eq. (3.2)-(3.4) (phi(t - tau) ~
#: phi - tau dphi/dt). In the main dictionary it changed the Lasso path on other effects (a null offset
#: read as two edge gains and a negative leakage), so it is a second question, not a sixth term.
LAG_TERMS = (
    Term("d phi/dt", "flow", "s", "the valve's flow follows its setpoint {ms:.3g} ms {late} than eq. (3.2)-(3.4) "
         "(valve dynamics: the spool lags its setpoint, as spool_dynamics in the library models)"),
)
# A position-proportional force (a spring) is left out of the force dictionary: on nominal logs the
# equation error as estimated here correlates with position by itself (fits of -23 and -253 N/m on a
# sine and a random-reference null log), which would be reported as a finding.


def _smooth(x: np.ndarray, n: int, deriv: int = 0, fs: float = 1.0) -> np.ndarray:
    return savgol_filter(x, n, 3, deriv=deriv, delta=1.0 / fs)


def flow_equation(y, u, p1, p_s, fs: float, model: PlantModel, lag: bool = False,
                  p2=None) -> tuple[np.ndarray, np.ndarray]:
    """Residual of the flow equation of one leg's cap side (N,) [m^3/s] and its dictionary (N, 5)
    (:data:`FLOW_TERMS`, or :data:`FLOW_TERMS_4WAY` on a 4-way valve), from its measured position y [m],
    valve setpoint u [V], P1 and P_s [Pa] (arrays (N,)) at ``fs`` [Hz]; ``p2`` [Pa] (N,) the rod side's
    logged pressure on a 4-way valve (None: not logged, the leakage column is zero). ``lag``: the
    dictionary of :data:`LAG_TERMS` instead (N, 1), and the residual of a flow that acts half a sample after
    its row (the logged u_v holds over the sample after it: without that, every leg of a 1 kHz hexapod log
    showed a lag of 0.53 ms)."""
    hyd, eff = model.hydraulics, model.effects
    n = max(5, int(round(SMOOTH_S * fs)) | 1)
    ydot = _smooth(y, n, 1, fs)
    dp1 = _smooth(p1, n, 1, fs)
    a1, a2 = hydraulics.flow_areas(hydraulics.spool_position(u, hyd), hyd)
    dps, dpt = p_s - p1, p1 - hyd.tank_pressure
    phi_pa = eff.edge_gain_pa * hydraulics.edge_flow(a1, dps, hyd)
    phi_at = -eff.edge_gain_at * hydraulics.edge_flow(a2, dpt, hyd)
    if hyd.four_way:  # the leak comes from the rod side (hexsim.plant.legs: C_l (P2 - P1))
        dpl = np.zeros_like(p1) if p2 is None else p2 - p1
    else:
        dpl = dps
    phi = phi_pa + phi_at + eff.leakage * dpl
    volume = hydraulics.chamber_volume(y, hyd)
    target = volume / hyd.bulk_modulus * dp1 + hyd.area_bottom * ydot - _smooth(phi, n)
    if lag:
        dphi = _smooth(phi_pa + phi_at, n, 1, fs)
        return target + 0.5 / fs * dphi, dphi[:, None]
    # the area's column with its sign: a coefficient c is an effective area (1 + c) A1 (r_Q = -c A1 ydot)
    x = np.column_stack([_smooth(phi_pa, n), _smooth(phi_at, n), _smooth(dpl, n), np.ones_like(y),
                         -hyd.area_bottom * ydot])
    _unless_noisy(target, x, y, hyd.area_bottom, n, fs)
    return target, x


def rod_flow_equation(y, u, p1, p2, p_s, fs: float, model: PlantModel) -> tuple[np.ndarray, np.ndarray]:
    """The 4-way valve's rod side: residual (N,) [m^3/s] of (A2 (L_s - y) + V_pl,B)/E dP2/dt - A2 ydot -
    (phi_PB - phi_BT + C_l (P1 - P2)) and its dictionary (N, len(:data:`ROD_FLOW_TERMS`)), from the measured
    y [m], u [V], P1, P2 and P_s [Pa] (arrays (N,)) at ``fs`` [Hz] (seed eq. 3.4 and 3.7 written for chamber
    B; :func:`hexsim.plant.hydraulics.valve_flow_rod`). P1 not logged: pass P2 for it (no leak column)."""
    hyd, eff = model.hydraulics, model.effects
    n = max(5, int(round(SMOOTH_S * fs)) | 1)
    ydot = _smooth(y, n, 1, fs)
    dp2 = _smooth(p2, n, 1, fs)
    a1, a2 = hydraulics.flow_areas(hydraulics.spool_position(u, hyd), hyd)  # P→B opens with A→T, B→T with P→A
    phi_pb = eff.edge_gain_pb * hydraulics.edge_flow(a2, p_s - p2, hyd)
    phi_bt = -eff.edge_gain_bt * hydraulics.edge_flow(a1, p2 - hyd.tank_pressure, hyd)
    phi = phi_pb + phi_bt + eff.leakage * (p1 - p2)
    volume = np.maximum(hyd.stroke - np.asarray(y, dtype=float), 0.0) * hyd.area_rod + hyd.pipeline_volume_rod
    target = volume / hyd.bulk_modulus * dp2 - hyd.area_rod * ydot - _smooth(phi, n)
    x = np.column_stack([_smooth(phi_pb, n), _smooth(phi_bt, n), _smooth(p1 - p2, n), np.ones_like(y),
                         hyd.area_rod * ydot])  # (1 + c) A2
    _unless_noisy(target, x, y, hyd.area_rod, n, fs)
    return target, x


def _unless_noisy(target: np.ndarray, x: np.ndarray, y: np.ndarray, area: float, n: int, fs: float) -> None:
    """Zero the area column (the last of ``x``, (N, k)) in place when the noise the position y [m] (N,)
    puts on A ydot is :data:`AREA_NOISE_SHARE` of the equation error ``target``'s rms or more: the noise
    of the Savitzky–Golay derivative is sigma_y times the norm of its coefficients."""
    sigma_v = noise_of(y, "position") * float(np.linalg.norm(savgol_coeffs(n, 3, deriv=1, delta=1.0 / fs)))
    if area * sigma_v >= AREA_NOISE_SHARE * float(np.sqrt(np.mean(target ** 2))):
        x[:, -1] = 0.0


def equation_errors(log, model: PlantModel) -> dict[str, tuple[np.ndarray, np.ndarray, tuple[Term, ...]]]:
    """Residuals of the equations a single-actuator log closes, per sample, with their dictionaries:
    equation -> (target (N,), features (N, k), the k terms). Needs pos_m and valve_cmd_V. The 3-way valve:
    the cap side's flow (p1_Pa) and the force equation (P_s A2 on the rod side). The 4-way valve: the cap
    side's flow with p1_Pa, the rod side's with p2_Pa, the force equation with both."""
    c = log.columns
    hyd, eff = model.hydraulics, model.effects
    fs = log.sample_rate_hz
    n = max(5, int(round(SMOOTH_S * fs)) | 1)
    y, u = c["pos_m"], c["valve_cmd_V"]
    p1, p2 = c.get("p1_Pa"), c.get("p2_Pa") if hyd.four_way else None
    p_s = c["ps_Pa"] if "ps_Pa" in c else np.full_like(y, hyd.supply_pressure)
    out = {}
    if p1 is not None:
        out["flow"] = (*flow_equation(y, u, p1, p_s, fs, model, p2=p2), FLOW_TERMS_4WAY if hyd.four_way else FLOW_TERMS)
    if p2 is not None:
        out["flow_rod"] = (*rod_flow_equation(y, u, p2 if p1 is None else p1, p2, p_s, fs, model),
                           ROD_FLOW_TERMS)
    rod_side = p2 if hyd.four_way else p_s
    if p1 is not None and rod_side is not None:
        ydot = _smooth(y, n, 1, fs)
        ydd = _smooth(y, n, 2, fs)
        mass = eff.mass_kg or log.moving_mass_kg
        incl = eff.inclination_deg if eff.inclination_deg is not None else log.inclination_deg
        f_hyd = p1 * hyd.area_bottom - rod_side * hyd.area_rod - hydraulics.friction_force(ydot, hyd)
        force_target = mass * ydd - _smooth(f_hyd, n) + mass * gravity() * math.cos(math.radians(incl))
        out["force"] = (force_target, np.column_stack([ydot, np.tanh(ydot / V_COULOMB), np.ones_like(y)]), FORCE_TERMS)
    return out


def _sparse_terms(target, x, fit, test, dictionary, leg: int | None) -> tuple[list[DiscoveredTerm], dict[str, float],
                                                                              bool]:
    """:func:`sparse_fit` on the ``fit`` samples, then the materiality cut on the ``test`` samples; the
    kept terms as JSON-ready dicts, as {"equation:term": coefficient}, and whether the equation is far
    off: a relative term beyond its :attr:`Term.limit` (an edge passing half its flow more or less, an
    area 20 % off) is no correction of the model's own equation, and no term is returned then (the caller
    says so, :func:`_far_off`)."""
    coef, se = sparse_fit(target[fit], x[fit])
    r_test = target[test]
    before = float(np.mean(r_test ** 2))
    for j in np.flatnonzero(coef):  # materiality on held-out samples: what the term removes
        without = coef.copy()
        without[j] = 0.0
        share = (np.mean((r_test - x[test] @ without) ** 2) - np.mean((r_test - x[test] @ coef) ** 2)) / before
        if share < MIN_SHARE:
            coef[j], se[j] = 0.0, np.nan
    after = float(np.mean((r_test - x[test] @ coef) ** 2))
    if any(t.limit is not None and abs(coef[j]) > t.limit for j, t in enumerate(dictionary)):
        return [], {}, True
    terms, found = [], {}
    for j, term in enumerate(dictionary):
        if coef[j] == 0:
            continue
        c = float(coef[j])
        words = term.words.format(c=c, pct=100 * abs(c), more="more" if c > 0 else "less", ms=1e3 * abs(c),
                                  late="later" if c < 0 else "earlier")
        found[f"{term.equation}:{term.name}"] = c
        terms.append(DiscoveredTerm(equation=term.equation, term=term.name, leg=leg, coefficient=c,
                                    std_error=float(se[j]), unit=term.unit, meaning=(f"leg{leg}: " if leg else "") + words,
                                    equation_error_held_out={"before": before, "after": after}))
    return terms, found, False


def _discover_legs(problem: ReplayProblem, base: PlantModel, base_scored, budget) -> Discovery:
    """The flow equation of each hexapod leg on its own logged signals (with that leg's own parameters):
    a leg-level flow effect (leakage, a null offset, an edge) shows in that leg's equation error only. Legs
    with 4-way valves: the cap side's equation with the leak from the rod side (:data:`FLOW_TERMS_4WAY`, P2
    from ``legN_p2_Pa``) and, with P2 logged, the rod side's (:data:`ROD_FLOW_TERMS`).
    The terms that map onto a parameter are added to their leg (:class:`hexsim.plant.effects.LegChange`), the
    log is replayed, and the held-out error before and after is reported; nothing is kept if it does not
    fall."""
    log, c = problem.log, problem.log.columns
    if any(f"leg{leg}_p1_Pa" not in c for leg in range(1, 7)):
        return Discovery(False, "discovery needs the legs' P1 (leg*_p1_Pa)")
    segments = problem.rows.reshape(problem.shape)
    fit, test = segments[problem.fit_rows].ravel(), segments[problem.test_rows].ravel()
    p_s = c["ps_Pa"] if "ps_Pa" in c else np.full(len(log.time), base.hydraulics.supply_pressure)
    terms, per_leg, far = _leg_terms(log, base, p_s, fit, test)
    if not terms and not far:  # the second question: a valve that lags, reported only
        terms = _lag_terms(log, p_s, base, fit, test)
    out = Discovery(True, method=f"LassoLarsIC (BIC) on each leg's flow-equation error over the fit segments, "
                    f"least squares on the chosen terms, kept at >= {MIN_T:g} standard errors and >= {MIN_SHARE:.0%} "
                    "of the held-out equation error", terms=terms, far_off_legs=far)
    if not per_leg:
        why = "no term of any leg's flow equation stands out of the noise"
        if far:
            why = _far_off(far)
        elif terms:
            why = "the valves' flow lags their setpoints: reported, not added to the model (no parameter of its flow " \
                  "equation maps onto a lag; the library's spool_dynamics does)"
        return dataclasses.replace(out, why=why)
    return _replay_leg_terms(problem, base, base_scored, budget, per_leg, out)


def _leg_terms(log, base: PlantModel, p_s: np.ndarray, fit: np.ndarray, test: np.ndarray) -> tuple[list, dict, list]:
    """Each leg's sparse terms (:func:`_sparse_terms` on :func:`_leg_equations` with the leg's own
    parameters): the JSON-ready terms of all legs, per leg with a term (its model, {"equation:term":
    coefficient}, the mean P_s - P1 [Pa] a constant inflow is read against as a leak: the 3-way valve only,
    :func:`apply_terms`), and the legs whose equation is far off."""
    from hexsim.measured.candidates import leg_model

    terms, per_leg, far = [], {}, []
    for leg in range(1, 7):
        own = leg_model(base, leg)
        f_leg = {}
        for target, x, dictionary in _leg_equations(log, leg, own, p_s):
            t_eq, f_eq, off = _sparse_terms(target, x, fit, test, dictionary, leg)
            if off and leg not in far:
                far.append(leg)
            terms += t_eq
            f_leg |= f_eq
        if f_leg:
            mean_dp = 0.0 if own.hydraulics.four_way else float(np.mean(p_s - log.columns[f"leg{leg}_p1_Pa"]))
            per_leg[leg] = (own, f_leg, mean_dp)
    return terms, per_leg, far


def _replay_leg_terms(problem: ReplayProblem, base: PlantModel, base_scored, budget, per_leg: dict,
                      out: Discovery) -> Discovery:
    """The terms of ``per_leg`` (:func:`_leg_terms`) that map onto a parameter, added to their legs and
    replayed: the account ``out`` with them kept if the held-out error falls (:meth:`Discovery.kept`), else
    with why not."""
    from hexsim.measured.candidates import with_leg

    model, applied = base, []
    for leg, (own, found, mean_dp) in per_leg.items():
        changed, keys = apply_terms(own, found, mean_dp)
        if keys:
            model = with_leg(model, leg, changed)
            applied += [f"leg{leg}:{k}" for k in keys]
    if not applied or budget is None:
        return dataclasses.replace(out, why="no term maps onto a parameter of its leg: reported, not replayed")
    scored = score(problem, problem.simulate(model), budget)
    before, after = held_out_cost(problem, base_scored), held_out_cost(problem, scored)
    if after >= before:
        return dataclasses.replace(out, why="adding the legs' terms did not lower the held-out error of the replay: "
                                   "reported, not kept")
    return dataclasses.replace(out.kept(applied, base_scored, scored, before, after),
                               leg_changes=[{"leg": ch.leg, "values": dict(ch.values)} for ch in model.leg_changes])


def held_out_cost(problem: ReplayProblem, scored) -> float:
    """The summed cost of ``scored``'s (:class:`hexsim.measured.scoring.Scored`) held-out rows."""
    return float(scored.window_cost[problem.test_rows].sum())


def _leg_signals(log, leg: int, four_way: bool) -> tuple:
    """Leg ``leg``'s logged y [m], u_v [V], P1 and, on a 4-way valve, P2 [Pa] (None if not logged), each (N,)."""
    c = log.columns
    return (c[f"leg{leg}_pos_m"], c[f"leg{leg}_valve_cmd_V"], c[f"leg{leg}_p1_Pa"],
            c.get(f"leg{leg}_p2_Pa") if four_way else None)


def _leg_equations(log, leg: int, own: PlantModel, p_s: np.ndarray) -> list[tuple]:
    """The flow equations leg ``leg`` of a hexapod log closes with its own parameters ``own``, as (target,
    features, dictionary): the cap side's (:data:`FLOW_TERMS`, a 4-way valve's :data:`FLOW_TERMS_4WAY`) and,
    on a 4-way valve with P2 logged, the rod side's (:data:`ROD_FLOW_TERMS`)."""
    y, u, p1, p2 = _leg_signals(log, leg, own.hydraulics.four_way)
    fs = log.sample_rate_hz
    out = [(*flow_equation(y, u, p1, p_s, fs, own, p2=p2), FLOW_TERMS_4WAY if own.hydraulics.four_way else FLOW_TERMS)]
    if p2 is not None:
        out.append((*rod_flow_equation(y, u, p1, p2, p_s, fs, own), ROD_FLOW_TERMS))
    return out


def _lag_terms(log, p_s: np.ndarray, base: PlantModel, fit: np.ndarray, test: np.ndarray) -> list[dict]:
    """:data:`LAG_TERMS` on each hexapod leg's flow equation (its own parameters), as
    :func:`_sparse_terms` reports them."""
    from hexsim.measured.candidates import leg_model

    terms = []
    for leg in range(1, 7):
        y, u, p1, p2 = _leg_signals(log, leg, base.hydraulics.four_way)
        target, x = flow_equation(y, u, p1, p_s, log.sample_rate_hz, leg_model(base, leg), lag=True, p2=p2)
        terms += _sparse_terms(target, x, fit, test, LAG_TERMS, leg)[0]
    return terms


def _far_off(legs: list[int]) -> str:
    """Why no term is reported for an equation that does not close (``legs`` [] : the single actuator)."""
    where = "every leg" if len(legs) == 6 else ", ".join(f"leg{leg}" for leg in legs) if legs else "the actuator"
    return (f"the flow equation of {where} does not close with a correction of the model's own terms (an edge "
            f"or the piston area would have to change by more than half / a fifth): the model is far off there, "
            f"not short of a small term")


def sparse_fit(target: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sparse coefficients (k,) and standard errors (k,) (NaN off the support): LassoLarsIC (BIC) on the
    columns scaled to unit RMS, least squares on the support, pruned to |coef| >= MIN_T s.e."""
    from sklearn.linear_model import LassoLarsIC

    scale = np.sqrt(np.mean(x * x, axis=0))
    scale[scale == 0] = 1.0
    lasso = LassoLarsIC(criterion="bic", fit_intercept=False).fit(x / scale, target)
    support = np.flatnonzero(lasso.coef_)
    coef, se = np.zeros(x.shape[1]), np.full(x.shape[1], np.nan)
    while support.size:
        xs = x[:, support]
        theta, *_ = np.linalg.lstsq(xs, target, rcond=None)
        r = target - xs @ theta
        err = fit_statistics(xs, r, n_independent=effective_n(r[None, :])).std_errors  # per independent residual
        weak = np.abs(theta) < MIN_T * err
        if not np.any(weak):
            coef[support], se[support] = theta, err
            break
        support = np.delete(support, int(np.argmin(np.abs(theta) / np.maximum(err, 1e-300))))
    return coef, se


def apply_terms(model: PlantModel, found: dict[str, float], mean_dp: float = 0.0) -> tuple[PlantModel, list[str]]:
    """The model with the terms that map onto its parameters; returns it and the names applied. A constant
    inflow c is taken as leakage c / mean(P_s - P1) (``mean_dp`` [Pa]) when no leakage term was found:
    over a log whose P_s - P1 hardly moves the two cannot be told apart."""
    hyd, eff = model.hydraulics, model.effects
    applied = []
    if "flow:1" in found and "flow:p_s - p1" not in found and mean_dp > 0 and found["flow:1"] > 0:
        found = found | {"flow:p_s - p1": found["flow:1"] / mean_dp}
        eff = eff.replace(leakage=eff.leakage + found["flow:p_s - p1"])
        applied.append("flow:1")
        found = {k: v for k, v in found.items() if k != "flow:p_s - p1"}
    if "flow:phi_PA" in found and eff.edge_gain_pa * (1 + found["flow:phi_PA"]) > 0:
        eff = eff.replace(edge_gain_pa=eff.edge_gain_pa * (1 + found["flow:phi_PA"]))
        applied.append("flow:phi_PA")
    if "flow:phi_AT" in found and eff.edge_gain_at * (1 + found["flow:phi_AT"]) > 0:
        eff = eff.replace(edge_gain_at=eff.edge_gain_at * (1 + found["flow:phi_AT"]))
        applied.append("flow:phi_AT")
    # the 3-way valve's leak from P_s; the 4-way's across the piston, seen by either chamber: one C_l, the
    # first side's coefficient, and the other side's term counts as applied with it
    leaks = [k for k in ("flow:p_s - p1", "flow:p2 - p1", "flow_rod:p1 - p2") if k in found]
    if leaks and eff.leakage + found[leaks[0]] >= 0:
        eff = eff.replace(leakage=eff.leakage + found[leaks[0]])
        applied += leaks
    for key, edge in (("flow_rod:phi_PB", "edge_gain_pb"), ("flow_rod:phi_BT", "edge_gain_bt")):
        if key in found and getattr(eff, edge) * (1 + found[key]) > 0:
            eff = eff.replace(**{edge: getattr(eff, edge) * (1 + found[key])})
            applied.append(key)
    if "force:ydot" in found:  # an extra force c ydot is a viscous friction of -c
        sp, sn = hyd.viscous_pos - found["force:ydot"], hyd.viscous_neg - found["force:ydot"]
        if sp >= 0 and sn >= 0:
            hyd = hyd.replace(viscous_pos=sp, viscous_neg=sn)
            applied.append("force:ydot")
    key = "force:tanh(ydot/1 mm/s)"
    if key in found:  # the model's arctan shape tends to pi/2 at speed: the Coulomb level scales by 2/pi
        dc = -found[key] * (1.0 if hyd.arctan_normalised else 2.0 / math.pi)
        cp, cn = hyd.coulomb_pos + dc, hyd.coulomb_neg + dc
        if cp >= 0 and cn >= 0:
            hyd = hyd.replace(coulomb_pos=cp, coulomb_neg=cn)
            applied.append(key)
    return model.replace(hydraulics=hyd, effects=eff), applied


def equation_terms(problem: ReplayProblem, errors: dict) -> tuple[list[dict], dict[str, float], bool, list[str]]:
    """The sparse terms of each equation of :func:`equation_errors` (``errors``) of a single-actuator log,
    fitted on the samples of the problem's fit windows and judged on its held-out windows (less the
    Savitzky–Golay edge of each window): the JSON-ready terms, {"equation:term": coefficient}, whether an
    equation is far off (:func:`_sparse_terms`), and the area terms not asked (:func:`_unless_noisy`)."""
    w = problem.windows
    edge = max(5, int(round(SMOOTH_S * problem.log.sample_rate_hz)))
    rows = lambda sel: (w.starts[sel][:, None] + np.arange(edge, w.length - edge)[None, :]).ravel()  # noqa: E731
    fit, test = rows(problem.fit_rows), rows(problem.test_rows)
    terms, found, far, not_asked = [], {}, False, []
    for target, x, dictionary in errors.values():
        t_eq, f_eq, off = _sparse_terms(target, x, fit, test, dictionary, None)
        terms += t_eq
        found |= f_eq
        far = far or off
        area = dictionary[-1]
        if area.name.endswith("ydot") and area.equation != "force" and not x[:, -1].any():
            not_asked.append(f"{area.equation}:{area.name}")
    return terms, found, far, not_asked


def discover(problem: ReplayProblem, base: PlantModel, base_scored, budget) -> Discovery:
    """Fit the sparse correction on the fit windows' samples, add what maps onto the model, replay and
    compare on the held-out windows (see the module doc). ``base``/``base_scored``: the model the verdict
    stands on and its :class:`hexsim.measured.scoring.Scored`; a replay is scored as the identifier scores one
    (:func:`hexsim.measured.scoring.score`) against ``budget`` (None: the terms only, none replayed).
    Returns the account (:class:`~hexsim.measured.records.Discovery`); ``terms`` empty
    if nothing stands out of the equation noise. Hexapod logs: each leg's flow equation(s), its terms added to
    that leg (:func:`_discover_legs`; 3-way and 4-way valves)."""
    log = problem.log
    if log.system == "hexapod":
        return _discover_legs(problem, base, base_scored, budget)
    errors = equation_errors(log, base)
    if not errors:
        return Discovery(False, "discovery needs a chamber pressure: p1_Pa" +
                         (" or p2_Pa (a 4-way valve)" if base.hydraulics.four_way else ""))
    terms, found, far, not_asked = equation_terms(problem, errors)
    out = Discovery(True, method="LassoLarsIC (BIC) on the equation errors of the fit windows, least squares on the "
                    f"chosen terms, kept at >= {MIN_T:g} standard errors and >= {MIN_SHARE:.0%} of the held-out "
                    "equation error", terms=terms,
                    not_asked={k: f"the position's derivative noise on A ydot is {AREA_NOISE_SHARE:.0%} or more of "
                               "the equation error's RMS: the area's term would fit that noise" for k in not_asked})
    if not found:
        return dataclasses.replace(out, why=_far_off([]) if far else "no term stands out of the equation noise")
    if budget is None:
        return dataclasses.replace(out, why="the terms only: not replayed")
    cost_before = held_out_cost(problem, base_scored)
    # the representable terms together, then each alone: the replay on held-out windows decides
    c = log.columns
    p_s = c["ps_Pa"] if "ps_Pa" in c else base.hydraulics.supply_pressure
    # a constant inflow read as a leak from P_s (the 3-way valve; the 4-way's leak has its own column)
    mean_dp = 0.0 if base.hydraulics.four_way else float(np.mean(p_s - c["p1_Pa"]))
    _, representable = apply_terms(base, found, mean_dp)
    trials = [representable] + ([[k] for k in representable] if len(representable) > 1 else [])
    best = None
    for keys in trials:
        model, applied = apply_terms(base, {k: found[k] for k in keys}, mean_dp)
        if not applied:
            continue
        scored = score(problem, problem.simulate(model), budget)
        cost = held_out_cost(problem, scored)
        if best is None or cost < best[0]:
            best = (cost, model, applied, scored)
    out = dataclasses.replace(out, not_representable=[k for k in found if k not in representable])
    if best is None or best[0] >= cost_before:
        return dataclasses.replace(out, why="adding the terms that map onto model parameters did not lower the "
                                   "held-out error of the replay: reported, not kept")
    cost_after, model, applied, scored = best
    return dataclasses.replace(out.kept(applied, base_scored, scored, cost_before, cost_after), effects_after={
        k: getattr(model.effects, k) for k in ("edge_gain_pa", "edge_gain_at", "leakage",
                                              *(("edge_gain_pb", "edge_gain_bt") if base.hydraulics.four_way else ()))})
