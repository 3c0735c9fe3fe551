"""``hexsim validate``: confront the model with a measurement log and report (Markdown, PNG, JSON).

Chain: :func:`hexsim.measured.measurement.read_log` → :func:`hexsim.measured.identify.identify` (valve replay, candidate
fits, choice) → :mod:`hexsim.measured.residuals` before and after → report. The identifier reads nothing but the
log and its sidecar.
"""

from __future__ import annotations

import dataclasses
import math
import pathlib

import numpy as np

from hexsim.measured.advice import (
    CalibrationAdvice,
    hexapod_hint,
    nominal_check,
    transient_check,
)
from hexsim.measured.candidates import CANDIDATES
from hexsim.measured.curve_read import curve_read_from_log, read_sentence
from hexsim.measured.effect_fit import (
    ALPHA,
    MIN_EXCESS_SHARE,
    WORSE_REL,
    judge,
    signal_labels,
)
from hexsim.measured.envelope import beyond_curve
from hexsim.measured.identify import (
    FIT_PER_ROUND,
    MAX_EFFECTS,
    SEARCH_SEGMENTS,
    Identification,
    default_candidates,
    identify,
)
from hexsim.measured.measurement import MeasurementLog, read_log
from hexsim.measured.records import (
    UNSETTLED,
    Discovery,
    ValidationReport,
)
from hexsim.measured.reports.validation import fit_label, write_report
from hexsim.measured.residuals import analyse
from hexsim.measured.scoring import SCALED, WITHIN, Scored, within_budget
from hexsim.plant.machine_keys import KEYS
from hexsim.plant.params import OFFSET_FIELDS
from hexsim.studies.metrics import STANDARD_GRAVITY
from hexsim.tables import StdoutTarget

#: A payload read from the legs' P1 offsets is reported when it is at least this heavy [kg] and the offsets
#: leave at most :data:`PAYLOAD_INCONSISTENCY` of the wrench unexplained.
PAYLOAD_MIN_KG = 5.0
PAYLOAD_INCONSISTENCY = 0.1


def hexapod_payload(ident: Identification) -> dict | None:
    """:func:`hexsim.measured.hexapod_replay.payload_from_statics` on the P1 calibration offsets of the final model
    (the nominal plus the accepted effects: a supply sag the nominal lacks also shifts every leg's P1) of
    a hexapod log, or None (single actuator, no P1, or offsets that are not one consistent load)."""
    if ident.problem.log.system != "hexapod" or "p1" not in ident.final.calibration:
        return None
    from hexsim.measured.hexapod_replay import payload_from_statics

    found = payload_from_statics(np.array(ident.final.calibration["p1"]["offset"]),
                                 geometry=ident.problem.log.machine.geometry)
    if abs(found["mass_kg"]) >= PAYLOAD_MIN_KG and found["inconsistency"] <= PAYLOAD_INCONSISTENCY:
        return found
    return None


def conclusions(ident: Identification, before: dict) -> list[str]:
    """What the residual says, in sentences an engineer reads first: which channels are off and by how
    much, sensor calibration that looks like a convention problem or a transducer error, leg-level signs
    on a hexapod, where the residual lives (direction of motion), the verdict and what discovery found.
    ``before``: the residual analysis of the nominal model (:func:`hexsim.measured.residuals.analyse`)."""
    ratio = {ch: math.sqrt(v) for ch, v in within_budget(ident.nominal, ident.budget).items()}
    off = [ch for ch, r in ratio.items() if r * r > WITHIN]
    return (_channel_sentences(ratio, off) + floor_sentences(ident.budget, ident.problem.units)
            + _calibration_sentences(ident) + sensor_consistency(ident.problem.log)
            + _leg_sentences(ident) + _direction_sentences(before, off) + _verdict_sentences(ident))


#: Band [Hz] in which the accelerometer is compared with the position's second derivative: above the
#: drift of a double integration, below the oil-spring ringing and the derivative filter's roll-off.
CONSISTENCY_BAND_HZ = (0.2, 20.0)


