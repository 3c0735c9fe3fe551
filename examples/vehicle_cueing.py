"""A car's braking stop and lane change, cued on the Micro Motion System: what the driver senses.

A small vehicle model (below, nothing downloaded) makes the motion at the driver's head, which is written
as a vehicle-motion CSV (docs/motion-cueing.md) and run through the classical washout, the inverse
kinematics, the hydraulics and the compensator (``hexsim run vehicle:PATH`` does the same). The cue
report says per axis how well the simulator's sensed cue follows the car's, and which false cues come
from the washout and which from the hardware (the reversal bumps).

Usage: python examples/vehicle_cueing.py [--out FIGURE.png] [--compensator NAME] [--manoeuvre braking|lane-change]
(the vehicle CSV and the cue report's JSON are written beside the figure)

The vehicle model (a textbook one, e.g. Gillespie 1992, "Fundamentals of Vehicle Dynamics", ch. 5-6, and
Rajamani 2012, "Vehicle Dynamics and Control", ch. 2):

* longitudinal: a point mass braking with a jerk-limited deceleration (0.5 s onset) until it stops;
* lateral: the linear single-track (bicycle) model of a 1500 kg car at 20 m/s (cornering stiffness 80/90
  kN/rad front/rear, CG 1.2 m behind the front axle and 1.4 m ahead of the rear) steered through one sine
  period of 3 s (a single lane change);
* body pitch and roll: second-order responses (1.5 Hz, damping 0.5) to the longitudinal and lateral
  acceleration with gradients of 1.2 deg/g (pitch) and 4 deg/g (roll), whose gravity components the
  driver feels; the head sits 0.6 m above the roll and pitch axes (its lever arm is added).
"""

from __future__ import annotations

import argparse
import pathlib
import sys

import numpy as np

G = 9.81
FS = 100.0  # Hz, the vehicle model's output rate


def _second_order(x: np.ndarray, f_n: float, zeta: float, dt: float) -> np.ndarray:
    """x filtered by w^2 / (s^2 + 2 zeta w s + w^2), semi-implicit Euler."""
    w = 2 * np.pi * f_n
    y = np.zeros_like(x)
    v = 0.0
    for k in range(1, len(x)):
        v += dt * (w * w * (x[k - 1] - y[k - 1]) - 2 * zeta * w * v)
        y[k] = y[k - 1] + dt * v
    return y


def braking(duration: float = 10.0, v0: float = 15.0, decel: float = 4.0) -> dict[str, np.ndarray]:
    """A stop from ``v0`` [m/s] at ``decel`` [m/s^2], braking from t = 1 s."""
    dt = 1 / FS
    t = np.arange(int(duration * FS) + 1) * dt
    a_cmd = -decel * np.clip((t - 1.0) / 0.5, 0, 1)
    v, a = np.empty_like(t), np.empty_like(t)
    speed = v0
    for k in range(len(t)):
        a[k] = a_cmd[k] if speed > 0 else 0.0
        speed = max(0.0, speed + a[k] * dt)
        v[k] = speed
    return _body(t, a, np.zeros_like(t), np.zeros_like(t))


def lane_change(duration: float = 8.0, speed: float = 20.0, steer: float = 0.02) -> dict[str, np.ndarray]:
    """A single lane change at ``speed`` [m/s]: the road wheels steered ``steer`` [rad] over one 3 s sine."""
    m, iz, lf, lr, cf, cr = 1500.0, 2500.0, 1.2, 1.4, 80e3, 90e3
    dt = 1 / FS
    t = np.arange(int(duration * FS) + 1) * dt
    delta = steer * np.sin(2 * np.pi * (t - 1.0) / 3.0) * ((t >= 1.0) & (t <= 4.0))
    beta = r = 0.0
    a_y, yaw_rate = np.zeros_like(t), np.zeros_like(t)
    for k in range(len(t)):
        alpha_f, alpha_r = delta[k] - beta - lf * r / speed, -beta + lr * r / speed
        fy_f, fy_r = cf * alpha_f, cr * alpha_r
        beta_dot = (fy_f + fy_r) / (m * speed) - r
        r_dot = (lf * fy_f - lr * fy_r) / iz
        a_y[k] = speed * (beta_dot + r)
        yaw_rate[k] = r
        beta, r = beta + dt * beta_dot, r + dt * r_dot
    return _body(t, np.zeros_like(t), a_y, yaw_rate)


def _body(t, a_x, a_y, yaw_rate, head_height: float = 0.6) -> dict[str, np.ndarray]:
    """The specific force and body rates at the driver's head from the CG's accelerations (vehicle axes)."""
    dt = t[1] - t[0]
    pitch = _second_order(-np.radians(1.2) * a_x / G, 1.5, 0.5, dt)  # nose down when braking
    roll = _second_order(np.radians(4.0) * a_y / G, 1.5, 0.5, dt)  # outward in a turn
    p, q = np.gradient(roll, dt), np.gradient(pitch, dt)
    p_dot, q_dot = np.gradient(p, dt), np.gradient(q, dt)
    f_x = a_x - G * np.sin(pitch) + q_dot * head_height
    f_y = a_y + G * np.sin(roll) - p_dot * head_height
    f_z = G * np.cos(pitch) * np.cos(roll)
    return {"time_s": t, "f_x_mps2": f_x, "f_y_mps2": f_y, "f_z_mps2": f_z, "p_radps": p, "q_radps": q,
            "r_radps": yaw_rate}


def write_vehicle_csv(path: pathlib.Path, columns: dict[str, np.ndarray]) -> None:
    names = list(columns)
    np.savetxt(path, np.column_stack([columns[n] for n in names]), delimiter=",", header=",".join(names),
               comments="", fmt="%.6g")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=pathlib.Path, default=pathlib.Path("vehicle_cueing.png"),
                        help="the figure (.png); the vehicle CSV and the report's JSON beside it")
    parser.add_argument("--compensator", default="none")
    parser.add_argument("--manoeuvre", choices=("braking", "lane-change"), default="braking")
    args = parser.parse_args(argv)
    csv = args.out.with_name(f"{args.out.stem}_{args.manoeuvre}.csv")
    write_vehicle_csv(csv, braking() if args.manoeuvre == "braking" else lane_change())
    print(f"wrote {csv} (the vehicle model's motion at the driver's head)")
    from hexsim.cli import main as hexsim

    return hexsim(["run", f"vehicle:{csv}", "--compensator", args.compensator, "--quiet",
                   "--json", str(args.out.with_suffix(".json")), "--plot", str(args.out)])


if __name__ == "__main__":
    sys.exit(main())
