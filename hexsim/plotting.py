"""The run's PNG: acceleration against its fundamental, acceleration noise with reversal peaks, flow
curve (u_v vs piston velocity, seed Fig. 3.10), pressures, tracking errors and spectrum."""

from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")  # headless: never open a window
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from hexsim.metrics import Smoothness  # noqa: E402
from hexsim.simulation import SimulationResult  # noqa: E402
from hexsim.tables import write_atomic  # noqa: E402


def plot_run(path: str | os.PathLike, result: SimulationResult, sm: Smoothness) -> None:
    """Write the six-panel PNG for a run to ``path`` (atomically)."""
    sc = result.config.scenario
    fig, ax = plt.subplots(3, 2, figsize=(13, 11), constrained_layout=True)
    fig.suptitle(f"hexsim {sc.name}: {sc.system}, {sc.frequency:g} Hz, compensator {result.config.compensator}")

    a = ax[0, 0]
    a.plot(sm.t, sm.fit + sm.noise, lw=0.8, label="measured")
    a.plot(sm.t, sm.fit, lw=1.2, ls="--", label=f"offset + fundamental ({sm.fundamental_amplitude:.3g} {sm.unit})")
    for tr in sm.reversal_times:
        a.axvline(tr, color="0.7", lw=0.6)
    a.set(title=sm.signal, xlabel="time [s]", ylabel=f"[{sm.unit}]")
    a.legend(loc="upper right", fontsize=8)

    a = ax[0, 1]
    a.plot(sm.t, sm.noise, lw=0.8, color="C3")
    a.plot(sm.reversal_peak_times, np.interp(sm.reversal_peak_times, sm.t, sm.noise), "kv", ms=5,
           label="reversal peaks")
    for tr in sm.reversal_times:
        a.axvline(tr, color="0.7", lw=0.6)
    a.set(title=f"acceleration noise: noise ratio {sm.noise_ratio:.3f}, mean reversal peak "
                f"{sm.mean_reversal_peak:.3g} {sm.unit}", xlabel="time [s]", ylabel=f"[{sm.unit}]")
    a.legend(loc="upper right", fontsize=8)

    a = ax[1, 0]
    for i in range(result.n_legs):
        a.plot(result.u_v[:, i], result.ydot[:, i], lw=0.6, label=f"leg{i + 1}")
    a.set(title="flow curve (seed Fig. 3.10)", xlabel="valve setpoint u_v [V]", ylabel="piston velocity [m/s]")
    a.axhline(0, color="0.6", lw=0.5)
    a.axvline(0, color="0.6", lw=0.5)
    a.legend(fontsize=7, ncol=2)

    a = ax[1, 1]
    for i in range(result.n_legs):
        a.plot(result.t, result.p1[:, i] / 1e5, lw=0.7, label=f"P1 leg{i + 1}")
    a.plot(result.t, result.p_s / 1e5, "k--", lw=1, label="P_s")
    a.set(title="pressures", xlabel="time [s]", ylabel="[bar]")
    a.legend(fontsize=7, ncol=2)

    a = ax[2, 0]
    for i in range(result.n_legs):
        a.plot(result.t, (result.y_ref[:, i] - result.y[:, i]) * 1e3, lw=0.7, label=f"leg{i + 1}")
    a.set(title="tracking error r − y", xlabel="time [s]", ylabel="[mm]")
    a.legend(fontsize=7, ncol=2)

    a = ax[2, 1]
    a.semilogy(sm.spectrum_hz, np.maximum(sm.spectrum, 1e-9), lw=0.7)
    a.set(title="spectrum of the analysed signal", xlabel="frequency [Hz]", ylabel=f"amplitude [{sm.unit}]",
          xlim=(0, min(250.0, sm.spectrum_hz[-1])))

    write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=90, format="png"))
    plt.close(fig)
