"""``hexsim sweep``: a grid of runs (scenario, controller and compensator settings) in worker processes.

Each grid point is one :class:`~hexsim.engine.config.RunConfig`; the points run in ``jobs`` worker
processes (:func:`hexsim.engine.workers.worker_pool`: forked where the platform can, each with its own MuJoCo
model). Rows come back in grid order whatever order the workers finish in, and every run is seeded by
its configuration alone, so a sweep gives the same numbers with any number of workers and any start
method (tests/studies/test_sweep.py checks it against serial runs).
"""

from __future__ import annotations

import dataclasses
import itertools
import time
from concurrent.futures import as_completed
from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

from hexsim.control.scenario import make_scenario
from hexsim.engine.config import RunConfig
from hexsim.engine.runner import simulate
from hexsim.engine.workers import in_workers, worker_pool
from hexsim.errors import InputError
from hexsim.studies.comparison import final_window_start
from hexsim.studies.metrics import max_tracking_error, run_smoothness

#: Metric columns of a sweep row, after the grid's own columns. Wall times are printed, not tabled, so
#: the same sweep writes the same bytes.
METRICS = ("noise_ratio", "peak_noise_g", "peak_noise", "mean_reversal_peak", "max_reversal_peak",
           "final_noise_ratio", "final_mean_reversal_peak", "max_tracking_error_mm", "max_constraint_violation_mm",
           "valve_saturated_samples")


@dataclass(frozen=True)
class Point:
    """One grid point: its settings (name -> value, in grid order) and the run they define."""

    index: int
    settings: dict
    config: RunConfig


def expand(grid: dict[str, list], make_config) -> list[Point]:
    """The Cartesian product of ``grid`` (name -> values), first name slowest; ``make_config(settings)``
    builds the run of one point (raising :class:`~hexsim.errors.HexsimError` for a bad one, before
    anything runs)."""
    names = list(grid)
    points = []
    for i, values in enumerate(itertools.product(*(grid[n] for n in names))):
        settings = dict(zip(names, values))
        points.append(Point(i, settings, make_config(settings)))
    return points


def evaluate_point(config: RunConfig, result=None) -> dict:
    """Run one configuration (or take its ``result``) and reduce it to the :data:`METRICS` (runs in a
    worker process).

    Whole run: smoothness of the platform (or load) acceleration from the second period on; final: the
    last quarter of the run (at least two periods), where adaptive compensators have settled."""
    result = simulate(config) if result is None else result
    sc = config.scenario
    whole = run_smoothness(result)
    final = run_smoothness(result, t_start=final_window_start(sc.duration, sc.frequency))
    return {
        "noise_ratio": whole.noise_ratio,
        "peak_noise_g": whole.peak_noise_g,
        "peak_noise": whole.peak_noise,
        "mean_reversal_peak": whole.mean_reversal_peak,
        "max_reversal_peak": float(np.max(whole.reversal_peaks)) if whole.reversal_peaks.size else float("nan"),
        "final_noise_ratio": final.noise_ratio,
        "final_mean_reversal_peak": final.mean_reversal_peak,
        "max_tracking_error_mm": 1e3 * max_tracking_error(result),
        "max_constraint_violation_mm": 1e3 * float(np.max(result.constraint_violation)),
        "valve_saturated_samples": result.saturated_samples,
    }


def run_sweep(points: list[Point], jobs: int = 2, progress: bool = True,
              start_method: str | None = None, evaluate=evaluate_point) -> tuple[list[dict], float]:
    """Run every point with ``jobs`` worker processes (1: in this process) started by ``start_method``,
    or on the active Dask client's workers (see :func:`hexsim.engine.workers.worker_pool`). Returns the rows (grid settings + :data:`METRICS`, in
    grid order) and the wall time [s] of the whole sweep, start-up included. ``evaluate(config) -> dict``
    (a module-level function, sent to the workers) reduces a run; default the :data:`METRICS`. Raises
    InputError for a start method the platform does not have."""
    start = time.perf_counter()
    results: list[dict | None] = [None] * len(points)
    if not in_workers(jobs):
        bar = tqdm(total=len(points), unit="run", disable=not progress, leave=False)
        for p in points:
            results[p.index] = evaluate(p.config)
            bar.update()
    else:
        with worker_pool(jobs, start_method) as pool:
            futures = {pool.submit(evaluate, p.config): p.index for p in points}
            bar = tqdm(total=len(points), unit="run", disable=not progress, leave=False)
            for fut in as_completed(futures):
                results[futures[fut]] = fut.result()
                bar.update()
    bar.close()
    rows = [{"point": p.index, **p.settings, **{k: _finite_or_none(v) for k, v in results[p.index].items()}}
            for p in points]
    return rows, time.perf_counter() - start


