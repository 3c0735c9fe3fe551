"""``hexsim tune``: choose and tune the reversal-bump compensator for a machine, and the file it writes.

Given a machine (calibrated or built in) and the motions of interest, every candidate (the seed's
buffered and directional compensators at their defaults and at other buffer lengths, the model-based
feedforward at three loop filters, the adaptive feedforward at two adaptation times and the slower one with
the 10 Hz loop filter) runs each motion
through the sweep path (:func:`hexsim.studies.sweeps.run_sweep`: worker processes, or Dask with a
scheduler), judged on the final window of each run (the last quarter, where the adaptive ones have
settled), on the machine as calibrated and on its :func:`neighbours` (a drifting null, the valve's edges a
tolerance off the file's, machines drawn from what the calibration leaves uncertain), the compensator keeping
the calibrated machine's leg model. The tuned compensator
is the one whose worst case (motion and neighbour) has the smallest mean reversal peak relative to the
uncompensated machine (ties within :data:`ROBUST_TIE` go to the best on the machine as calibrated); a
candidate that makes a single reversal worse than none's anywhere, or refused by its model check, is never
chosen. Where no candidate is left, a second round runs the model-based ones again stopping the neighbours'
dead-band tolerance short of each valve edge (``dead_band_margin``, :class:`compensation.CompensatorSettings`).

The tuned file (JSON, :data:`FORMAT`) holds the compensator's name and settings and, for the model-based
ones, the leg model it inverts (:class:`compensation.leg_model.LegModel`: per leg the flow curve table
u_v -> ẏ at the rest pressure, the friction table, the chamber's constants, the legs' inertia), plus the
predicted figures; ``hexsim run --compensator FILE`` loads it (the same U_c for the same inputs), and a
real motion computer can read the same tables (``docs/compensation.md``).
"""

from __future__ import annotations

import dataclasses
import pathlib
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from compensation import MODEL_BASED, NAMES, CompensatorSettings, SettingsError
from compensation.leg_model import LegModel
from hexsim.engine.config import RunConfig
from hexsim.errors import InputError
from hexsim.plant.machine import Machine
from hexsim.studies.comparison import final_window_start
from hexsim.studies.metrics import run_smoothness
from hexsim.studies.sweeps import Point, evaluate_point, run_sweep
from hexsim.tables import read_json_object, write_json

#: Version of the tuned-compensator file.
FORMAT = "hexsim-tuned/1"

#: The candidates: (compensator, settings changed from the defaults).
CANDIDATES = (
    ("none", {}),
    ("buffered", {}),
    ("buffered", {"buffer_time": 1.5}),
    ("buffered", {"buffer_time": 6.0}),
    ("directional", {}),
    ("feedforward", {"loop_filter_hz": 10.0}),
    ("feedforward", {}),
    ("feedforward", {"loop_filter_hz": 40.0}),
    ("adaptive", {}),
    ("adaptive", {"adapt_time": 1.0}),
    ("adaptive", {"adapt_time": 1.0, "loop_filter_hz": 10.0}),
)


def leg_model_of(config: RunConfig) -> LegModel:
    """The leg model a model-based compensator gets on ``config``'s machine and scenario start (built from
    the machine file, :func:`hexsim.control.feedforward.leg_model`). Raises InputError for a machine whose
    inverse would give an extreme or unstable compensation (the reason named)."""
    from hexsim.engine.runner import Simulator

    return Simulator(dataclasses.replace(config, compensator="feedforward", compensator_model=None)).compensator.model


@dataclass(frozen=True)
class Candidate:
    """One compensator and its settings, as tried and as written to a tuned file."""

    compensator: str
    settings: CompensatorSettings

    @property
    def label(self) -> str:
        changed = {f.name: getattr(self.settings, f.name) for f in dataclasses.fields(self.settings)
                   if getattr(self.settings, f.name) != getattr(CompensatorSettings(), f.name)}
        return self.compensator + "".join(f" {k}={v:g}" for k, v in changed.items())


