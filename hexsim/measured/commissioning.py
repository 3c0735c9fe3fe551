"""Commissioning: the machine's own logs, run with the tuned compensator, taken back into its model, and a
tuned file improved from them (``hexsim tune --from-logs``; docs/compensation.md).

A calibration sees the valve where its experiments drove it: a chirp dwells at small commands, a step passes
through the rest in a few milliseconds. The motions the compensator is tuned for cross the valve's curve
elsewhere, slowly, over and over (a 50 mm, 0.5 Hz sine crosses a port-limited spool's corner at 0.9 V four
times a period), and every log of the machine running them measures the valve's flow there. So commissioning
is run, log, learn, run again: each edge's curve is read again from the flows of the commissioning logs and of
the calibration's own logs (the calibrated file names them; :func:`hexsim.measured.flow_curve.fit_flow_curves`,
held to the calibrated machine's openings where the flows say little: near null, which a compensated run jumps),
the machine file takes the curves (flow area ``curve``: :func:`hexsim.measured.curves.curve_machine`) — unless
the calibrated valve is a rounded edge whose few parameters, refitted to the same flows, predict their held-out
windows as well (:mod:`hexsim.measured.form_refit`: a knot grid rounds the corner the form has sharp) — and the
tuned file's leg model (:class:`compensation.leg_model.LegModel`) is built again from that machine, its
compensator and settings kept; the predicted figures are those of the new model. A user runs it on the machine
at most three times (docs/compensation.md: measured on machines hexsim did not write).
"""

from __future__ import annotations

import dataclasses
import pathlib
from dataclasses import dataclass

from compensation.leg_model import LegModel
from hexsim.errors import InputError
from hexsim.measured.curves import curve_machine, curve_report
from hexsim.measured.flow_curve import FlowCurves, held_out_ms
from hexsim.measured.form_refit import REFITTED_FORMS, RefitForm, refit_form
from hexsim.measured.measurement import MeasurementLog, read_log
from hexsim.measured.null_drift import NullDrift, drifts_taken_out
from hexsim.plant.machine import Machine


@dataclass(frozen=True)
class Commissioning:
    """What :func:`commission` learned: the ``machine`` with each edge's curve read from the ``logs`` (the
    commissioning logs, then the calibration's own that were found), or with its flow-area form's parameters
    refitted where that predicts them as well (``form``, the refit, kept or not; None for a machine whose valve is
    a curve or a table), the :class:`FlowCurves`, the leg ``model`` a model-based compensator inverts on it,
    ``curved``: the machine with the curves, taken or not (None: ``machine`` is it), and each commissioning log's
    null ``drifts`` (:class:`hexsim.measured.null_drift.NullDrift`: taken out of its commands before the curves
    were read where one was found)."""

    machine: Machine
    curves: FlowCurves
    logs: tuple[str, ...]
    model: LegModel
    form: RefitForm | None = None
    curved: Machine | None = None
    drifts: tuple[NullDrift, ...] = ()

    @property
    def kept_form(self) -> bool:
        """Whether the machine kept its flow-area form (refitted) rather than the curves."""
        return self.form is not None and self.machine.hydraulics.flow_area != "curve"

    def form_summary(self) -> dict | None:
        """The form's refit as the report gives it (:meth:`report`'s ``form``); None without one."""
        if self.form is None:
            return None
        ms, _ = held_out_ms(self.curves)
        return {"flow_area": self.form.machine.hydraulics.flow_area, "kept": self.kept_form,
                "refitted": self.form.keys, "held_out_flow_rms_m3": self.form.held_out ** 0.5,
                "curves_held_out_flow_rms_m3": ms ** 0.5}

    def report(self) -> dict:
        """The tuned file's ``commissioning`` entry: the logs read, the curves (:func:`hexsim.measured.curves.
        curve_report`, the points as the curve's machine would hold them) and the form's refit: its parameters and
        both readings' held-out flow error (rms [m^3] over 10 ms intervals)."""
        out = {"logs": list(self.logs), "curves": curve_report(self.curves, "calibrated", self.curved or self.machine)}
        if self.form is not None:
            out["form"] = self.form_summary()
        if self.drifts:
            out["null_drift"] = [d.record() for d in self.drifts]
        return out


def calibration_logs(machine: Machine) -> list[pathlib.Path]:
    """The logs ``machine``'s calibration was fitted to (its file's ``calibration`` block), those that still
    exist (relative paths as the calibration wrote them, else beside the machine file); none for a machine that
    was not calibrated."""
    found = []
    for name in (machine.calibration or {}).get("logs", []):
        for path in (pathlib.Path(name), *([machine.path.parent / pathlib.Path(name).name] if machine.path else [])):
            if path.exists():
                found.append(path)
                break
    return found


def commission(paths: list[pathlib.Path], machine: Machine, *, own_logs: bool = True) -> Commissioning:
    """Read the valve's curves from the logs ``paths`` (single-actuator logs of ``machine`` running, the tuned
    compensator among them) and, with ``own_logs``, the calibration's own (:func:`calibration_logs`), on
    ``machine``; the machine with them and its leg model. A run whose valve null drifted during it (the oil warming)
    is read with the drift taken out of its commands (:func:`hexsim.measured.null_drift.drifts_taken_out`). Raises
    InputError naming the log for a hexapod log, one without the valve command, position or ``p1_Pa``, or too few
    samples away from the stroke's ends."""
    from hexsim.engine.config import RunConfig
    from hexsim.studies.tuning import leg_model_of

    if machine.system != "single-actuator":
        raise InputError(f"{machine.label}: commissioning from logs reads a single actuator's valve (this machine is "
                         f"a {machine.system}); tune each leg's file, or calibrate the hexapod again on its logs")
    extra = [p for p in calibration_logs(machine) if p.resolve() not in {q.resolve() for q in paths}] if own_logs else []
    logs: list[MeasurementLog] = [read_log(p, machine=machine) for p in (*paths, *extra)]
    for log in logs:
        if log.system != "single-actuator":
            raise InputError(f"{log.path}: commissioning reads single-actuator logs (this is {log.system})")
    runs, drifts, curves = drifts_taken_out(logs[:len(paths)], logs[len(paths):], machine)
    logs = [*runs, *logs[len(paths):]]  # the runs' commands less their null's drift where one was found
    curved = curve_machine(machine, curves)
    form = refit_form(logs, machine) if machine.hydraulics.flow_area in REFITTED_FORMS else None
    # the form unless the curves predict the held-out windows better by one standard error
    new = form.machine if form is not None and form.held_out <= sum(held_out_ms(curves)) else curved
    new = dataclasses.replace(new, description=(machine.description + " Commissioned by hexsim tune --from-logs.").strip())
    model = leg_model_of(RunConfig.from_machine(new, "actuator"))
    return Commissioning(new, curves, tuple(str(log.path) for log in logs), model, form, curved, tuple(drifts))
