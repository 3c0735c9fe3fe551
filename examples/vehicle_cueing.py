"""A library of manoeuvres (a car's braking stop, lane change, slalom and road with bumps, an airliner's take-off
roll), cued on the Micro Motion System: what the driver senses.

A small vehicle model (below, nothing downloaded) makes the motion at the driver's head, which is written
as a vehicle-motion CSV (docs/motion-cueing.md) and run through the classical washout, the inverse
kinematics, the hydraulics and the compensator (``hexsim run vehicle:PATH`` does the same). The cue
report says per axis how well the simulator's sensed cue follows the car's, and which false cues come
from the washout and which from the hardware (the reversal bumps).

Usage: python examples/vehicle_cueing.py [--out FIGURE.png] [--compensator NAME]
           [--manoeuvre braking|lane-change|slalom|road-bumps|take-off]
(the vehicle CSV and the cue report's JSON are written beside the figure;
``python examples/cueing_comparison.py`` runs the whole library through classical, tuned and MPC cueing)

The vehicle models (textbook ones, e.g. Gillespie 1992, "Fundamentals of Vehicle Dynamics", ch. 5-6, and
Rajamani 2012, "Vehicle Dynamics and Control", ch. 2; nothing downloaded):

* longitudinal: a point mass braking with a jerk-limited deceleration (0.5 s onset) until it stops;
* lateral: the linear single-track (bicycle) model of a 1500 kg car (cornering stiffness 80/90 kN/rad
  front/rear, CG 1.2 m behind the front axle and 1.4 m ahead of the rear, yaw inertia 2500 kg m^2) steered
  through one sine period of 3 s at 20 m/s (a single lane change) or four periods of 2.4 s at 15 m/s (a
  slalom through cones 18 m apart);
* vertical: two quarter cars (front and rear axle, 2.6 m apart; sprung 350 kg and unsprung 40 kg each,
  suspension 25 kN/m and 2 kN s/m, tyre 200 kN/m; Gillespie ch. 5) at 15 m/s over three 30 mm, 0.6 m long
  bumps and a 20 mm pothole: the body's heave and pitch, the rear axle meeting each one wheelbase later;
* an airliner's take-off roll (a point mass: 3.0 m/s^2 of thrust less a drag growing with the square of the
  speed, 2.5 m/s^2 left at 70 m/s; rotation at 65 m/s to 10 deg at 3 deg/s, then 1 m/s^2 up as it lifts off;
  the runway's joints at every 5 m a 0.1 m/s^2, 20 ms knock);
* body pitch and roll: second-order responses (1.5 Hz, damping 0.5) to the longitudinal and lateral
  acceleration with gradients of 1.2 deg/g (pitch) and 4 deg/g (roll), whose gravity components the
  driver feels (with the road's pitch, or the aircraft's rotation, added); the head sits 0.6 m above the roll
  and pitch axes (its lever arm is added).
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
    dt = 1 / FS
    t = np.arange(int(duration * FS) + 1) * dt
    delta = steer * np.sin(2 * np.pi * (t - 1.0) / 3.0) * ((t >= 1.0) & (t <= 4.0))
    return _bicycle(t, delta, speed)


def slalom(duration: float = 14.0, speed: float = 15.0, steer: float = 0.025, period: float = 2.4
           ) -> dict[str, np.ndarray]:
    """A slalom at ``speed`` [m/s] through cones 18 m apart: the road wheels steered ``steer`` [rad] over four
    sine periods of ``period`` [s] (two cones a period at 15 m/s), from t = 1 s."""
    dt = 1 / FS
    t = np.arange(int(duration * FS) + 1) * dt
    delta = steer * np.sin(2 * np.pi * (t - 1.0) / period) * ((t >= 1.0) & (t <= 1.0 + 4 * period))
    return _bicycle(t, delta, speed)


def _bicycle(t: np.ndarray, delta: np.ndarray, speed: float) -> dict[str, np.ndarray]:
    """The linear single-track model (module doc) at ``speed`` [m/s], road-wheel angle ``delta`` (N,) [rad]."""
    m, iz, lf, lr, cf, cr = 1500.0, 2500.0, 1.2, 1.4, 80e3, 90e3
    dt = t[1] - t[0]
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


def road_bumps(duration: float = 10.0, speed: float = 15.0) -> dict[str, np.ndarray]:
    """Two quarter cars (module doc) at ``speed`` [m/s] over three 30 mm bumps (half sines 0.6 m long, at 20, 45
    and 80 m) and a 20 mm pothole at 110 m: the body's heave acceleration and its pitch (nose down when the
    rear axle is the higher), semi-implicit Euler at 1 ms, sampled at the model's rate."""
    ms, mu, ks, cs, kt, wheelbase = 350.0, 40.0, 25e3, 2e3, 200e3, 2.6
    h = 1e-3
    t_fine = np.arange(int(duration / h) + 1) * h

    def road(x: np.ndarray) -> np.ndarray:
        z = np.zeros_like(x)
        for start, height in ((20.0, 0.03), (45.0, 0.03), (80.0, 0.03), (110.0, -0.02)):
            inside = (x >= start) & (x <= start + 0.6)
            z[inside] += height * np.sin(np.pi * (x[inside] - start) / 0.6)
        return z

    def quarter(z_road: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        zs = vs = zu = vu = 0.0
        body, body_acc = np.empty_like(z_road), np.empty_like(z_road)
        for k, zr in enumerate(z_road):
            f_s = ks * (zu - zs) + cs * (vu - vs)
            a_s, a_u = f_s / ms, (kt * (zr - zu) - f_s) / mu
            vs, vu = vs + h * a_s, vu + h * a_u
            zs, zu = zs + h * vs, zu + h * vu
            body[k], body_acc[k] = zs, a_s
        return body, body_acc

    x = speed * t_fine
    front, acc_front = quarter(road(x))
    rear, acc_rear = quarter(road(x - wheelbase))
    every = int(round(1 / (FS * h)))
    t = t_fine[::every]
    a_z = 0.5 * (acc_front + acc_rear)[::every]
    pitch = ((rear - front) / wheelbase)[::every]
    return _body(t, np.zeros_like(t), np.zeros_like(t), np.zeros_like(t), a_z=a_z, pitch_extra=pitch)


def take_off(duration: float = 32.0) -> dict[str, np.ndarray]:
    """An airliner's take-off roll (module doc): brakes released at 1 s, rotation at 65 m/s, lift-off."""
    dt = 1 / FS
    t = np.arange(int(duration * FS) + 1) * dt
    drag = (3.0 - 2.5) / 70.0**2
    a_x, theta, a_z = np.zeros_like(t), np.zeros_like(t), np.zeros_like(t)
    speed, distance, rotated_at = 0.0, 0.0, None
    for k in range(1, len(t)):
        thrust = 3.0 * min(max((t[k] - 1.0) / 2.0, 0.0), 1.0)  # spooling up over 2 s
        a_x[k] = thrust - drag * speed * speed
        speed += a_x[k] * dt
        distance += speed * dt
        if rotated_at is None and speed >= 65.0:
            rotated_at = t[k]
        if rotated_at is not None:
            theta[k] = np.radians(min(3.0 * (t[k] - rotated_at), 10.0))
            a_z[k] = 1.0 * min(max((t[k] - rotated_at - 3.3) / 1.0, 0.0), 1.0)  # lift-off after the rotation
        if rotated_at is None and distance % 5.0 < speed * dt:  # a runway joint: 0.1 m/s^2 for 20 ms
            a_z[k:k + 2] += 0.1
    return _body(t, a_x, np.zeros_like(t), np.zeros_like(t), a_z=a_z, pitch_extra=-theta, suspension=False)


def _body(t, a_x, a_y, yaw_rate, head_height: float = 0.6, a_z=None, pitch_extra=None,
          suspension: bool = True) -> dict[str, np.ndarray]:
    """The specific force and body rates at the driver's head from the CG's accelerations (vehicle axes);
    ``a_z`` (N,) the body's vertical acceleration [m/s^2] and ``pitch_extra`` (N,) [rad, nose down] a pitch of
    its own (the road's, an aircraft's rotation) on top of the suspension's (``suspension``: False for none)."""
    dt = t[1] - t[0]
    # nose down when braking
    pitch = _second_order(-np.radians(1.2) * a_x / G, 1.5, 0.5, dt) if suspension else np.zeros_like(t)
    if pitch_extra is not None:
        pitch = pitch + pitch_extra
    roll = _second_order(np.radians(4.0) * a_y / G, 1.5, 0.5, dt)  # outward in a turn
    p, q = np.gradient(roll, dt), np.gradient(pitch, dt)
    p_dot, q_dot = np.gradient(p, dt), np.gradient(q, dt)
    f_x = a_x - G * np.sin(pitch) + q_dot * head_height
    f_y = a_y + G * np.sin(roll) - p_dot * head_height
    f_z = G * np.cos(pitch) * np.cos(roll) + (0.0 if a_z is None else a_z)
    return {"time_s": t, "f_x_mps2": f_x, "f_y_mps2": f_y, "f_z_mps2": f_z, "p_radps": p, "q_radps": q,
            "r_radps": yaw_rate}


#: The library: name -> the vehicle model that makes its motion at the driver's head.
MANOEUVRES = {"braking": braking, "lane-change": lane_change, "slalom": slalom, "road-bumps": road_bumps,
              "take-off": take_off}


def write_vehicle_csv(path: pathlib.Path, columns: dict[str, np.ndarray]) -> None:
    names = list(columns)
    np.savetxt(path, np.column_stack([columns[n] for n in names]), delimiter=",", header=",".join(names),
               comments="", fmt="%.6g")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=pathlib.Path, default=pathlib.Path("vehicle_cueing.png"),
                        help="the figure (.png); the vehicle CSV and the report's JSON beside it")
    parser.add_argument("--compensator", default="none")
    parser.add_argument("--manoeuvre", choices=tuple(MANOEUVRES), default="braking")
    args = parser.parse_args(argv)
    csv = args.out.with_name(f"{args.out.stem}_{args.manoeuvre}.csv")
    write_vehicle_csv(csv, MANOEUVRES[args.manoeuvre]())
    print(f"wrote {csv} (the vehicle model's motion at the driver's head)")
    from hexsim.cli import main as hexsim

    return hexsim(["run", f"vehicle:{csv}", "--compensator", args.compensator, "--quiet",
                   "--json", str(args.out.with_suffix(".json")), "--plot", str(args.out)])


if __name__ == "__main__":
    sys.exit(main())
