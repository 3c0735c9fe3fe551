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

import numpy as np

from compensation.leg_model import LegModel
from hexsim.errors import InputError
from hexsim.measured.curves import curve_machine, curve_report
from hexsim.measured.flow_curve import FlowCurves, held_out_ms
from hexsim.measured.form_refit import REFITTED_FORMS, RefitForm, refit_form
from hexsim.measured.measurement import MeasurementLog, read_log
from hexsim.measured.null_drift import NullDrift, drifts_taken_out
from hexsim.measured.proof import RunFigures, run_figures
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


#: Relative margin by which a file's runs must measure worse than another's (felt seat peak, then reversal peak)
#: to be called worse: run-to-run scatter of the same file on the proof's machines is 5-10 %.
WORSE_MARGIN = 0.1
#: Standard deviations of the period averages' noise a reversal peak must exceed another's by as well.
WORSE_SIGMAS = 3.0


def felt(figures: RunFigures) -> float:
    """The seat peak as the passenger tells files apart: its multiple of the perception threshold, 1 below it (a
    cue not felt is not felt less)."""
    return max(figures.seat_ratio, 1.0)


def worse(runs: list[RunFigures], than: list[RunFigures]) -> str | None:
    """Why ``runs`` (one file's on the machine) measured worse than ``than`` (another file's), on the runs of the
    same motion (:meth:`RunFigures.same_motion`), or None (not worse, or nothing to compare): its felt seat peak
    (:func:`felt`) above the other's by ``WORSE_MARGIN``, or the same felt and its reversal peak above by the
    margin and ``WORSE_SIGMAS`` of the averages' noise."""
    a = [r for r in runs if any(r.same_motion(s) for s in than)]
    b = [s for s in than if any(s.same_motion(r) for r in runs)]
    if not a or not b:
        return None
    fa, fb = np.mean([felt(r) for r in a]), np.mean([felt(s) for s in b])
    seat = (f"the seat peak {np.mean([r.seat_ratio for r in a]):.2f}× the threshold against "
            f"{np.mean([s.seat_ratio for s in b]):.2f}×")
    if fa > fb * (1.0 + WORSE_MARGIN):
        return seat
    if fa * (1.0 + WORSE_MARGIN) < fb:
        return None
    ra, rb = np.mean([r.reversal_peak for r in a]), np.mean([s.reversal_peak for s in b])
    noise = np.hypot(np.mean([r.noise for r in a]), np.mean([s.noise for s in b]))
    if ra > rb * (1.0 + WORSE_MARGIN) + WORSE_SIGMAS * noise:
        return f"the reversal peak {ra:.4f} m/s² against {rb:.4f} ({seat})"
    return None


#: The keys of a tuned file that make the compensator it loads (what a commissioning that keeps an earlier file
#: restores).
FILE_KEYS = ("compensator", "settings", "model", "machine", "predicted")


@dataclass(frozen=True)
class RanFile:
    """A tuned file as it ran on the machine: ``name`` (the path it was run from), ``keys`` (its
    ``FILE_KEYS``) and the :class:`RunFigures` of its ``runs``."""

    name: str
    keys: dict
    runs: tuple[RunFigures, ...]


def files_run(doc: dict) -> list[RanFile]:
    """The files a tuned document's commissionings recorded as run on the machine, in order. Raises InputError for
    an entry whose runs are not figures."""
    found = []
    for entry in doc.get("commissioning") or []:
        if isinstance(entry, dict) and isinstance(entry.get("ran"), dict):
            try:
                runs = tuple(RunFigures(**r) for r in entry.get("runs", []))
            except TypeError:
                raise InputError(f"the tuned file's commissioning runs are not a run's figures: "
                                 f"{entry.get('runs')!r}") from None
            found.append(RanFile(str(entry.get("ran_file", "")), entry["ran"], runs))
    return found


