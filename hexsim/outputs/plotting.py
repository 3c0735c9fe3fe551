"""The run's PNG: acceleration against its fundamental, acceleration noise with reversal peaks, flow
curve (u_v vs piston velocity, seed Fig. 3.10), pressures, tracking errors and spectrum."""

from __future__ import annotations

import os
import pathlib

import numpy as np
from matplotlib.figure import (
    Figure,  # no pyplot: the user's backend is never switched, no window opens
)

from compensation.base import STATE_UNITS
from hexsim.engine.config import SimulationResult
from hexsim.studies.metrics import Smoothness
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


def plot_run(path: str | os.PathLike, result: SimulationResult, sm: Smoothness, perception=None) -> None:
    """Write the run's figure to ``path`` (atomically; .png, .pdf or .svg): the analysed acceleration
    against its fundamental and its noise with the reversal peaks, the flow curve (seed Fig. 3.10),
    pressures, tracking errors, the spectrum, for a compensated run the compensator's parameters
    and compensation curve and, with ``perception`` (a hexapod's
    :class:`~hexsim.studies.perception.BumpPerception`), the false cue as the occupant senses it against
    the thresholds. Every time panel spans the whole run."""
    sc = result.config.scenario
    compensated = result.config.compensator_name != "none"
    rows = 3 + compensated + (perception is not None)
    fig = Figure(figsize=(13, 3.7 * rows), layout="constrained")
    ax = fig.subplots(rows, 2)
    fig.suptitle(f"hexsim {sc.name}: {sc.system}, {sc.frequency:g} Hz, compensator {result.config.compensator_name}")
    time_axes = [*_acceleration_panels(ax[0, 0], ax[0, 1], sm), _pressure_panel(ax[1, 1], result),
                 _tracking_panel(ax[2, 0], result)]
    _flow_curve_panel(ax[1, 0], result, compensated)
    _spectrum_panel(ax[2, 1], sm)
    if compensated:
        time_axes.append(_compensator_panels(ax[3, 0], ax[3, 1], result))
    if perception is not None:
        time_axes.extend(_perception_panels(ax[rows - 1, 0], ax[rows - 1, 1], perception))
    for a in time_axes:
        a.set_xlim(0.0, result.t[-1])
    save_figure(fig, path, dpi=90)


def plot_open_loop(path: str | os.PathLike, result: SimulationResult) -> None:
    """The figure of an open-loop run (a ``valve:`` scenario; atomically, .png, .pdf or .svg): valve
    setpoints, piston positions, velocities and the chamber pressures over time."""
    sc = result.config.scenario
    fig = Figure(figsize=(12, 7), layout="constrained")
    ax = fig.subplots(2, 2)
    fig.suptitle(f"hexsim {pathlib.Path(sc.name[6:]).name}: open loop, {sc.system}, machine {result.config.machine_label}")
    for i in range(result.n_legs):
        ax[0, 0].plot(result.t, result.u_v[:, i], lw=0.8, label=f"leg{i + 1}")
        ax[0, 1].plot(result.t, result.y[:, i] * 1e3, lw=0.8, label=f"leg{i + 1}")
        ax[1, 0].plot(result.t, result.ydot[:, i] * 1e3, lw=0.8, label=f"leg{i + 1}")
    ax[0, 0].set(title="valve setpoint u_v", xlabel="time [s]", ylabel="[V]")
    ax[0, 1].set(title="piston position y", xlabel="time [s]", ylabel="[mm]")
    ax[1, 0].set(title="piston velocity", xlabel="time [s]", ylabel="[mm/s]")
    _pressure_panel(ax[1, 1], result)
    for a in ax.flat:
        a.set_xlim(0.0, result.t[-1])
    save_figure(fig, path, dpi=90)