def evaluate_tuning(config: RunConfig) -> dict:
    """The sweep's figures of one run (:func:`hexsim.studies.sweeps.evaluate_point`) plus, for a
    hexapod, the bumps of the final window a seated occupant feels (:mod:`hexsim.studies.perception`).
    Runs in a worker process."""
    from hexsim.engine.runner import simulate
    from hexsim.studies.perception import bump_perception

    result = simulate(config)
    row = evaluate_point(config, result)
    sc = config.scenario
    final = run_smoothness(result, t_start=final_window_start(sc.duration, sc.frequency))
    row["final_max_reversal_peak"] = float(np.max(final.reversal_peaks)) if final.reversal_peaks.size else None
    row["final_reversal_peaks"] = [float(v) for v in final.reversal_peaks]
    if sc.system == "hexapod":
        p = bump_perception(result, final).figures()
        row["felt"], row["reversals"] = p["perceptible"], p["reversals"]
        row["seat_peak_mps2"] = max(p["axes"][a]["seat_max_weighted_mps2"] or 0.0 for a in "xyz")
    return row


@dataclass(frozen=True)
class Neighbour:
    """A machine near the calibrated one that a tuned compensator must not fail on (module doc): ``name``,
    ``why`` (for the table), ``machine`` in place of the file's (one drawn from what its calibration leaves
    uncertain: :meth:`hexsim.measured.records.CalibrationRecord.plausible`), the valve's edges opening
    ``open_earlier_V`` [V] earlier than the file's (a dead band the calibration got wrong:
    :func:`hexsim.plant.hydraulics.as_curve`), the valve's null drifting ``null_rate`` [V/s] while the oil warms
    ``warm_k`` [K] over the run (:class:`hexsim.plant.temperature.WarmUp`). The compensator keeps the calibrated
    machine's leg model: only the machine moves."""

    name: str
    why: str
    open_earlier_V: float = 0.0
    null_rate: float = 0.0
    warm_k: float = 0.0
    machine: Machine | None = dataclasses.field(default=None, repr=False, compare=False)

    def apply(self, config: RunConfig) -> RunConfig:
        from hexsim.plant import hydraulics
        from hexsim.plant.temperature import WarmUp

        if self.machine is not None:
            config = dataclasses.replace(config, machine=self.machine)
        changes = {}
        if self.open_earlier_V:
            config = config.with_machine(hydraulics=hydraulics.as_curve(config.hydraulics, self.open_earlier_V))
        if self.warm_k:
            duration = config.scenario.duration
            changes["warm_up"] = WarmUp(self.warm_k, duration, null_drift=self.null_rate * duration / self.warm_k)
        return dataclasses.replace(config, **changes)


#: Default dead-band tolerance [V] of :func:`neighbours`: each valve edge opening this much earlier or later than
#: the file says. A proportional valve's overlap is held to about a micrometre of spool (some 10 mV of command
#: on the seed's valve, 1 mm of spool per 10 V); a calibration that read the curve from the logs' flows places
#: the edges to a few millivolts. Measured on the built-in actuator (12 s, ``python -m hexsim tune actuator``):
#: at 10 mV the fixed feedforward keeps about 60 % against none's bump on the worse side, at 25 mV it is worse
#: than none on an underlap: the dead band is what a model-based compensator must know best.
DEAD_BAND_TOLERANCE_V = 0.01


def neighbours(dead_band_V: float = DEAD_BAND_TOLERANCE_V, drawn: Sequence[Machine] = ()) -> tuple[Neighbour, ...]:
    """The machines :func:`tune` judges a candidate on (issue 53's "plausible neighbours"): the machine as
    calibrated; its valve's null drifting 1 mV/s while the oil warms 15 K over the run (seed §5.5's warm-up;
    proportional valves' zero point drifts about 1 % of the rated signal over tens of kelvin); for
    ``dead_band_V`` > 0 [V], each valve edge opening that much earlier (an underlap the calibration took for
    overlap) and later; and each of the ``drawn`` machines (the calibrated parameters moved by their standard
    errors: :meth:`hexsim.measured.records.CalibrationRecord.plausible`, the draws ``hexsim tune --check``
    predicts on). Raises InputError for a negative or non-finite tolerance, or one above 0.1 V."""
    if not (np.isfinite(dead_band_V) and 0.0 <= dead_band_V <= 0.1):
        raise InputError(f"tune: the dead-band tolerance must be between 0 and 0.1 V, got {dead_band_V!r}")
    out = [Neighbour("calibrated", "the machine file as calibrated"),
           Neighbour("drift", "null drifting 1 mV/s while the oil warms 15 K over the run", null_rate=1e-3, warm_k=15.0)]
    if dead_band_V > 0:
        mv = f"{1e3 * dead_band_V:g} mV"
        out += [Neighbour("underlap", f"each valve edge opening {mv} earlier than the file's", open_earlier_V=dead_band_V),
                Neighbour("overlap", f"each valve edge opening {mv} later than the file's", open_earlier_V=-dead_band_V)]
    out += [Neighbour(f"drawn{i}", "the calibrated parameters drawn from their standard errors and correlation",
                      machine=m) for i, m in enumerate(drawn, start=1)]
    return tuple(out)


