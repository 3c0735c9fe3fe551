"""A hexapod written independently of hexsim (no hexsim import): the "real machine" of the hexapod's
calibrate-then-validate tests. Its own equations, integrated by classical Runge-Kutta at 50 µs (numba;
against 10 µs within 2 Pa of P1 and 3e-10 m of position on 2 s of its motions with every effect below, a
thousandth of the logs' noise):

- six legs of :mod:`tests.independent_actuator` (its valve, orifice, cap chamber, Stribeck friction and end
  stops, :func:`tests.independent_actuator.leg_at`), each with its own parameters (six valves, six data sheets),
  its spool ideal or a second-order loop (the leg's ``spool_hz``) behind the leg's ``play`` on the setpoint;
- one supply for the six legs: ideal, or sagging through ``supply_resistance`` with the flow the legs draw,
  first order with ``supply_tau`` (logged, with noise, as a transducer reads it);
- a rigid platform (mass, principal inertia about its centre of mass) moved by the legs' forces along the
  leg axes, Newton–Euler about the centre of mass in the world frame; the legs are massless but for each
  piston rod, whose mass moves along its leg (added to the mass matrix as m_r J_i^T J_i, its weight along the
  axis on the piston; the barrels' and the rods' rotation are left out, as a real machine differs from any
  model);
- orientation as a unit quaternion; leg i joins base joint a_i (world) to platform joint b_i (platform frame);
  piston y_i = |p + R b_i - a_i| - L_min;
- a P controller per leg at 500 Hz on the noisy leg positions (valves saturated at ±10 V), tracking the legs'
  lengths of a platform motion (inverse kinematics written here); the positions may reach it (and the log)
  ``sensor_delay`` late;
- logged at 1 kHz: each leg's setpoint, valve command, position and P1, the supply, and the accelerometer at the
  platform frame's origin, in the platform frame, as the mean specific force over each sample interval.

The geometry's numbers are the Micro Motion System's (a drawing's data, not hexsim's code).
"""

from __future__ import annotations

import math
import pathlib
from dataclasses import dataclass, field

import numba
import numpy as np
from independent_actuator import Actuator, _pack, leg_at
from independent_actuator import write as write_log

G = 9.81


@dataclass(frozen=True)
class Hexapod:
    base_radius: float = 0.6
    base_height: float = 0.15
    base_angles: tuple[float, ...] = (-12.0, 12.0, 108.0, 132.0, 228.0, 252.0)
    platform_radius: float = 0.4
    platform_angles: tuple[float, ...] = (-48.0, 48.0, 72.0, 168.0, 192.0, 288.0)
    l_min: float = 0.52
    stroke: float = 0.2
    mass: float = 600.0
    inertia: tuple[float, float, float] = (80.0, 80.0, 144.0)
    com: tuple[float, float, float] = (0.0, 0.0, 0.2)  # platform frame
    rod_mass: float = 2.5
    legs: tuple[Actuator, ...] = field(default_factory=lambda: (Actuator(),) * 6)
    kp: float = 200.0
    supply_resistance: float = 0.0  # [Pa s/m^3] the supply's sag per unit flow drawn by the six legs; 0: ideal
    supply_tau: float = 0.02  # [s] its time constant
    sensor_delay: float = 0.0  # [s] the leg positions' delay (the motion computer's, all legs alike)

    def joints(self) -> tuple[np.ndarray, np.ndarray, float]:
        """(base joints (6, 3) world, platform joints (6, 3) platform frame, the platform frame's height at the
        neutral pose, every piston at mid-stroke)."""
        ab = np.radians(self.base_angles)
        ap = np.radians(self.platform_angles)
        a = np.stack([self.base_radius * np.cos(ab), self.base_radius * np.sin(ab), np.full(6, self.base_height)], 1)
        b = np.stack([self.platform_radius * np.cos(ap), self.platform_radius * np.sin(ap), np.zeros(6)], 1)
        planar = np.linalg.norm(b[0, :2] - a[0, :2])
        return a, b, self.base_height + math.sqrt((self.l_min + self.stroke / 2) ** 2 - planar**2)


