"""The reversal bump on the 600 kg Micro Motion System in heave (seed §2.3.1, Fig. 2.7).

Source: "Compensation of the reversal bump", Rexroth-Hydraudyne / TU Eindhoven, 2005. The platform is
driven in heave, A sin(2 pi f t) faded in over one period; the ideal platform acceleration is the
commanded -A (2 pi f)^2 sin(2 pi f t) on top of gravity. The script plots the measured accelerometer
against that ideal and marks the bump at every velocity reversal.

    python examples/heave_bump.py [--duration 20] [--out heave_bump.png]
"""

from __future__ import annotations

import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from hexsim.control.scenario import make_scenario  # noqa: E402
from hexsim.engine.config import RunConfig  # noqa: E402
from hexsim.engine.runner import simulate  # noqa: E402
from hexsim.studies.metrics import run_smoothness  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=20.0)
    parser.add_argument("--frequency", type=float, default=0.5)
    parser.add_argument("--out", default="heave_bump.png")
    args = parser.parse_args()

    sc = make_scenario("heave", duration=args.duration, frequency=args.frequency)
    result = simulate(RunConfig(sc))
    sm = run_smoothness(result)

    w = 2 * np.pi * sc.frequency
    ideal = result.gravity - sc.amplitude * w**2 * np.sin(w * sm.t)  # specific force of the commanded heave
    print(f"commanded acceleration amplitude  {sc.amplitude * w**2:.4f} m/s^2")
    print(f"measured fundamental              {sm.fundamental_amplitude:.4f} m/s^2")
    print(f"noise ratio                       {sm.noise_ratio:.4f}")
    print(f"reversal peaks [m/s^2]            {np.round(sm.reversal_peaks, 3).tolist()}")
    print(f"noise floor away from reversals   {sm.noise_floor:.4f} m/s^2")

    fig, ax = plt.subplots(2, 1, figsize=(10, 7), sharex=True, constrained_layout=True)
    ax[0].plot(sm.t, sm.fit + sm.noise, lw=0.8, label="platform accelerometer z (simulated)")
    ax[0].plot(sm.t, ideal, "k--", lw=1, label="ideal: commanded heave + g")
    ax[0].set(ylabel="specific force z [m/s^2]", title=f"heave {sc.amplitude} m at {sc.frequency} Hz, no compensation")
    ax[0].legend(loc="upper right")
    ax[1].plot(sm.t, sm.noise, color="C3", lw=0.8, label="acceleration noise (signal − fundamental)")
    ax[1].plot(sm.reversal_peak_times, np.interp(sm.reversal_peak_times, sm.t, sm.noise), "kv", label="reversal bump")
    for tr in sm.reversal_times:
        ax[1].axvline(tr, color="0.7", lw=0.6)
    ax[1].set(xlabel="time [s]", ylabel="[m/s^2]")
    ax[1].legend(loc="upper right")
    fig.savefig(args.out, dpi=90)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
