"""The validation's report (:func:`hexsim.measured.validation.validate`): Markdown from its JSON document and
the residual figure (before / after the added effects: time, velocity, spectrum per channel)."""

from __future__ import annotations

import math
import pathlib

import numpy as np

from hexsim.measured.identify import Identification
from hexsim.measured.records import ValidationReport
from hexsim.tables import write_atomic, write_json

#: The files of a validation's report folder.
FIGURE, MARKDOWN, DOCUMENT = "residuals.png", "report.md", "validation.json"


def write_report(ident: Identification, doc: ValidationReport, folder: pathlib.Path | None = None,
                 json_path: pathlib.Path | None = None) -> None:
    """Every file a validation writes: the report ``folder`` (:func:`write_folder`) and the JSON document alone at
    ``json_path``, where given. Raises OSError where either cannot be written."""
    if folder is not None:
        write_folder(folder, ident, doc)
    if json_path is not None:
        write_json(json_path, doc)


def write_folder(folder: pathlib.Path, ident: Identification, doc: ValidationReport) -> None:
    """The report folder of a validation: :data:`MARKDOWN` (:func:`markdown`), :data:`FIGURE` (:func:`plot`)
    and :data:`DOCUMENT` (the JSON document ``doc``), the folder made if needed, each file written whole
    (:func:`hexsim.tables.write_atomic`). Raises OSError where the folder cannot be made."""
    folder.mkdir(parents=True, exist_ok=True)
    plot(ident, folder / FIGURE, doc["verdict"])
    write_atomic(folder / MARKDOWN, lambda tmp: tmp.write_text(markdown(doc, [FIGURE]), encoding="utf-8"))
    write_json(folder / DOCUMENT, doc)


def plus_minus(v: dict) -> str:
    """'value ± s.e. unit', or 'value unit (no s.e.: at a bound)' when the s.e. could not be estimated."""
    se = v.get("std_error")
    if se is None or not math.isfinite(se):
        return f"{v['value']:.4g} {v['unit']} (no s.e.: at a bound)"
    return f"{v['value']:.4g} ± {se:.2g} {v['unit']}"


def _md(text: str) -> str:
    """Text for a Markdown table cell: pipes escaped."""
    return str(text).replace("|", "\\|")


def _fmt(value: float, unit: str) -> str:
    """A value in the unit a person reads: Pa as bar, m as mm or µm."""
    if unit == "Pa":
        return f"{value / 1e5:.4g} bar"
    if unit == "m":
        return f"{value * 1e3:.4g} mm" if abs(value) >= 1e-3 else f"{value * 1e6:.3g} µm"
    return f"{value:.4g} {unit}"


def _discovery_markdown(doc: dict) -> list[str]:
    """The report's discovery section (none when discovery did not run)."""
    lines: list[str] = []
    disc = doc.get("discovery")
    if disc and disc.get("done"):
        lines += ["", "## Discovery (sparse correction of the flow and force equations)", "", disc["method"] + ".", ""]
        if disc["terms"]:
            lines += ["| equation | term | coefficient ± s.e. | meaning | added to the model |", "|---|---|---|---|---|"]
            for t in disc["terms"]:
                key = f"{t['equation']}:{t['term']}"
                key = f"leg{t['leg']}:{key}" if t.get("leg") else key
                lines.append(f"| {t['equation']} | {_md(t['term'])} | {t['coefficient']:.4g} ± {t['std_error']:.2g} "
                             f"{_md(t['unit'])} | {_md(t['meaning'])} | {'yes' if key in disc['added_to_model'] else 'no'} |")
            if disc.get("added_to_model"):
                lines += ["", "| channel | held-out RMS before | after |", "|---|---|---|"]
                for ch, v in disc["held_out_rms_before"].items():
                    u = doc["units"][ch]
                    lines.append(f"| {ch} | {_fmt(v, u)} | {_fmt(disc['held_out_rms_after'][ch], u)} |")
        else:
            lines.append(disc.get("why", "No term found."))
    return lines


def effect_label(entry: dict) -> str:
    """Name of an added effect or candidate of the JSON, with its leg: ``leakage@leg3``."""
    name = entry.get("name", entry.get("effect"))
    return name if entry.get("leg") is None else f"{name}@leg{entry['leg']}"