def sensor_consistency(log: MeasurementLog) -> list[str]:
    """Sensors checked against each other before any model: the single actuator's accelerometer against
    the second derivative of its position (Savitzky–Golay, 51 ms; both band-passed to
    :data:`CONSISTENCY_BAND_HZ`, zero-phase Butterworth), by the least-squares slope s and the correlation
    r. A sentence if they disagree: |s - 1| > 5 % with |r| > 0.9 (a scale error of one sensor, or a sign /
    axis problem for s < 0), or |r| < 0.5 with the position moving (a channel that does not belong to this
    axis). Nothing for a hexapod log (its accelerometer is the platform's) or without both columns."""
    from scipy.signal import butter, sosfiltfilt

    from hexsim.signals import savgol, savgol_length

    c, fs = log.columns, log.sample_rate_hz
    if log.system != "single-actuator" or "acc_mps2" not in c or "pos_m" not in c or fs <= 4 * CONSISTENCY_BAND_HZ[1]:
        return []
    if len(log.time) < 10 * savgol_length(fs, 0.051):
        return []
    sos = butter(2, CONSISTENCY_BAND_HZ, btype="bandpass", fs=fs, output="sos")
    from_position = sosfiltfilt(sos, savgol(c["pos_m"], fs, 0.051, deriv=2))
    measured = sosfiltfilt(sos, c["acc_mps2"])
    trim = slice(int(fs), len(measured) - int(fs)) if len(measured) > 4 * fs else slice(None)
    x, y = from_position[trim], measured[trim]
    if float(x @ x) <= 0 or np.std(x) < 0.05:  # the motion is too slow to compare (< 0.05 m/s^2 rms)
        return []
    slope, r = float(x @ y / (x @ x)), float(np.corrcoef(x, y)[0, 1])
    band = f"{CONSISTENCY_BAND_HZ[0]:g}–{CONSISTENCY_BAND_HZ[1]:g} Hz"
    if abs(r) > 0.9 and abs(slope - 1.0) > 0.05:
        what = ("a sign or axis problem of one of them" if slope < 0 else
                "a scale error of one of the two sensors (accelerometer sensitivity or position transducer gain)")
        return [f"Sensors against each other: the accelerometer reads {slope:.3f} times the second derivative of "
                f"the position ({band}, correlation {r:.3f}): {what}."]
    if abs(r) < 0.5:
        return [f"Sensors against each other: the accelerometer hardly follows the second derivative of the "
                f"position ({band}, correlation {r:.2f}): a channel of another axis, or a sensor that is not "
                f"working."]
    return []


#: A channel's budget is the calibration's floor, not the sensor, where what the calibration left uncertain is
#: this many times the sensor's noise.
FLOOR_DOMINATES = 3.0


def _readable(value: float, unit: str) -> str:
    """``value`` [SI ``unit``] as an engineer reads it: pressures in bar, lengths in mm."""
    if unit == "Pa":
        return f"{value / 1e5:.3g} bar"
    if unit == "m":
        return f"{value * 1e3:.3g} mm"
    return f"{value:.3g} {unit}"


def floor_sentences(budget, units: dict[str, str]) -> list[str]:
    """Where a verdict's budget is the calibration's floor rather than the sensors' noise (the calibration's
    uncertainty, :func:`hexsim.measured.scoring.calibration_uncertainty`, at least :data:`FLOOR_DOMINATES` times
    the noise): a sentence naming the channels, both figures and what it means — an effect smaller than the floor
    is not resolved on this machine, whatever the verdict. ``budget``: a :class:`hexsim.measured.scoring.Budget`;
    ``units``: channel -> SI unit. Empty where the noise sets every budget."""
    floor = {ch: c for ch, c in budget.calibration.items()
             if ch in budget.noise and c > FLOOR_DOMINATES * max(budget.noise[ch], 1e-300)}
    if not floor:
        return []
    parts = [f"{ch} ({_readable(c, units.get(ch, ''))} against {_readable(budget.noise[ch], units.get(ch, ''))} "
             f"of sensor noise, {c / max(budget.noise[ch], 1e-300):.3g}×)" for ch, c in floor.items()]
    return ["The budget is this machine's calibration floor, not its sensors, on " + ", ".join(parts)
            + ": an effect smaller than that is not resolved on this machine, whatever the verdict; a calibration "
            "that reaches its own logs' budget lowers it (docs/calibration.md)."]