NEIGHBOURS = neighbours()

#: Machines drawn from a calibrated file's uncertainty that ``hexsim tune`` judges every candidate on besides
#: :data:`NEIGHBOURS` (``--draws``): each adds a run per candidate and motion.
TUNE_DRAWS = 2

#: Candidates whose worst case is within this factor of the best one's are as robust as it (the neighbours'
#: figures are a few reversals each); among them the one best on the machine as calibrated is chosen.
ROBUST_TIE = 1.1


@dataclass(frozen=True)
class TuneResult:
    """Every candidate's rows (one per motion and neighbour, :func:`evaluate_tuning`'s figures with
    ``neighbour``; the second round's too, where :func:`tune` ran one), the chosen candidate, the worst ratio of
    its final mean reversal peak to none's over the motions and neighbours and where (``worst_at``: (motion,
    neighbour)); ``refused``: candidates whose model the checks refused, with the reason; ``worse``: candidates
    that made a reversal worse than none's on some motion and neighbour (never chosen), with where; ``model``:
    the machine's leg model the model-based candidates ran on (None where it was refused)."""

    candidates: tuple[Candidate, ...]
    rows: dict[str, list[dict]]
    chosen: Candidate
    worst_ratio: float
    refused: dict[str, str]
    model: LegModel | None
    worst_at: tuple[str, str] = ("", "")
    worse: dict[str, str] = dataclasses.field(default_factory=dict)
    neighbours: tuple[Neighbour, ...] = ()


def tune(base: RunConfig, motions: tuple[str, ...], *, jobs: int = 2, progress: bool = False,
         neighbours: tuple[Neighbour, ...] = NEIGHBOURS) -> TuneResult:
    """Try every candidate on every motion (scenarios as on the command line, with ``base``'s duration
    where it has one) on ``base``'s machine and each of its ``neighbours``, the model-based ones inverting the
    calibrated machine's leg model on all of them, and choose the best worst case (module docstring): among the
    candidates that make no single reversal worse than none's anywhere, those whose largest ratio of the final
    mean reversal peak to none's is within :data:`ROBUST_TIE` of the smallest, and of them the best on the
    machine as calibrated (the first neighbour). Where none is safe and the neighbours move the valve's edges, a
    second round tries the model-based candidates again stopping that far short of each edge
    (``dead_band_margin``: a dead band known to that tolerance is never jumped too far). Raises InputError when
    no candidate of either round is safe."""
    candidates = tuple(Candidate(name, dataclasses.replace(base.compensator_settings, **changes))
                       for name, changes in CANDIDATES)
    refused: dict[str, str] = {}
    model = None
    try:
        model = leg_model_of(base)
    except InputError as exc:
        refused.update({c.label: str(exc) for c in candidates if c.compensator in MODEL_BASED})
    tried = [c for c in candidates if c.label not in refused]
    rows = _rows(base, tried, motions, neighbours, model, jobs, progress)
    none = {(r["motion"], r["neighbour"]): r for r in rows["none"]}
    ratios, worse = _judged(rows, none)
    margin = max((n.open_earlier_V for n in neighbours), default=0.0)
    if not _any_safe(ratios, worse) and margin > 0 and model is not None:
        short = [Candidate(c.compensator, dataclasses.replace(c.settings, dead_band_margin=margin))
                 for c in tried if c.compensator in MODEL_BASED]
        rows.update(_rows(base, short, motions, neighbours, model, jobs, progress))
        tried += short
        ratios, worse = _judged(rows, none)
    safe = {label: v for label, v in ratios.items() if label not in worse}
    if not _any_safe(ratios, worse):
        raise InputError("tune: no compensator makes the reversal bump smaller than none on these motions and their "
                         f"neighbours without making a reversal worse somewhere: {_nearest(rows, none)} (a smaller "
                         "--dead-band-tolerance, if the valve's edges are known better, narrows the neighbours)")
    best = min(v[0] for v in safe.values())
    robust = [label for label, v in safe.items() if v[0] <= ROBUST_TIE * best]
    own = {label: max(_ratio(r, none[r["motion"], r["neighbour"]]) for r in rows[label]
                      if r["neighbour"] == neighbours[0].name) for label in robust}
    label = min(robust, key=lambda k: (own[k], safe[k]))
    return TuneResult(tuple(tried), rows, next(c for c in tried if c.label == label), safe[label][0], refused, model,
                      safe[label][1], worse, tuple(neighbours))


