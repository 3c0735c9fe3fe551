"""When a log's sensors were read: the acquisition's timing, read from the logs' transients.

A replay compares its model with the log row by row, and a row's state must be the model's at the instant the
sensors were read. hexsim's own logs read the position and pressures at the instant their row's valve command
takes effect, and the accelerometer as its mean over the interval before the row (a boxcar anti-alias filter).
A real controller's log need not: its converters may read the sensors a fraction of a sample after the command
went out, the command may reach the valve a while after the sensors were read (an output latency), and an
accelerometer may be sampled at an instant. None of it matters on a slow motion; all of it matters where the
valve moves fast. At a 10 V step of the reference plant R1 (``../shared/reference-plants``) P1 moves 18 bar in
the first 0.1 ms and the oil spring rings at 100 Hz: R1's logs read the state one 0.1 ms integration step after
the command and the accelerometer at the command's instant, so a replay sampled as hexsim's own logs missed
each step by 18 bar and the ringing by a third, its step log stayed 15 budgets off on P1 and 6 on the
acceleration, and the calibration took the early pressure rise for a stiffer oil (2.1 GPa at its bound for a
true 1.3).

:func:`fit_timing` reads the timing from one replay per log at a machine's parameters, the channels recorded at
every physics step (:func:`hexsim.measured.replay.replay`, ``fine``), then sampled at every candidate
(:func:`hexsim.measured.replay.sampled`) and judged in the log's noise budgets with the sensors' offsets and
scales fitted (:func:`hexsim.measured.scoring.residual_vector`): the state's skew on the position and pressures
(:data:`SKEWS`: the physics step over ±1 ms), the accelerometer's sampling (its interval mean, or an instant at
each skew) on the acceleration. A candidate replaces hexsim's own timing only where it lowers the cost by more
than :data:`GAIN`: a slow log, which cannot tell the timings apart, keeps it.
"""

from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass

import numpy as np

from hexsim.measured.replay import replay, sampled
from hexsim.measured.scoring import REPLAY_DT, residual_vector
from hexsim.plant.machine import Machine, with_keys
from hexsim.plant.params import SensorSpec

#: The skews tried [s]: the replay's physics step over ±1 ms (a 1 kHz log's sample either way).
SKEWS = tuple(round(k * REPLAY_DT, 10) for k in range(-10, 11))
#: A timing other than hexsim's own is taken only where it lowers the logs' cost (in budgets squared) by more
#: than this share: one that the transients cannot tell from hexsim's own is not read into them.
GAIN = 0.02


@dataclass(frozen=True)
class Timing:
    """The acquisition's timing read from the logs (:class:`hexsim.plant.params.SensorSpec`'s three timing
    fields) and the costs behind it, each the logs' residuals over their budgets, squared and summed:
    ``state_cost`` skew [s] -> the position's and pressures', ``mean_cost`` the acceleration's sampled as its
    interval mean, ``instant_cost`` skew [s] -> the acceleration's sampled at that instant (empty without an
    accelerometer)."""

    sample_skew: float
    acceleration_sampling: str
    acceleration_skew: float
    state_cost: dict
    mean_cost: float
    instant_cost: dict

    def keys(self) -> dict:
        """The machine file's keys of this timing (``sensors.*``)."""
        return {"sensors.sample_skew_s": self.sample_skew, "sensors.acceleration_sampling": self.acceleration_sampling,
                "sensors.acceleration_skew_s": self.acceleration_skew}


def _cost(ev, fine: dict, spec: SensorSpec, channels: tuple[str, ...]) -> float:
    """The replay evidence ``ev``'s residuals over its budget on ``channels``, squared and summed over all its
    windows, with its step-by-step replay ``fine`` sampled as ``spec`` says."""
    p = ev.problem
    sub = int(round(1.0 / (p.log.sample_rate_hz * REPLAY_DT)))
    sim = sampled(fine, sub, REPLAY_DT, spec)
    part = _only_channels(p, channels)
    rows = np.arange(len(p.windows.starts))
    return float(np.sum(residual_vector(part, {ch: sim[ch] for ch in part.channels}, ev.budget, rows) ** 2))