def _channel_sentences(ratio: dict[str, float], off: list[str]) -> list[str]:
    clean = [ch for ch in ratio if ch not in off]
    if not off:
        return ["The nominal model reproduces every channel within its budget, the sensors' noise, the replay's "
                "numerical tolerance and, on a calibrated machine, the calibration's uncertainty "
                "(held-out RMS / budget: " + ", ".join(f"{ch} {r:.2g}" for ch, r in ratio.items()) + ")."]
    out = ["Off beyond noise and tolerance: " + ", ".join(f"{ch} ({ratio[ch]:.3g} budgets)" for ch in off)
           + (f"; at noise: {', '.join(clean)}." if clean else ".")]
    if off == ["position"] and {"p1", "acceleration"} <= set(clean):
        out.append("Only the position disagrees while P1 and the acceleration are clean: look at the position "
                   "sensor (scale, delay) or the valve's flow gain before friction or load.")
    return out


def _beyond_sentences(ident: Identification) -> list[str]:
    """A sensor offset the nominal replay asked beyond its data sheet (machine file ``sensors``): physics, not
    the sensor; the candidates were fitted with it held at its limit. Where the accepted effects bring it within
    the data sheet (the final model's own offset fit asks nothing beyond), they account for it; otherwise the
    effects that give one are named (on R1's five effect logs, none of them an inclination or a load, the nominal
    asked +0.23…+0.48 m/s² of the accelerometer and the accepted effect left -0.12…+0.03)."""
    out = []
    asked, final = ident.nominal.calibration, ident.final.calibration
    log = ident.problem.log
    for ch, name in OFFSET_FIELDS.items():
        beyond = [(j, b) for j, b in enumerate(asked.get(ch, {}).get("beyond", [])) if b is not None]
        if not beyond:
            continue
        key, unit = next((k.path, k.unit) for k in KEYS if k.target == ("sensors", name))
        j, worst = max(beyond, key=lambda item: abs(item[1]))
        labels = signal_labels(ident.problem, ch)
        limit = log.machine.sensors.offset_limit(ch)
        scale = 1e5 if unit == "Pa" else 1.0
        shown = "bar" if unit == "Pa" else unit
        asks = f"The {labels[j] if len(labels) > 1 else ch} sensor's offset asks {worst / scale:+.3g} {shown}"
        sheet = f"beyond its data sheet's ±{limit / scale:.3g} {shown} ({key}): physics, not the sensor"
        now = final.get(ch, {})
        if ident.accepted and not any(b is not None for b in now.get("beyond", [])) and len(now.get("offset", [])) > j:
            effects = " + ".join(fit_label(f) for f in ident.accepted)
            out.append(f"{asks} on the nominal model, {sheet}, and the model with {effects} accounts for it (its offset "
                       f"there {now['offset'][j] / scale:+.3g} {shown}, within the data sheet); the candidates were "
                       f"judged with it held at its limit.")
            continue
        what = (f"an inclination: the axis {_tilt(log, worst)} from vertical instead of "
                f"{log.inclination_deg:g}°, or a load" if ch == "acceleration" and log.system == "single-actuator"
                else "a load (weight, payload) or a supply level" if ch != "acceleration"
                else "the platform's pose or a payload")
        out.append(f"{asks}, {sheet} ({what}); it is held at its limit and the effects are judged with it held.")
    return out


def _tilt(log: MeasurementLog, offset: float) -> str:
    """The axis angle [deg, text] whose g cos θ differs from the log's declared one by an accelerometer
    offset ``offset`` [m/s^2]."""
    c = math.cos(math.radians(log.inclination_deg)) + offset / STANDARD_GRAVITY
    return f"{math.degrees(math.acos(c)):.0f}°" if -1.0 <= c <= 1.0 else "further"


