"""The friction map's figure (:func:`hexsim.measured.friction_id.identify_friction`, ``hexsim friction --plot``)."""

from __future__ import annotations

import pathlib

import numpy as np

from hexsim.measured.friction_id import PARAMS, V_MIN, stribeck


def plot_map(result: dict, path: pathlib.Path) -> None:
    from matplotlib.figure import (
        Figure,  # no pyplot: the user's backend is never switched
    )

    from hexsim.outputs.plotting import save_figure

    vel, ff = result["_samples"]
    fig = Figure(figsize=(7, 4.5), layout="tight")
    ax = fig.subplots()
    steady = result["acceleration_source"].startswith("left out")  # steady windows: no M ydd term
    ax.plot(vel, ff, ",", color="0.5", label="F_f = F_L - M g cos θ, steady windows (seed eq. 2.3)" if steady
            else "F_f = F_L - M ydd - M g cos θ (seed eq. 2.3)")
    for side, sgn in (("positive", 1), ("negative", -1)):
        if "cannot_fit" in result[side]:
            continue
        x = np.array([result[side]["parameters"][p]["value"] for p in PARAMS])
        v = sgn * np.linspace(V_MIN, max(np.abs(vel).max(), 2 * V_MIN), 200)
        ax.plot(v, stribeck(v, x, result.get("_hydraulics")), color="C0" if sgn > 0 else "C3",
                label=f"Stribeck fit, {side} (seed eq. 3.9)")
    ax.set_xlabel("velocity [m/s]")
    ax.set_ylabel("friction force [N]")
    names = [pathlib.Path(part).name for part in result["log"].split(", ")]
    ax.set_title("friction-velocity map: " + (names[0] if len(names) == 1 else f"{len(names)} experiments"))
    ax.legend(fontsize=8, markerscale=20)
    save_figure(fig, path, dpi=100)


def summary(result: dict) -> str:
    """The friction identification ``result`` (:func:`hexsim.measured.friction_id.identify_friction`) as
    ``hexsim friction`` prints it: where the force and acceleration came from, each steady point measured and
    fitted, each side's parameters with their standard errors (or why they cannot be identified)."""
    lines = [f"machine: {result['machine']}",
             f"friction from {result['force_source']}, M = {result['mass_kg']:g} kg, "
             f"inclination {result['inclination_deg']:g}°, {result['experiments']} experiment(s); "
             f"acceleration: {result['acceleration_source']}"]
    for row in result["steady"]:
        fitted = "no fit" if row["fitted_N"] is None else f"{row['fitted_N']:7.1f} N fitted"
        lines.append(f"  steady {row['velocity_mps'] * 1e3:+8.1f} mm/s: F_f = {row['friction_N']:7.1f} N measured, "
                     f"{fitted}")
    for side in ("positive", "negative"):
        if "cannot_fit" in result[side]:
            lines.append(f"  {side:8s}: cannot fit: {result[side]['cannot_fit']}")
            continue
        ps = result[side]["parameters"]
        lines.append(f"  {side:8s}: " + ", ".join(
            f"{k} unidentifiable" if "unidentifiable" in v else f"{k} = {v['value']:.4g} ± {v['std_error']:.2g} {v['unit']}"
            for k, v in ps.items()) + f"  (rms {result[side]['rms_N']:.3g} N, robust scatter "
            f"{result[side]['scatter_N']:.3g} N, {result[side]['samples']} samples)")
        reasons: dict[str, list[str]] = {}
        for k, v in ps.items():
            if "unidentifiable" in v:
                reasons.setdefault(v["unidentifiable"], []).append(k)
        lines += [f"    {', '.join(names)}: {why}" for why, names in reasons.items()]
    return "\n".join(lines)
