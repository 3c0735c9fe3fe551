"""``hexsim validate``: confront the model with a measurement log and report (Markdown, PNG, JSON).

Chain: :func:`hexsim.measurement.read_log` → :func:`hexsim.identify.identify` (valve replay, candidate
fits, choice) → :mod:`hexsim.residuals` before and after → report. The identifier reads nothing but the
log and its sidecar.
"""

from __future__ import annotations

import json
import pathlib

import numpy as np

from hexsim.identify import CANDIDATES, Identification, identify
from hexsim.measurement import MeasurementLog
from hexsim.residuals import analyse
from hexsim.tables import write_atomic


def summary(ident: Identification) -> dict:
    """The JSON document: added_effect, parameters, error_before/after (NRMSE per channel), candidates,
    residual analysis before/after, what the log lacked and which defaults were assumed."""
    p = ident.problem
    u, vel, pos, near = p.motion_state()
    cut = p.analysis_view
    chosen = ident.chosen
    return {
        "log": str(p.log.path),
        "system": p.log.system,
        "added_effect": ident.added_effect,
        "parameters": chosen.parameters if chosen else {},
        "error_before": ident.error_before,
        "error_after": ident.error_after,
        "error_definition": "NRMSE: RMS of (replayed - measured) / the measured signal's standard deviation "
                            "(floored: 0.1 mm, 0.1 bar, 0.05 m/s^2), over all " + p.scored,
        "replay": p.replay_mode,
        "rms_before": {ch: float(np.sqrt(np.mean(r**2))) for ch, r in ident.nominal_residuals.items()},
        "rms_after": {ch: float(np.sqrt(np.mean(r**2))) for ch, r in ident.chosen_residuals.items()},
        "units": p.units,
        "nominal": {"cost_fit": ident.nominal_cost_fit, "cost_held_out": ident.nominal_cost_held_out,
                    "aic": ident.nominal_aic, "bic": ident.nominal_bic},
        "candidates": [c.as_dict() | {"physics": CANDIDATES[c.name].physics} for c in ident.candidates],
        "selection": "largest held-out gain, chosen only if >= 5 % and BIC below the nominal's",
        "residuals_before": analyse(cut(ident.nominal_residuals), u, vel, pos, near, p.log.sample_rate_hz),
        "residuals_after": analyse(cut(ident.chosen_residuals), u, vel, pos, near, p.log.sample_rate_hz),
        "windows": p.window_doc,
        "not_checked": p.log.missing,
        "assumed": p.log.assumed,
    }


def markdown(doc: dict, png_names: list[str]) -> str:
    lines = [f"# Validation of `{doc['log']}`", "",
             f"**Added effect: `{doc['added_effect']}`**", ""]
    if doc["added_effect"] == "none":
        lines += ["No candidate lowered the held-out error enough (≥ 5 % and a lower BIC): the nominal model "
                  "explains the log, or the residual lives where no candidate reaches (see the conditioned "
                  "table below).", ""]
    lines += [f"Replay: {doc['replay']}", "",
              "## Error per channel (NRMSE)", "", "| channel | before | after |", "|---|---|---|"]
    for ch, before in doc["error_before"].items():
        lines.append(f"| {ch} | {before:.4g} | {doc['error_after'][ch]:.4g} |")
    lines += ["", "## Candidates", "",
              "| effect | parameters ± s.e. | held-out gain | ΔBIC vs nominal |", "|---|---|---|---|"]
    for c in doc["candidates"]:
        ps = ", ".join(f"{k} = {v['value']:.4g} ± {v['std_error']:.2g} {v['unit']}" for k, v in c["parameters"].items())
        lines.append(f"| {c['effect']} | {ps} | {c['held_out_gain']:+.3f} | {c['bic'] - doc['nominal']['bic']:+.1f} |")
    lines += ["", "## Residual before → after", "", "| channel | Ljung–Box p | max cross-corr. with u_v (bound) | "
              "spectrum peak [Hz] |", "|---|---|---|---|"]
    for ch in doc["residuals_before"]:
        b, a = doc["residuals_before"][ch], doc["residuals_after"][ch]
        lines.append(f"| {ch} | {b['ljung_box']['p_value']:.2g} → {a['ljung_box']['p_value']:.2g} | "
                     f"{b['cross_correlation_u_v']['max_abs']:.3f} → {a['cross_correlation_u_v']['max_abs']:.3f} "
                     f"({b['cross_correlation_u_v']['bound_95']:.3f}) | {b['spectrum_peak_hz']:.1f} → "
                     f"{a['spectrum_peak_hz']:.1f} |")
    lines += ["", "## Where the residual lives (before; RMS per class of the motion state)", ""]
    chans = list(doc["residuals_before"])
    lines += ["| class | " + " | ".join(chans) + " |", "|---" * (len(chans) + 1) + "|"]
    classes = doc["residuals_before"][chans[0]]["conditioned"]
    for cls in classes:
        row = [f"{doc['residuals_before'][ch]['conditioned'].get(cls, {}).get('rms', float('nan')):.3g}" for ch in chans]
        lines.append(f"| {cls} | " + " | ".join(row) + " |")
    lines += ["", f"Not checked (columns missing): {', '.join(doc['not_checked']) or 'nothing'}.",
              f"Assumed: {'; '.join(doc['assumed']) or 'nothing'}.", ""]
    lines += [f"![{n}]({n})" for n in png_names]
    return "\n".join(lines) + "\n"