def _calibration_sentences(ident: Identification) -> list[str]:
    out = []
    final = ident.final.calibration  # the calibration of the model the verdict stands on
    for a in final.get("acceleration", {}).get("offset", []):
        if abs(abs(a) - STANDARD_GRAVITY) < 0.15 * STANDARD_GRAVITY:
            out.append(f"The accelerometer reads {a:+.2f} m/s^2 off the model: a constant offset of about "
                       f"{'+' if a > 0 else '-'}g is a convention problem (the log holds acceleration, the "
                       "format specific force, or the reverse), not physics; it is calibrated out.")
            break
    out += _beyond_sentences(ident)
    settled = ident.verdict not in UNSETTLED
    for ch in SCALED:
        cal = final.get(ch)
        if not cal or not any(abs(sc - 1.0) > 0.005 for sc in cal["scale"]):
            continue
        worst = max(cal["scale"], key=lambda sc: abs(sc - 1.0))
        if not settled:
            out.append(f"The {ch} sensor's scale fits {worst:.4f}: with the model still off, the scale takes up part "
                       "of the model error and says little about the sensor.")
        elif ch == "position":
            out.append(f"The position sensor's scale fits {worst:.4f}: a transducer scale error of this size, or a "
                       "flow gain off by as much (the two trade in the position increments); calibrated out, not "
                       "taken for an effect.")
        else:
            out.append(f"The accelerometer's scale fits {worst:.4f}: a sensitivity error, calibrated out and not "
                       "taken for an effect.")
    return out


def _leg_sentences(ident: Identification) -> list[str]:
    """Hexapod: a leg's static tracking error (its position offset off the legs' common one beyond the log's
    limit, :data:`hexsim.measured.hexapod_replay.CLOSED_LOOP_OFFSET_M`, left in the residual) where what is
    left exceeds the position's budget, a payload in the legs' P1 offsets, one leg's residual standing out."""
    out, p = [], ident.problem
    position = ident.nominal.calibration.get("position", {})  # before any effect: what the effects were asked
    for label, offset in sorted(position.get("static_error", {}).items(), key=lambda kv: -abs(kv[1])):
        common = position["common_offset"]
        offset -= common
        if abs(offset) - p.position_offset_limit <= ident.budget.total.get("position", 0.0):
            continue  # left in the residual, but within the position's budget: nothing to say
        kp = p.log.kp
        out.append(f"The position of {label} reads {offset * 1e3:+.3f} mm off the closed-loop replay beyond the "
                   f"legs' common offset ({common * 1e3:+.3f} mm): a static tracking error, left in the "
                   "residual for the effects to explain (a transducer offset would not show here: the controller "
                   "holds the measured position on the setpoint on the machine as in the replay). A valve null "
                   f"offset of about {-offset * kp:+.3f} V on that leg would hold it there (K_p = {kp:g} V/m), "
                   "or a flow the leg needs at rest (a leak).")
    payload = hexapod_payload(ident)
    if payload is not None:
        out.append(f"The six legs' P1 offsets are one load, not six sensor offsets: a payload change of "
                   f"{payload['mass_kg']:+.1f} kg at ({payload['x_m']:+.3f}, {payload['y_m']:+.3f}) m on the platform "
                   f"(statics at the neutral pose; {payload['inconsistency']:.1%} of the wrench no payload makes). "
                   "Calibrated out in the replay, reported here as physics.")
    for ch in ("position", "p1"):
        rms = ident.nominal.held_out_rms_signals.get(ch, [])
        if len(rms) < 3:
            continue
        j = int(np.argmax(rms))
        others = float(np.median([v for i, v in enumerate(rms) if i != j]))
        if rms[j] > 5.0 * max(others, ident.budget.total[ch]):
            label = signal_labels(p, ch)[j]
            out.append(f"The {ch} residual of {label} is {rms[j] / max(others, 1e-300):.0f}x the median of the other "
                       f"legs: a leg-level effect on {label} (leakage, null offset, sensor of that leg), not one "
                       "on all legs.")
    return out


