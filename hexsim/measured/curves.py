"""The calibration's step from a flow-area form to the valve's own curves, read from the logs' flows.

The seed's flow-area forms (3.3, 3.11, their blend and the port-limited spool) are priors: a real spool is none
of them (a rounded metering edge meeting a port narrower than the perimeter, edges that open before null), and
what a form cannot follow becomes structure in every later residual, and a compensator that inverts it jumps
where the true curve bends (docs/compensation.md). When the chosen form misses its own logs' budget (or the
user asks for it, ``--flow-area …,curve``), :func:`with_curve` reads each edge's curve from the logs' flows
(:func:`hexsim.measured.flow_curve.fit_flow_curves`, at the return line's pressure the flows choose), puts it in the machine file (flow area ``curve``, the
calibrated form beyond the commands the logs reach), fits the form's other parameters (less
:data:`CURVE_REPLACES`) again to the replays from there, and keeps it where it predicts the held-out windows
:data:`CURVE_GAIN` better than the form.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np

from hexsim.measured.estimates import AT_A_BOUND
from hexsim.measured.fitting import Fit, FitOptions, fit_parameters
from hexsim.measured.flow_curve import (
    FlowCurves,
    fit_flow_curves,
    tank_pressure_from_flows,
    unit_gains,
)
from hexsim.measured.parameters import ParameterSet
from hexsim.measured.scoring import WITHIN
from hexsim.plant.machine import Machine, with_keys, with_valve

#: The chosen form's parameters the curves replace (their shape is the curves'; the edges' gains stay, as a
#: scale of each curve the replays refine: an open-loop replay's position asks for the flow to a few parts in
#: a thousand, the flow balance gives it to about a percent).
CURVE_REPLACES = ("valve.smooth_area_gain", "valve.overlap_m", "valve.spool_diameter_m", "valve.rated_flow_m3ps")

#: The curves replace the chosen form only if they predict the held-out windows this much better (a form's few
#: parameters are the simpler answer where the curves gain little).
CURVE_GAIN = 0.9

#: The return line's pressure, read from the flows before the curves (:func:`with_curve`).
TANK = "supply.tank_pressure_Pa"


def reaches_budget(replays: list, machine: Machine) -> bool:
    """Whether ``machine`` reproduces every replayed log's held-out windows within the budget (RMS within
    sqrt(:data:`hexsim.measured.scoring.WITHIN`) budgets in every channel): a calibrated form that does needs no
    curve."""
    limit = math.sqrt(WITHIN)
    return all(v <= limit for r in replays for v in r.errors(machine).held_out_rms_in_budgets.values())


def curve_machine(machine: Machine, curves: FlowCurves, points: tuple[list, list] | None = None) -> Machine:
    """``machine`` with its valve's opening the edges' curves (flow area ``curve``: :meth:`FlowCurves.points`,
    ``machine``'s form beyond the commands the logs reached, or the edges' ``points`` where given), the curves
    carrying the P→A and A→T gains (1 now; a 4-way valve's P→B and B→T relative to them) and any overlap or
    underlap (the file's 0)."""
    pa, at = curves.points(machine) if points is None else points
    return with_valve(unit_gains(machine), flow_area="curve", opening_table=[], flow_curve_PA=pa, flow_curve_AT=at,
                      overlap_m=0.0)


def with_curve(replays: list, residual: Callable[[Machine], np.ndarray], best: dict, tried: list[dict],
               options: FitOptions, independent_share, notify: Callable[[str], None],
               label: str = "curve (read from the logs' flows)") -> dict:
    """The chosen form's calibration ``best`` (``flow_area``, ``start``, ``params``, ``fit``, ``machine``) with
    the valve's curves read from the ``replays``' logs (:class:`hexsim.measured.dynamics.ReplayEvidence`; at the
    return line's pressure the flows choose, :func:`~hexsim.measured.flow_curve.tank_pressure_from_flows`), the
    form's other parameters fitted again from there to the calibration's own ``residual`` (``options``,
    ``independent_share``: as the form's fit; those the form's fit left at a bound from their prior again,
    :func:`_bounded_by_the_form`); kept in place of the form if it predicts the held-out windows
    :data:`CURVE_GAIN` better (its cost added to ``tried`` as ``label``). Returns the chosen, as ``best`` with ``curve``
    (the :class:`~hexsim.measured.flow_curve.FlowCurves`), ``form`` (the form it started from) and ``prior``
    (the form's start: the user's file, whose values the report calls the priors) when the curves are."""
    params = ParameterSet(p for p in best["params"] if p.key not in CURVE_REPLACES)
    bounds = {p.key: (p.lower, p.upper) for p in params}
    logs = [r.log for r in replays]
    read = {}
    if TANK in bounds:  # the return line's pressure is the flows' to choose, not the form's (it traded it)
        read[TANK], _ = tank_pressure_from_flows(logs, best["machine"], *bounds[TANK])
    curves = fit_flow_curves(logs, with_keys(best["machine"], read))
    read |= {k: float(np.clip(v, *bounds[k])) for k, v in {"oil.bulk_modulus_Pa": curves.bulk_modulus,
             "cylinder.dead_volume_cap_m3": curves.pipeline_volume}.items() if k in bounds}
    restart = _bounded_by_the_form(best, params)
    start = with_keys(curve_machine(best["machine"], curves), restart | read)  # the replay fit's start
    notify(f"read the valve's curves from the logs' flows (to {curves.pa.reach:.3g} V on P→A, {curves.at.reach:.3g} V "
           f"on A→T); calibrating {len(params)} parameters with them")
    fit = fit_parameters(residual, start, params, independent_share=independent_share, options=options,
                         notify=notify)
    fit = _held_where_started(fit, best, start, read)
    result = params.apply(start, fit.values)
    cost = sum(r.errors(result).held_out_cost for r in replays)
    form_cost = sum(r.errors(best["machine"]).held_out_cost for r in replays)
    tried.append({"flow_area": label, "held_out_cost": cost})
    if cost >= CURVE_GAIN * form_cost:
        notify(f"kept the {best['flow_area']} flow area: the curves read from the logs predict the held-out windows "
               f"at {cost / form_cost:.2f} of its cost (they replace the form below {CURVE_GAIN:g})")
        return best
    return {"flow_area": "curve", "start": start, "prior": best["start"], "params": params, "fit": fit,
            "machine": result, "curve": curves, "form": best["flow_area"]}


def with_curve_again(replays: list, residual: Callable[[Machine], np.ndarray], first: dict, tried: list[dict],
                     options: FitOptions, independent_share, notify: Callable[[str], None]) -> dict:
    """The curves read once more (:func:`with_curve`), from the flows as the first curve calibration ``first``'s
    machine replays them (its pressures, bulk modulus and return line, not the form's), and the parameters fitted
    again from there: kept in place of ``first`` where they predict the held-out windows :data:`CURVE_GAIN` better
    (their cost added to ``tried`` as a second reading). The form's first calibration leaves the flows read through
    its own errors (on the independent 4-way axis the tank line and bulk modulus the sharp form gave: its steps log
    held out at 2.6 / 4.1 / 4.3 budgets after one reading, 1.6 / 1.4 / 1.7 after two)."""
    again = {**first, "start": first["prior"], "flow_area": first["form"]}  # the user's priors, the form's name
    notify("reading the valve's curves again, from the flows as the calibrated machine replays them")
    second = with_curve(replays, residual, again, tried, options, independent_share, notify,
                        label="curve (read again from the calibrated machine's flows)")
    return first if second is again else second


def _bounded_by_the_form(best: dict, params: ParameterSet) -> dict[str, float]:
    """The keys of ``params`` the chosen form's fit left at a bound of their range, each at its prior (the
    form's start) again: the form pushed them there to make up for a curve it could not follow, so the fit
    with the curves starts them where the user's file has them (or, for those the flows read, the bulk modulus
    and dead volume, where the flows put them: :func:`with_curve`), and the held-at-prior rule then compares
    the bound with that start, not with itself."""
    formed = dict(zip(best["params"].keys, best["fit"].values))
    prior = dict(zip(params.keys, params.priors(best["start"])))
    return {p.key: float(prior[p.key]) for p in params
            if p.key in formed and p.estimate(formed[p.key], 0.0).status == AT_A_BOUND}


def _held_where_started(fit: Fit, best: dict, start: Machine, read: dict[str, float]) -> Fit:
    """``fit`` with each parameter it held at a value other than the user's prior saying where that value came
    from (read from the logs' flows, or the chosen form's calibration): "held at its prior" is the fit's start."""
    prior = dict(zip(fit.params.keys, fit.params.priors(best["start"])))
    began = dict(zip(fit.params.keys, fit.params.priors(start)))
    held = {}
    for key, why in fit.held.items():
        if math.isclose(began[key], prior[key], rel_tol=1e-9, abs_tol=0.0):
            held[key] = why
        else:
            source = "read from the logs' flows" if key in read else f"the {best['flow_area']} form's calibration"
            held[key] = f"{why}; held at {began[key]:.6g}, {source} (the file's prior: {prior[key]:.6g})"
    return dataclasses.replace(fit, held=held)


def curve_report(curves: FlowCurves, form: str, machine: Machine) -> dict:
    """The calibration report's account of the curves read from the logs' flows (:func:`with_curve`), the
    points as ``machine`` (the calibrated file) holds them."""
    hyd = machine.hydraulics
    return {"from_form": form, "flow_curve_PA": [list(p) for p in hyd.flow_curve_pa],
            "flow_curve_AT": [list(p) for p in (hyd.flow_curve_at or hyd.flow_curve_pa)],
            "reach_V": {"PA": curves.pa.reach, "AT": curves.at.reach}, "regularisation": curves.weight,
            "held_to_machine": curves.prior_strength,
            "bulk_modulus_Pa": curves.bulk_modulus, "dead_volume_cap_m3": curves.pipeline_volume,
            "held_out_flow_rms_m3": {f"{w:g}": v for w, v in curves.held_out.items()},
            "flow_rms_m3": curves.rms, "measured_flow_rms_m3": curves.flow_rms,
            "commands_measured_V": [round(v, 4) for v in curves.reached],
            "note": "each edge's opening read from the flow balance (continuity integrated over 10 ms against the "
                    "orifice equation; l1 penalty on the slope's changes, its weight by held-out windows); beyond "
                    f"the commands reached, the {form} form's shape; the other parameters then refitted to the "
                    "replays"}
