"""The friction map's figure (:func:`hexsim.measured.friction_id.identify_friction`, ``hexsim friction --plot``)."""

from __future__ import annotations

import pathlib

import numpy as np

from hexsim.measured.estimates import FITTED
from hexsim.measured.friction_id import V_MIN, FrictionMap


def plot_map(result: FrictionMap, path: pathlib.Path) -> None:
    """The friction-velocity map of ``result``: its samples and each direction's fitted curve, written to
    ``path`` (.png, .pdf or .svg; raises InputError for another suffix or a missing folder)."""
    from matplotlib.figure import (
        Figure,  # no pyplot: the user's backend is never switched
    )

    from hexsim.outputs.plotting import save_figure

    vel, ff = result.velocity, result.force
    fig = Figure(figsize=(7, 4.5), layout="tight")
    ax = fig.subplots()
    steady = result.acceleration_source.startswith("left out")  # steady windows: no M ydd term
    ax.plot(vel, ff, ",", color="0.5", label="F_f = F_L - M g cos θ, steady windows (seed eq. 2.3)" if steady
            else "F_f = F_L - M ydd - M g cos θ (seed eq. 2.3)")
    for fit, sgn in ((result.positive, 1), (result.negative, -1)):
        if not fit.fitted:
            continue
        v = sgn * np.linspace(V_MIN, max(np.abs(vel).max(), 2 * V_MIN), 200)
        ax.plot(v, fit.friction(v, result.hydraulics), color="C0" if sgn > 0 else "C3",
                label=f"Stribeck fit, {fit.side} (seed eq. 3.9)")
    ax.set_xlabel("velocity [m/s]")
    ax.set_ylabel("friction force [N]")
    names = [pathlib.Path(part).name for part in result.log.split(", ")]
    ax.set_title("friction-velocity map: " + (names[0] if len(names) == 1 else f"{len(names)} experiments"))
    ax.legend(fontsize=8, markerscale=20)
    save_figure(fig, path, dpi=100)


def summary(result: FrictionMap) -> str:
    """The friction identification ``result`` (:func:`hexsim.measured.friction_id.identify_friction`) as
    ``hexsim friction`` prints it: where the force and acceleration came from, each steady point measured and
    fitted, each side's parameters with their standard errors (or why they cannot be identified)."""
    lines = [f"machine: {result.machine}",
             f"friction from {result.force_source}, M = {result.mass_kg:g} kg, "
             f"inclination {result.inclination_deg:g}°, {result.experiments} experiment(s); "
             f"acceleration: {result.acceleration_source}"]
    for row in result.steady:
        fitted = "no fit" if row["fitted_N"] is None else f"{row['fitted_N']:7.1f} N fitted"
        lines.append(f"  steady {row['velocity_mps'] * 1e3:+8.1f} mm/s: F_f = {row['friction_N']:7.1f} N measured, "
                     f"{fitted}")
    for fit in (result.positive, result.negative):
        if not fit.fitted:
            lines.append(f"  {fit.side:8s}: cannot fit: {fit.cannot_fit}")
            continue
        lines.append(f"  {fit.side:8s}: " + ", ".join(
            f"{k} unidentifiable" if e.status != FITTED else f"{k} = {e.value:.4g} ± {e.std_error:.2g} {e.unit}"
            for k, e in fit.parameters.items()) + f"  (rms {fit.rms_N:.3g} N, robust scatter "
            f"{fit.scatter_N:.3g} N, {fit.samples} samples)")
        reasons: dict[str, list[str]] = {}
        for k, why in fit.unidentifiable.items():
            reasons.setdefault(why, []).append(k)
        lines += [f"    {', '.join(names)}: {why}" for why, names in reasons.items()]
    return "\n".join(lines)