def fit_timing(replays: list, machine: Machine) -> Timing | None:
    """The timing of the single-actuator logs whose evidence is ``replays``
    (:class:`hexsim.measured.dynamics.ReplayEvidence`), replayed on ``machine`` (module doc); None where there
    is none (no single-actuator replay). Raises PhysicsError where the machine cannot run a log."""
    single = [ev for ev in replays if ev.log.system == "single-actuator"]
    if not single:
        return None
    base = machine.sensors
    state = dict.fromkeys(SKEWS, 0.0)
    mean, instant = 0.0, dict.fromkeys(SKEWS, 0.0)
    with_acc = False
    for ev in single:
        fine = replay(ev.log, ev.model(machine), ev.problem.windows, dt=REPLAY_DT, fine=True)
        for skew in SKEWS:
            state[skew] += _cost(ev, fine, dataclasses.replace(base, sample_skew=skew), ("position", "p1", "p2", "p_s"))
        if "acceleration" in ev.problem.channels:
            with_acc = True
            mean += _cost(ev, fine, dataclasses.replace(base, acceleration_sampling="mean"), ("acceleration",))
            for skew in SKEWS:
                spec = dataclasses.replace(base, acceleration_sampling="instant", acceleration_skew=skew)
                instant[skew] += _cost(ev, fine, spec, ("acceleration",))
    skew = min(state, key=state.get)
    if state[skew] > (1.0 - GAIN) * state[0.0]:
        skew = 0.0
    if not with_acc:
        return Timing(skew, "mean", 0.0, state, 0.0, {})
    best = min(instant, key=instant.get)
    if instant[best] <= (1.0 - GAIN) * mean:
        return Timing(skew, "instant", best, state, mean, instant)
    return Timing(skew, "mean", 0.0, state, mean, instant)


def _only_channels(problem, channels: tuple[str, ...]):
    """A shallow copy of ``problem`` scoring only its ``channels`` that are among ``channels``."""
    out = copy.copy(problem)
    out.channels = [ch for ch in problem.channels if ch in channels]
    return out


def accelerometer_sampling(replays: list, machine: Machine) -> tuple[Machine, str | None]:
    """How the logs' accelerometer was sampled, read on ``machine`` (the prior of a calibration) from the
    single-actuator ``replays`` (:func:`fit_timing`): ``machine`` with ``sensors.acceleration_sampling`` and
    ``acceleration_skew_s`` set where an instant fits the logs better than hexsim's interval mean, and a
    sentence saying what was read (None where there is no single-actuator log with an accelerometer, or the
    machine already says "instant"). The accelerometer's timing shows on any model (the oil spring's ringing
    is in every step's first milliseconds); the state's skew is not read here (it trades against the oil's
    stiffness on a model that is still far off) but fitted with the other parameters
    (:func:`hexsim.measured.parameters.default_parameters`)."""
    if machine.sensors.acceleration_sampling == "instant":
        return machine, None
    timing = fit_timing(replays, machine)
    if timing is None or not timing.instant_cost:
        return machine, None
    if timing.acceleration_sampling == "mean":
        return machine, (f"the accelerometer read as its mean over each sample interval (hexsim's own logs): no "
                         f"instant fits the logs better by {GAIN:.0%}")
    return (with_keys(machine, {"sensors.acceleration_sampling": "instant",
                                "sensors.acceleration_skew_s": timing.acceleration_skew}),
            f"the accelerometer read at an instant, not as its mean over each sample interval: the logs' "
            f"acceleration in budgets squared {timing.mean_cost:.4g} as a mean, "
            f"{timing.instant_cost[timing.acceleration_skew]:.4g} at {timing.acceleration_skew * 1e3:+.1f} ms "
            f"(the instant then fitted with the other parameters)")