def _direction_sentences(before: dict, off: list[str]) -> list[str]:
    out = []
    for ch in off:
        cond = before.get(ch, {}).get("conditioned", {})
        up, down = cond.get("velocity > 0", {}).get("rms"), cond.get("velocity < 0", {}).get("rms")
        if up and down and max(up, down) > 3.0 * min(up, down):
            side = "retracting (v < 0, the return edge A→T)" if down > up else "extending (v > 0, the supply edge P→A)"
            out.append(f"The {ch} residual is {max(up, down) / min(up, down):.1f}x larger while {side}: a "
                       "direction-dependent effect (edge asymmetry, friction of one direction).")
    return out


#: Another candidate that passed leaves at most this much more held-out cost than the accepted one: the
#: log hardly tells them apart, and the report says so.
CLOSE_CALL = 1.1


def _close_call_sentences(ident: Identification) -> list[str]:
    """One sentence per round in which a candidate that also passed explains the held-out data about as
    well as the accepted one (left-over cost within :data:`CLOSE_CALL`)."""
    chosen = {f.key for f in ident.accepted}
    out = []
    for fits in ident.rounds:
        passed = [f for f in fits if f.accepted]
        best = [f for f in passed if f.key in chosen]
        if not best:
            continue
        left = 1.0 - best[0].held_out_gain
        close = [f for f in passed if f.key not in chosen and 1.0 - f.held_out_gain <= CLOSE_CALL * left]
        if close:
            others = ", ".join(f"{fit_label(f)} ({f.held_out_gain:.3f})" for f in close)
            out.append(f"{others} explain{'s' if len(close) == 1 else ''} the held-out data almost as well as "
                       f"{fit_label(best[0])} (held-out gain {best[0].held_out_gain:.3f}): the log hardly tells them "
                       f"apart; {fit_label(best[0])} is reported as the better one.")
    return out


def _verdict_sentences(ident: Identification) -> list[str]:
    out = []
    if ident.verdict == "explained":
        out.append("Accepted: " + " + ".join(fit_label(f) for f in ident.accepted) + "; with it every channel is within "
                   "its budget.")
    elif ident.verdict == "partial":
        left = [ch for ch, v in within_budget(ident.final, ident.budget).items() if v > WITHIN]
        out.append("Accepted: " + " + ".join(fit_label(f) for f in ident.accepted) + (
            f"; structure is left in {', '.join(left)} that no library effect explains." if left else "."))
        for f in ident.accepted:
            if f.at_edge:
                out.append(f"{fit_label(f)} explains {f.held_out_gain:.1%} of the held-out error with "
                           f"{'; '.join(f.at_edge)}: the effect is in this log, but its form or its range does not "
                           f"fit this machine (a partial explanation, not a calibrated value).")
    elif ident.verdict == "unexplained" and not ident.rounds:
        out.append("No library effect was tried (every candidate left out): the model is off this log beyond its "
                   "budget, and what it lacks is not named here.")
    elif ident.verdict == "unexplained":
        out.append("No library effect passes the acceptance test: the model lacks something outside the list.")
    out += _close_call_sentences(ident)
    found = ident.discovery or Discovery(False)
    if found.on.startswith("the nominal model"):
        out.append(f"Discovery on {found.on}.")
    for term in found.terms:
        out.append(f"Discovered in the {term['equation']} equation: {term['meaning']} "
                   f"(coefficient {term['coefficient']:.4g} ± {term['std_error']:.2g} {term['unit']}).")
    if found.added_to_model:
        out.append(f"With the discovered term(s) added to the model the held-out error drops by "
                   f"{found.held_out_cost_recovered:.1%} (cost in budgets).")
    elif found.why:
        out.append(f"Discovery: {found.why}.")
    return out


