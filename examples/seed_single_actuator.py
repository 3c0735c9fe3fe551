"""Replication of the seed's single-actuator simulation (seed ch. 3, Fig. 3.5-3.10).

Source: "Compensation of the reversal bump", Rexroth-Hydraudyne / TU Eindhoven, 2005, eq. (3.2)-(3.11),
appendix A. One vertical actuator, M = 40 kg, r = 0.05 sin(pi t) + L_s/2 faded in over 2 s, P control.
As in the seed's Simulink model the controller runs at the 10 kHz physics rate (continuous P).

It computes the ideal references and plots the simulation against them:
- the hydraulic eigenfrequency f_e from eq. (3.7) at the piston position, and the seed's 109 Hz
  estimate at mid-stroke, against the spectrum of the acceleration (sharp-edged area, eq. 3.3, rings
  at f_e; the smooth area, eq. 3.11, does not);
- the static flow curve of eq. (5.1) (velocity = flow / A1 at zero acceleration) against the simulated
  flow curve, which shows the flat zone around u_v = 0.

    python examples/seed_single_actuator.py [--duration 10] [--out seed_single_actuator.png]
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
from hexsim.plant import hydraulics  # noqa: E402
from hexsim.plant.machine import Machine  # noqa: E402
from hexsim.plant.params import ControllerParams, HydraulicParams  # noqa: E402

M = 40.0  # [kg] seed app. A; the same number is in models/single_actuator.xml


def static_flow_curve(u_v: np.ndarray, p: HydraulicParams, gravity: float) -> np.ndarray:
    """Seed eq. (5.1): piston velocity at zero acceleration, P1 at the static value (eq. 3.8)."""
    p1 = hydraulics.equilibrium_pressure(M * gravity, p)
    return hydraulics.static_velocity(u_v, p1, p)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--out", default="seed_single_actuator.png")
    args = parser.parse_args()

    controller = ControllerParams(rate_hz=10_000.0, position_noise=0.0)
    runs = {}
    for area in ("sharp", "smooth"):
        p = HydraulicParams(flow_area=area)
        machine = Machine(hydraulics=p, controller=controller)
        runs[area] = simulate(RunConfig(make_scenario("actuator", duration=args.duration), machine,
                                        record_rate_hz=5000.0))
    p = HydraulicParams()
    f_mid = hydraulics.eigenfrequency(M, p, stroke=0.2)
    f_lo, f_hi = hydraulics.eigenfrequency(M, p, y=0.15), hydraulics.eigenfrequency(M, p, y=0.05)
    print(f"P1(0) = {runs['smooth'].p1_initial[0] / 1e5:.2f} bar (seed: (P_s - P_t) A2/A1 + M g/A1)")
    print(f"f_e = {f_mid:.1f} Hz at mid-stroke (seed §3.3: ≈ 109 Hz); {f_lo:.0f} Hz at y = 0.15 m, {f_hi:.0f} Hz at y = 0.05 m")

    fig, ax = plt.subplots(2, 2, figsize=(12, 8), constrained_layout=True)
    for area, r in runs.items():
        sel = r.t >= 2.0
        ax[0, 0].plot(r.t[sel], r.acc[sel, 2], lw=0.7, label=f"{area} area")
        a = r.acc[sel, 2] - r.acc[sel, 2].mean()
        f = np.fft.rfftfreq(a.size, r.t[1] - r.t[0])
        spec = np.abs(np.fft.rfft(a * np.hanning(a.size))) * 4 / a.size
        ax[0, 1].semilogy(f, spec, lw=0.7, label=f"{area} area")
        ax[1, 0].plot(r.u_v[sel, 0], r.ydot[sel, 0], lw=0.7, label=f"{area} area (simulated)")
        band = (f > 0.8 * f_lo) & (f < 1.2 * f_hi)
        print(f"{area:6s}: spectral amplitude between {0.8 * f_lo:.0f} and {1.2 * f_hi:.0f} Hz: max {spec[band].max():.2e} m/s^2")
    for fe, label in ((f_mid, "f_e mid-stroke (109 Hz)"), (f_lo, "f_e at y = 0.15"), (f_hi, "f_e at y = 0.05")):
        ax[0, 1].axvline(fe, color="k", ls="--", lw=0.7)
        ax[0, 1].text(fe, ax[0, 1].get_ylim()[1], label, rotation=90, va="top", fontsize=7)
    ax[0, 0].set(title="actuator acceleration (seed Fig. 3.5 / 3.9)", xlabel="time [s]", ylabel="[m/s^2]")
    ax[0, 1].set(title="spectrum (seed Fig. 3.6 / 3.9)", xlabel="frequency [Hz]", ylabel="[m/s^2]", xlim=(0, 300))
    u = np.linspace(-1.2, 1.2, 241)
    ax[1, 0].plot(u, static_flow_curve(u, p, runs["smooth"].gravity), "k--", lw=1, label="ideal static, eq. (5.1)")
    ax[1, 0].set(title="flow curve (seed Fig. 3.10)", xlabel="u_v [V]", ylabel="piston velocity [m/s]")
    r = runs["smooth"]
    ax[1, 1].plot(r.t, r.p1[:, 0] / 1e5, lw=0.8, label="P1 smooth")
    ax[1, 1].plot(runs["sharp"].t, runs["sharp"].p1[:, 0] / 1e5, lw=0.6, alpha=0.7, label="P1 sharp")
    ax[1, 1].set(title="bottom-chamber pressure (seed Fig. 3.4 / 3.8)", xlabel="time [s]", ylabel="[bar]")
    for a in ax.flat:
        a.legend(fontsize=8)
    fig.savefig(args.out, dpi=90)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