#: The figures :func:`sweep_lines` shows of each point (all of :data:`METRICS` are in the CSV and JSON).
SHOWN = ("noise_ratio", "peak_noise_g", "mean_reversal_peak", "final_mean_reversal_peak", "max_tracking_error_mm")


def sweep_lines(rows: list[dict], grid: tuple[str, ...], simulated_s: float, wall_s: float, workers: int) -> list[str]:
    """What ``hexsim sweep`` prints of its ``rows`` (:func:`run_sweep`'s): one line per point (its number, the
    ``grid``'s settings and :data:`SHOWN`'s figures, 12 characters each) and the throughput: runs per minute and
    ``simulated_s`` [s] over ``wall_s`` [s] on ``workers`` worker(s)."""
    shown = ["point", *grid, *SHOWN]
    lines = ["  ".join(f"{c:>12.12s}" for c in shown)]
    lines += ["  ".join(f"{row[c]:>12.5g}" if isinstance(row[c], float) else f"{str(row[c]):>12.12s}" for c in shown)
              for row in rows]
    lines.append(f"{len(rows)} runs, {simulated_s:g} simulated s in {wall_s:.1f} s wall: {len(rows) / wall_s * 60:.1f} "
                 f"runs/min, {simulated_s / wall_s:.1f}× real time over {workers} worker(s)")
    return lines


def _finite_or_none(value):
    """NaN (a metric that does not exist, e.g. no reversal in the window) as None: empty in CSV, null in JSON."""
    return None if isinstance(value, float) and not np.isfinite(value) else value


#: What a Python sweep grid may vary, by where the name lives.
_SCENARIO_KEYS = ("duration", "amplitude", "frequency")


def vary(base: RunConfig, settings: dict) -> RunConfig:
    """``base`` with ``settings`` applied: a scenario name or keyword (``scenario``, ``duration``,
    ``amplitude``, ``frequency``: the scenario is rebuilt by :func:`hexsim.control.scenario.make_scenario`), a
    :class:`RunConfig` field (``machine``, ``compensator``, ``seed``, ``engine``, ``timestep``, …), a part of
    the machine (``hydraulics``, ``controller``, ``effects``) or a field of
    :class:`~hexsim.plant.params.HydraulicParams`, :class:`~hexsim.plant.params.ControllerParams`,
    :class:`~hexsim.plant.effects.Effects` or :class:`~compensation.CompensatorSettings` (on the machine
    ``machine`` names where it is varied too). Raises
    InputError naming an unknown setting."""
    if "machine" in settings:
        base = dataclasses.replace(base, machine=settings["machine"])
    sc_keys = {k: v for k, v in settings.items() if k in _SCENARIO_KEYS or k == "scenario"}
    changes: dict = {}
    if sc_keys:
        name = sc_keys.pop("scenario", base.scenario.name)
        kept = {} if "scenario" in settings else {"duration": base.scenario.duration,
                                                    "amplitude": base.scenario.amplitude,
                                                    "frequency": base.scenario.frequency}
        changes["scenario"] = make_scenario(name, **{**kept, **sc_keys})
    groups = {"hydraulics": base.hydraulics, "controller": base.controller, "effects": base.effects,
              "compensator_settings": base.compensator_settings}
    fields = {f.name for f in dataclasses.fields(RunConfig)}
    parts: dict = {}
    for key, value in settings.items():
        if key in _SCENARIO_KEYS or key in ("scenario", "machine"):
            continue
        if key in groups:  # a whole group (``effects=Effects(...)``)
            owner, groups[key] = key, value
        else:
            owner = next((g for g, obj in groups.items() if key in {f.name for f in dataclasses.fields(obj)}), None)
            if owner is None:
                if key not in fields:
                    raise InputError(f"sweep: {key!r} is not a scenario keyword, a RunConfig field or a parameter")
                changes[key] = value
                continue
            groups[owner] = dataclasses.replace(groups[owner], **{key: value})
        (changes if owner == "compensator_settings" else parts)[owner] = groups[owner]
    config = dataclasses.replace(base, **changes)
    return config.with_machine(**parts) if parts else config


def sweep(base: RunConfig, grid: dict[str, list], *, jobs: int = 2, progress: bool = False) -> list[dict]:
    """Every combination of ``grid`` (name -> values, see :func:`vary` for the names), run in ``jobs``
    worker processes; one row per point: its settings and the :data:`METRICS`, in grid order."""
    return run_sweep(expand(grid, lambda settings: vary(base, settings)), jobs=jobs, progress=progress)[0]