def plot(ident: Identification, path: pathlib.Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from hexsim.residuals import spectrum

    p = ident.problem
    chans = p.channels
    fig, ax = plt.subplots(len(chans), 3, figsize=(15, 3 * len(chans)), squeeze=False)
    fs = p.log.sample_rate_hz
    u, vel, pos, near = p.motion_state()
    before, after = p.analysis_view(ident.nominal_residuals), p.analysis_view(ident.chosen_residuals)
    tw = p.sample_times()
    for i, ch in enumerate(chans):
        b, a = before[ch], after[ch]
        ax[i, 0].plot(tw.ravel(), b.ravel(), ",", color="C3", label="before")
        ax[i, 0].plot(tw.ravel(), a.ravel(), ",", color="C0", label="after")
        ax[i, 0].set_ylabel(f"{ch} residual [{p.units[ch]}]")
        ax[i, 0].legend(loc="upper right", markerscale=20)
        ax[i, 1].plot(vel.ravel(), b.ravel(), ",", color="C3")
        ax[i, 1].plot(vel.ravel(), a.ravel(), ",", color="C0")
        ax[i, 1].set_xlabel("measured velocity [m/s]")
        f, pb = spectrum(b, fs)
        _, pa = spectrum(a, fs)
        ax[i, 2].semilogy(f, pb, color="C3")
        ax[i, 2].semilogy(f, pa, color="C0")
        ax[i, 2].set_xlabel("frequency [Hz]")
        ax[i, 2].set_ylabel("PSD")
    ax[-1, 0].set_xlabel("time [s]")
    fig.suptitle(f"{p.log.path.name}: residual before (red) / after adding {ident.added_effect} (blue)")
    fig.tight_layout()
    write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=90, format="png"))
    plt.close(fig)


def validate(log: MeasurementLog, *, report: pathlib.Path | None = None, json_path: pathlib.Path | None = None,
             jobs: int = 2, progress: bool = False) -> dict:
    """Identify (see :func:`hexsim.identify.identify`), then write the report folder (report.md +
    residuals.png) and/or the JSON. Returns the JSON document. Raises InputError for a log the replay
    cannot use or a report folder that cannot be created."""
    ident = identify(log, jobs=jobs, progress=progress)
    doc = summary(ident)
    if report is not None:
        report.mkdir(parents=True, exist_ok=True)
        plot(ident, report / "residuals.png")
        write_atomic(report / "report.md", lambda tmp: tmp.write_text(markdown(doc, ["residuals.png"])))
        write_atomic(report / "validation.json", lambda tmp: tmp.write_text(json.dumps(doc, indent=2) + "\n"))
    if json_path is not None:
        write_atomic(json_path, lambda tmp: tmp.write_text(json.dumps(doc, indent=2) + "\n"))
    return doc
