"""Motion cueing: a vehicle's motion at the driver's head turned into platform setpoints by the classical
washout (Conrad & Schmidt 1970; Reid & Nahon 1985, "Flight simulation motion-base drive algorithms: part 1",
UTIAS Report 296; the structure every simulator vendor ships).

The vehicle motion (:class:`VehicleMotion`, ``docs/motion-cueing.md``) is the specific force f = a - g
[m/s^2] and the angular velocity (p, q, r) [rad/s] at the driver's head in vehicle axes (x forward, y left,
z up; a vehicle at rest reads f = (0, 0, +9.81)). Three channels make the platform's pose:

* **translational** (high pass): the scaled, limited specific force less 1 g on z, through a third-order
  high pass s^2/(s^2 + 2 zeta w_n s + w_n^2) * s/(s + w_b) and integrated twice, so that onsets are cued
  and the platform returns to neutral: position = s / ((s^2 + 2 zeta w_n s + w_n^2)(s + w_b)) * a;
* **tilt coordination** (low pass): the sustained part of the scaled surge and sway specific force is cued
  by tilting the platform so that gravity supplies it (pitch = -asin(f_x / g), roll = asin(f_y / g)), through
  a second-order low pass, limited in angle and in rate below the canals' threshold so the tilt itself is
  not sensed as rotation;
* **rotational** (high pass): the scaled, limited angular velocity through s^2/(s^2 + 2 zeta w s + w^2),
  integrated to angles (small angles: body rates as Euler rates).

The parameters (:class:`WashoutParams`) come from a JSON file or the defaults, sized for the Micro Motion
System's ±0.1 m of stroke.
"""

from __future__ import annotations

import math
import pathlib
from dataclasses import asdict, dataclass, field, fields

import numpy as np
from scipy.spatial.transform import Rotation

from hexsim.errors import InputError
from hexsim.signals import LinearModel
from hexsim.tables import read_numeric_csv, read_settings

G = 9.81  # [m/s^2] the vehicle's 1 g (the models' gravity)
#: the vehicle-motion CSV's columns: time, specific force (vehicle axes) and body rates at the head
VEHICLE_COLUMNS = ("time_s", "f_x_mps2", "f_y_mps2", "f_z_mps2", "p_radps", "q_radps", "r_radps")


