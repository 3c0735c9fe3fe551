"""Scenarios: setpoints over time, either platform poses (hexapod) or one piston position (actuator).

- ``actuator``: the seed's single-actuator test, r = 0.05 sin(pi t) + L_s/2 with the sine faded in by a
  ramp over the first period (2 s) (seed eq. 2.1 / 3.10, §3.3).
- ``heave``, ``surge``, ``sway``, ``roll``, ``pitch``, ``yaw``: a sine in that degree of freedom about
  the neutral pose, faded in over one period like the motion computer's signal generator (seed §2.2.4).
- ``file:PATH``: a CSV of platform setpoints relative to the neutral pose with ``time_s`` and any of
  ``dof_ref_{x,y,z}_m`` and ``dof_ref_{roll,pitch,yaw}_rad`` (the measurement-log column names),
  linearly interpolated.
- ``vehicle:PATH``: a vehicle's motion at the driver's head (specific force and body rates, vehicle axes;
  :mod:`hexsim.control.washout`) turned into platform setpoints by the classical washout, with its
  parameters from a JSON file (``washout=``) or the defaults.
- ``valve:PATH``: an open-loop experiment: a CSV with ``time_s`` and the valve setpoints u_v [V],
  ``valve_cmd_V`` (single actuator) or ``leg{i}_valve_cmd_V`` (hexapod, i = 1…6), each held until the next
  row; the measurement-log column names, so a measured log's CSV replays as it is (its other columns are
  ignored). No position controller runs: the command drives the valves directly.
"""

from __future__ import annotations

import math
import pathlib
from dataclasses import dataclass, field

import numpy as np

from hexsim.errors import InputError
from hexsim.tables import read_numeric_csv

#: The platform's degrees of freedom, in the order of a pose (N, 6): x (surge), y (sway), z (heave) [m],
#: roll, pitch, yaw [rad].
DOF_NAMES = ("x", "y", "z", "roll", "pitch", "yaw")
SINE_DOFS = {"surge": 0, "sway": 1, "heave": 2, "roll": 3, "pitch": 4, "yaw": 5}
#: Default sine amplitude per scenario [m or rad] and frequency [Hz] (the seed's 0.05 m at 0.5 Hz).
DEFAULT_AMPLITUDE = {"actuator": 0.05, "surge": 0.05, "sway": 0.05, "heave": 0.05,
                     "roll": math.radians(5), "pitch": math.radians(5), "yaw": math.radians(5)}
DEFAULT_FREQUENCY = 0.5
SCENARIOS = ("actuator", *SINE_DOFS)
FILE_COLUMNS = {f"dof_ref_{n}_{'m' if i < 3 else 'rad'}": i for i, n in enumerate(DOF_NAMES)}


def fade_in(t: np.ndarray, period: float) -> np.ndarray:
    """Ramp from 0 at t = 0 to 1 at t = ``period`` [s], then 1 (seed §3.3)."""
    return np.clip(np.asarray(t, dtype=float) / period, 0.0, 1.0)


