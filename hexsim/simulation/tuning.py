"""``hexsim tune``: choose and tune the reversal-bump compensator for a machine, and the file it writes.

Given a machine (calibrated or built in) and the motions of interest, every candidate (the seed's
buffered and directional compensators at their defaults and at other buffer lengths, the model-based
feedforward at three loop filters, the adaptive feedforward at two adaptation times) runs each motion
through the sweep path (:func:`hexsim.simulation.sweeps.run_sweep`: worker processes, or Dask with a
scheduler), judged on the final window of each run (the last quarter, where the adaptive ones have
settled). The tuned compensator is the one whose worst motion has the smallest mean reversal peak
relative to the uncompensated machine; a candidate worse than none on any motion, or refused by its
model check, is never chosen.

The tuned file (JSON, :data:`FORMAT`) holds the compensator's name and settings and, for the model-based
ones, the leg model it inverts (:class:`compensation.model_based.LegModel`: per leg the flow curve table
u_v -> ẏ at the rest pressure, the friction table, the chamber's constants, the legs' inertia), plus the
predicted figures; ``hexsim run --compensator FILE`` loads it (the same U_c for the same inputs), and a
real motion computer can read the same tables (``docs/compensation.md``).
"""

from __future__ import annotations

import dataclasses
import pathlib
from dataclasses import dataclass

import numpy as np

from compensation import MODEL_BASED, NAMES, CompensatorSettings, SettingsError
from compensation.model_based import LegModel
from hexsim.errors import InputError
from hexsim.simulation.comparison import final_window_start
from hexsim.simulation.config import RunConfig
from hexsim.simulation.metrics import run_smoothness
from hexsim.simulation.sweeps import Point, evaluate_point, run_sweep
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
)


def leg_model_of(config: RunConfig) -> LegModel:
    """The leg model a model-based compensator gets on ``config``'s machine and scenario start (built from
    the machine file, :func:`hexsim.control.feedforward.leg_model`). Raises InputError for a machine whose
    inverse would give an extreme or unstable compensation (the reason named)."""
    from hexsim.simulation.runner import Simulator

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
    """The sweep's figures of one run (:func:`hexsim.simulation.sweeps.evaluate_point`) plus, for a
    hexapod, the bumps of the final window a seated occupant feels (:mod:`hexsim.simulation.perception`).
    Runs in a worker process."""
    from hexsim.simulation.perception import bump_perception
    from hexsim.simulation.runner import simulate

    result = simulate(config)
    row = evaluate_point(config, result)
    sc = config.scenario
    final = run_smoothness(result, t_start=final_window_start(sc.duration, sc.frequency))
    row["final_max_reversal_peak"] = float(np.max(final.reversal_peaks)) if final.reversal_peaks.size else None
    if sc.system == "hexapod":
        p = bump_perception(result, final).figures()
        row["felt"], row["reversals"] = p["perceptible"], p["reversals"]
        row["seat_peak_mps2"] = max(p["axes"][a]["seat_max_weighted_mps2"] or 0.0 for a in "xyz")
    return row


@dataclass(frozen=True)
class TuneResult:
    """Every candidate's rows (one per motion, :func:`evaluate_tuning`'s figures), the chosen candidate and
    the worst ratio of its final mean reversal peak to none's over the motions; ``refused``: candidates
    whose model the checks refused, with the reason; ``model``: the machine's leg model the model-based
    candidates ran on (None where it was refused)."""

    candidates: tuple[Candidate, ...]
    rows: dict[str, list[dict]]
    chosen: Candidate
    worst_ratio: float
    refused: dict[str, str]
    model: LegModel | None


def tune(base: RunConfig, motions: tuple[str, ...], *, jobs: int = 2, progress: bool = False) -> TuneResult:
    """Try every candidate on every motion (scenarios as on the command line, with ``base``'s duration
    where it has one) on ``base``'s machine and choose (module docstring). Raises InputError when no
    candidate improves on none."""
    candidates = tuple(Candidate(name, dataclasses.replace(base.compensator_settings, **changes))
                       for name, changes in CANDIDATES)
    refused: dict[str, str] = {}
    model = None
    try:
        model = leg_model_of(base)
    except InputError as exc:
        refused.update({c.label: str(exc) for c in candidates if c.compensator in MODEL_BASED})
    tried = [c for c in candidates if c.label not in refused]
    points = []
    for c in tried:
        for motion in motions:
            config = dataclasses.replace(base, scenario=_motion(base, motion), compensator=c.compensator,
                                         compensator_settings=c.settings, progress=False)
            points.append(Point(len(points), {"candidate": c.label, "motion": motion}, config))
    flat, _ = run_sweep(points, jobs=jobs, progress=progress, evaluate=evaluate_tuning)
    rows = {c.label: [r for r in flat if r["candidate"] == c.label] for c in tried}
    none = rows["none"]
    ratios = {label: max(_ratio(r, n) for r, n in zip(rs, none)) for label, rs in rows.items() if label != "none"}
    label = min(ratios, key=ratios.get)
    if not ratios[label] < 1.0:
        raise InputError("tune: no compensator makes the reversal bump smaller than none on these motions")
    return TuneResult(tuple(tried), rows, next(c for c in tried if c.label == label), ratios[label], refused, model)


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
           "predicted": {label: result.rows[label] for label in ("none", "buffered", chosen.label)}}
    if chosen.compensator in MODEL_BASED:
        doc["model"] = result.model.to_dict()
    write_json(path, doc)
    return doc


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


def tune_table(result: TuneResult) -> str:
    """none / the seed's buffered / the tuned compensator per motion: mean and max reversal peak of the
    final window, noise ratio, and the bumps felt where the perception model applies."""
    head = f"{'compensator':<34} {'motion':<9} {'mean rev. peak':>14} {'max rev. peak':>13} {'reduction':>9} " \
           f"{'noise ratio':>11} {'felt':>7}"
    lines = [head, "-" * len(head)]
    none = result.rows["none"]
    for label in dict.fromkeys(("none", "buffered", result.chosen.label)):
        for row, base in zip(result.rows[label], none):
            felt = f"{row['felt']}/{row['reversals']}" if "felt" in row else "—"
            red = 100.0 * (1.0 - _ratio(row, base))
            lines.append(f"{label:<34} {row['motion']:<9} {row['final_mean_reversal_peak']:>14.4f} "
                         f"{row['final_max_reversal_peak']:>13.4f} {red:>8.0f}% {row['final_noise_ratio']:>11.4f} {felt:>7}")
    return "\n".join(lines)

