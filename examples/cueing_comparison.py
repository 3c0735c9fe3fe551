"""The manoeuvre library cued three ways on the Micro Motion System, side by side: the classical washout with
its defaults, the classical washout tuned to the library (``hexsim cue-tune``) and model-predictive cueing
(``--cueing mpc``), each through the inverse kinematics, the hydraulics and the compensator.

    python examples/cueing_comparison.py [--out FIGURE.png] [--compensator NAME] [--iterations 30]
                                         [--manoeuvres braking,lane-change,slalom,road-bumps,take-off] [--rrd]

(everything it writes goes beside the figure, named after it: the vehicle CSVs, the tuned washout, each drive's
JSON, the table)

1. each manoeuvre's motion at the driver's head, from the vehicle models of ``examples/vehicle_cueing.py``
   (nothing downloaded), written as a vehicle-motion CSV;
2. ``hexsim cue-tune`` on all of them (the washout file ``FIGURE_tuned.json``);
3. ``hexsim run vehicle:CSV`` with the defaults, ``--washout FIGURE_tuned.json`` and ``--cueing mpc``, each with
   ``--compensator`` (default none) and ``--json``; ``--rrd`` too with ``--rrd``;
4. the table (markdown, on stdout and in ``FIGURE.md``): per manoeuvre and cueing, the sensed-cue
   correlation on each axis the vehicle moves (its sensed cue passes the axis' perception threshold), the
   false cues of the washout, of the hardware and at reversal bumps (all axes), the bumps a seated driver
   feels at the legs' reversals (ISO 2631-1, where the ideal platform is quiet), how many times a leg reverses,
   the legs' least stroke margin; and the figure, the correlations and the bumps felt.

It made the side-by-side table of docs/motion-cueing.md.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from vehicle_cueing import MANOEUVRES, write_vehicle_csv  # noqa: E402

CUEINGS = ("classical", "tuned", "mpc")


def run(csv: pathlib.Path, cueing: str, tuned: pathlib.Path, compensator: str, rrd: bool) -> dict:
    """One drive's cue report (the run's JSON, written beside ``csv``)."""
    from hexsim.cli import main as hexsim

    json_path = csv.with_name(f"{csv.stem}_{cueing}.json")
    args = ["run", f"vehicle:{csv}", "--compensator", compensator, "--quiet", "--json", str(json_path)]
    args += {"classical": [], "tuned": ["--washout", str(tuned)], "mpc": ["--cueing", "mpc"]}[cueing]
    if rrd:
        args += ["--rrd", str(csv.with_name(f"{csv.stem}_{cueing}.rrd"))]
    if hexsim(args) != 0:
        raise SystemExit(f"hexsim {' '.join(args)} failed")
    return json.loads(json_path.read_text())


def moving_axes(doc: dict) -> list[str]:
    """The axes the vehicle moves on (module doc)."""
    return [a for a, f in doc["axes"].items() if f["peak_vehicle"] > f["sensed_threshold"]]


def row(manoeuvre: str, cueing: str, doc: dict, axes: list[str]) -> str:
    corr = ", ".join(f"{a} {doc['axes'][a]['correlation']:+.2f}" if doc["axes"][a]["correlation"] is not None
                     else f"{a} —" for a in axes)
    fc = doc["false_cues"]
    felt = sum(s["perceptible_at_reversals"] for s in doc["seat"].values())
    worst = max(s["max_weighted_mps2"] for s in doc["seat"].values())
    margin = 1e3 * doc["legs"]["min_stroke_margin_m"]
    return (f"| {manoeuvre} | {cueing} | {corr} | {fc['washout']} / {fc['hardware']} / {fc['reversal_bump']} | "
            f"{felt} ({worst:.3f} m/s²) | {doc['leg_reversals']} | {margin:.0f} mm |")


def figure(results: dict, axes: dict[str, list[str]], path: pathlib.Path) -> None:
    """The correlations (mean over each manoeuvre's moving ``axes``) and the bumps felt, per cueing."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(results)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.2))
    width = 0.26
    for k, cueing in enumerate(CUEINGS):
        corr = [np.mean([results[n][cueing]["axes"][a]["correlation"] or 0.0 for a in axes[n]]) for n in names]
        felt = [sum(s["perceptible_at_reversals"] for s in results[n][cueing]["seat"].values()) for n in names]
        x = np.arange(len(names)) + (k - 1) * width
        ax1.bar(x, corr, width, label=cueing)
        ax2.bar(x, felt, width, label=cueing)
    for ax, title in ((ax1, "sensed-cue correlation (mean over the moving axes)"),
                      (ax2, "bumps felt at the seat at leg reversals")):
        ax.set_xticks(np.arange(len(names)), names)
        ax.set_title(title)
        ax.axhline(0.0, color="k", lw=0.5)
        ax.legend()
    ax1.axhline(0.8, color="grey", ls="--", lw=0.8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=pathlib.Path, default=pathlib.Path("cueing_comparison.png"),
                        help="the figure (.png); everything else beside it, named after it")
    parser.add_argument("--compensator", default="none")
    parser.add_argument("--iterations", type=int, default=30, help="hexsim cue-tune's generations (default 30)")
    parser.add_argument("--manoeuvres", default=",".join(MANOEUVRES))
    parser.add_argument("--rrd", action="store_true", help="a rerun recording of every drive as well")
    args = parser.parse_args(argv)
    names = [n for n in args.manoeuvres.split(",") if n]
    unknown = [n for n in names if n not in MANOEUVRES]
    if unknown:
        parser.error(f"unknown manoeuvre {unknown[0]!r}; choose from {', '.join(MANOEUVRES)}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    csvs = {}
    for name in names:
        csvs[name] = args.out.with_name(f"{args.out.stem}_{name}.csv")
        write_vehicle_csv(csvs[name], MANOEUVRES[name]())
    from hexsim.cli import main as hexsim

    tuned = args.out.with_name(f"{args.out.stem}_tuned.json")
    start = time.perf_counter()
    if hexsim(["cue-tune", *map(str, csvs.values()), "--out", str(tuned), "--iterations", str(args.iterations)]) != 0:
        return 1
    print(f"tuned the washout on {len(names)} manoeuvres in {time.perf_counter() - start:.0f} s", flush=True)
    results = {name: {c: run(csvs[name], c, tuned, args.compensator, args.rrd) for c in CUEINGS}
               for name in names}
    lines = [f"compensator {args.compensator}; correlation of the sensed cue on each axis the vehicle moves; "
             "false cues washout / hardware / reversal bump (all axes); bumps felt at the seat at leg reversals "
             "(largest hardware cue, ISO 2631-1 weighted); leg reversals; least stroke margin", "",
             "| manoeuvre | cueing | correlation | false cues | felt at reversals | leg reversals | margin |",
             "|---|---|---|---|---|---|---|"]
    axes = {name: moving_axes(results[name]["classical"]) for name in names}
    for name in names:
        lines += [row(name, c, results[name][c], axes[name]) for c in CUEINGS]
    solver = [(n, results[n]["mpc"]) for n in names]
    lines += ["", "MPC: " + "; ".join(
        f"{n} {d['cueing_solver']['real_time_factor']:.1f}x real time (mean solve "
        f"{d['cueing_solver']['solve_ms_mean']:.1f} ms, largest {d['cueing_solver']['solve_ms_max']:.0f} ms, "
        f"{d['cueing_solver']['unsolved']} unsolved)" for n, d in solver)]
    text = "\n".join(lines)
    print(text)
    table = args.out.with_suffix(".md")
    table.write_text(text + "\n")
    figure(results, axes, args.out)
    print(f"wrote {table}, {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