def best_of(files: list[RanFile]) -> RanFile | None:
    """The file whose runs measured best (none measured worse than it: :func:`worse`; the earlier on a tie)."""
    best = None
    for f in files:
        if not f.runs:
            continue
        if best is None or worse(best.runs, f.runs):
            best = f
    return best


@dataclass(frozen=True)
class CommissioningStep:
    """One ``hexsim tune --from-logs``: the improved tuned file's document (``doc``, not written), what the logs
    taught the model (``learned``), the figures of the runs the tuned file ran (``runs``), the logs not judged and
    why (``unjudged``), and ``kept``: None when the file holds the model learned, else {"file": the file kept,
    "because": why}."""

    doc: dict
    learned: Commissioning
    runs: tuple[RunFigures, ...]
    unjudged: tuple[tuple[str, str], ...]
    kept: dict | None


def commissioning_step(paths: list[pathlib.Path], tuned: pathlib.Path, machine: Machine, *,
                       jobs: int = 2) -> CommissioningStep:
    """Run, log, learn, run again, one step: the logs ``paths`` (the runs so far, the tuned file's newest among
    them) taken into ``machine``'s model (:func:`commission`), and the tuned file at ``tuned`` improved from it —
    unless the machine measured the file worse than one run before it.

    The runs the tuned file made are the logs no earlier commissioning of it read (nor the calibration); each is
    measured as its passenger gets it with the accelerometer's noise averaged out
    (:func:`hexsim.measured.proof.run_figures`) and recorded in the file's ``commissioning`` entry with the file
    that ran it. A model learned from logs is better on average, not on every machine: where the file's runs
    measured worse (:func:`worse`) than the best file run before it, the improved file keeps that one's compensator
    and model (``kept``), and once that has happened commissioning has converged: later steps keep the file the
    machine ran best. Otherwise the file takes the leg model learned
    (:func:`hexsim.studies.tuning.retuned`). Raises InputError as :func:`commission` and
    :func:`hexsim.studies.tuning.read_tuned`."""
    from hexsim.engine.config import RunConfig
    from hexsim.studies.tuning import read_tuned, retuned
    from hexsim.tables import read_json_object

    read_tuned(tuned)  # refused before the work: a file that holds no leg model, or is not a tuned file
    doc = read_json_object(tuned, "a tuned compensator")
    entries = [e for e in doc.get("commissioning") or [] if isinstance(e, dict)]
    seen = {pathlib.Path(p).resolve() for e in entries for p in e.get("logs", [])}
    seen |= {p.resolve() for p in calibration_logs(machine)}
    runs, unjudged = [], []
    for path in paths:
        if path.resolve() in seen:
            continue
        try:
            runs.append(run_figures(path, machine))
        except InputError as exc:
            unjudged.append((str(path), str(exc)))
    earlier = files_run(doc)
    ran = {key: doc[key] for key in FILE_KEYS if key in doc}
    learned = commission(paths, machine)
    entry = {**learned.report(), "ran_file": str(tuned), "ran": ran, "runs": [r.record() for r in runs]}
    best = best_of(earlier)
    why = worse(runs, best.runs) if best is not None and runs else None
    if why is not None:
        kept = {"file": best.name, "because": f"{pathlib.Path(str(tuned)).name} ran worse on the machine: {why}"}
        new = {**{k: v for k, v in doc.items() if k not in FILE_KEYS}, **best.keys}  # nothing of the worse file's
    elif any(e.get("kept") for e in entries):
        kept = {"file": str(tuned), "because": "an earlier step found a commissioned file worse than the one before "
                                               "it: commissioning has converged on the file the machine ran best"}
        new = dict(doc)
    else:
        kept = None
        base = RunConfig.from_machine(learned.machine, "actuator")
        new = retuned(tuned, base, learned.model, entry, jobs=jobs)
    if kept is not None:
        entry["kept"] = kept
        new["commissioning"] = [*entries, entry]
    return CommissioningStep(new, learned, tuple(runs), tuple(unjudged), kept)
