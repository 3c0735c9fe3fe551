"""A log's valve curve read beyond the commands its machine's calibration measured, from the log itself, with the
effects the identification named refitted on it (:mod:`hexsim.measured.envelope`: where those commands are and
why a misfit beyond them is the calibration's envelope before it is an effect).

- :func:`curve_read_from_log` reads the curve there (the measured commands held to the calibrated file's curve,
  :func:`hexsim.measured.flow_curve.fit_flow_curves`), each edge's rise scaled by the replays together with the named
  effects' parameters (:func:`hexsim.measured.effect_fit.refit_on_baseline`), and replays the log on it;
  :func:`hexsim.measured.validation.validate` judges the effects there, or identifies again on it where nothing was
  named and the reading is within the budget, and says that an effect confined to those commands is not resolved on
  this calibration (R1's nulls: `none`; its leakage, null offset, spool, hysteresis and supply sag: `explained`);
- :func:`read_sentence` says what the reading found.

On the identification's side of the floor above scoring (it refits effects), above the envelope it reads.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from hexsim.errors import InputError, PhysicsError
from hexsim.measured.curves import curve_machine
from hexsim.measured.effect_fit import Baseline, refit_on_baseline
from hexsim.measured.envelope import GAIN_BOUNDS, splice
from hexsim.measured.flow_curve import FlowCurves, fit_flow_curves
from hexsim.measured.replay import nominal_plant
from hexsim.measured.scoring import WITHIN, within_budget
from hexsim.plant.machine import Machine

#: Readings of the curve at most (:func:`curve_read_from_log`): the flows are read at the spool through the named
#: effects as last fitted, so an effect that the reading moves asks for the flows read again, until the log is within
#: its budget, no effect parameter moves by more than :data:`READ_TOLERANCE` of its value or the worst channel's
#: held-out RMS falls by less than :data:`READ_GAIN`. R1's leakage log on its two-log calibration: 1.62 budgets after
#: the first reading, with the leak at 2.995e-12 m^3/(s Pa) where the calibrated curve had it at 3.18e-12, 1.02 after
#: the second; R1's null offset log on R1's own model, the offset named at 0.06 V: 0.0788, 0.0791, 0.0799 V in three
#: readings (5.3, 4.1, 3.0 budgets of position; the later readings keep the first's penalty weight and edges).
READINGS = 4
READ_TOLERANCE = 0.01
READ_GAIN = 0.1


def curve_read_from_log(problem, budget, beyond: dict, fits: tuple = (), like: FlowCurves | None = None) -> dict | None:
    """A single actuator's log (its replay ``problem``, :class:`hexsim.measured.scoring.Problem`, and the ``budget``
    measured on its nominal: :attr:`hexsim.measured.identify.Identification.nominal_budget`) on its machine with the
    valve's curve read from the log's own flows beyond the commands the calibration measured (``beyond``,
    :func:`hexsim.measured.envelope.beyond_curve`; within them held to the calibrated curve, exactly), with the
    effects the identification named on the calibrated curve (``fits``, :class:`hexsim.measured.effect_fit.FitResult`,
    in their order; the flows are read at the spool through them, e.g. a null offset). Each edge's rise there is
    scaled by a gain fitted on the log's fit windows together with the effects' parameters
    (:func:`hexsim.measured.effect_fit.refit_on_baseline`: the flows give a curve to about a percent, an open-loop
    replay asks for parts in a thousand, as the calibration refines its curve's gains; an effect fitted on the
    calibrated curve carries what the curve there missed), the flows read again through the effects so fitted while
    they leave the log off, move and gain (:data:`READINGS`), the best reading kept, judged on its held-out windows
    against that budget as the identification judges a candidate.

    Returns ``machine`` (the log's machine with that curve and without the effects: the baseline to identify them on
    again), each channel's held-out RMS in budgets with the effects (``held_out_rms_in_budgets``), ``within`` (every
    channel within sqrt(WITHIN) budgets), the commands read (``read_V``), the scales (``gains``), the effects refitted
    on it (``fits``, FitResults holding the joint model and its scores), the model's scores on every window
    (``scored``, :class:`hexsim.measured.scoring.Scored`) and the first reading's curves (``curves``: the penalty
    weight and edges every later reading keeps, ``like`` of :func:`hexsim.measured.flow_curve.fit_flow_curves`;
    ``like`` given, its own are kept from the first); None where the curve cannot be read from the log (no p1_Pa,
    too few intervals) or the log not replayed on it."""
    base = problem.log.machine
    lo, hi = beyond["calibrated_V"]
    best = None
    for _ in range(READINGS if fits else 1):
        on = base if not fits else dataclasses.replace(base, hydraulics=fits[-1].model.hydraulics,
                                                        effects=fits[-1].model.effects)
        try:
            curves = fit_flow_curves([dataclasses.replace(problem.log, machine=on)], on, toward_machine=True,
                                     hold_within=(lo, hi), like=like)
        except InputError:
            return None
        like = like or curves
        points = splice(base, curves, lo, hi)

        def machine(k, points=points, curves=curves) -> Machine:
            return curve_machine(base, curves, points(k))

        baseline = Baseline(lambda k: nominal_plant(dataclasses.replace(problem.log, machine=machine(k))),
                            np.ones(2), np.full(2, GAIN_BOUNDS[0]), np.full(2, GAIN_BOUNDS[1]))
        try:
            refitted, gains, scored = refit_on_baseline(problem, list(fits), budget, baseline)
        except (InputError, PhysicsError):  # the log cannot be replayed on the curve read (too few windows, a blow-up)
            return None
        rms = {ch: math.sqrt(v) for ch, v in within_budget(scored, budget).items()}
        moved = max((float(np.max(np.abs(f.x - r.x) / np.maximum(np.abs(f.x), 1e-12))) for f, r in zip(fits, refitted)),
                    default=0.0)
        fits, was = tuple(refitted), best["worst"] if best else math.inf
        if best is None or max(rms.values()) < was:  # the best reading is kept, not the last
            best = {"machine": machine(gains), "read_V": [lo, hi], "gains": [float(g) for g in gains],
                    "fits": list(fits), "scored": scored, "curves": like, "held_out_rms_in_budgets": rms,
                    "within": max(rms.values()) <= math.sqrt(WITHIN), "worst": max(rms.values())}
        if best["within"] or moved <= READ_TOLERANCE or max(rms.values()) > (1.0 - READ_GAIN) * was:
            break
    best.pop("worst")
    return best


def read_sentence(read: dict, effects: list[str], chosen: bool, instead: str | None = None) -> str:
    """What the curve read from the log (:func:`curve_read_from_log`) says: the model's held-out RMS with it, and
    whether the verdict is now made on it (``chosen``: the effects refitted on that curve passed the identification's
    test against it without them, or the identification on that baseline settled what the one on the calibrated
    curve left open); ``effects``: the effects the reading was made with, named on the calibrated curve or, where
    ``instead`` names the one named there, a rival read in its place."""
    lo, hi = read["read_V"]
    figures = ", ".join(f"{ch} {v:.3g}" for ch, v in read["held_out_rms_in_budgets"].items())
    listed = ", ".join(effects)
    through = ("" if not effects else f" with {listed} refitted on it in place of the {instead} named on the "
               f"calibrated curve (which leaves it off there)" if instead else f" with the {listed} named on the "
               f"calibrated curve refitted on it")
    head = (f"The valve's curve read from this log beyond {lo:.3g}…{hi:.3g} V{through} (held to the calibrated "
            f"curve within, its scale there fitted to this log's fit windows): {figures} budgets (held-out windows). ")
    if chosen:
        made = ("the effects, refitted there, pass the identification's test against it without them"
                if effects else "the identification made again on it settles the log")
        return head + (f"The verdict is made on that curve ({made}): an effect confined to those commands is not "
                       "resolved on this calibration.")
    if effects and read["within"]:
        return head + ("The effects do not pass the identification's test against that curve without them; "
                       "the verdict stays the one made on the calibrated curve (calibrate with a log that dwells "
                       "there to settle it).")
    return head + "It does not settle the verdict: more than the curve there is off, or the curve is not read to the " \
                  "replay's precision."
