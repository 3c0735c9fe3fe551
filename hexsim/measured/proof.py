"""Proof on logs: a log of the machine running with a compensator beside the machine simulated with it on
the log's own setpoints (``hexsim tune --check``; docs/compensation.md)."""

from __future__ import annotations

import dataclasses
import pathlib
from dataclasses import dataclass

import numpy as np

from hexsim.control.scenario import Scenario
from hexsim.errors import InputError
from hexsim.measured.measurement import read_log
from hexsim.measured.replay import measured_velocity
from hexsim.signals import dominant_frequency
from hexsim.simulation.config import RunConfig
from hexsim.simulation.metrics import smoothness
from hexsim.simulation.perception import ISO_PERCEPTION_THRESHOLD
from hexsim.simulation.runner import simulate

#: Periods at the start of a log left out of its smoothness (the fade-in and the compensator's start).
PROOF_SKIP_PERIODS = 2.0
#: Seconds at the end of a log left out: the simulation's reference is held past the log's last setpoint,
#: and a feedforward answers the stop.
PROOF_END_S = 0.1


def proof(path: pathlib.Path, base: RunConfig) -> dict:
    """A log of the machine running with a compensator beside the machine simulated with it on the log's own
    setpoints: the smoothness (mean and max reversal peak, noise ratio) of both, from the third period on.

    ``base``: the machine and the compensator (a tuned file's, ``run --compensator FILE``). The log
    (docs/measurement-log.md): a single actuator's ``ref_m`` and ``acc_mps2``, or a hexapod's
    ``leg{i}_ref_m`` and the platform accelerometer on the axis whose setpoint moves most (a translation:
    ``dof_ref_{x,y,z}_m`` needed). The simulation starts at the log's first positions and follows its
    setpoints held sample by sample. Raises InputError naming the log and what it lacks."""
    log = read_log(path, base.machine or None, needs=("pos_m",))
    t = log.time - log.time[0]
    cols = log.columns
    if log.system == "hexapod":
        ref = np.column_stack([cols[f"leg{i}_ref_m"] for i in range(1, log.n_legs + 1)])
        pos = np.column_stack([cols[f"leg{i}_pos_m"] for i in range(1, log.n_legs + 1)])
        dofs = [k for k in ("x", "y", "z") if f"dof_ref_{k}_m" in cols and f"platform_acc_{k}_mps2" in cols]
        if not dofs:
            raise InputError(f"{path}: a proof needs a translation's setpoint and the platform accelerometer on it "
                             "(dof_ref_{x,y,z}_m and platform_acc_{x,y,z}_mps2)")
        k = max(dofs, key=lambda d: np.ptp(cols[f"dof_ref_{d}_m"]))
        axis, setpoint, acc = "xyz".index(k), cols[f"dof_ref_{k}_m"], cols[f"platform_acc_{k}_mps2"]
    else:
        if "acc_mps2" not in cols:
            raise InputError(f"{path}: a proof needs the accelerometer (acc_mps2)")
        ref, pos = cols["ref_m"][:, None], cols["pos_m"][:, None]
        axis, setpoint, acc = -1, cols["ref_m"], cols["acc_mps2"]
    try:
        frequency = dominant_frequency(t, setpoint)
    except ValueError:
        raise InputError(f"{path}: the setpoint does not move; a proof needs a periodic motion") from None
    t0 = PROOF_SKIP_PERIODS / frequency
    if t[-1] < t0 + 1.0 / frequency:
        raise InputError(f"{path}: {t[-1]:.1f} s hold less than three periods of its {frequency:.3g} Hz motion")
    scenario = Scenario(f"log:{path.name}", log.system if log.system == "hexapod" else "actuator", float(t[-1]),
                        axis, frequency, 0.0, legs=(t, ref), start=pos[0].copy())
    result = simulate(dataclasses.replace(base, scenario=scenario, progress=False))
    # the reversals where the piston turns (single actuator); a hexapod's, where its setpoint does
    if axis < 0:
        sim_acc, sim_vel = result.acc[:, 2], result.ydot[:, 0]
        measured_vel = measured_velocity(log, pos[:, 0])
    else:
        sim_acc, sim_vel, measured_vel = result.acc[:, axis], None, None
    rows = {}
    for name, (tt, a, v) in {"measured": (t, acc, measured_vel), "predicted": (result.t, sim_acc, sim_vel)}.items():
        keep = tt <= t[-1] - PROOF_END_S  # where the log's setpoints end, the held reference stops at once
        sm = smoothness(tt[keep], a[keep], frequency, t0, np.interp(tt[keep], t, setpoint), name=name, unit="m/s^2",
                        velocity=None if v is None else v[keep])
        rows[name] = {"mean_reversal_peak": sm.mean_reversal_peak, "reversals": int(sm.reversal_peaks.size),
                      "max_reversal_peak": float(sm.reversal_peaks.max()) if sm.reversal_peaks.size else None,
                      "noise_ratio": sm.noise_ratio}
    return {"log": str(path), "frequency_hz": frequency, "compensator": base.compensator_name, **rows}


