"""An imperceptible reversal bump: the model-based compensators against the seed's, on the built-in machine,
on machines that are not their machine file, and on a machine that drifts.

1. The built-in Micro Motion System (hexsim's model is the machine): every degree of freedom's default sine
   (``hexsim compare DOF --duration D``), none / the seed's buffered / feedforward / adaptive / oracle:
   the final window's mean reversal peak and its reduction against none, the bumps a seated occupant feels
   and the largest ISO 2631-1 weighted seat peak (threshold 0.015 m/s²).
2. Machines off appendix A within data-sheet tolerances: the independent actuator of ``tests/`` (its own
   equations), calibrated on two closed-loop logs (``examples/calibrate_then_validate.calibrated``), with
   hexsim's compensators running inside its own 500 Hz loop on the calibrated file's leg model: none /
   buffered / feedforward / adaptive, mean reversal peak from the third period on.
3. A drifting machine: the oil warms 15 K and the valve's null drifts 0.05 V over ``--drift`` seconds, on the
   Micro Motion System (heave, hexsim's warm-up) and on the independent actuator: none / feedforward /
   adaptive, the reduction, the worst single reversal against none's, and when the adaptive one settled
   (from then on every reversal below a fifth of none's mean).

    python examples/tuned_compensation.py [--dofs heave,roll,...] [--machines port,quadratic,sharp,drawn11]
                                          [--duration 60] [--drift 120] [--out tuned_compensation.png]

It made the tables of docs/compensation.md.
"""

from __future__ import annotations

import argparse
import dataclasses
import pathlib
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from hexsim.control.scenario import make_scenario  # noqa: E402
from hexsim.engine.config import RunConfig  # noqa: E402
from hexsim.engine.runner import simulate  # noqa: E402
from hexsim.plant.machine import load_machine  # noqa: E402
from hexsim.plant.temperature import WarmUp  # noqa: E402
from hexsim.studies.comparison import compare  # noqa: E402
from hexsim.studies.metrics import run_smoothness  # noqa: E402
from hexsim.studies.tuning import leg_model_of  # noqa: E402

HERE = pathlib.Path(__file__).resolve().parent
sys.path[:0] = [str(HERE), str(HERE.parent / "tests")]
from calibrate_then_validate import MACHINES, calibrated, drawn  # noqa: E402
from helpers import in_the_loop, reversal_peaks, truth_smoothness  # noqa: E402

NAMES = ("none", "buffered", "feedforward", "adaptive", "oracle")
DOFS = ("heave", "surge", "sway", "roll", "pitch", "yaw")


def built_in(dofs: list[str], duration: float, jobs: int) -> dict:
    """Part 1: the league per DOF (final window)."""
    print(f"\n1. Micro Motion System, {duration:g} s per DOF, final window (hexsim compare DOF --duration {duration:g})\n")
    print("| DOF | none [m/s² or rad/s²] | buffered | feedforward | adaptive | oracle | felt (ff / adaptive) | "
          "seat W peak, adaptive [m/s²] |")
    print("|---|---|---|---|---|---|---|---|")
    out = {}
    for dof in dofs:
        base = RunConfig.from_machine(load_machine(None), make_scenario(dof, duration=duration))
        entries = {e.compensator: e for e in compare(base, NAMES, jobs=jobs)}
        out[dof] = {n: e.mean_reversal_peak for n, e in entries.items()}
        cells = [f"{entries['none'].mean_reversal_peak:.4f}"]
        cells += [f"{entries[n].mean_reversal_peak:.4f} ({entries[n].reduction_pct:.0f} %)" for n in NAMES[1:]]
        felt = " / ".join(f"{entries[n].perception['perceptible']}/{entries[n].perception['reversals']}"
                          for n in ("feedforward", "adaptive"))
        seat = max(entries["adaptive"].perception["axes"][a]["seat_max_weighted_mps2"] or 0.0 for a in "xyz")
        print(f"| {dof} | " + " | ".join(cells) + f" | {felt} | {seat:.4f} |", flush=True)
    return out


def calibrated_machines(names: list[str], folder: pathlib.Path) -> dict:
    """Part 2: none / buffered / feedforward / adaptive on each independent machine, calibrated."""
    print("\n2. Independent actuators off appendix A, calibrated on two closed-loop logs; 20 s, 0.5 Hz, 50 mm\n")
    print("| machine | none [m/s²] | buffered | feedforward | adaptive |")
    print("|---|---|---|---|---|")
    prior = load_machine(None)
    out = {}
    for name in names:
        truth = MACHINES[name] if name in MACHINES else drawn(int(name[5:]))
        model = leg_model_of(RunConfig.from_machine(load_machine(calibrated(name, truth, folder, prior)), "actuator"))
        means = {n: reversal_peaks(truth, 20.0, None if n == "none" else in_the_loop(n, model)).mean()
                 for n in NAMES[:4]}
        out[name] = means
        print(f"| {name} | {means['none']:.4f} | " + " | ".join(
            f"{means[n]:.4f} ({100 * (1 - means[n] / means['none']):.0f} %)" for n in NAMES[1:4]) + " |", flush=True)
    return out