def plot_cueing(path: str | os.PathLike, result: SimulationResult, report) -> None:
    """The figure of a ``vehicle:`` run (atomically; .png, .pdf or .svg): per axis the sensed cue of the
    vehicle, the ideal platform (the washout alone) and the simulator with the sensed threshold, then the
    platform's pose against its setpoint; ``report``: the run's :class:`~hexsim.studies.cueing.CueReport`."""
    from hexsim.studies.perception import AXES

    traces = {"vehicle": report.sensed_vehicle, "ideal": report.sensed_ideal, "simulator": report.sensed_simulator}
    fig = Figure(figsize=(13, 12), layout="constrained")
    ax = fig.subplots(4, 2)
    fig.suptitle(f"hexsim {pathlib.Path(result.config.scenario.name[8:]).name}: motion cueing, compensator "
                 f"{result.config.compensator_name}, machine {result.config.machine_label}")
    for k, axis in enumerate(AXES):
        a = ax.flat[k]
        unit = "m/s^2" if k < 3 else "rad/s"
        for who, style in (("vehicle", "-"), ("ideal", "--"), ("simulator", "-")):
            a.plot(report.t, traces[who][:, k], ls=style, lw=0.9, label=who if who != "ideal" else "ideal platform")
        thr = report.axes[axis].sensed_threshold
        a.axhspan(-thr, thr, color="0.9", lw=0, label="below threshold")
        fc = report.axes[axis].false_cues
        a.set(title=f"{axis}: sensed cue (false cues: washout {fc['washout']}, hardware {fc['hardware']}, "
                    f"bumps {fc['reversal_bump']})", xlabel="time [s]", ylabel=f"[{unit}]")
        a.title.set_fontsize("medium")
        a.legend(loc="upper right", fontsize=7)
    t = result.t
    ref = result.config.scenario.poses(t)
    for k, name in enumerate(("x", "y", "z")):
        ax[3, 0].plot(t, result.pose[:, k] * 1e3, lw=0.9, label=f"{name}")
        ax[3, 0].plot(t, ref[:, k] * 1e3, lw=0.7, ls="--", color="0.4")
    for k, name in enumerate(("roll", "pitch", "yaw")):
        ax[3, 1].plot(t, np.degrees(result.pose[:, 3 + k]), lw=0.9, label=name)
        ax[3, 1].plot(t, np.degrees(ref[:, 3 + k]), lw=0.7, ls="--", color="0.4")
    ax[3, 0].set(title="platform position (dashed: setpoint)", xlabel="time [s]", ylabel="[mm]")
    ax[3, 1].set(title="platform attitude (dashed: setpoint)", xlabel="time [s]", ylabel="[deg]")
    for a in ax[3]:
        a.legend(loc="upper right", fontsize=7)
    save_figure(fig, path, dpi=90)


def _perception_panels(a, b, p) -> tuple:
    """The false cue at the seat, ISO 2631-1 weighted, against the Annex C threshold (a), and the vestibular
    models' output at the head as a multiple of each axis' sensed threshold (b)."""
    from hexsim.studies.perception import AXES, ISO_WEIGHTINGS

    for k, axis in enumerate("xyz"):
        a.plot(p.t, p.weighted[:, k], lw=0.8, label=f"{axis} ({ISO_WEIGHTINGS[axis]})")
    for sign in (1, -1):
        a.axhline(sign * p.seat_threshold, color="k", ls="--", lw=0.8,
                  label="perception threshold (ISO 2631-1 Annex C)" if sign > 0 else None)
    a.set(title=f"seat: weighted false cue, {int(np.sum(p.seat.max(axis=1) > 1))} of {len(p.reversal_times)} "
                f"bumps above threshold", xlabel="time [s]", ylabel="[m/s^2]")
    for k, axis in enumerate(AXES):
        b.plot(p.t, np.abs(p.sensed[:, k]) / p.thresholds[axis], lw=0.8, label=axis)
    b.axhline(1.0, color="k", ls="--", lw=0.8, label="threshold")
    b.set(title=f"head: vestibular sensed false cue / threshold, "
                f"{int(np.sum(p.vestibular.max(axis=1) > 1))} bumps above", xlabel="time [s]", ylabel="[-]")
    for axis in (a, b):
        axis.title.set_fontsize("medium")
        axis.legend(loc="upper right", fontsize=7, ncol=2)
    return a, b


def _acceleration_panels(a, b, sm: Smoothness) -> tuple:
    """The analysed signal with its offset + fundamental fit (a) and the noise with the reversal peaks (b);
    the start before the analysis window (fade-in, one settling period) shaded."""
    a.plot(sm.t, sm.fit + sm.noise, lw=0.8, label="measured")
    a.plot(sm.t, sm.fit, lw=1.2, ls="--", label=f"offset + fundamental ({sm.fundamental_amplitude:.3g} {sm.unit})")
    a.set(title=sm.signal, xlabel="time [s]", ylabel=f"[{sm.unit}]")
    b.plot(sm.t, sm.noise, lw=0.8, color="C3")
    b.plot(sm.reversal_peak_times, np.interp(sm.reversal_peak_times, sm.t, sm.noise), "kv", ms=5,
           label="reversal peaks")
    b.set(title=f"acceleration noise: ratio {sm.noise_ratio:.3f}, mean reversal peak "
                f"{sm.mean_reversal_peak:.3g} {sm.unit}", xlabel="time [s]", ylabel=f"[{sm.unit}]")
    b.title.set_fontsize("medium")  # the whole title inside the panel (a long one ran past the figure edge)
    for axis in (a, b):
        for tr in sm.reversal_times:
            axis.axvline(tr, color="0.7", lw=0.6)
        axis.legend(loc="upper right", fontsize=8)
        axis.axvspan(0.0, sm.t[0], color="0.92", lw=0)
        axis.text(0.5 * sm.t[0], 0.03, "not analysed", transform=axis.get_xaxis_transform(), ha="center",
                  fontsize=7, color="0.4")
    return a, b


def _flow_curve_panel(a, result: SimulationResult, compensated: bool) -> None:
    """Piston velocity against the valve setpoint u_v per leg (seed Fig. 3.10); compensated: leg 1 also
    against the P output u_p = u_v - U_c, the curve the P loop sees."""
    for i in range(result.n_legs):
        a.plot(result.u_v[:, i], result.ydot[:, i], lw=0.6, label=f"leg{i + 1}")
    if compensated:
        a.plot(result.u_v[:, 0] - result.u_c[:, 0], result.ydot[:, 0], "k", lw=0.6, label="leg1 vs P output u_p")
    a.set(title="flow curve (seed Fig. 3.10)", xlabel="valve setpoint u_v [V]", ylabel="piston velocity [m/s]")
    a.axhline(0, color="0.6", lw=0.5)
    a.axvline(0, color="0.6", lw=0.5)
    a.legend(fontsize=7, ncol=2)