@dataclass(frozen=True)
class PassengerView:
    """A machine's run as its passenger gets it (:func:`passenger_view`): the reversal bump on the acceleration
    (``reversal_peaks`` [m/s^2], each the largest departure from the fundamental within ±0.1 s of a reversal,
    :func:`hexsim.simulation.metrics.smoothness`; their ``mean`` and ``max``), the ISO 2631-1 W_k weighted false
    cue at the seat over the whole window (``seat_peak`` [m/s^2]: every reversal and every crossing of a corner
    of the valve's curve between them) and its multiple of the perception threshold (``seat_ratio``, 0.015 m/s^2:
    ISO 2631-1:1997 Annex C), and the ``noise_ratio``."""

    reversal_peaks: np.ndarray
    seat_peak: float
    noise_ratio: float

    @property
    def mean(self) -> float:
        return float(np.mean(self.reversal_peaks)) if self.reversal_peaks.size else float("nan")

    @property
    def max(self) -> float:
        return float(np.max(self.reversal_peaks)) if self.reversal_peaks.size else float("nan")

    @property
    def seat_ratio(self) -> float:
        return self.seat_peak / ISO_PERCEPTION_THRESHOLD

    def worst_against(self, none: "PassengerView") -> float:
        """The largest ratio of a reversal's peak to the same reversal's without compensation (the runs' reversals
        in order; the shorter count): above 1, a reversal the compensation made worse."""
        n = min(self.reversal_peaks.size, none.reversal_peaks.size)
        return float(np.max(self.reversal_peaks[:n] / none.reversal_peaks[:n])) if n else float("nan")


def passenger_view(t: np.ndarray, acc: np.ndarray, setpoint: np.ndarray, frequency: float, t_start: float,
                   velocity: np.ndarray | None = None) -> PassengerView:
    """The :class:`PassengerView` of an acceleration ``acc`` [m/s^2] along a vertical axis, sampled at t (N,) [s]
    (uniform), from ``t_start`` [s]: its reversal peaks where ``setpoint`` (N,) [m] turns (moved to the measured
    motion's turns when ``velocity`` (N,) [m/s] is given), the W_k weighting (ISO 2631-1 Annex A, vertical,
    :func:`hexsim.simulation.perception.iso2631`) of its departure from the fundamental at ``frequency`` [Hz],
    started a period earlier so that the filter has settled. Raises ValueError for a window shorter than a
    period."""
    from hexsim.signals import fit_fundamental
    from hexsim.simulation.perception import iso2631

    sm = smoothness(t, acc, frequency, t_start, setpoint, name="acceleration", unit="m/s^2", velocity=velocity)
    lead = t >= t_start - 1.0 / frequency
    cue = acc[lead] - fit_fundamental(t[lead], acc[lead], frequency)[3]
    weighted = iso2631("Wk").apply(cue, 1.0 / float(np.median(np.diff(t))))
    seat = float(np.max(np.abs(weighted[t[lead] >= t_start])))
    return PassengerView(sm.reversal_peaks, seat, sm.noise_ratio)