@dataclass(frozen=True)
class Scenario:
    """What to drive and how to judge it.

    system: ``"hexapod"`` or ``"actuator"``; duration [s]; axis: index of the DOF the metrics use
    (0…5 as in :data:`DOF_NAMES`, or -1 for the actuator's piston);
    frequency: drive frequency [Hz] (for a file, the dominant frequency of the motion axis);
    fade_period: fade-in time [s] after which metrics may start.
    """

    name: str
    system: str
    duration: float
    axis: int
    frequency: float
    fade_period: float
    amplitude: float | None = None
    _table: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False, compare=False)
    #: piston setpoints given directly, (times (N,) [s], values (N, n_legs) [m]), each held until the next
    #: row (a measurement log's leg{i}_ref_m); no platform setpoint then
    legs: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False, compare=False)
    #: valve setpoints given directly (open loop), (times (N,) [s], values (N, n_legs) [V]), each held
    #: until the next row; no position controller runs
    valve: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False, compare=False)
    #: piston positions (n_legs,) [m] to start from (a valve file's first ``pos_m``); None: the neutral pose
    start: np.ndarray | None = field(default=None, repr=False, compare=False)
    #: a ``vehicle:`` scenario's cueing: (VehicleMotion, WashoutParams, WashoutOutput) of
    #: :mod:`hexsim.control.washout`; None for other scenarios
    cueing: tuple | None = field(default=None, repr=False, compare=False)
    #: setpoint rows written while the run goes (:func:`live_scenario`): the reference's derivatives are then
    #: taken sample by sample as they come (:class:`hexsim.control.feedforward.LiveDerivatives`)
    live: bool = False

    @property
    def open_loop(self) -> bool:
        """Whether the valve setpoints are given (``valve:PATH``): no position controller runs."""
        return self.valve is not None

    @classmethod
    def sine(cls, name: str = "heave", *, amplitude: float | None = None, frequency: float | None = None,
             duration: float | None = None) -> "Scenario":
        """A sine in one degree of freedom (``surge``, ``sway``, ``heave``, ``roll``, ``pitch``, ``yaw``;
        amplitude [m or rad], default 0.05 m / 5°) or the single ``actuator`` (amplitude [m] about mid
        stroke), at ``frequency`` [Hz] (default 0.5), faded in over one period; ``duration`` [s]
        (default max(20, 6 periods)). Raises InputError for an unknown name or a bad value."""
        if name.startswith("file:"):
            raise InputError("Scenario.sine: use Scenario.from_file for a setpoint file")
        return make_scenario(name, duration=duration, amplitude=amplitude, frequency=frequency)

    @classmethod
    def from_file(cls, path, *, duration: float | None = None) -> "Scenario":
        """Platform setpoints from a CSV (``time_s`` and any of ``dof_ref_*``, see the module doc);
        ``duration`` [s] default the file's. Raises InputError naming the file, column or row."""
        return _file_scenario(pathlib.Path(path), duration)

    @property
    def axis_name(self) -> str:
        return "piston" if self.axis < 0 else DOF_NAMES[self.axis]

    @property
    def rotational(self) -> bool:
        return self.axis >= 3

    def poses(self, t: np.ndarray) -> np.ndarray:
        """Platform setpoints (N, 6) [m, rad] relative to the neutral pose at times t (N,) [s] (hexapod)."""
        t = np.asarray(t, dtype=float)
        if self.legs is not None or self.valve is not None:
            raise ValueError(f"scenario {self.name} gives {'piston' if self.legs is not None else 'valve'} setpoints, "
                             f"not platform poses")
        if self._table is not None:
            times, values = self._table
            return np.stack([np.interp(t, times, values[:, k]) for k in range(6)], axis=1)
        out = np.zeros((t.size, 6))
        out[:, self.axis] = self.axis_setpoint(t)
        return out

    def axis_setpoint(self, t: np.ndarray) -> np.ndarray:
        """Setpoint of the motion axis at times t [s]: sine part for sines and the actuator (relative to
        neutral), the interpolated column for files."""
        t = np.asarray(t, dtype=float)
        if self._table is not None:
            times, values = self._table
            return np.interp(t, times, values[:, self.axis])
        return fade_in(t, self.fade_period) * self.amplitude * np.sin(2 * np.pi * self.frequency * t)


def make_scenario(name: str, *, duration: float | None = None, amplitude: float | None = None,
                  frequency: float | None = None, controller_rate_hz: float = 500.0, washout=None,
                  mpc=None) -> Scenario:
    """Build a scenario by name (see module doc); ``washout``: the cueing's parameter file (path), or
    :class:`~hexsim.control.washout.WashoutParams` / :class:`~hexsim.control.mpc_cueing.MPCParams` for a
    ``vehicle:`` scenario; ``mpc``: (platform limits, head point (3,) [m]) to cue it by model-predictive
    cueing instead of the classical washout. Raises InputError for an unknown name or bad option."""
    if (washout is not None or mpc is not None) and not name.startswith("vehicle:"):
        raise InputError(f"--{'washout' if mpc is None else 'cueing'} applies to a vehicle:PATH scenario, not {name}")
    if name.startswith("vehicle:"):
        if amplitude is not None or frequency is not None:
            raise InputError("--amplitude and --frequency do not apply to a vehicle: scenario")
        return vehicle_scenario(name[8:], washout, duration=duration, controller_rate_hz=controller_rate_hz, mpc=mpc)
    if name.startswith(("file:", "valve:")):
        if amplitude is not None or frequency is not None:
            raise InputError(f"--amplitude and --frequency do not apply to a {name.split(':')[0]}: scenario")
        if name.startswith("valve:"):
            return _valve_scenario(pathlib.Path(name[6:]), duration)
        return _file_scenario(pathlib.Path(name[5:]), duration)
    if name not in SCENARIOS:
        raise InputError(f"unknown scenario {name!r}; choose one of {', '.join(SCENARIOS)}, file:PATH or valve:PATH")
    frequency = DEFAULT_FREQUENCY if frequency is None else frequency
    amplitude = DEFAULT_AMPLITUDE[name] if amplitude is None else amplitude
    if not (math.isfinite(frequency) and frequency > 0):
        raise InputError(f"--frequency must be a positive number of Hz, got {frequency}")
    nyquist = controller_rate_hz / 2
    if frequency >= nyquist:
        raise InputError(
            f"--frequency {frequency} Hz is at or above the controller's Nyquist rate {nyquist:g} Hz "
            f"(controller at {controller_rate_hz:g} Hz)"
        )
    if not (math.isfinite(amplitude) and amplitude > 0):
        raise InputError(f"--amplitude must be a positive number, got {amplitude}")
    period = 1.0 / frequency
    duration = max(20.0, 6 * period) if duration is None else duration
    _check_duration(duration, 3 * period, f"{name} at {frequency:g} Hz (fade-in + one settling period + one analysed period)")
    if name == "actuator":
        return Scenario(name, "actuator", duration, -1, frequency, period, amplitude)
    return Scenario(name, "hexapod", duration, SINE_DOFS[name], frequency, period, amplitude)


