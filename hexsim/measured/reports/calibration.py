"""The calibration's report (:func:`hexsim.measured.calibration.calibrate`): the terminal table, Markdown and the
features figure (each feature's error in its weight, the machine file's and the calibrated)."""

from __future__ import annotations

import math
import pathlib

import numpy as np

from hexsim.measured.estimates import AT_A_BOUND, FITTED, HELD
from hexsim.tables import write_atomic

#: The files of a calibration's report folder.
FIGURE, MARKDOWN = "features.png", "report.md"


def write_folder(folder: pathlib.Path, report: dict) -> None:
    """The report folder of a calibration: :data:`MARKDOWN` (:func:`markdown`) and :data:`FIGURE`
    (:func:`plot_features`), the folder made if needed, each file written whole. Raises OSError where the
    folder cannot be made."""
    folder.mkdir(parents=True, exist_ok=True)
    plot_features(report, folder / FIGURE)
    write_atomic(folder / MARKDOWN, lambda tmp: tmp.write_text(markdown(report, FIGURE), encoding="utf-8"))


def status(row: dict) -> str:
    """A parameter row's status, why (all but fitted) and, held or at a bound, the experiment that would identify it
    (issue 52: nothing at a bound without the experiment that frees it)."""
    text = row["status"] if row["status"] == FITTED else f"{row['status']}: {row.get('why', '')}"
    if row["status"] in (HELD, AT_A_BOUND) and row.get("experiment"):
        text += f"; identify it with {row['experiment']}"
    return text


def table(report: dict) -> str:
    """The report as lines for stdout: parameters, then errors before/after, held out, left out."""
    lines = [f"{'parameter':30s} {'prior':>11s} {'calibrated':>11s} {'± s.e.':>9s}  status"]
    for r in report["parameters"]:
        lines.append(f"{r['key']:30s} {r['prior']:11.5g} {r['value']:11.5g} {r['std_error']:9.2g}  {status(r)}")

    def errs(e: dict) -> str:
        s = (f"speed {e['speed_error_mean']:.1%} mean, {e['speed_error_max']:.1%} worst ({e['speeds']})"
             if e["speeds"] else "no speed")
        if e["pressures"]:
            s += (f"; pressure {e['pressure_error_mean_Pa'] / 1e5:.2f} bar mean, "
                  f"{e['pressure_error_max_Pa'] / 1e5:.2f} bar worst ({e['pressures']})")
        return s

    def budgets(e: dict) -> str:
        return ", ".join(f"{ch} {v:.3g}" for ch, v in e["held_out_rms_in_budgets"].items() if ch != "p_s")

    def transients(rows: list[dict], what: str) -> None:
        for row in rows:
            head = f"{what} {pathlib.Path(row['before']['log']).name} (RMS / budget) before: "
            lines.extend([head + budgets(row["before"]), f"{'after: ':>{len(head)}s}{budgets(row['after'])}"])

    if "flow_area" in report:
        fa = report["flow_area"]
        lines.append(f"flow area        {fa['chosen']} (prior {fa['prior']}; held-out cost {fa['held_out_cost']:.4g}); "
                     f"{'screened' if len(fa['tried']) > 1 else 'held-out cost'}: " + ", ".join(
            f"{t['flow_area']} {t['held_out_cost']:.4g}" if "held_out_cost" in t else f"{t['flow_area']} refused"
            for t in fa["tried"]))
    if "commands_measured_V" in report:
        lo, hi = report["commands_measured_V"]
        lines.append(f"commands measured {lo:.3g}…{hi:.3g} V at the spool (the logs dwelt there): beyond, the valve's "
                     "curve is the calibration's extrapolation, and a validation or a tuned compensator there rests on "
                     "it; add a log that dwells where the machine will run")
    if "fit" in report:
        lines.append(f"fitted features  before: {errs(report['fit']['before'])}")
        lines.append(f"                 after:  {errs(report['fit']['after'])}")
    transients(report.get("transients", []), "held-out windows of")
    transients([r for r in report.get("replayed", []) if "after" in r], "windows of")
    held = report.get("held_out", {})
    if "before" in held:
        lines.append(f"held-out logs    before: {errs(held['before'])}")
        lines.append(f"                 after:  {errs(held['after'])}")
    transients(held.get("transients", []), "held-out log")
    for row in report.get("leave_one_log_out", []):
        lines.append(f"left out {pathlib.Path(row['log']).name:22s} {errs(row)}")
    own = report.get("own_budget")
    if own:
        lines.append(own.get("sentence", "The calibrated model reaches its own logs' budget (held-out " + ", ".join(
            f"{ch} {v:.3g}" for ch, v in own["held_out_rms_in_budgets"].items()) + " budgets)."))
    return "\n".join(lines)


