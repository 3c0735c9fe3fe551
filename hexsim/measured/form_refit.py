"""A commissioning's other reading of the valve: the calibrated rounded edge kept, its parameters refitted to the
logs' flow balance, where it predicts their held-out windows as well as the curve read from them.

Commissioning reads each edge's curve from the flows (:func:`hexsim.measured.flow_curve.fit_flow_curves`): knots
some 18 mV apart at 0.9 V, piecewise linear, then the machine file's monotone cubic through its points. The corner
a calibrated ``rounded`` form has sharp (a rounded metering edge meeting its port) is rounded over the knots'
spacing, and the seat feels a rounding of 0.5 % of the flow over 40 mV at every crossing (docs/compensation.md;
on the reference plant R1 the commissioned seat 2.2-2.4x the threshold where the refitted form gives
0.93-1.00x). Where the form is the valve's shape, its few
parameters read from the same flows place the corner better than any knot grid. So :func:`refit_form` fits
them — the supply and return edges' gains, the rounded edge's gain k_a (seed eq. 3.11) and the overlap that
places the port's line (eq. 3.3), so the corner — with 1/E and V_pl/E as the curve's fit has them, on
the same flows and robust weights (soft L1), and scores the refitted form on the same blocked held-out windows
(each window predicted by the fit without it). :func:`hexsim.measured.commissioning.commission` keeps the form
unless the curve predicts those windows better by one standard error (the one-standard-error rule: Hastie,
Tibshirani & Friedman, The Elements of Statistical Learning, 2nd ed., §7.10).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hexsim.measured.fitting import bounded_fit
from hexsim.measured.flow_balance import FOLDS, FlowSamples
from hexsim.measured.flow_curve import (
    BETA_BOUNDS,
    BETA_PRIOR_SHARE,
    balance_samples,
    edge_opening,
    fold_mean,
    intervals,
    robust_scale,
    soft_l1,
    unit_gains,
    within_reach,
)
from hexsim.measured.measurement import MeasurementLog
from hexsim.plant.machine import Machine, with_keys

#: The forms whose parameters a commissioning refits and may keep (another form's valve is read as curves). Only the
#: rounded edge: on the independent port-limited actuator (tests/independent_actuator.py, ``corner``; its dead band
#: and its corner both set by the overlap) the refitted port form, though its edges' gains came within 0.3 % of the
#: truth, left reversals of 0.056-0.066 m/s^2 (0.047-0.055 with the overlap held) where the tuned file gave
#: 0.042-0.045 and the curves 0.037 (examples/proof_on_the_machine.py, seeds 20-22).
REFITTED_FORMS = ("rounded",)
#: Each parameter's bracket relative to the calibrated value (the edges' gains, k_a) or the spool stroke (the
#: overlap, from none to this share of it): a commissioning corrects a calibration, it does not replace it.
GAIN_BRACKET, OVERLAP_SHARE = (0.8, 1.25), 0.1


@dataclass(frozen=True)
class RefitForm:
    """The ``machine`` with its form's parameters refitted, the ``keys`` fitted with their values, and the
    blocked held-out windows' weighted mean square flow error ``held_out`` [m^6] with its standard error
    ``held_out_se`` (as :class:`hexsim.measured.flow_curve.FlowCurves` has the curve's)."""

    machine: Machine
    keys: dict
    held_out: float
    held_out_se: float


def _keys(machine: Machine) -> list[tuple[str, float, float, float]]:
    """(machine-file key, value, lower, upper) of the parameters refitted on ``machine``'s rounded edge: the edges'
    gains, k_a and the overlap that places the port's line (below where (3.11) would no longer meet it)."""
    hyd, eff = machine.hydraulics, machine.effects
    lo, hi = GAIN_BRACKET
    top = min(OVERLAP_SHARE * hyd.x_v_max, 0.9 * math.pi * hyd.spool_diameter / (4.0 * hyd.smooth_area_gain * hi))
    return [("valve.edge_gain_PA", eff.edge_gain_pa, lo * eff.edge_gain_pa, hi * eff.edge_gain_pa),
            ("valve.edge_gain_AT", eff.edge_gain_at, lo * eff.edge_gain_at, hi * eff.edge_gain_at),
            ("valve.smooth_area_gain", hyd.smooth_area_gain, lo * hyd.smooth_area_gain, hi * hyd.smooth_area_gain),
            ("valve.overlap_m", min(max(hyd.overlap, 0.0), top), 0.0, top)]


class _Balance:
    """The flow balance of the kept intervals as the form's prediction needs it: per sample the command and the
    full opening's volumes of the edge each side feeds, the intervals' starts, and per interval the displaced
    volume, the compressed volume's two factors and the window."""

    def __init__(self, samples: list[FlowSamples], reach: list[float]) -> None:
        self.parts = []
        for s in samples:
            starts, most = intervals(s)
            self.parts.append((s, starts, within_reach(most, reach)))
        self.b = np.concatenate([s.displaced[k] for s, _, k in self.parts])
        self.beta_rows = np.concatenate([np.column_stack([-s.swept_dp[k], -s.dead_dp[k]]) for s, _, k in self.parts])
        self.block = np.concatenate([s.block[k] for s, _, k in self.parts])

    def swept(self, machine: Machine) -> np.ndarray:
        """The volume the form's openings (``machine``'s, with its edge gains) pass into the chamber per kept
        interval (n,) [m^3]; a rod side's supply edge follows the A→T shape at -u and its return the P→A."""
        out = []
        for s, starts, keep in self.parts:
            pa, at = edge_opening(machine, 0, s.u), edge_opening(machine, 1, -s.u)  # each on its own axis
            per = at * s.supply + pa * s.ret if s.mirror else pa * s.supply + at * s.ret
            out.append(np.add.reduceat(per, starts)[keep])
        return np.concatenate(out)


def refit_form(logs: list[MeasurementLog], machine: Machine) -> RefitForm:
    """``machine``'s rounded edge (:data:`REFITTED_FORMS`) with its parameters refitted to ``logs``' flow
    balance (module doc), and its held-out windows' error. Raises InputError as
    :func:`hexsim.measured.flow_curve.fit_flow_curves` (a log without p1_Pa, too few intervals)."""
    samples, reach, _ = balance_samples(logs, unit_gains(machine), machine.sensors.sample_skew)
    balance = _Balance(samples, reach)
    keys = _keys(machine)
    x0 = np.array([v for _, v, _, _ in keys])
    lower, upper = np.array([lo for *_, lo, _ in keys]), np.array([hi for *_, hi in keys])
    x0 = np.clip(x0, lower, upper)
    scale = np.where(x0 != 0.0, np.abs(x0), upper - lower)

    def machine_at(x: np.ndarray) -> Machine:
        return with_keys(machine, {k: float(v) for (k, *_), v in zip(keys, x)})

    c = robust_scale(balance.b)
    beta_prior = np.array([1.0 / machine.hydraulics.bulk_modulus,
                           machine.hydraulics.pipeline_volume / machine.hydraulics.bulk_modulus])
    weights = np.ones_like(balance.b)

    def fit(rows: np.ndarray, x_start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        def residual(z: np.ndarray) -> np.ndarray:
            r, _ = _with_beta(balance, machine_at(z * scale), rows, weights, beta_prior, c)
            return r

        z = bounded_fit(residual, [x_start / scale], lower / scale, upper / scale, x_scale=1.0, diff_step=1e-4,
                        xtol=1e-8, ftol=1e-10, max_nfev=60).x
        return z * scale, _with_beta(balance, machine_at(z * scale), rows, weights, beta_prior, c)[1]

    everything = np.ones_like(balance.b, dtype=bool)
    x = x0
    for _ in range(3):  # the robust weights (soft L1), as the curve's fit has them
        x, beta = fit(everything, x)
        e = (balance.swept(machine_at(x)) + balance.beta_rows @ beta - balance.b) / c
        weights = soft_l1(e)
    errors = []
    for k in range(FOLDS):
        out = balance.block == k
        xk, beta = fit(~out, x)
        r = balance.swept(machine_at(xk)) + balance.beta_rows @ beta - balance.b
        errors.append(float(np.sum(weights[out] * r[out] ** 2) / np.sum(weights[out])))
    fitted = {key: float(v) for (key, *_), v in zip(keys, x)}
    return RefitForm(machine_at(x), fitted, *fold_mean(errors))


def _with_beta(balance: _Balance, machine: Machine, rows: np.ndarray, weights: np.ndarray, prior: np.ndarray,
               c: float) -> tuple[np.ndarray, np.ndarray]:
    """The weighted residuals [in units of ``c``] of the intervals ``rows`` with the form's openings on
    ``machine`` and (1/E, V_pl/E) solved for them (linear, held weakly at ``prior``, a share of its value a
    standard deviation: :data:`~hexsim.measured.flow_curve.BETA_PRIOR_SHARE`; within the bulk modulus' bracket),
    and those two."""
    swept = balance.swept(machine)
    w = np.sqrt(weights[rows]) / c
    a = balance.beta_rows[rows] * w[:, None]
    t = (balance.b[rows] - swept[rows]) * w
    p = 1.0 / (BETA_PRIOR_SHARE * prior + 1e-30)
    beta = np.linalg.lstsq(np.vstack([a, np.diag(p)]), np.concatenate([t, p * prior]), rcond=None)[0]
    beta[0] = min(max(beta[0], BETA_BOUNDS[0]), BETA_BOUNDS[1])
    beta[1] = max(beta[1], 0.0)
    return np.concatenate([a @ beta - t, p * (beta - prior)]), beta