def _rows(base: RunConfig, candidates: list[Candidate], motions: tuple[str, ...], neighbours: tuple[Neighbour, ...],
          model: LegModel | None, jobs: int, progress: bool) -> dict[str, list[dict]]:
    """Each candidate's rows (:func:`evaluate_tuning`, one per motion and neighbour), run on the sweep path."""
    points = []
    for c in candidates:
        held = {"compensator_model": model} if c.compensator in MODEL_BASED else {}
        for motion in motions:
            for n in neighbours:
                config = n.apply(dataclasses.replace(base, scenario=_motion(base, motion), compensator=c.compensator,
                                                     compensator_settings=c.settings, progress=False, **held))
                points.append(Point(len(points), {"candidate": c.label, "motion": motion, "neighbour": n.name}, config))
    flat, _ = run_sweep(points, jobs=jobs, progress=progress, evaluate=evaluate_tuning)
    return {c.label: [r for r in flat if r["candidate"] == c.label] for c in candidates}


def _judged(rows: dict[str, list[dict]], none: dict) -> tuple[dict, dict]:
    """(label -> (the largest ratio of its final mean reversal peak to none's, where), label -> where it made a
    reversal worse than none's) over the candidates' ``rows`` but none's."""
    ratios, worse = {}, {}
    for label, rs in rows.items():
        if label == "none":
            continue
        ratios[label] = max((_ratio(r, none[r["motion"], r["neighbour"]]), (r["motion"], r["neighbour"])) for r in rs)
        bad = [(r["motion"], r["neighbour"]) for r in rs if _worst_reversal(r, none[r["motion"], r["neighbour"]]) >= 1.0]
        if bad:
            worse[label] = f"a reversal worse than none's on {bad[0][0]}, {bad[0][1]}"
    return ratios, worse


def _any_safe(ratios: dict, worse: dict) -> bool:
    """Whether a candidate makes the bump smaller than none's everywhere without a worse reversal anywhere."""
    return any(v[0] < 1.0 for label, v in ratios.items() if label not in worse)


def _nearest(rows: dict[str, list[dict]], none: dict) -> str:
    """What the candidate nearest to a safe one did (``rows`` per candidate label, ``none`` the uncompensated row per
    (motion, neighbour)): the one whose worst single reversal against none's is smallest, with its mean bump's range
    against none's over the motions and neighbours and where its worst reversal was."""
    worst = {label: max((_worst_reversal(r, none[r["motion"], r["neighbour"]]), r["motion"], r["neighbour"])
                        for r in rs) for label, rs in rows.items() if label != "none" and rs}
    if not worst:
        return "no candidate ran"
    label = min(worst, key=lambda k: worst[k][0])
    ratios = [_ratio(r, none[r["motion"], r["neighbour"]]) for r in rows[label]]
    w, motion, neighbour = worst[label]
    return (f"the nearest, {label}, takes the mean reversal bump to {min(ratios):.2f}-{max(ratios):.2f}x none's over "
            f"them, and one reversal to {w:.2f}x none's on {motion}, {neighbour}")