def summary(ident: Identification) -> ValidationReport:
    """The JSON document: verdict, added_effects, calibration, budget, error_before/after (NRMSE per
    channel), candidates with their judgement, residual analysis before/after, conclusions, what the log
    lacked and which defaults were assumed."""
    p = ident.problem
    u, vel, pos, near = p.motion_state()
    cut = p.analysis_view
    before = analyse(cut(ident.nominal_residuals), u, vel, pos, near, p.log.sample_rate_hz)
    after = analyse(cut(ident.chosen_residuals), u, vel, pos, near, p.log.sample_rate_hz)
    s0 = p.settle
    first = ident.accepted[0] if ident.accepted else None
    return {
        "log": str(p.log.path),
        "machine": p.log.machine.label,
        "system": p.log.system,
        "verdict": ident.verdict,
        "added_effect": ident.added_effect,
        "added_effects": [{"name": f.name, "leg": f.leg, "parameters": f.parameters} for f in ident.accepted],
        "parameters": first.parameters if first else {},
        "calibration": {"nominal": ident.nominal.calibration, "final": ident.final.calibration},
        "budget": ident.budget.as_dict(p.units),
        "held_out_rms_in_budgets": {ch: math.sqrt(v) for ch, v in within_budget(ident.final, ident.budget).items()},
        "held_out_rms_per_signal": {ch: {label: {"before": ident.nominal.held_out_rms_signals[ch][j],
                                                 "after": ident.final.held_out_rms_signals[ch][j]}
                                         for j, label in enumerate(signal_labels(p, ch))} for ch in p.channels},
        "error_before": ident.error_before,
        "error_after": ident.error_after,
        "error_definition": "NRMSE: RMS of (replayed, sensor-calibrated - measured) / the measured signal's "
                            "standard deviation (floored: 0.1 mm, 0.1 bar, 0.05 m/s^2), over all " + p.scored,
        "replay": p.replay_mode,
        "rms_before": {ch: float(np.sqrt(np.mean(r[:, s0:] ** 2))) for ch, r in ident.nominal_residuals.items()},
        "rms_after": {ch: float(np.sqrt(np.mean(r[:, s0:] ** 2))) for ch, r in ident.chosen_residuals.items()},
        "units": p.units,
        "candidates": [c.as_dict() | {"physics": CANDIDATES[c.name].physics,
                                      "plausible_range_source": CANDIDATES[c.name].source} for c in ident.candidates],
        "screening": ident.screening,
        "selection": (f"forward selection (at most {MAX_EFFECTS}): a candidate is accepted if its held-out "
                      f"improvement beyond the numerical tolerance passes a one-sided t-test over the held-out "
                      f"windows at {ALPHA:g} / (candidates in the round), it removes at least "
                      f"{MIN_EXCESS_SHARE:.0%} of the held-out cost beyond the budget, no signal's (each leg's) held-out RMS "
                      f"rises by more than its budget and {WORSE_REL:.0%}, and its parameters lie inside their plausible ranges, "
                      f"off the bounds and above the log's resolution; a channel is explained within "
                      f"sqrt({WITHIN:g}) budgets. Hexapod: leg-level candidates also on each leg whose residual "
                      f"stands out, every candidate screened by its best start on the first {SEARCH_SEGMENTS} "
                      f"segments, the best {FIT_PER_ROUND} fitted there and judged on the whole log (the "
                      f"Bonferroni count is the candidates fitted)"),
        "conclusions": conclusions(ident, before),
        "payload_from_statics": hexapod_payload(ident),
        "discovery": None if ident.discovery is None else ident.discovery.record(),
        "residuals_leg": p.focus_leg,  # hexapod: the leg the residual analysis looks at
        "residuals_before": before,
        "residuals_after": after,
        "windows": p.window_doc,
        "not_checked": p.log.missing,
        "assumed": p.log.assumed,
    }