def _check_duration(duration: float, minimum: float, why: str) -> None:
    if not (math.isfinite(duration) and duration > 0):
        raise InputError(f"--duration must be a positive number of seconds, got {duration}")
    if duration < minimum * (1 - 1e-6):
        raise InputError(f"--duration {duration:g} s is too short: {why} needs at least {minimum:g} s")


def _file_scenario(path: pathlib.Path, duration: float | None) -> Scenario:
    from hexsim.signals import (
        dominant_frequency,  # scipy.optimize: only for files, so --help stays quick
    )

    cols = read_numeric_csv(path)
    unknown = [c for c in cols if c != "time_s" and c not in FILE_COLUMNS]
    if unknown:
        raise InputError(f"{path}: unknown column {unknown[0]!r}; expected time_s and any of {', '.join(FILE_COLUMNS)}")
    present = [c for c in FILE_COLUMNS if c in cols]
    if not present:
        raise InputError(f"{path}: no setpoint column; expected any of {', '.join(FILE_COLUMNS)}")
    times = cols["time_s"]
    if times[0] != 0.0:
        raise InputError(f"{path}: column 'time_s', row 2: the first time must be 0 s, got {times[0]:g} s")
    values = np.zeros((times.size, 6))
    for c in present:
        values[:, FILE_COLUMNS[c]] = cols[c]
    # Motion axis for the metrics: largest peak-to-peak motion, rotations weighted by a 0.5 m lever arm
    # (roughly the platform radius) so metres and radians compare.
    weights = np.array([1, 1, 1, 0.5, 0.5, 0.5])
    axis = int(np.argmax(np.ptp(values, axis=0) * weights))
    try:
        frequency = dominant_frequency(times, values[:, axis])
    except ValueError:
        raise InputError(f"{path}: the setpoints do not move") from None
    period = 1.0 / frequency
    duration = float(times[-1]) if duration is None else duration
    if duration > times[-1] + 1e-12:
        raise InputError(f"{path}: --duration {duration:g} s is longer than the file ({times[-1]:g} s)")
    _check_duration(duration, 3 * period, f"{path.name} (dominant {frequency:.3g} Hz on {DOF_NAMES[axis]})")
    return Scenario(f"file:{path}", "hexapod", duration, axis, frequency, period, None, (times, values))