def rotation(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll)."""
    cr, sr, cp, sp, cy, sy = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch), math.cos(yaw), math.sin(yaw)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


@numba.njit(cache=True)
def _quat_matrix(q):
    w, x, y, z = q[0], q[1], q[2], q[3]
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


@numba.njit(cache=True)
def _rhs(z, u, legs, a, b, mass, inertia, rod_mass, l_min, supply, out, work):
    """State z: centre of mass (3), quaternion (4), its velocity (3), angular velocity (3, world), P1 (6), each
    leg's spool position and velocity (12), the supply pressure (1); ``supply`` (set pressure, R_s, tau_s).
    The derivatives into ``out`` (32,); ``work`` (9, 6): scratch (the mass matrix, the force, a leg's Jacobian
    row and the rotation), so a step allocates only the 6x6 solve."""
    out[:] = 0.0
    mm, f, jac, rot = work[0:6], work[6], work[7], work[8]
    norm = math.sqrt(z[3] ** 2 + z[4] ** 2 + z[5] ** 2 + z[6] ** 2)
    qw, qx, qy, qz = z[3] / norm, z[4] / norm, z[5] / norm, z[6] / norm
    r00, r01, r02 = 1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qw * qz), 2 * (qx * qz + qw * qy)
    r10, r11, r12 = 2 * (qx * qy + qw * qz), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qw * qx)
    r20, r21, r22 = 2 * (qx * qz - qw * qy), 2 * (qy * qz + qw * qx), 1 - 2 * (qx * qx + qy * qy)
    rot[0], rot[1], rot[2], rot[3], rot[4], rot[5] = r00, r01, r02, r10, r11, r12
    vx, vy, vz, wx, wy, wz = z[7], z[8], z[9], z[10], z[11], z[12]
    mm[:, :] = 0.0
    mm[0, 0] = mm[1, 1] = mm[2, 2] = mass
    R = ((r00, r01, r02), (r10, r11, r12), (r20, r21, r22))
    for i in range(3):  # R diag(I) R^T, the inertia in the world frame
        for j in range(3):
            mm[3 + i, 3 + j] = R[i][0] * inertia[0] * R[j][0] + R[i][1] * inertia[1] * R[j][1] \
                + R[i][2] * inertia[2] * R[j][2]
    iwx = mm[3, 3] * wx + mm[3, 4] * wy + mm[3, 5] * wz
    iwy = mm[4, 3] * wx + mm[4, 4] * wy + mm[4, 5] * wz
    iwz = mm[5, 3] * wx + mm[5, 4] * wy + mm[5, 5] * wz
    f[0], f[1], f[2] = 0.0, 0.0, -mass * G
    f[3], f[4], f[5] = -(wy * iwz - wz * iwy), -(wz * iwx - wx * iwz), -(wx * iwy - wy * iwx)
    drawn = 0.0
    for i in range(6):
        bx, by, bz = b[i, 0], b[i, 1], b[i, 2]
        rx, ry, rz = r00 * bx + r01 * by + r02 * bz, r10 * bx + r11 * by + r12 * bz, r20 * bx + r21 * by + r22 * bz
        ex, ey, ez = z[0] + rx - a[i, 0], z[1] + ry - a[i, 1], z[2] + rz - a[i, 2]
        length = math.sqrt(ex * ex + ey * ey + ez * ez)
        nx, ny, nz = ex / length, ey / length, ez / length
        jac[0], jac[1], jac[2] = nx, ny, nz
        jac[3], jac[4], jac[5] = ry * nz - rz * ny, rz * nx - rx * nz, rx * ny - ry * nx
        yd = nx * (vx + wy * rz - wz * ry) + ny * (vy + wz * rx - wx * rz) + nz * (vz + wx * ry - wy * rx)
        c = legs[i]
        x = (u[i] - c[10]) / c[6] * c[5]  # ideal spool (seed eq. 3.2)
        if c[29] > 0:  # a second-order spool loop
            wv, xv, vv = c[29], z[19 + 2 * i], z[20 + 2 * i]
            out[19 + 2 * i], out[20 + 2 * i] = vv, wv * wv * (x - xv) - 2.0 * c[30] * wv * vv
            x = xv
        dp1, force, flow = leg_at(c, length - l_min, yd, z[13 + i], x, z[31])
        drawn += flow
        along = force - rod_mass * G * nz
        for j in range(6):
            f[j] += jac[j] * along
            for k in range(6):
                mm[j, k] += rod_mass * jac[j] * jac[k]
        out[13 + i] = dp1
    acc = np.linalg.solve(mm, f)
    out[0], out[1], out[2] = vx, vy, vz
    # dq/dt = 1/2 (0, w) (x) q, w in the world frame
    out[3] = 0.5 * (-wx * qx - wy * qy - wz * qz)
    out[4] = 0.5 * (wx * qw + wy * qz - wz * qy)
    out[5] = 0.5 * (-wx * qz + wy * qw + wz * qx)
    out[6] = 0.5 * (wx * qy - wy * qx + wz * qw)
    for j in range(6):
        out[7 + j] = acc[j]
    if supply[1] > 0:
        out[31] = (supply[0] - supply[1] * drawn - z[31]) / supply[2]


@numba.njit(cache=True)
def _advance(z, u, legs, a, b, mass, inertia, rod_mass, l_min, supply, h, n):
    """n classical Runge-Kutta steps of h [s] from z (32,) (not changed; a new state is returned)."""
    z = z.copy()
    k1, k2, k3, k4, zt = np.empty(32), np.empty(32), np.empty(32), np.empty(32), np.empty(32)
    work = np.empty((9, 6))
    for _ in range(n):
        _rhs(z, u, legs, a, b, mass, inertia, rod_mass, l_min, supply, k1, work)
        for i in range(32):
            zt[i] = z[i] + 0.5 * h * k1[i]
        _rhs(zt, u, legs, a, b, mass, inertia, rod_mass, l_min, supply, k2, work)
        for i in range(32):
            zt[i] = z[i] + 0.5 * h * k2[i]
        _rhs(zt, u, legs, a, b, mass, inertia, rod_mass, l_min, supply, k3, work)
        for i in range(32):
            zt[i] = z[i] + h * k3[i]
        _rhs(zt, u, legs, a, b, mass, inertia, rod_mass, l_min, supply, k4, work)
        for i in range(32):
            z[i] += h / 6.0 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i])
        norm = math.sqrt(z[3] ** 2 + z[4] ** 2 + z[5] ** 2 + z[6] ** 2)
        for i in range(3, 7):
            z[i] /= norm
    return z


def motion(s: Hexapod, duration: float, poses, rng: np.random.Generator, step: float = 5e-5,
           noise: tuple[float, float, float] = (2e-6, 2e3, 0.02)) -> dict[str, np.ndarray]:
    """A closed-loop run of ``duration`` s tracking ``poses(t)`` -> (6,) (x, y, z [m], roll, pitch, yaw [rad]
    relative to the neutral pose): the log's columns at 1 kHz with noise (position m, pressure Pa,
    acceleration m/s^2) on the measured channels; the controller sees the noisy positions."""
    a, b_frame, height = s.joints()
    com = np.asarray(s.com)
    b = b_frame - com  # platform joints from the centre of mass, platform frame
    legs = np.stack([_pack(leg_) for leg_ in s.legs])
    a1, a2, ps = legs[:, 0], legs[:, 1], legs[:, 3]
    origin = np.array([0.0, 0.0, height])
    dt = 1e-3
    t = np.arange(0.0, duration, dt)

    def lengths(pose):
        rot = rotation(*pose[3:])
        return np.linalg.norm(origin + pose[:3] + b_frame @ rot.T - a, axis=1) - s.l_min

    ref = np.array([lengths(poses(tj)) for tj in t])
    # at rest at the neutral pose: the legs' forces carry the weights (J^T F = weight wrench)
    c0 = origin + com
    r = b
    vec = c0 + r - a
    n = vec / np.linalg.norm(vec, axis=1, keepdims=True)
    jac = np.concatenate([n, np.cross(r, n)], axis=1)  # (6 legs, 6)
    force = np.linalg.solve(jac.T, np.array([0.0, 0.0, s.mass * G, 0.0, 0.0, 0.0])) + s.rod_mass * G * n[:, 2]
    p1 = (force + ps * a2) / a1
    spool = np.zeros(12)
    spool[0::2] = -legs[:, 10] / legs[:, 6] * legs[:, 5]  # each spool at rest where u = 0 puts it
    z = np.concatenate([c0, [1.0, 0.0, 0.0, 0.0], np.zeros(6), p1, spool, [ps[0]]])
    supply = np.array([ps[0], s.supply_resistance, s.supply_tau])
    play = np.array([leg_.play for leg_ in s.legs])
    inertia = np.asarray(s.inertia, dtype=float)
    sensor = -com  # the platform frame's origin from the centre of mass, platform frame
    cols = {k: np.empty((len(t), 6)) for k in ("pos", "p1", "u")}
    true_pos = np.empty((len(t), 6))
    supply_log = np.empty(len(t))
    acc = np.empty((len(t), 3))
    u = np.zeros(6)
    spool_u = np.zeros(6)
    substeps = int(round(dt / step))

    def sensor_velocity(z):
        rot = _quat_matrix(z[3:7])
        return z[7:10] + np.cross(z[10:13], rot @ sensor), rot

    v_prev, _ = sensor_velocity(z)
    for j in range(len(t)):
        rot = _quat_matrix(z[3:7])
        true_pos[j] = np.linalg.norm(z[0:3] + b @ rot.T - a, axis=1) - s.l_min
        seen = true_pos[j] if not s.sensor_delay else np.array(
            [np.interp(t[j] - s.sensor_delay, t[:j + 1], true_pos[:j + 1, i]) for i in range(6)])
        measured = seen + rng.normal(0.0, noise[0], 6)
        if j % 2 == 0:
            u = np.clip(s.kp * (ref[j] - measured), -10.0, 10.0)
            spool_u = np.minimum(np.maximum(spool_u, u - play), u + play)  # each leg's play (backlash)
        cols["p1"][j], cols["u"][j], supply_log[j] = z[13:19], u, z[31]
        cols["pos"][j] = measured
        z = _advance(z, spool_u, legs, a, b, s.mass, inertia, s.rod_mass, s.l_min, supply, step, substeps)
        assert np.all(np.isfinite(z)), f"non-finite state at t = {t[j]:.3f} s"
        v_now, rot = sensor_velocity(z)
        acc[j] = rot.T @ ((v_now - v_prev) / dt + np.array([0.0, 0.0, G]))  # the interval j … j+1
        v_prev = v_now
    acc = np.vstack([[rot.T @ np.array([0.0, 0.0, G])], acc[:-1]])  # row j: the mean over the interval before it
    out = {"time_s": t}
    for i in range(6):
        out |= {f"leg{i + 1}_ref_m": ref[:, i], f"leg{i + 1}_valve_cmd_V": cols["u"][:, i],
                f"leg{i + 1}_pos_m": cols["pos"][:, i],
                f"leg{i + 1}_p1_Pa": cols["p1"][:, i] + rng.normal(0.0, noise[1], len(t))}
    out["ps_Pa"] = (supply_log + rng.normal(0.0, noise[1], len(t)) if s.supply_resistance > 0
                    else np.full(len(t), float(ps[0])))
    for k, axis in enumerate("xyz"):
        out[f"platform_acc_{axis}_mps2"] = acc[:, k] + rng.normal(0.0, noise[2], len(t))
    return out


def write(columns: dict[str, np.ndarray], path: pathlib.Path, description: str, kp: float = 200.0) -> pathlib.Path:
    """The measurement-log CSV + sidecar of a hexapod's ``columns`` (:func:`independent_actuator.write`)."""
    return write_log(columns, path, description, kp, system="hexapod")