@dataclass(frozen=True)
class VehicleMotion:
    """A vehicle's motion at the driver's head: t (N,) [s] strictly increasing; specific_force (N, 3)
    [m/s^2] and angular_velocity (N, 3) [rad/s], vehicle axes (x forward, y left, z up); ``source``: the
    file or model it came from."""

    t: np.ndarray
    specific_force: np.ndarray
    angular_velocity: np.ndarray
    source: str = "python"

    def at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Specific force and angular velocity (M, 3) linearly interpolated at times t (M,) [s]."""
        f = np.stack([np.interp(t, self.t, self.specific_force[:, k]) for k in range(3)], axis=1)
        w = np.stack([np.interp(t, self.t, self.angular_velocity[:, k]) for k in range(3)], axis=1)
        return f, w


def read_vehicle(path: str | pathlib.Path) -> VehicleMotion:
    """A vehicle-motion CSV (:data:`VEHICLE_COLUMNS`, every one required). Raises InputError naming the
    file, column and row for a missing column, a non-number, times not increasing, or a specific force
    that cannot be a ground vehicle's or an aircraft's (beyond 10 g) or rates beyond 10 rad/s."""
    path = pathlib.Path(path)
    cols = read_numeric_csv(path, required=VEHICLE_COLUMNS)
    f = np.stack([cols[c] for c in VEHICLE_COLUMNS[1:4]], axis=1)
    w = np.stack([cols[c] for c in VEHICLE_COLUMNS[4:]], axis=1)
    for name, values, limit in (("specific force", f, 10 * G), ("angular velocity", w, 10.0)):
        bad = np.argwhere(np.abs(values) > limit)
        if bad.size:
            row, k = bad[0]
            column = VEHICLE_COLUMNS[1 + k] if name == "specific force" else VEHICLE_COLUMNS[4 + k]
            raise InputError(f"{path}: row {row + 2}, column {column}: {values[row, k]:g} is beyond any vehicle's "
                             f"{name} (|value| <= {limit:g})")
    if cols["time_s"][-1] - cols["time_s"][0] < 1.0:
        raise InputError(f"{path}: the motion lasts {cols['time_s'][-1] - cols['time_s'][0]:g} s; at least 1 s")
    return VehicleMotion(cols["time_s"] - cols["time_s"][0], f, w, str(path))


def _triple(value, name: str, positive: bool = True) -> tuple[float, float, float]:
    if not (isinstance(value, (list, tuple)) and len(value) == 3):
        raise InputError(f"washout {name}: expected three numbers [x, y, z], got {value!r}")
    out = tuple(float(v) for v in value)
    if not all(math.isfinite(v) and (v > 0 if positive else v >= 0) for v in out):
        raise InputError(f"washout {name}: expected three {'positive' if positive else 'non-negative'} numbers, "
                         f"got {list(value)!r}")
    return out


@dataclass(frozen=True)
class WashoutParams:
    """The classical washout's parameters (module doc); per-axis triples are (x, y, z) or (roll, pitch, yaw).

    Scaling and limiting: ``scale_specific_force``, ``scale_angular_velocity`` [-]; ``limit_specific_force_mps2``
    [m/s^2] and ``limit_angular_velocity_radps`` [rad/s] after scaling (a saturation). Translational high
    pass: ``hp_omega_radps`` w_n, ``hp_zeta``, ``hp_break_radps`` w_b. Tilt: ``tilt_omega_radps`` and
    ``tilt_zeta`` of the low pass, ``tilt_rate_limit_degps`` (below the canals' 2 deg/s threshold,
    Benson et al. 1989) and ``tilt_acceleration_limit_degps2`` (the tilt rate changes no faster: a rate
    that flips in one sample is a canal cue of its own), ``tilt_limit_deg``. Rotational high pass:
    ``rot_omega_radps``, ``rot_zeta``.
    ``rotation_centre_m`` (3,) [m, platform frame]: the point the platform's rotations turn about (the
    translations are those of this point); the platform frame's origin by default, the driver's head in
    Reid & Nahon's setting, which on a small platform costs stroke: 6.5 deg of tilt about a head 1.47 m up
    moves the platform's origin 0.17 m.
    Defaults: the structure's usual damping (zeta 1 for the high passes, 1/sqrt 2 for the tilt; Reid & Nahon
    1985), breaks and gains sized for ±0.1 m of stroke and a car's manoeuvres (a 4 m/s^2 stop stays within
    ±60 mm of surge); docs/motion-cueing.md tabulates them.
    """

    scale_specific_force: tuple[float, float, float] = (0.5, 0.5, 0.5)
    scale_angular_velocity: tuple[float, float, float] = (0.5, 0.5, 0.5)
    limit_specific_force_mps2: tuple[float, float, float] = (3.0, 3.0, 3.0)
    limit_angular_velocity_radps: tuple[float, float, float] = (0.5, 0.5, 0.5)
    hp_omega_radps: tuple[float, float, float] = (4.0, 4.0, 5.0)
    hp_zeta: float = 1.0
    hp_break_radps: tuple[float, float, float] = (1.0, 1.0, 1.0)
    tilt_omega_radps: float = 3.0
    tilt_zeta: float = 1 / math.sqrt(2)
    tilt_rate_limit_degps: float = 1.5
    tilt_acceleration_limit_degps2: float = 8.0
    tilt_limit_deg: float = 8.0
    rot_omega_radps: tuple[float, float, float] = (1.0, 1.0, 1.0)
    rot_zeta: float = 1.0
    rotation_centre_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    source: str = field(default="defaults", compare=False)

    def __post_init__(self) -> None:
        centre = self.rotation_centre_m
        if not (isinstance(centre, (list, tuple)) and len(centre) == 3 and all(
                isinstance(v, (int, float)) and math.isfinite(v) for v in centre)):
            raise InputError(f"washout rotation_centre_m: expected [x, y, z] in metres, got {centre!r}")
        object.__setattr__(self, "rotation_centre_m", tuple(float(v) for v in centre))
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name in ("source", "rotation_centre_m"):
                continue
            if isinstance(value, tuple):
                object.__setattr__(self, f.name, _triple(value, f.name, positive=not f.name.startswith("scale")))
            elif not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise InputError(f"washout {f.name}: expected a positive number, got {value!r}")
        if self.tilt_limit_deg >= 30:
            raise InputError(f"washout tilt_limit_deg: {self.tilt_limit_deg:g} deg is beyond tilt coordination's "
                             f"small-angle use (< 30)")

    @classmethod
    def from_file(cls, path: str | pathlib.Path) -> "WashoutParams":
        """The parameters a JSON object gives (any subset of the fields; the rest default). Raises
        InputError naming the file and the key for an unknown key or a bad value."""
        return read_settings(cls, path, "washout")

    def document(self) -> dict:
        """The parameters as a JSON-ready dict (the file's form)."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items() if k != "source"}


@dataclass(frozen=True)
class WashoutOutput:
    """What the washout commands: t (N,) [s]; poses (N, 6) [m, rad] relative to neutral (x, y, z, roll,
    pitch, yaw); each channel's part: translation (N, 3) [m], tilt (N, 2) [rad] (roll, pitch), rotation
    (N, 3) [rad]; limited: (6,) samples whose input the scaling's limit saturated (x, y, z, p, q, r),
    tilt_rate_limited: samples where the tilt's rate or acceleration limit held it back from its target;
    solver: an optimising cueing's solve statistics (:func:`hexsim.control.mpc_cueing.mpc_washout`), None for
    the classical washout."""

    t: np.ndarray
    poses: np.ndarray
    translation: np.ndarray
    tilt: np.ndarray
    rotation: np.ndarray
    limited: np.ndarray
    tilt_rate_limited: int
    solver: dict | None = None


def washout(vehicle: VehicleMotion, params: WashoutParams = WashoutParams(), rate_hz: float = 500.0,
            duration: float | None = None) -> WashoutOutput:
    """The classical washout (module doc) of ``vehicle`` sampled at ``rate_hz`` [Hz] over ``duration`` [s]
    (default the vehicle's). Returns the platform setpoints and each channel's part."""
    duration = float(vehicle.t[-1]) if duration is None else duration
    t = np.arange(int(math.floor(duration * rate_hz)) + 1) / rate_hz
    f, w = vehicle.at(t)
    a = (f - np.array([0.0, 0.0, G])) * np.array(params.scale_specific_force)
    lim_f = np.array(params.limit_specific_force_mps2)
    w_s = w * np.array(params.scale_angular_velocity)
    lim_w = np.array(params.limit_angular_velocity_radps)
    limited = np.concatenate([np.sum(np.abs(a) > lim_f, axis=0), np.sum(np.abs(w_s) > lim_w, axis=0)])
    a, w_s = np.clip(a, -lim_f, lim_f), np.clip(w_s, -lim_w, lim_w)
    translation = np.empty((t.size, 3))
    for k in range(3):
        wn, wb = params.hp_omega_radps[k], params.hp_break_radps[k]
        model = LinearModel("translational washout", (1.0, 0.0),
                            tuple(np.polymul([1.0, 2 * params.hp_zeta * wn, wn * wn], [1.0, wb])), "m", "")
        translation[:, k] = model.apply(a[:, k], rate_hz)
    wt = params.tilt_omega_radps
    low = LinearModel("tilt low pass", (wt * wt,), (1.0, 2 * params.tilt_zeta * wt, wt * wt), "m/s^2", "")
    f_low = low.apply(a[:, :2], rate_hz)
    s_max = math.sin(math.radians(params.tilt_limit_deg))
    target = np.stack([np.arcsin(np.clip(f_low[:, 1] / G, -s_max, s_max)),  # roll from sway
                       -np.arcsin(np.clip(f_low[:, 0] / G, -s_max, s_max))], axis=1)  # pitch from surge
    tilt, n_rate = rate_limited(target, math.radians(params.tilt_rate_limit_degps) / rate_hz,
                                math.radians(params.tilt_acceleration_limit_degps2) / rate_hz**2)
    rotation = np.empty((t.size, 3))
    for k in range(3):
        wr = params.rot_omega_radps[k]
        model = LinearModel("rotational washout", (1.0, 0.0), (1.0, 2 * params.rot_zeta * wr, wr * wr), "rad", "")
        rotation[:, k] = model.apply(w_s[:, k], rate_hz)
    poses = np.concatenate([translation, rotation], axis=1)
    poses[:, 3:5] += tilt
    centre = np.array(params.rotation_centre_m)
    if np.any(centre):  # the platform's origin where the rotation about the centre puts it
        turn = Rotation.from_euler("ZYX", poses[:, [5, 4, 3]])
        poses[:, :3] += centre - turn.apply(centre)
    return WashoutOutput(t, poses, translation, tilt, rotation, limited, n_rate)


def rate_limited(target: np.ndarray, step: float, change: float) -> tuple[np.ndarray, int]:
    """``target`` (N, k) followed from rest at zero, each column at no more than ``step`` per sample (the rate
    limit) and its per-sample step changing by no more than ``change`` per sample (the acceleration limit): a
    discrete time-optimal follower that brakes in time (the largest step from which braking at ``change``
    stops within the distance left, sqrt(change^2 / 4 + 2 change |d|) - change / 2), so it neither flips its
    rate in one sample nor overshoots. Returns the followed (N, k) and the samples (any column) where it was
    held back from the target. Raises ValueError for a non-positive ``step`` or ``change``."""
    if not (step > 0 and change > 0):
        raise ValueError(f"rate_limited: step and change must be positive, got {step!r}, {change!r}")
    out = np.empty_like(target)
    x = np.zeros(target.shape[1])
    rate = np.zeros(target.shape[1])
    held = 0
    for i, goal in enumerate(target):
        d = goal - x
        brake = np.sqrt(0.25 * change * change + 2.0 * change * np.abs(d)) - 0.5 * change
        wanted = np.sign(d) * np.minimum(np.minimum(step, brake), np.abs(d))
        new = rate + np.clip(wanted - rate, -change, change)
        held += bool(np.any(np.abs(new - d) > 1e-15))
        rate = new
        x = x + rate
        out[i] = x
    return out, held