def markdown(doc: dict, png_names: list[str]) -> str:
    effects = " + ".join(f"`{effect_label(e)}`" for e in doc["added_effects"]) or "none"
    lines = [f"# Validation of `{doc['log']}`", "", f"Machine: {doc['machine']}.", "",
             f"**Verdict: {doc['verdict']}** — added effects: {effects}", ""]
    lines += [f"- {c}" for c in doc["conclusions"]] + [""]
    for e in doc["added_effects"]:
        lines.append(f"`{effect_label(e)}`: " + _md(", ".join(f"{k} = {plus_minus(v)}" for k, v in e["parameters"].items())))
    lines += ["", f"Replay: {doc['replay']} (model: {doc.get('model', 'platform')})", "", "## Error per channel", "",
              "| channel | NRMSE before | NRMSE after | budget (noise, tolerance; of it the calibration's) |",
              "|---|---|---|---|"]
    for ch, before in doc["error_before"].items():
        b, u = doc["budget"][ch], doc["units"][ch]
        cal = f"; {_fmt(b['calibration'], u)}" if b.get("calibration") else ""
        lines.append(f"| {ch} | {before:.4g} | {doc['error_after'][ch]:.4g} | {_fmt(b['budget'], u)} "
                     f"({_fmt(b['noise'], u)}, {_fmt(b['tolerance'], u)}{cal}) |")
    multi = {ch: v for ch, v in doc["held_out_rms_per_signal"].items() if len(v) > 1}
    if multi:
        lines += ["", "## Held-out RMS per leg / axis", "", "| channel | signal | before | after |", "|---|---|---|---|"]
        for ch, per in multi.items():
            for label, v in per.items():
                u = doc["units"][ch]
                lines.append(f"| {ch} | {label} | {_fmt(v['before'], u)} | {_fmt(v['after'], u)} |")
    lines += ["", "## Sensor calibration (nuisance, fitted with every model)", "", "| channel | offset | scale |",
              "|---|---|---|"]
    for ch, cal in doc["calibration"]["final"].items():
        u = doc["units"][ch]
        lines.append(f"| {ch} | {', '.join(_fmt(o, u) for o in cal['offset'])} | "
                     f"{', '.join(f'{s_:.4f}' for s_ in cal['scale'])} |")
    if doc["candidates"]:
        lines += ["", "## Candidates", "", "| effect | on top of | parameters ± s.e. | held-out gain | p | accepted / why not |",
                  "|---|---|---|---|---|---|"]
        for c in doc["candidates"]:
            ps = ", ".join(f"{k} = {plus_minus(v)}" for k, v in c["parameters"].items())
            why = "accepted" if c["accepted"] else "; ".join(c["rejected_because"])
            lines.append(f"| {effect_label(c)} | {', '.join(c['on_top_of']) or 'nominal'} | {_md(ps)} | "
                         f"{c['held_out_gain']:+.3f} | {c['p_value']:.2g} | {_md(why)} |")
    else:
        lines += ["", "No candidate was fitted: the nominal model leaves nothing beyond noise and tolerance."]
    for i, table in enumerate(doc.get("screening") or []):
        if table:
            out = [f"{t['candidate']} ({t['start_cost_ratio']:.3g})" for t in table if not t["fitted"]]
            lines += ["", f"Screened out in round {i + 1} (cost of the best start on the search segments relative "
                      f"to the model it extends; only the best were fitted): " + _md(", ".join(out)) + "."]
    lines += _discovery_markdown(doc)
    lines += _residuals_markdown(doc)
    lines += ["", f"Not checked (columns missing): {', '.join(doc['not_checked']) or 'nothing'}.",
              f"Assumed: {'; '.join(doc['assumed']) or 'nothing'}.", ""]
    lines += [f"![{n}]({n})" for n in png_names]
    return "\n".join(lines) + "\n"