def _worst_reversal(row: dict, none: dict) -> float:
    """The largest ratio of one of the final window's reversal peaks to the same reversal's without compensation."""
    a, b = row.get("final_reversal_peaks") or [], none.get("final_reversal_peaks") or []
    n = min(len(a), len(b))
    return max((x / y for x, y in zip(a[:n], b[:n]) if y > 0), default=float("inf"))


def _motion(base: RunConfig, name: str):
    from hexsim.control.scenario import make_scenario

    sc = base.scenario
    return make_scenario(name, duration=sc.duration) if sc.duration else make_scenario(name)


def _ratio(row: dict, none: dict) -> float:
    """Final mean reversal peak over none's on the same motion (inf where either is missing)."""
    a, b = row.get("final_mean_reversal_peak"), none.get("final_mean_reversal_peak")
    return a / b if a is not None and b else float("inf")


def write_tuned(path: pathlib.Path, result: TuneResult, base: RunConfig, motions: tuple[str, ...]) -> dict:
    """Write the tuned file (:data:`FORMAT`): compensator, settings, the leg model for a model-based one,
    the machine, the motions and the predicted figures of none, the seed's buffered and the tuned one.
    Returns the document. Written whole or not at all (:func:`hexsim.tables.write_json`)."""
    chosen = result.chosen
    doc = {"format": FORMAT, "compensator": chosen.compensator, "settings": dataclasses.asdict(chosen.settings),
           "machine": base.machine_label, "motions": list(motions),
           "neighbours": {n.name: n.why for n in result.neighbours},
           "worst_case": {"ratio_to_none": result.worst_ratio, "motion": result.worst_at[0],
                          "neighbour": result.worst_at[1]},
           "predicted": {label: result.rows[label] for label in ("none", "buffered", chosen.label)}}
    if chosen.compensator in MODEL_BASED:
        doc["model"] = result.model.to_dict()
    write_json(path, doc)
    return doc


def compensator_options(spec: str) -> dict:
    """The RunConfig fields of a compensator given as a built-in's name or a tuned file (``*.json``,
    :func:`read_tuned`): ``compensator``, and for a file its ``compensator_settings`` and ``compensator_model``.
    Raises InputError as :func:`read_tuned`."""
    if not spec.endswith(".json"):
        return {"compensator": spec}
    name, settings, model = read_tuned(spec)
    return {"compensator": name, "compensator_settings": settings, "compensator_model": model}


def read_tuned(path: str | pathlib.Path) -> tuple[str, CompensatorSettings, LegModel | None]:
    """(compensator name, its settings, its leg model or None) of a tuned file. Raises InputError naming
    the file and what is wrong (unreadable, not a tuned file, an unknown compensator or setting, a model
    the checks refuse)."""
    path = pathlib.Path(path)
    doc = read_json_object(path, "a tuned compensator")
    if doc.get("format") != FORMAT:
        raise InputError(f"{path}: not a tuned compensator file (format must be {FORMAT!r})")
    name = doc.get("compensator")
    if name not in NAMES or name == "oracle":
        raise InputError(f"{path}: compensator {name!r} is not one a file can hold")
    known = {f.name for f in dataclasses.fields(CompensatorSettings)}
    settings = doc.get("settings", {})
    if not isinstance(settings, dict) or set(settings) - known:
        raise InputError(f"{path}: settings: unknown {sorted(set(settings) - known) if isinstance(settings, dict) else settings!r}")
    try:
        model = LegModel.from_dict(doc["model"], "model") if name in MODEL_BASED else None
        return name, CompensatorSettings(**settings), model
    except KeyError:
        raise InputError(f"{path}: the {name} compensator needs its 'model'") from None
    except (SettingsError, TypeError) as exc:
        raise InputError(f"{path}: {exc}") from None