def vehicle_scenario(vehicle, washout=None, *, duration: float | None = None,
                     controller_rate_hz: float = 500.0, mpc=None) -> Scenario:
    """The platform setpoints the classical washout makes of ``vehicle`` (a vehicle-motion CSV's path or a
    :class:`~hexsim.control.washout.VehicleMotion`) with ``washout`` (a JSON file's path, WashoutParams, or
    None for the defaults), at the controller's rate; with ``mpc`` = (:class:`~hexsim.control.mpc_cueing.
    PlatformLimits`, the head (3,) [m, platform frame]) those of the model-predictive cueing
    (:func:`hexsim.control.mpc_cueing.mpc_washout`, ``washout`` then its MPCParams or their file). The
    metrics' axis is the one that moves most (as for a setpoint file). Raises InputError naming the file,
    column, row or key that is wrong."""
    from hexsim.control.mpc_cueing import MPCParams, mpc_washout
    from hexsim.control.washout import VehicleMotion, WashoutParams, read_vehicle
    from hexsim.control.washout import washout as run_washout

    motion = vehicle if isinstance(vehicle, VehicleMotion) else read_vehicle(vehicle)
    kind = WashoutParams if mpc is None else MPCParams
    params = washout if isinstance(washout, kind) else kind() if washout is None else kind.from_file(washout)
    end = float(motion.t[-1])
    duration = end if duration is None else duration
    _check_duration(duration, 1.0, "a vehicle motion")
    if duration > end + 1e-9:
        raise InputError(f"{motion.source}: --duration {duration:g} s is longer than the vehicle motion ({end:g} s)")
    if mpc is None:
        out = run_washout(motion, params, controller_rate_hz, duration)
    else:
        out = mpc_washout(motion, mpc[0], params, mpc[1], controller_rate_hz, duration)
    weights = np.array([1, 1, 1, 0.5, 0.5, 0.5])
    axis = int(np.argmax(np.ptp(out.poses, axis=0) * weights))
    return Scenario(f"vehicle:{motion.source}", "hexapod", duration, axis, 1.0 / duration, 0.0, None,
                    (out.t, out.poses), cueing=(motion, params, out))


def _valve_scenario(path: pathlib.Path, duration: float | None) -> Scenario:
    """An open-loop experiment from a CSV of valve setpoints (module doc). Raises InputError naming the
    file, column or row: no valve column, a time that does not start at 0, a setpoint beyond ±10.5 V, a
    duration longer than the file."""
    cols = read_numeric_csv(path)
    times = cols["time_s"]
    legs = [f"leg{i}_valve_cmd_V" for i in range(1, 7)]
    if "valve_cmd_V" in cols:
        names, system = ["valve_cmd_V"], "actuator"
    elif all(c in cols for c in legs):
        names, system = legs, "hexapod"
    else:
        raise InputError(f"{path}: no valve setpoint column; expected valve_cmd_V (single actuator) or "
                         f"leg1_valve_cmd_V … leg6_valve_cmd_V (hexapod)")
    if times[0] != 0.0:
        raise InputError(f"{path}: column 'time_s', row 2: the first time must be 0 s, got {times[0]:g} s")
    values = np.column_stack([cols[c] for c in names])
    for j, c in enumerate(names):
        bad = np.abs(values[:, j]) > 10.5
        if np.any(bad):
            r = int(np.argmax(bad))
            raise InputError(f"{path}: column {c!r}, row {r + 2}: value {values[r, j]:g} is not a valve setpoint in V "
                             f"within ±10 V")
    end = float(times[-1] + (times[-1] - times[-2] if len(times) > 1 else 0.0))
    duration = end if duration is None else duration
    if not (math.isfinite(duration) and duration > 0):
        raise InputError(f"--duration must be a positive number of seconds, got {duration}")
    if duration > end + 1e-9:
        raise InputError(f"{path}: --duration {duration:g} s is longer than the file ({end:g} s)")
    axis = -1 if system == "actuator" else 2
    start = np.array([cols["pos_m"][0]]) if system == "actuator" and "pos_m" in cols else None
    return Scenario(f"valve:{path}", system, duration, axis, 1.0 / duration, 0.0, None, valve=(times, values),
                    start=start)


def live_scenario(system: str, neutral: np.ndarray, duration: float, *, open_loop: bool = False,
                  name: str = "live") -> Scenario:
    """A scenario whose setpoint rows are written while it runs (``hexsim serve``, the FMUs): it holds the
    legs at ``neutral`` (n,) [m] for ``duration`` [s] until a caller writes the controller's setpoint rows
    (``Simulator.coupling.setpoints``), or with ``open_loop`` holds the valves at 0 V until it writes the
    valve rows (``Simulator.coupling.valve``)."""
    neutral = np.asarray(neutral, dtype=float)
    valve = (np.zeros(1), np.zeros((1, neutral.size))) if open_loop else None
    return Scenario(name, system, float(duration), 2 if system == "hexapod" else -1, 0.0, 0.0,
                    legs=(np.zeros(1), neutral[None, :]), valve=valve, start=neutral.copy() if open_loop else None,
                    live=True)
