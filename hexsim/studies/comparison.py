"""``hexsim compare``: every compensator on the same scenario, against ``none`` and the oracle.

Each compensator runs in its own worker process (one MuJoCo model per process: the control callback is
process-global). The league table is computed on the final window of each run (the last quarter, at
least two periods), where the adaptive compensators have settled; the settling time comes from the
whole run.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from compensation import COMPENSATORS
from hexsim.engine.config import RunConfig
from hexsim.engine.runner import simulate
from hexsim.engine.workers import in_workers, worker_pool
from hexsim.studies.metrics import Smoothness, run_smoothness
from hexsim.studies.perception import DEFAULT_THRESHOLDS, Thresholds, bump_perception

#: Order of the league table: the baseline first, the yardstick last.
ORDER = ("none", "iterative-1", "iterative-2", "buffered", "directional", "feedforward", "adaptive", "oracle")
SETTLE_BAND = 0.10  # "within 10 % of their final value"


def final_window_start(duration: float, frequency: float) -> float:
    """Start [s] of the final window: the last quarter of the run, at least two periods."""
    return duration - max(0.25 * duration, 2.0 / frequency)


def period_levels(sm: Smoothness, frequency: float) -> tuple[np.ndarray, np.ndarray]:
    """Reversal-peak level per drive period: (times [s], mean peak of the reversals in that period).

    A period holds one reversal of each direction, whose peaks differ (gravity helps one way, seed §4.2),
    so levels are compared period by period."""
    if sm.reversal_peaks.size < 2:
        return sm.reversal_times, sm.reversal_peaks
    n = sm.reversal_peaks.size // 2 * 2
    return sm.reversal_times[1:n:2], sm.reversal_peaks[:n].reshape(-1, 2).mean(axis=1)


def settling_time(times: np.ndarray, levels: np.ndarray, final: float) -> float | None:
    """First time [s] after which the period levels stay within ±10 % of ``final``; None if never.

    The levels are first averaged over three periods (centred): single reversal peaks scatter by about
    ±15 % with the default position noise, which alone would keep a 10 % band from ever holding."""
    if levels.size >= 3:
        levels = np.convolve(levels, np.ones(3) / 3, mode="same")
        levels[0], levels[-1] = levels[1], levels[-2]
    outside = np.flatnonzero(np.abs(levels - final) > SETTLE_BAND * final)
    if outside.size == 0:
        return float(times[0]) if times.size else None
    if outside[-1] == levels.size - 1:
        return None
    return float(times[outside[-1] + 1])


@dataclass
class Entry:
    """One compensator's figures and the (decimated) traces the comparison plot needs (leg 1)."""

    compensator: str
    noise_ratio: float
    peak_noise_g: float | None
    peak_noise: float
    mean_reversal_peak: float
    settling_time_s: float | None
    saturated_samples: int
    unit: str
    reduction_pct: float | None = None
    # the final window's bumps as the occupant senses them (hexapod only): perception.BumpPerception.figures()
    perception: dict | None = None
    final_parameters: dict[str, list[float]] = field(default_factory=dict)
    traces: dict[str, np.ndarray] = field(default_factory=dict, repr=False)

    def figures(self) -> dict:
        return {
            "compensator": self.compensator,
            "noise_ratio": self.noise_ratio,
            "peak_noise": self.peak_noise,
            "peak_noise_g": self.peak_noise_g,
            "mean_reversal_peak": self.mean_reversal_peak,
            "reversal_peak_reduction_pct": self.reduction_pct,
            "settling_time_s": self.settling_time_s,
            "valve_saturated_samples": self.saturated_samples,
            "final_parameters": self.final_parameters,
            "perception": self.perception,
        }


