"""The acceptance report: every measured figure with its tolerance and pass/fail, per compensator, as
Markdown with its figures (Bode plots of the frequency response and the OMCT, the turn-around bumps) and
JSON. Only shows: the figures come from :mod:`hexsim.studies.acceptance`."""

from __future__ import annotations

import pathlib

import numpy as np
from matplotlib.figure import Figure

from hexsim.outputs.plotting import save_figure
from hexsim.tables import write_atomic, write_json


def _status(passed: bool | None) -> str:
    return "—" if passed is None else ("pass" if passed else "**FAIL**")


def _value(check) -> str:
    v = check.value
    return f"{v:.4g} {check.unit}".strip() if isinstance(v, float) else f"{v} {check.unit}".strip()


def markdown(results: list, tolerances, figures: list[str]) -> str:
    """The report's text: the machine, the tolerance file and its source, a verdict per compensator, then
    one table of every check (a value and a status column per compensator) and the figures."""
    names = [r.compensator for r in results]
    lines = [f"# Motion acceptance tests: {results[0].machine}", "",
             f"Tolerances: `{tolerances.path}` ({tolerances.source or 'no source given'}). Tests: "
             f"{', '.join(tolerances.run)}. Method: docs/acceptance.md.", ""]
    for r in results:
        judged = [c for c in r.checks if c.passed is not None]
        failed = [c for c in judged if not c.passed]
        lines.append(f"- compensator **{r.compensator}**: {len(judged) - len(failed)} of {len(judged)} checks with a "
                     f"tolerance passed" + (f"; failed: {', '.join(c.item for c in failed[:6])}"
                                            f"{' …' if len(failed) > 6 else ''}" if failed else ""))
    lines += ["", "| test | item | tolerance | " + " | ".join(f"{n} | {n}: status" for n in names) + " |",
              "|---|---|---|" + "---|---|" * len(names)]
    for i, check in enumerate(results[0].checks):
        cells = []
        for r in results:
            c = r.checks[i]
            cells += [_value(c), _status(c.passed)]
        lines.append(f"| {check.test} | {check.item} | {check.limit or 'none given'} | " + " | ".join(cells) + " |")
    lines.append("")
    lines += [f"![{name}]({name})" for name in figures]
    return "\n".join(lines) + "\n"


def _bode(path: pathlib.Path, results: list, attr: str, title: str) -> None:
    series = getattr(results[0], attr)
    fig = Figure(figsize=(12, 6.5), layout="constrained")
    gain, phase = fig.subplots(2, 1, sharex=True)
    for k, name in enumerate(series):
        for j, r in enumerate(results):
            f, g, p = getattr(r, attr)[name]
            style = ("-", "--", ":")[j % 3]
            label = f"{name}" + (f" ({r.compensator})" if len(results) > 1 else "")
            gain.semilogx(f, g, style, marker="o", ms=3, color=f"C{k}", label=label)
            phase.semilogx(f, np.degrees(np.unwrap(np.radians(p))), style, marker="o", ms=3, color=f"C{k}")
    gain.set(title=title, ylabel="gain [dB]")
    phase.set(xlabel="frequency [Hz]", ylabel="phase [deg] (unwrapped)")
    gain.legend(fontsize=7, ncol=2)
    for a in (gain, phase):
        a.grid(True, which="both", lw=0.3)
    save_figure(fig, path, dpi=90)


def _turn_around(path: pathlib.Path, results: list) -> None:
    dofs = list(results[0].turn_around)
    fig = Figure(figsize=(9, 4), layout="constrained")
    ax = fig.subplots()
    width = 0.8 / len(results)
    for j, r in enumerate(results):
        peaks = [r.turn_around[d]["max_bump"] for d in dofs]
        ax.bar(np.arange(len(dofs)) + j * width, peaks, width, label=r.compensator)
    ax.set_xticks(np.arange(len(dofs)) + 0.4 - width / 2, [f"{d} [{results[0].turn_around[d]['unit']}]" for d in dofs])
    ax.set(title="turn-around check: largest reversal bump (acceleration minus its fundamental)", ylabel="bump")
    ax.legend()
    save_figure(fig, path, dpi=90)


def write_report(folder: pathlib.Path, results: list, tolerances) -> list[pathlib.Path]:
    """Write report.md, acceptance.json and the figures (frequency_response.png, omct.png,
    turn_around.png, those the tests made) into ``folder`` (made if missing, its parent must exist);
    each file atomically. Returns the paths written."""
    folder.mkdir(exist_ok=True)
    written, figures = [], []
    for attr, name, title in (("bode", "frequency_response.png", "frequency response: measured pose / setpoint"),
                              ("omct", "omct.png", "OMCT: simulator at the head / vehicle input")):
        if getattr(results[0], attr):
            _bode(folder / name, results, attr, title)
            figures.append(name)
    if results[0].turn_around:
        _turn_around(folder / "turn_around.png", results)
        figures.append("turn_around.png")
    write_json(folder / "acceptance.json", {"tolerances": tolerances.path, "source": tolerances.source,
                                            "results": [r.document() for r in results]})
    text = markdown(results, tolerances, figures)
    write_atomic(folder / "report.md", lambda tmp: tmp.write_text(text, encoding="utf-8"))
    written += [folder / "report.md", folder / "acceptance.json", *(folder / f for f in figures)]
    return written
