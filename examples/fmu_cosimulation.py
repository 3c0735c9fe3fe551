"""The leg and platform FMUs (``hexsim fmu``) simulated by fmpy as a user's tool would, beside ``hexsim run`` on
the same machine: the mean reversal peak at communication steps of 1-10 ms and each interpolation, and the
wall time against the run's (docs/fmu.md's table).

    pip install fmpy          # or pip install "hexsim[test]"
    python examples/fmu_cosimulation.py [--duration 12] [--steps 1,2,5,10] [--out fmus]
"""

from __future__ import annotations

import argparse
import pathlib
import time

import numpy as np
from fmpy import simulate_fmu

from hexsim.control.scenario import make_scenario
from hexsim.engine.config import RunConfig
from hexsim.engine.runner import simulate
from hexsim.interfaces.cosim import INTERPOLATIONS, peak_hold_reversal_peaks
from hexsim.interfaces.fmu import PLATFORM_INPUTS, build_fmu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=12.0)
    parser.add_argument("--steps", default="1,2,5,10", help="communication steps [ms]")
    parser.add_argument("--out", type=pathlib.Path, default=pathlib.Path("fmus"))
    args = parser.parse_args()
    steps = [float(s) * 1e-3 for s in args.steps.split(",")]
    fmus = {"actuator": build_fmu("leg", args.out), "heave": build_fmu("platform", args.out)}
    print("| FMU, scenario | step | interpolation | mean reversal peak: FMU / run | worst single reversal | "
          "wall time: FMU / run |")
    print("|---|---|---|---|---|---|")
    for scenario_name, path in fmus.items():
        scenario = make_scenario(scenario_name, duration=args.duration)
        start = time.perf_counter()
        run = simulate(RunConfig.from_machine(None, scenario))
        run_wall = time.perf_counter() - start
        for h in steps:
            for interpolation in ("cubic", "linear", "hold"):
                if interpolation != "cubic" and h < max(steps):
                    continue  # the others at the longest step only
                times = np.arange(0.0, args.duration, h)
                if scenario_name == "actuator":
                    # the piston setpoint at each communication point: mid-stroke (where the fade-in starts) + the sine
                    names, values = ["y_ref"], (run.y_ref[0, 0] + scenario.axis_setpoint(times))[:, None]
                    axis = "acc"
                else:
                    names, values = [p.name for p in PLATFORM_INPUTS], scenario.poses(times)
                    axis = "acc_z"
                signal = np.zeros(len(times), dtype=[("time", float)] + [(n, float) for n in names])
                signal["time"] = times
                for k, n in enumerate(names):
                    signal[n] = values[:, k]
                start = time.perf_counter()
                result = simulate_fmu(str(path), start_time=0.0, stop_time=args.duration - h, output_interval=h,
                                      input=signal, output=["sample_time", f"{axis}_max", f"{axis}_min"],
                                      start_values={"duration_s": args.duration,
                                                    "interpolation": INTERPOLATIONS[interpolation]})
                wall = time.perf_counter() - start
                fmu, ran = peak_hold_reversal_peaks(result["sample_time"], result[f"{axis}_max"],
                                                    result[f"{axis}_min"], run, h)
                print(f"| {path.stem}, {scenario_name} {args.duration:g} s | {h * 1e3:g} ms | {interpolation} | "
                      f"{fmu.mean():.4f} / {ran.mean():.4f} = {fmu.mean() / ran.mean():.3f} | "
                      f"{np.max(np.abs(fmu / ran - 1)) * 100:.1f} % | {wall:.1f} / {run_wall:.1f} s = "
                      f"{wall / run_wall:.1f}x |")


if __name__ == "__main__":
    main()
