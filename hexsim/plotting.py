"""The run's PNG: acceleration against its fundamental, acceleration noise with reversal peaks, flow
curve (u_v vs piston velocity, seed Fig. 3.10), pressures, tracking errors and spectrum."""

from __future__ import annotations

import os

import pathlib

import numpy as np
from matplotlib.figure import Figure  # no pyplot: the user's backend is never switched, no window opens

from compensation.base import STATE_UNITS
from hexsim.metrics import Smoothness
from hexsim.simulation import SimulationResult
from hexsim.tables import write_atomic

#: Lowest spectrum amplitude drawn, relative to the largest line (-100 dB).
SPECTRUM_RANGE = 1e-5
#: File types --plot writes (by the path's suffix).
PLOT_FORMATS = ("png", "pdf", "svg")


def save_figure(fig: Figure, path: str | os.PathLike, dpi: float) -> None:
    """Write ``fig`` to ``path`` atomically, in the format its suffix names (.png, .pdf or .svg; dpi for
    PNG). Raises InputError (via write_atomic) if the folder does not exist."""
    fmt = pathlib.Path(path).suffix.lower().lstrip(".")
    write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=dpi, format=fmt if fmt in PLOT_FORMATS else "png"))


def plot_run(path: str | os.PathLike, result: SimulationResult, sm: Smoothness) -> None:
    """Write the six-panel PNG for a run to ``path`` (atomically)."""
    sc = result.config.scenario
    compensated = result.config.compensator_name != "none"
    rows = 4 if compensated else 3
    fig = Figure(figsize=(13, 3.7 * rows), layout="constrained")
    ax = fig.subplots(rows, 2)
    fig.suptitle(f"hexsim {sc.name}: {sc.system}, {sc.frequency:g} Hz, compensator {result.config.compensator_name}")

    a = ax[0, 0]
    a.plot(sm.t, sm.fit + sm.noise, lw=0.8, label="measured")
    a.plot(sm.t, sm.fit, lw=1.2, ls="--", label=f"offset + fundamental ({sm.fundamental_amplitude:.3g} {sm.unit})")
    for tr in sm.reversal_times:
        a.axvline(tr, color="0.7", lw=0.6)
    a.set(title=sm.signal, xlabel="time [s]", ylabel=f"[{sm.unit}]")
    a.legend(loc="upper right", fontsize=8)
    time_axes = [a]

    a = ax[0, 1]
    a.plot(sm.t, sm.noise, lw=0.8, color="C3")
    a.plot(sm.reversal_peak_times, np.interp(sm.reversal_peak_times, sm.t, sm.noise), "kv", ms=5,
           label="reversal peaks")
    for tr in sm.reversal_times:
        a.axvline(tr, color="0.7", lw=0.6)
    a.set(title=f"acceleration noise: ratio {sm.noise_ratio:.3f}, mean reversal peak "
                f"{sm.mean_reversal_peak:.3g} {sm.unit}", xlabel="time [s]", ylabel=f"[{sm.unit}]")
    a.title.set_fontsize("medium")  # the whole title inside the panel (a long one ran past the figure edge)
    a.legend(loc="upper right", fontsize=8)
    time_axes.append(a)
    for a in time_axes:  # before the analysis window: the fade-in and one settling period
        a.axvspan(0.0, sm.t[0], color="0.92", lw=0)
        a.text(0.5 * sm.t[0], 0.03, "not analysed", transform=a.get_xaxis_transform(), ha="center", fontsize=7,
               color="0.4")

    a = ax[1, 0]
    for i in range(result.n_legs):
        a.plot(result.u_v[:, i], result.ydot[:, i], lw=0.6, label=f"leg{i + 1}")
    if compensated:  # what the P loop sees: its own output u_v - U_c against the velocity
        a.plot(result.u_v[:, 0] - result.u_c[:, 0], result.ydot[:, 0], "k", lw=0.6,
               label="leg1 vs P output u_p")
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
    time_axes.append(a)

    a = ax[2, 0]
    for i in range(result.n_legs):
        a.plot(result.t, (result.y_ref[:, i] - result.y[:, i]) * 1e3, lw=0.7, label=f"leg{i + 1}")
    a.set(title="tracking error r − y", xlabel="time [s]", ylabel="[mm]")
    a.legend(fontsize=7, ncol=2)
    time_axes.append(a)

    a = ax[2, 1]
    floor = SPECTRUM_RANGE * sm.spectrum.max()  # a floor 100 dB below the largest line: no plot of round-off
    a.semilogy(sm.spectrum_hz, np.maximum(sm.spectrum, floor), lw=0.7)
    a.set(title="spectrum of the analysed signal", xlabel="frequency [Hz]", ylabel=f"amplitude [{sm.unit}]",
          xlim=(0, min(250.0, sm.spectrum_hz[-1])), ylim=(floor, 2 * sm.spectrum.max()))

    if compensated:
        a = ax[3, 0]
        for key, values in result.compensator_state.items():
            a.plot(result.t, values[:, 0], lw=1, label=f"{key} [{STATE_UNITS.get(key, '?')}]")
        a.set(title=f"{result.config.compensator_name}: parameters, leg1", xlabel="time [s]",
              ylabel="value (unit in the legend)")
        if a.lines:
            a.legend(fontsize=8)
        time_axes.append(a)
        a = ax[3, 1]
        for i in range(result.n_legs):
            a.plot(result.u_v[:, i] - result.u_c[:, i], result.u_c[:, i], ".", ms=1, label=f"leg{i + 1}")
        a.set(title="compensation curve U_c(u_p)", xlabel="P output u_p = u_v − U_c [V]", ylabel="U_c [V]")
    for a in time_axes:  # every time panel on the run's time axis
        a.set_xlim(0.0, result.t[-1])

    save_figure(fig, path, dpi=90)