def _residuals_markdown(doc: dict) -> list[str]:
    """The report's residual sections: whiteness, correlation with u_v and spectrum before → after, and
    the RMS of the residual before per class of the motion state."""
    where = f" (position and P1 of leg{doc['residuals_leg']})" if doc.get("residuals_leg") else ""
    lines = ["", f"## Residual before → after{where}", "", "| channel | Ljung–Box p | max cross-corr. with u_v (bound) | "
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
        lines.append(f"| {_md(cls)} | " + " | ".join(row) + " |")
    return lines


def plot(ident: Identification, path: pathlib.Path, verdict: str | None = None) -> None:
    from matplotlib.figure import (
        Figure,  # no pyplot: the user's backend is never switched
    )

    from hexsim.measured.residuals import spectrum
    from hexsim.outputs.plotting import save_figure

    p = ident.problem
    chans = p.channels
    fig = Figure(figsize=(15, 3 * len(chans)), layout="tight")
    ax = fig.subplots(len(chans), 3, squeeze=False)
    fs = p.log.sample_rate_hz
    u, vel, pos, near = p.motion_state()
    before, after = p.analysis_view(ident.nominal_residuals), p.analysis_view(ident.chosen_residuals)
    tw = p.sample_times()
    for i, ch in enumerate(chans):
        b, a = before[ch], after[ch]
        ax[i, 0].plot(tw.ravel(), b.ravel(), ",", color="C3", label="before")
        ax[i, 0].plot(tw.ravel(), a.ravel(), ",", color="C0", label="after")
        leg = f" leg{p.focus_leg}" if p.focus_leg is not None and ch in ("position", "p1") else ""
        ax[i, 0].set_ylabel(f"{ch}{leg} residual [{p.units[ch]}]")
        ax[i, 0].legend(loc="upper right", markerscale=20)
        ax[i, 1].plot(vel.ravel(), b.ravel(), ",", color="C3")
        ax[i, 1].plot(vel.ravel(), a.ravel(), ",", color="C0")
        ax[i, 1].set_xlabel("measured velocity [m/s]")
        f, pb = spectrum(b, fs)
        _, pa = spectrum(a, fs)
        peak = max(float(pb.max()), float(pa.max()))
        if peak > 0:  # a floor 100 dB under the peak, as the run's spectrum; zeros cannot be log-scaled
            ax[i, 2].semilogy(f, np.maximum(pb, 1e-10 * peak), color="C3")
            ax[i, 2].semilogy(f, np.maximum(pa, 1e-10 * peak), color="C0")
        else:
            ax[i, 2].text(0.5, 0.5, "residual zero: no spectrum", transform=ax[i, 2].transAxes, ha="center")
        ax[i, 2].set_xlabel("frequency [Hz]")
        ax[i, 2].set_ylabel("PSD")
    ax[-1, 0].set_xlabel("time [s]")
    added = " + ".join(fit_label(f) for f in ident.accepted) or "nothing"
    fig.suptitle(f"{p.log.path.name}: residual before (red) / after adding {added} (blue), verdict {verdict or ident.verdict}")
    save_figure(fig, path, dpi=90)


def fit_label(fit) -> str:
    """``leakage`` or ``leakage on leg3``."""
    return fit.name if fit.leg is None else f"{fit.name} on leg{fit.leg}"


def log_lines(log) -> list[str]:
    """What ``hexsim validate`` says of a log before judging it: its machine, what it assumed and the checks its
    missing columns leave out (a :class:`hexsim.measured.measurement.MeasurementLog`)."""
    lines = [f"machine: {log.machine.label}", *(f"assumed: {note}" for note in log.assumed)]
    if log.missing:
        lines.append(f"not checked (missing columns): {', '.join(log.missing)}")
    return lines


def summary(doc: dict) -> str:
    """The validation document ``doc`` (:func:`hexsim.measured.validation.validate`) as ``hexsim validate``
    prints it: the windows left out, the verdict and its conclusions, the added effects with their values, each
    channel's error before and after, and every candidate tried with why it was accepted or rejected."""
    from hexsim.measured.scoring import left_out_text

    lines = []
    left_out = doc["windows"].get("left_out")
    if left_out and left_out_text(left_out):
        lines.append(f"left out: {left_out_text(left_out)}")
    lines.append(f"verdict: {doc['verdict']}")
    lines += [f"  {line}" for line in doc["conclusions"]]
    lines.append(f"added effect: {doc['added_effect']}")
    lines += [f"  {effect_label(effect)}: " + ", ".join(f"{k} = {plus_minus(v)}" for k, v in effect["parameters"].items())
              for effect in doc["added_effects"]]
    lines.append(f"{'channel':14s} {'NRMSE before':>13s} {'after':>9s} {'held-out RMS / budget':>22s}")
    lines += [f"{ch:14s} {before:13.4g} {doc['error_after'][ch]:9.4g} {doc['held_out_rms_in_budgets'][ch]:22.3g}"
              for ch, before in doc["error_before"].items()]
    if doc["candidates"]:
        lines.append(f"{'candidate':20s} {'on top of':>16s} {'held-out gain':>13s} {'p':>9s}  verdict")
    for c in doc["candidates"]:
        why = "accepted" if c["accepted"] else "; ".join(c["rejected_because"])
        lines.append(f"{effect_label(c):20s} {'+'.join(c['on_top_of']) or 'nominal':>16s} {c['held_out_gain']:+13.3f} "
                     f"{c['p_value']:9.2g}  {why}")
    return "\n".join(lines)