def evaluate(config: RunConfig, thresholds: Thresholds = DEFAULT_THRESHOLDS) -> Entry:
    """Run one configuration and reduce it to an :class:`Entry`, its bumps judged with the perception
    ``thresholds`` (runs in a worker process)."""
    result = simulate(config)
    sc = config.scenario
    t_final = final_window_start(sc.duration, sc.frequency)
    full = run_smoothness(result)
    final = run_smoothness(result, t_start=t_final)
    times, levels = period_levels(full, sc.frequency)
    in_final = times >= t_final
    final_level = float(levels[in_final].mean()) if np.any(in_final) else final.mean_reversal_peak
    step = max(1, result.t.size // 6000)
    s_est = result.compensator_state.get("s")
    traces = {
        "t": result.t[::step], "u_v": result.u_v[::step, 0], "u_c": result.u_c[::step, 0],
        "ydot": result.ydot[::step, 0],
        "peak_t": full.reversal_peak_times, "peaks": full.reversal_peaks,
        "acc_t": final.t, "acc": final.fit + final.noise, "acc_fit": final.fit,
    }
    for key, value in result.compensator_state.items():
        traces[f"param_{key}"] = value[::step, 0]
    if s_est is None:  # the chord of the flow curve, as the seed estimates s (§5.3)
        s_est = np.full((1, 1), np.ptp(result.ydot[:, 0]) / max(np.ptp(result.u_v[:, 0]), 1e-9))
    traces["s"] = float(s_est[-1, 0])
    perception = bump_perception(result, final, thresholds=thresholds).figures() if sc.system == "hexapod" else None
    return Entry(perception=perception,
        compensator=config.compensator_name, noise_ratio=final.noise_ratio, peak_noise_g=final.peak_noise_g,
        peak_noise=final.peak_noise, mean_reversal_peak=final.mean_reversal_peak,
        settling_time_s=settling_time(times, levels, final_level), saturated_samples=result.saturated_samples,
        unit=final.unit, final_parameters={k: v[-1].tolist() for k, v in result.compensator_state.items()},
        traces=traces,
    )


def compare(base: RunConfig, names: tuple[str, ...] = ORDER, jobs: int = 2,
            thresholds: Thresholds = DEFAULT_THRESHOLDS,
            labelled: tuple[tuple[str, RunConfig], ...] = ()) -> list[Entry]:
    """Run ``base`` once per compensator in ``names`` (``none`` is always included), then each of the
    ``labelled`` configurations (label, config: e.g. a tuned file's compensator with its settings and leg
    model, :func:`hexsim.studies.tuning.read_tuned`), with ``jobs`` worker processes; returns the entries
    in that order, labelled, with the reduction of the mean reversal peak vs none and, for a hexapod, the
    bumps felt with the perception ``thresholds``. Raises ValueError for an unknown name."""
    names = tuple(dict.fromkeys(("none", *names)))
    unknown = [n for n in names if n not in COMPENSATORS]
    if unknown:
        raise ValueError(f"unknown compensator {unknown[0]!r}; choose from {', '.join(COMPENSATORS)}")
    configs = [dataclasses.replace(base, compensator=n, progress=False) for n in names]
    configs += [dataclasses.replace(c, progress=False) for _, c in labelled]
    if not in_workers(jobs):
        entries = [evaluate(c, thresholds) for c in configs]
    else:
        with worker_pool(jobs) as pool:
            entries = list(pool.map(evaluate, configs, [thresholds] * len(configs)))
    for entry, (label, _) in zip(entries[len(names):], labelled):
        entry.compensator = label
    baseline = entries[0].mean_reversal_peak
    for e in entries:
        e.reduction_pct = 100.0 * (1.0 - e.mean_reversal_peak / baseline) if baseline > 0 else None
    return entries


def league_table(entries: list[Entry]) -> str:
    """The league table as aligned text."""
    unit = entries[0].unit
    felt = entries[0].perception is not None
    w = max(12, *(len(e.compensator) for e in entries))
    head = (f"{'compensator':<{w}} {'noise_ratio':>11} {'peak_noise':>14} {'mean rev. peak [' + unit + ']':>22} "
            f"{'reduction':>9} {'settled after':>13} {'saturated':>9}" + (f" {'felt (seat ratio)':>18}" if felt else ""))
    rows = [head, "-" * len(head)]
    for e in entries:
        peak = f"{e.peak_noise_g:.4f} g" if e.peak_noise_g is not None else f"{e.peak_noise:.3f} {unit}"
        red = f"{e.reduction_pct:.0f} %" if e.reduction_pct is not None else "—"
        settle = f"{e.settling_time_s:.1f} s" if e.settling_time_s is not None else "not settled"
        rows.append(f"{e.compensator:<{w}} {e.noise_ratio:>11.4f} {peak:>14} {e.mean_reversal_peak:>22.4f} "
                    f"{red:>9} {settle:>13} {e.saturated_samples:>9}" + (f" {_felt(e.perception):>18}" if felt else ""))
    rows.append("felt: bumps of the final window perceptible to a seated occupant (ISO 2631-1 at the seat or the "
                "vestibular models at the head) and the worst seat ratio to the threshold" if felt else "")
    return "\n".join(rows).rstrip()


def _felt(p: dict) -> str:
    """'n/R (ratio x)': the perceptible bumps of the final window and the largest seat ratio."""
    worst = max(p["axes"][a]["seat_max_ratio"] or 0.0 for a in "xyz")
    return f"{p['perceptible']}/{p['reversals']} ({worst:.2f}x)"