def calibration_advice(ident: Identification, notify=None) -> CalibrationAdvice | None:
    """What validate says of the log's machine before any effect, composed from the calibration's checks
    (:mod:`hexsim.measured.calibration`): an uncalibrated machine visibly off a constant-command log's steady
    motions (:func:`nominal_check`); where the verdict is not settled on a machine never calibrated, what a
    calibration from a single actuator's transients moves (:func:`transient_check`, on the identification's
    own replay problem and nominal budget, not built again) or the hexapod's hint (:func:`hexapod_hint`).
    None when there is nothing to check."""
    from hexsim.measured.dynamics import ReplayEvidence

    log = ident.problem.log
    check = nominal_check(log)
    if check is not None or ident.verdict not in UNSETTLED or log.machine.calibration is not None:
        return check
    if log.system == "hexapod":
        return hexapod_hint(log)
    if notify:
        notify("the machine was never calibrated: calibrating its nominal on this log's transients")
    return transient_check(log, ReplayEvidence.of_problem(ident.problem, ident.nominal_budget))


def _on_the_curve_read(ident: Identification, beyond: dict, candidates: tuple[str, ...], jobs: int, notify):
    """``ident`` (unsettled on a log beyond the commands its calibration measured) with the valve's curve read from
    the log there (:func:`hexsim.measured.curve_read.curve_read_from_log`, with the effects ``ident`` named refitted on
    it; where one effect was named and that reading stays off, with each of its rivals instead, :func:`_rivals`, the
    first within the budget kept). Where effects were read and the reading with them is within the budget, they are
    judged as the identification judges a candidate against the curve read without them
    (:func:`_explained_on_the_curve`): the verdict ``explained`` with their values refitted there where they pass
    (R1's leakage, null offset and supply sag logs on a two-log calibration; its spool dynamics log, where the
    calibrated curve named a sensor delay). Where nothing was named, or the curve read without the effects is itself
    within the budget, the identification again on the machine with that curve (its own budget, its figures for the
    report), kept if it answers none or explained; otherwise the reading's figures only. (Identified again where the
    reading leaves the nominal off, the independent spool's 6 s log took 12 s more and named nothing.) Returns the
    identification kept; ``beyond`` takes the reading's account where the curve could be read
    (``curve_read_from_log``: commands, scales, held-out RMS, the effects read with, whether chosen, the sentence)."""
    if notify:
        notify("reading the valve's curve from the log beyond the commands the calibration measured")
    problem, budget = ident.problem, ident.nominal_budget
    read = curve_read_from_log(problem, budget, beyond, tuple(ident.accepted))
    if read is None:
        return ident
    instead, tried = None, 1
    if len(ident.accepted) == 1 and not read["within"]:
        for rival in _rivals(ident):
            if notify:
                notify(f"reading the curve with {rival.name} instead of {ident.accepted[0].name}")
            tried += 1
            other = curve_read_from_log(problem, budget, beyond, (rival,), like=read["curves"])
            if other is not None and other["within"]:
                read, instead = other, ident.accepted[0].name
                break
    effects = [f.name for f in read["fits"]]
    alone = read if not effects else curve_read_from_log(problem, budget, beyond, like=read["curves"]) \
        if read["within"] else None
    kept = ident
    if effects and alone is not None and not alone["within"]:
        kept = _explained_on_the_curve(ident, read, alone["scored"], tried)
    elif alone is not None and alone["within"]:  # the curve alone explains the log: the effects afresh on it
        # against the reading's budget, the calibrated file's: the curve machine carries no calibration record of its
        # curve, so a budget measured on it leaves the calibration's uncertainty out (R1's null sine: 1.35 -> 2.18)
        again = identify(dataclasses.replace(problem.log, machine=alone["machine"]), candidates=candidates,
                         jobs=jobs, notify=notify, budget=budget)
        if again.verdict in ("none", "explained"):
            kept, read, effects, instead = again, alone, [], None
    chosen = kept is not ident
    shown = {k: v for k, v in read.items() if k not in ("machine", "fits", "scored", "curves")}
    beyond["curve_read_from_log"] = shown | {"effects": effects, "instead_of": instead, "chosen": chosen,
                                             "sentence": read_sentence(read, effects, chosen, instead)}
    return kept


#: A first-round candidate whose held-out gain on the calibrated curve is at least this share of the best one's is a
#: rival of the effect named there (:func:`_rivals`): R1's spool dynamics log, 0.82 against the sensor delay's 0.84.
RIVAL_SHARE = 0.5
#: Rivals read at most, best first (each reading costs a few seconds).
MAX_RIVALS = 2