def drifting(duration: float, folder: pathlib.Path) -> None:
    """Part 3: a 15 K warm-up and a 0.05 V null drift over ``duration``."""
    print(f"\n3. A drifting machine: 15 K warm-up and the null drifting 0.05 V over {duration:g} s\n")
    print("| machine | none [m/s²] | feedforward | adaptive | worst reversal / none's (ff, adaptive) | "
          "adaptive settled after |")
    print("|---|---|---|---|---|---|")
    warm = WarmUp(delta_c=15.0, duration_s=duration, null_drift=0.05 / 15.0)
    base = RunConfig.from_machine(load_machine(None), make_scenario("heave", duration=duration), warm_up=warm)
    runs = {}
    for n in ("none", "feedforward", "adaptive"):
        sm = run_smoothness(simulate(dataclasses.replace(base, compensator=n)))
        runs[n] = (sm.reversal_times, sm.reversal_peaks)
    _drift_row("Micro Motion System, heave", runs)
    truth = MACHINES["port"].replace(null_rate=0.05 / duration, warm_rate=15.0 / duration)
    model = leg_model_of(RunConfig.from_machine(load_machine(calibrated("port", MACHINES["port"], folder,
                                                                        load_machine(None))), "actuator"))
    runs = {}
    for n in ("none", "feedforward", "adaptive"):
        sm = truth_smoothness(truth, duration, None if n == "none" else in_the_loop(n, model))
        runs[n] = (sm.reversal_times, sm.reversal_peaks)
    _drift_row("independent actuator (port), calibrated", runs)


def _drift_row(label: str, runs: dict) -> None:
    t, none = runs["none"]
    cells = [f"{none.mean():.4f}"]
    worst = []
    for n in ("feedforward", "adaptive"):
        peaks = runs[n][1][:len(none)]
        cells.append(f"{peaks.mean():.4f} ({100 * (1 - peaks.mean() / none.mean()):.0f} %)")
        worst.append(f"{np.max(peaks / none[:len(peaks)]):.2f}")
    above = np.flatnonzero(runs["adaptive"][1] > 0.2 * none.mean())
    settled = t[0] if above.size == 0 else (t[above[-1] + 1] if above[-1] + 1 < len(t) else None)
    print(f"| {label} | " + " | ".join(cells) + f" | {', '.join(worst)} | "
          + ("never" if settled is None else f"{settled:.0f} s") + " |", flush=True)


def figure(path: pathlib.Path, dofs: dict, machines: dict) -> None:
    fig, ax = plt.subplots(1, 2, figsize=(11, 4), constrained_layout=True)
    for a, table, title in ((ax[0], dofs, "Micro Motion System (final window)"),
                            (ax[1], machines, "independent actuators, calibrated")):
        labels = list(table)
        if not labels:
            a.set_axis_off()
            continue
        for k, n in enumerate(n for n in NAMES if any(n in row for row in table.values())):
            a.bar(np.arange(len(labels)) + 0.16 * k, [table[x].get(n, np.nan) for x in labels], 0.16, label=n)
        a.set_xticks(np.arange(len(labels)) + 0.32, labels)
        a.set_yscale("log")
        a.set_ylim(top=a.get_ylim()[1] * 10)  # room for the legend above the bars
        a.set_ylabel("mean reversal peak [m/s² or rad/s²]")
        a.set_title(title)
    ax[0].legend(loc="upper center", fontsize=8, ncol=5)
    fig.savefig(path, dpi=110)
    print(f"\nwrote {path}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dofs", default=",".join(DOFS), help="degrees of freedom of part 1 (comma separated)")
    parser.add_argument("--machines", default="port,quadratic,sharp,drawn11,drawn12",
                        help="independent machines of part 2: port, quadratic, sharp or drawnSEED ('': skip parts 2 "
                             "and 3)")
    parser.add_argument("--duration", type=float, default=60.0, help="part 1's run length [s]")
    parser.add_argument("--drift", type=float, default=120.0, help="part 3's run length [s] (0: skip it)")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--work", type=pathlib.Path, help="folder for the calibration logs and files (default: a "
                        "temporary one)")
    parser.add_argument("--out", type=pathlib.Path, default=pathlib.Path("tuned_compensation.png"))
    args = parser.parse_args()
    names = [n for n in args.machines.split(",") if n]
    for name in names:
        if name not in MACHINES and not (name.startswith("drawn") and name[5:].isdigit()):
            parser.error(f"--machines: unknown machine {name!r} ({', '.join(MACHINES)} or drawnSEED)")
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.work or pathlib.Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        dofs = built_in(args.dofs.split(","), args.duration, args.jobs)
        machines = calibrated_machines(names, folder) if names else {}
        if args.drift > 0 and names:
            drifting(args.drift, folder)
    figure(args.out, dofs, machines)


if __name__ == "__main__":
    main()