def predict(base: RunConfig, name: str, settings: CompensatorSettings, model: LegModel | None,
            motions: tuple[str, ...], *, jobs: int = 2) -> dict[str, list[dict]]:
    """The predicted figures (:func:`evaluate_tuning`) of none and of the compensator ``name`` with ``settings``
    (and its leg ``model``) on each of ``motions`` on ``base``'s machine: label -> rows, as a tuned file's
    ``predicted``."""
    chosen = Candidate(name, settings)
    points = []
    for label, comp, options in (("none", "none", {}), (chosen.label, name, {"compensator_settings": settings,
                                                                            "compensator_model": model})):
        for motion in motions:
            config = dataclasses.replace(base, scenario=_motion(base, motion), compensator=comp, progress=False,
                                         **options)
            points.append(Point(len(points), {"candidate": label, "motion": motion}, config))
    flat, _ = run_sweep(points, jobs=jobs, progress=False, evaluate=evaluate_tuning)
    labels = dict.fromkeys(p.settings["candidate"] for p in points)
    return {label: [r for r in flat if r["candidate"] == label] for label in labels}


def retuned(path: str | pathlib.Path, base: RunConfig, model: LegModel, commissioning: dict, *,
            jobs: int = 2) -> dict:
    """The tuned file at ``path`` with its leg model replaced by ``model`` (built from ``base``'s machine, e.g.
    after :func:`hexsim.measured.commissioning.commission`), its predicted figures those of the new model on
    its motions (:func:`predict`), the machine ``base``'s and ``commissioning`` (what was learned, from which
    logs) recorded. Returns the document (not written). Raises InputError as :func:`read_tuned`, and for a
    tuned compensator that holds no leg model (the seed's: nothing to improve from logs)."""
    name, settings, old = read_tuned(path)
    if old is None:
        raise InputError(f"{path}: the {name} compensator holds no leg model; commissioning improves a model-based "
                         f"one (feedforward, adaptive): tune again")
    doc = read_json_object(pathlib.Path(path), "a tuned compensator")
    motions = tuple(doc.get("motions") or ("actuator",))
    doc.update(model=model.to_dict(), machine=base.machine_label,
               predicted=predict(base, name, settings, model, motions, jobs=jobs),
               commissioning=[*doc.get("commissioning", []), commissioning])
    return doc


def tune_table(result: TuneResult) -> str:
    """none / the seed's buffered / the tuned compensator per motion and neighbour: mean and max reversal peak
    of the final window, the reduction against none, the worst single reversal's ratio to none's, and the bumps
    felt where the perception model applies."""
    shown = [k for k in dict.fromkeys(("none", "buffered", result.chosen.label)) if k in result.rows]
    w = max(34, *map(len, shown))
    head = f"{'compensator':<{w}} {'motion':<9} {'neighbour':<10} {'mean rev. peak':>14} {'max rev. peak':>13} " \
           f"{'reduction':>9} {'worst rev.':>10} {'felt':>7}"
    lines = [head, "-" * len(head)]
    none = result.rows["none"]
    for label in shown:
        for row, base in zip(result.rows[label], none):
            felt = f"{row['felt']}/{row['reversals']}" if "felt" in row else "—"
            red = 100.0 * (1.0 - _ratio(row, base))
            lines.append(f"{label:<{w}} {row['motion']:<9} {row.get('neighbour', ''):<10} "
                         f"{row['final_mean_reversal_peak']:>14.4f} {row['final_max_reversal_peak']:>13.4f} "
                         f"{red:>8.0f}% {_worst_reversal(row, base):>10.2f} {felt:>7}")
    return "\n".join(lines)


def tune_lines(result: TuneResult, neighbours_scored) -> list[str]:
    """What ``hexsim tune`` says of ``result``: the candidates refused and not chosen with the reason, the
    table (:func:`tune_table`) and the choice with its worst case among ``neighbours_scored`` (the
    :func:`neighbours` it was scored on)."""
    lines = [f"refused {label}: {why}" for label, why in result.refused.items()]
    lines += [f"not chosen {label}: {why}" for label, why in result.worse.items()]
    margins = {c.settings.dead_band_margin for c in result.candidates}
    if len(margins) > 1:
        lines.append(f"no candidate of the first round was safe: the model-based ones ran again stopping "
                     f"{1e3 * max(margins):g} mV short of each valve edge (dead_band_margin)")
    lines.append(tune_table(result))
    motion, neighbour = result.worst_at
    lines.append(f"tuned: {result.chosen.label} (worst case {100 * (1 - result.worst_ratio):.0f} % below none, on "
                 f"{motion}, {neighbour}; neighbours: {', '.join(n.name for n in neighbours_scored)})")
    return lines