def _rivals(ident: Identification) -> list:
    """The first round's candidates other than the one named whose held-out gain is at least :data:`RIVAL_SHARE`
    of the best one's, best first, at most :data:`MAX_RIVALS`: on a curve missed beyond the measured commands the
    best may be the one that carries the curve's misfit, not the effect (R1's 25 Hz spool read as an 8.7 ms sensor
    delay)."""
    first = ident.rounds[0] if ident.rounds else []
    gains = [f.held_out_gain for f in first if math.isfinite(f.held_out_gain)]
    if not gains:
        return []
    named = ident.accepted[0].key
    rivals = [f for f in first if f.key != named and math.isfinite(f.held_out_gain)
              and f.held_out_gain >= RIVAL_SHARE * max(gains)]
    return sorted(rivals, key=lambda f: -f.held_out_gain)[:MAX_RIVALS]


def _explained_on_the_curve(ident: Identification, read: dict, without: Scored, tried: int = 1) -> Identification:
    """``ident`` explained by its named effects as the curve read refitted them (``read``'s ``fits``, within the
    budget), where each passes the identification's test against the curve read without them (``without``:
    :func:`hexsim.measured.effect_fit.judge`, with the readings ``tried`` as the candidates of a round: significant
    and material on the held-out windows, no signal worse, its parameters plausible); ``ident`` otherwise. An effect
    read in place of the one named (a rival, :func:`_rivals`) takes its place."""
    fits = read["fits"]
    for f in fits:
        judge(ident.problem, without, f, ident.nominal_budget, tried)
    if not all(f.accepted for f in fits):
        return ident
    return dataclasses.replace(ident, budget=ident.nominal_budget, accepted=fits, final=fits[-1].scored,
                               verdict="explained", discovery=None)


def validate(log, *, report=None, json_path=None, jobs: int = 2, progress: bool = False, notify=None,
             without: tuple[str, ...] = (), model: str = "platform") -> ValidationReport:
    """Identify (see :func:`hexsim.measured.identify.identify`) on ``log`` (a :class:`MeasurementLog` or the path of
    a log, ``docs/measurement-log.md``), then write the report folder ``report`` (report.md +
    residuals.png + validation.json) and/or the JSON file ``json_path``. Returns the JSON document
    (verdict, added effects, calibration, noise budget, errors before/after). ``without``: library
    effects left out of the candidates (listed in the JSON as ``left_out``); ``model``: the hexapod
    formulation a hexapod log is replayed on, ``"platform"`` (default) or ``"full"`` (the JSON's
    ``model``). Raises InputError for a log that cannot be read or replayed, an unknown ``model`` or a
    report folder that cannot be created."""
    if not isinstance(log, MeasurementLog):
        log = read_log(log)
    report = None if report is None else pathlib.Path(report)
    json_path = None if json_path is None or isinstance(json_path, StdoutTarget) else pathlib.Path(json_path)
    candidates = tuple(n for n in default_candidates(log) if n not in without)
    ident = identify(log, candidates=candidates, jobs=jobs, progress=progress, notify=notify, model=model)
    beyond = beyond_curve(log)
    if beyond is not None and ident.verdict in UNSETTLED:  # is it the curve the calibration never measured?
        ident = _on_the_curve_read(ident, beyond, candidates, jobs, notify)
    doc = summary(ident)
    doc.update(left_out=list(without), model=ident.problem.model)
    check = calibration_advice(ident, notify)
    if check is not None:
        doc["nominal_check"] = check.as_dict()
        if check.off and ident.verdict != "none":
            doc["conclusions"].insert(0, check.sentence)
    if beyond is not None:
        doc["beyond_calibrated_curve"] = beyond
        read = beyond.get("curve_read_from_log")
        if read is not None:
            doc["conclusions"].insert(0, read["sentence"])
        if ident.verdict != "none" or read is not None:
            doc["conclusions"].insert(0, beyond["sentence"])
    write_report(ident, doc, report, json_path)
    return doc
