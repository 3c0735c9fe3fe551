"""A real servo cylinder against hexsim: every measured open-loop run replayed from the machine file.

Source: a servo-valve controlled differential cylinder (bore 16 mm, rod 10 mm, stroke 0.2 m, about 44 bar),
open-loop runs at constant command +U then -U, published in the public repository
ingxfm/find-the-viscous-friction-value-from-a-bunch-of-.mat-data-files (examples/data/servo_cylinder/README.md).
The machine file is hexsim's built-in ``servo_cylinder`` (models/machines/servo_cylinder.json): the
source's geometry and supply, friction from ``hexsim friction`` on the paired runs, the rest guesses.

For each log it runs ``hexsim.simulate`` on the log's own valve command (``valve:LOG.csv``, open loop,
from the log's first position) and compares the steady motions, measured and simulated, with the same
function (:func:`hexsim.studies.metrics.steady_segments`): speed and the chamber pressure that run
logged (p1 in the pA runs, p2 in the pB runs). It prints the table of docs/servo-cylinder.md and plots
position and pressure, measured against simulated, for one log.

    python examples/servo_cylinder.py [--machine servo_cylinder] [--only 3V] [--out servo_cylinder.png]
"""

from __future__ import annotations

import argparse
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import hexsim  # noqa: E402
from hexsim.control.scenario import make_scenario  # noqa: E402
from hexsim.measured.measurement import read_log  # noqa: E402
from hexsim.studies.metrics import steady_segments  # noqa: E402

DATA = pathlib.Path(__file__).resolve().parent / "data" / "servo_cylinder"


def compare(path: pathlib.Path, machine: hexsim.Machine) -> tuple[list[dict], hexsim.SimulationResult]:
    """Rows (log, u_V, measured/simulated speed and pressure) of one log, and the simulated run."""
    log = read_log(path, machine=machine)
    channel = "p1_Pa" if "p1_Pa" in log.columns else "p2_Pa"
    sim = hexsim.simulate(hexsim.RunConfig.from_machine(machine, make_scenario(f"valve:{path}")))
    measured = steady_segments(log.time, log.columns["valve_cmd_V"], log.columns["pos_m"],
                               {"p": log.columns[channel]})
    simulated = steady_segments(sim.t, sim.u_v[:, 0], sim.y[:, 0],
                                {"p": sim.p1[:, 0] if channel == "p1_Pa" else sim.p2[:, 0]})
    rows = []
    for m in measured:
        s = next((s for s in simulated if s["u_V"] == m["u_V"]), None)
        if s is None:
            continue
        rows.append({"log": path.stem, "u_V": m["u_V"], "channel": channel[:2],
                     "v_meas": m["velocity_mps"], "v_sim": s["velocity_mps"], "p_meas": m["p"], "p_sim": s["p"]})
    return rows, sim


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--machine", default="servo_cylinder", help="machine file or built-in name")
    ap.add_argument("--only", default="", help="only logs whose name contains this (e.g. 3V)")
    ap.add_argument("--out", default="servo_cylinder.png")
    args = ap.parse_args()
    machine = hexsim.load_machine(args.machine)
    paths = sorted(p for p in DATA.glob("cyl_*.csv") if args.only in p.name)
    print(f"machine {machine.label}")
    print(f"{'log':18s} {'u_v':>6s} {'speed meas':>11s} {'sim':>8s} {'err':>6s}   {'p':2s} {'meas':>7s} {'sim':>7s} {'err':>7s}")
    speed_err, p_err, plotted = [], [], None
    for path in paths:
        rows, sim = compare(path, machine)
        plotted = plotted or (path, sim)
        for r in rows:
            e_v = r["v_sim"] / r["v_meas"] - 1.0
            e_p = (r["p_sim"] - r["p_meas"]) / 1e5
            speed_err.append(abs(e_v))
            p_err.append(abs(e_p))
            print(f"{r['log']:18s} {r['u_V']:+5.1f}V {r['v_meas'] * 1e3:+9.1f}mm/s {r['v_sim'] * 1e3:+7.1f} {e_v:+6.1%}   "
                  f"{r['channel']} {r['p_meas'] / 1e5:6.2f}bar {r['p_sim'] / 1e5:6.2f} {e_p:+6.2f}bar")
    print(f"{len(speed_err)} steady motions: speed error mean {np.mean(speed_err):.1%}, worst {np.max(speed_err):.1%}; "
          f"pressure error mean {np.mean(p_err):.2f} bar, worst {np.max(p_err):.2f} bar")

    path, sim = plotted
    log = read_log(path, machine=machine)
    channel = "p1_Pa" if "p1_Pa" in log.columns else "p2_Pa"
    fig, ax = plt.subplots(2, 1, figsize=(9, 6), sharex=True, layout="constrained")
    ax[0].plot(log.time, log.columns["pos_m"] * 1e3, lw=0.8, label="measured")
    ax[0].plot(sim.t, sim.y[:, 0] * 1e3, lw=0.8, ls="--", label="hexsim")
    ax[0].set(ylabel="piston position [mm]", title=f"{path.name}: measured vs hexsim ({machine.name}, open loop)")
    ax[1].plot(log.time, log.columns[channel] / 1e5, lw=0.6, label=f"measured {channel}")
    ax[1].plot(sim.t, (sim.p1 if channel == "p1_Pa" else sim.p2)[:, 0] / 1e5, lw=0.8, ls="--", label="hexsim")
    ax[1].set(xlabel="time [s]", ylabel="pressure [bar]")
    for a in ax:
        a.legend(fontsize=8)
    fig.savefig(args.out, dpi=90)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