def _pressure_panel(a, result: SimulationResult):
    for i in range(result.n_legs):
        a.plot(result.t, result.p1[:, i] / 1e5, lw=0.7, label=f"P1 leg{i + 1}")
        if result.config.hydraulics.four_way:
            a.plot(result.t, result.p2[:, i] / 1e5, lw=0.7, ls=":", label=f"P2 leg{i + 1} (rod side)")
    a.plot(result.t, result.p_s / 1e5, "k--", lw=1, label="P_s")
    a.set(title="pressures", xlabel="time [s]", ylabel="[bar]")
    a.legend(fontsize=7, ncol=2)
    return a


def _tracking_panel(a, result: SimulationResult):
    for i in range(result.n_legs):
        a.plot(result.t, (result.y_ref[:, i] - result.y[:, i]) * 1e3, lw=0.7, label=f"leg{i + 1}")
    a.set(title="tracking error r − y", xlabel="time [s]", ylabel="[mm]")
    a.legend(fontsize=7, ncol=2)
    return a


def _spectrum_panel(a, sm: Smoothness) -> None:
    floor = SPECTRUM_RANGE * sm.spectrum.max()  # a floor 100 dB below the largest line: no plot of round-off
    a.semilogy(sm.spectrum_hz, np.maximum(sm.spectrum, floor), lw=0.7)
    a.set(title="spectrum of the analysed signal", xlabel="frequency [Hz]", ylabel=f"amplitude [{sm.unit}]",
          xlim=(0, min(250.0, sm.spectrum_hz[-1])), ylim=(floor, 2 * sm.spectrum.max()))


def _compensator_panels(a, b, result: SimulationResult):
    """Leg 1's compensator parameters over time, each with its unit (a), and the compensation curve
    U_c against the P output u_p for every leg (b). Returns the time panel."""
    for key, values in result.compensator_state.items():
        a.plot(result.t, values[:, 0], lw=1, label=f"{key} [{STATE_UNITS.get(key, '?')}]")
    a.set(title=f"{result.config.compensator_name}: parameters, leg1", xlabel="time [s]",
          ylabel="value (unit in the legend)")
    if a.lines:
        a.legend(fontsize=8)
    for i in range(result.n_legs):
        b.plot(result.u_v[:, i] - result.u_c[:, i], result.u_c[:, i], ".", ms=1, label=f"leg{i + 1}")
    b.set(title="compensation curve U_c(u_p)", xlabel="P output u_p = u_v − U_c [V]", ylabel="U_c [V]")
    return a


def plot_compare(path: str | os.PathLike, entries: list, scenario) -> None:
    """The comparison figure in the seed's Fig. 5.12 layout, one column per compensator (leg 1): flow curve
    against the P output u_p with the desired line s u_p, parameter evolution (each with its unit; a
    compensator that adapts nothing says so), compensation curve U_c(u_p), u_p - ẏ/s over time, the
    reversal peaks and the acceleration at the end of the run against the uncompensated one. Written
    atomically (.png, .pdf or .svg)."""
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
        a.plot(u_p, tr["ydot"], lw=0.4, label="ẏ vs P output u_p")
        u = np.linspace(u_p.min(), u_p.max(), 50)
        a.plot(u, s * u, "k--", lw=1, label=f"desired s u_p (s = {s:.3f} m/(s V))")
        a.set(title=f"{e.compensator}: flow curve", xlabel="P output u_p [V]", ylabel="ẏ [m/s]")
        a.legend(fontsize=7)
        a = ax[1, j]
        for key in ("a", "b", "c"):
            if f"param_{key}" in tr:
                a.plot(tr["t"], tr[f"param_{key}"], lw=1, label=f"{key} [{STATE_UNITS[key]}]")
        a.set(title="parameter evolution", xlabel="time [s]", ylabel="value (unit in the legend)")
        if a.lines:
            a.legend(fontsize=7)
        else:  # the oracle adapts nothing: no empty axes
            a.text(0.5, 0.5, f"{e.compensator}: no adapted parameters\n(the exact inverse of the true flow curve)",
                   ha="center", va="center", transform=a.transAxes, fontsize=9, color="0.3")
            a.set_axis_off()
        a = ax[2, j]
        a.plot(u_p, tr["u_c"], ".", ms=1)
        a.set(title="compensation curve U_c(u_p)", xlabel="P output u_p [V]", ylabel="U_c [V]")
        a = ax[3, j]
        a.plot(tr["t"], u_p - tr["ydot"] / s, lw=0.5)
        a.set(title="u_p − ẏ/s (seed's UC)", xlabel="time [s]", ylabel="[V]")
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
    save_figure(fig, path, dpi=75)