def plot_compare(path: str | os.PathLike, entries: list, scenario) -> None:
    """The comparison PNG in the seed's Fig. 5.12 layout, one column per compensator (leg 1): flow curve
    with the desired line s u_v, parameter evolution, compensation curve U_c(u_v), u_v - ẏ/s over time,
    and the acceleration at the end of the run against the uncompensated one. Written atomically."""
    base = entries[0]
    cols = [e for e in entries if e.compensator != "none"] or entries
    fig = Figure(figsize=(4.2 * len(cols), 20), layout="constrained")
    ax = fig.subplots(6, len(cols), squeeze=False)
    fig.suptitle(f"hexsim compare {scenario.name} ({scenario.duration:g} s): leg1, seed Fig. 5.12 layout")
    for j, e in enumerate(cols):
        tr = e.traces
        s = tr["s"]
        a = ax[0, j]
        u_p = tr["u_v"] - tr["u_c"]  # the P controller's output, before compensation (seed Fig. 5.3)
        a.plot(u_p, tr["ydot"], lw=0.4, label="ẏ vs P output u_v")
        u = np.linspace(u_p.min(), u_p.max(), 50)
        a.plot(u, s * u, "k--", lw=1, label=f"desired s u_v (s = {s:.3f})")
        a.set(title=f"{e.compensator}: flow curve", xlabel="u_v [V]", ylabel="ẏ [m/s]")
        a.legend(fontsize=7)
        a = ax[1, j]
        for key in ("a", "b", "c"):
            if f"param_{key}" in tr:
                a.plot(tr["t"], tr[f"param_{key}"], lw=1, label=key)
        a.set(title="parameter evolution", xlabel="time [s]")
        if a.lines:
            a.legend(fontsize=7)
        a = ax[2, j]
        a.plot(u_p, tr["u_c"], ".", ms=1)
        a.set(title="compensation curve", xlabel="u_v [V]", ylabel="U_c [V]")
        a = ax[3, j]
        a.plot(tr["t"], u_p - tr["ydot"] / s, lw=0.5)
        a.set(title="u_v − ẏ/s", xlabel="time [s]", ylabel="[V]")
        a = ax[4, j]
        a.plot(tr["peak_t"], tr["peaks"], "o-", ms=3, lw=0.8, label=e.compensator)
        a.plot(base.traces["peak_t"], base.traces["peaks"], "o-", ms=2, lw=0.6, color="0.6", label="none")
        a.set(title="reversal peaks", xlabel="time [s]", ylabel=f"[{e.unit}]",
              ylim=(0, 1.5 * max(base.traces["peaks"].max(initial=0), 1e-9)))
        a.legend(fontsize=7)
        a = ax[5, j]
        keep = base.traces["acc_t"] >= base.traces["acc_t"][-1] - 2.0 / scenario.frequency
        a.plot(base.traces["acc_t"][keep], base.traces["acc"][keep], color="0.6", lw=0.7, label="none")
        keep = tr["acc_t"] >= tr["acc_t"][-1] - 2.0 / scenario.frequency
        a.plot(tr["acc_t"][keep], tr["acc"][keep], lw=0.8, label=e.compensator)
        a.set(title="acceleration, last two periods", xlabel="time [s]", ylabel=f"[{e.unit}]")
        a.legend(fontsize=7)
    save_figure(fig, path, dpi=60)
