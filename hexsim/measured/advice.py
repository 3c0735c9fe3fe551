"""What ``hexsim validate`` says first of a machine that was never calibrated: whether its nominal is off the log,
and what a calibration on that log alone moves (:class:`CalibrationAdvice`; docs/validation.md)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from hexsim.errors import InputError, PhysicsError
from hexsim.measured.calibration import calibrate
from hexsim.measured.estimates import AT_A_BOUND, HELD
from hexsim.measured.measurement import MeasurementLog
from hexsim.measured.steady import axis_load, feature_errors, features, predict

#: A nominal this far off a log's steady motions is "visibly off": validate says to calibrate first.
OFF_SPEED, OFF_PRESSURE = 0.03, 1e5


@dataclass(frozen=True)
class CalibrationAdvice:
    """What ``hexsim validate`` says of an uncalibrated machine's nominal before any effect: whether it is
    ``off`` the log, the ``sentence`` put first among the conclusions ("calibrate first"; empty when there is
    nothing to say), the parameters a calibration on this log alone ``moved`` (key, prior, value, std_error,
    unit, status) and the check's own figures (``figures``: steady speed and pressure errors, or the held-out
    RMS in budgets before and after). :meth:`as_dict` is the validation JSON's ``nominal_check``."""

    off: bool
    sentence: str = ""
    moved: tuple[dict, ...] = ()
    figures: dict = dataclasses.field(default_factory=dict)

    def as_dict(self) -> dict:
        return {"off": self.off, **self.figures} | ({"moved": list(self.moved), "sentence": self.sentence}
                                                   if self.sentence else {})


def nominal_check(log: MeasurementLog) -> CalibrationAdvice | None:
    """How far an uncalibrated machine is from an open-loop constant-command log's steady motions (the
    advice's figures: :func:`hexsim.measured.steady.feature_errors`), and, if visibly off (speeds beyond :data:`OFF_SPEED` or pressures
    beyond :data:`OFF_PRESSURE` [Pa]), which parameters a calibration on this log alone moves beyond two
    standard errors and 5 % of their bracket, in the sentence ``hexsim validate`` puts first ("calibrate
    first"). None for a machine that was calibrated, or a log without a steady motion."""
    if log.machine.calibration is not None or log.system != "single-actuator" or "valve_cmd_V" not in log.columns:
        return None
    try:
        feats = features(log)
    except InputError:
        return None
    loads = {log.path.name: axis_load(log)}
    err = feature_errors(feats, predict(feats, log.machine, loads))
    off = (err["speed_error_max"] or 0.0) > OFF_SPEED or (err["pressure_error_max_Pa"] or 0.0) > OFF_PRESSURE
    if not off:
        return CalibrationAdvice(False, figures=err)
    report = calibrate([log], log.machine, cross_validate=False, dynamics="never").report
    moved = _moved(report)
    what = []
    if err["speed_error_max"]:
        what.append(f"speeds up to {err['speed_error_max']:.1%} off")
    if err["pressure_error_max_Pa"]:
        what.append(f"pressures up to {err['pressure_error_max_Pa'] / 1e5:.2f} bar off")
    changes = _changes(moved)
    return CalibrationAdvice(True, f"The machine's nominal is visibly off this log's steady motions ({', '.join(what)}): "
                             f"calibrate first (hexsim calibrate, docs/calibration.md), then judge effects on the "
                             f"calibrated machine" + (f"; a calibration on this log alone moves {changes}" if changes
                                                      else "") + ".", tuple(moved), err)


def _moved(report: dict) -> list[dict]:
    """The parameters a calibration moved beyond two standard errors and 5 % of their bracket."""
    return [{k: r[k] for k in ("key", "prior", "value", "std_error", "unit", "status")} for r in report["parameters"]
            if r["status"] != HELD
            and abs(r["value"] - r["prior"]) > max(2.0 * r["std_error"], 0.05 * (r["upper"] - r["lower"]))]


def _changes(moved: list[dict]) -> str:
    return ", ".join(f"{r['key']} {r['prior']:.4g} → {r['value']:.4g} {r['unit']}"
                     + (" (at a bound)" if r["status"] == AT_A_BOUND else "") for r in moved)


def transient_check(log: MeasurementLog, evidence=None) -> CalibrationAdvice | None:
    """For a log that is no constant-command experiment, judged against a machine that was never calibrated:
    what a calibration from this log's own transients (:mod:`hexsim.measured.dynamics`, the machine's own
    flow-area form) moves and how far it brings the held-out windows, as the sentence ``hexsim validate``
    puts first when its verdict is not ``none``: the nominal may be what is off, not an effect. ``evidence``:
    the log's replay already built (:meth:`hexsim.measured.dynamics.ReplayEvidence.of_problem` on a
    validation's problem and nominal budget), else built here. None for a calibrated machine, a hexapod
    log, or a log the replay cannot use."""
    if log.machine.calibration is not None or log.system != "single-actuator":
        return None
    try:
        report = calibrate([log], log.machine, flow_areas=(log.machine.hydraulics.flow_area,),
                           cross_validate=False, dynamics="always", evidence=(evidence,) if evidence else ()).report
    except (InputError, PhysicsError):  # a log the replay cannot use: validate's own answer stands alone
        return None
    before = report["transients"][0]["before"]["held_out_rms_in_budgets"]
    after = report["transients"][0]["after"]["held_out_rms_in_budgets"]
    moved = _moved(report)
    worst = max(before, key=lambda ch: before[ch])
    sentence = (f"This machine was never calibrated, and a calibration of its nominal from this log's own transients "
                f"brings the held-out {worst} from {before[worst]:.3g} to {after[worst]:.3g} budgets"
                + (f", moving {_changes(moved)}" if moved else "") + ": calibrate on calibration experiments of the "
                "machine first (hexsim calibrate, docs/calibration.md), then judge effects on the calibrated machine; "
                "an effect found on the uncalibrated file may be the nominal's error.")
    return CalibrationAdvice(bool(moved), sentence, tuple(moved),
                             {"held_out_rms_in_budgets": {"before": before, "after": after}})


def hexapod_hint(log: MeasurementLog) -> CalibrationAdvice:
    """For a hexapod log judged against a machine that was never calibrated: the sentence ``hexsim validate``
    puts first when its verdict is not ``none``. Not measured (a hexapod's calibration takes minutes,
    :func:`calibrate`): six valves each within their data sheet's tolerance, a payload and the oil are
    the first suspects of a replay that misses on every leg."""
    return CalibrationAdvice(True, (
        f"The machine {log.machine.label} was never calibrated: each leg's valve (its edges' flow gains within a "
        f"data sheet's ±10 %), the oil's bulk modulus, the seals' friction and the payload may be what is off, not an "
        f"effect. Calibrate it first on a closed-loop log of the machine (hexsim calibrate LOG --out CAL.json, "
        f"docs/calibration.md), then judge effects with --machine CAL.json."))