def markdown(report: dict, figure: str | None = None) -> str:
    """report.md of a calibration: the machine and logs, the parameters (prior, value, standard error,
    bounds and their source, status and why), the errors before and after, held out and left out."""
    lines = [f"# Calibration of {report['machine']}", "", f"Method: {report['method']}; weights: speed "
             f"{report['weights']['speed']}, pressure {report['weights']['pressure_Pa'] / 1e5:g} bar."
             + (f" Standard errors and correlations: {report['covariance']}." if "covariance" in report else ""), "",
             "Logs fitted: " + ", ".join(f"`{pathlib.Path(p).name}`" for p in report["logs"]), ""]
    if "held_out" in report:
        lines += ["Logs held out: " + ", ".join(f"`{pathlib.Path(p).name}`" for p in report["held_out"]["logs"]), ""]
    lines += ["| key | unit | prior | calibrated | ± s.e. | bounds | bounds from | status |", "|---|---|---|---|---|---|---|---|"]
    for r in report["parameters"]:
        lines.append(f"| `{r['key']}` | {r['unit']} | {r['prior']:.5g} | {r['value']:.5g} | {r['std_error']:.2g} | "
                     f"{r['lower']:.4g} … {r['upper']:.4g} | {r['bounds_source']} | {status(r)} |")
    lines += ["", "```", table(report).split("\n", len(report["parameters"]) + 1)[-1], "```", ""]
    if figure:
        lines += [f"![measured against predicted features]({figure})", ""]
    return "\n".join(lines)


def plot_features(report: dict, path) -> None:
    """Each fitted feature's error, before (the machine file) and after calibration, against its measured
    value: speeds as relative errors [%], pressures in bar; and, with transients, each log's held-out
    windows' RMS per channel in budgets before and after; written atomically (.png, .pdf or .svg)."""
    from matplotlib.figure import (
        Figure,  # no pyplot: the user's backend is never switched
    )

    from hexsim.outputs.plotting import save_figure

    rows = report.get("rows", [])
    transients = report.get("transients", [])
    fig = Figure(figsize=(5.5 * (2 * bool(rows) + bool(transients)), 4.5), layout="constrained")
    axes = list(fig.subplots(1, 2 * bool(rows) + bool(transients), squeeze=False)[0])
    if transients:
        ax = axes.pop()
        labels, before, after = [], [], []
        for row in transients:
            name = pathlib.Path(row["before"]["log"]).stem
            for ch, v in row["before"]["held_out_rms_in_budgets"].items():
                if ch != "p_s":
                    labels.append(f"{name}\n{ch}")
                    before.append(v)
                    after.append(row["after"]["held_out_rms_in_budgets"][ch])
        x = np.arange(len(labels))
        ax.bar(x - 0.2, before, 0.4, label="the machine file")
        ax.bar(x + 0.2, after, 0.4, label="calibrated")
        ax.axhline(math.sqrt(2.0), color="k", lw=0.6, ls="--")
        ax.set_yscale("log")
        ax.set_xticks(x, labels, fontsize=7, rotation=60)
        ax.set(title="transients: held-out windows", ylabel="RMS / budget (dashed: √2)")
        ax.legend(fontsize=8)
    if not rows:
        fig.suptitle(f"hexsim calibrate: {report['machine']}")
        save_figure(fig, path, dpi=90)
        return
    speed_ax, press_ax = axes
    panels = ((speed_ax, lambda r: r["quantity"] == "velocity", "steady speeds", "measured speed [mm/s]",
               "predicted / measured − 1 [%]", lambda r, k: 100.0 * (r[k] / r["measured"] - 1.0), 1e3),
              (press_ax, lambda r: r["quantity"] != "velocity", "chamber pressures (steady, end stops)",
               "measured pressure [bar]", "predicted − measured [bar]", lambda r, k: (r[k] - r["measured"]) / 1e5, 1e-5))
    for ax, pick, title, xlabel, ylabel, error, scale in panels:
        sel = [r for r in rows if pick(r)]
        x = np.array([r["measured"] for r in sel]) * scale
        for key, marker, label in (("before", "x", "the machine file"), ("after", "o", "calibrated")):
            ax.plot(x, [error(r, key) for r in sel], marker, ms=5, ls="none", label=label)
        ax.axhline(0.0, color="k", lw=0.6)
        ax.set(title=title, xlabel=xlabel, ylabel=ylabel)
        ax.legend(fontsize=8)
    fig.suptitle(f"hexsim calibrate: {report['machine']}, fitted features")
    save_figure(fig, path, dpi=90)
