"""Replaying a measurement log through the model: the same hydraulics and MuJoCo mechanics as
:func:`hexsim.engine.runner.simulate`, with the log in place of the scenario.

**Valve replay** of a single-actuator log (identification and the per-channel errors): the logged valve
setpoints u_v drive the model open loop over windows short enough that the integrating position does
not drift far (:data:`hexsim.measured.scoring.WINDOW_S`). Each window starts from the measured state at its first
sample (position, velocity from a Savitzky–Golay derivative of the position, P1, P_s). The controller
is out of the loop, so what it would have compensated (a flow offset, a lag) stays in the residual
where it can be seen. Hexapod logs are replayed closed loop instead (:mod:`hexsim.measured.hexapod_replay`).

All windows run at once as independent copies of the single actuator in one MuJoCo model (one slide
joint and one accelerometer per window), built from the shipped ``single_actuator.xml``.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import mujoco
import numpy as np
from scipy.signal import cont2discrete, lfilter, ss2tf

from hexsim.errors import InputError, PhysicsError
from hexsim.measured.measurement import MeasurementLog
from hexsim.plant import hydraulics, legs
from hexsim.plant.effects import Effects, LegChange
from hexsim.plant.legs import PlantState, leg_table, step_plant
from hexsim.plant.model import PlantIndex, check_warnings, model_spec
from hexsim.plant.params import HydraulicParams, SensorSpec
from hexsim.signals import savgol, savgol_length

#: Channels compared, in report order: name -> (log column of the single actuator, unit, floor of the scale).
CHANNELS = {
    "position": ("pos_m", "m", 1e-4),
    "p1": ("p1_Pa", "Pa", 1e4),
    "p2": ("p2_Pa", "Pa", 1e4),
    "p_s": ("ps_Pa", "Pa", 1e4),
    "acceleration": ("acc_mps2", "m/s^2", 0.05),
}


def batch_model(n: int, effects: Effects, stroke_m: float | None = None) -> mujoco.MjModel:
    """n independent copies of the single actuator (slides ``leg1``…``legN``, sensors ``legI_acc``,
    ``legI_pos``), 0.3 m apart, with the load of ``effects`` (mass, inclination) applied to every copy and each
    slide travelling ``stroke_m`` [m] (the machine's ``cylinder.stroke_m``; None: the MJCF's):
    the actuator's own spec, its load body attached n times (``MjsFrame.attach_body``). A fresh copy of
    a cached compile (building 30 copies takes ~45 ms, about a replay's own time)."""
    return copy.deepcopy(_batch_model(n, effects.mass_kg, effects.inclination_deg, stroke_m))


@functools.lru_cache(maxsize=8)
def _batch_model(n: int, mass_kg: float | None, inclination_deg: float | None,
                 stroke_m: float | None) -> mujoco.MjModel:
    effects = Effects(mass_kg=mass_kg, inclination_deg=inclination_deg)

    def bare() -> mujoco.MjSpec:  # the single actuator loaded, without its motor, sensors and keyframe
        spec = model_spec("actuator", effects=effects, stroke_m=stroke_m)
        for element in [*spec.actuators, *spec.sensors, *spec.keys]:
            spec.delete(element)
        return spec

    single = model_spec("actuator", stroke_m=stroke_m)  # kept alive: an element's arrays are views of its spec's memory
    neutral = [float(q) for q in single.key("neutral").qpos]
    spec = bare()
    spec.delete(spec.body("load"))
    for i in range(1, n + 1):
        frame = spec.worldbody.add_frame(pos=[float(f"{0.3 * (i - 1):g}"), 0.0, 0.0])
        child = bare()  # kept alive while its body is attached (the body does not hold its spec)
        frame.attach_body(child.body("load"), f"copy{i}_", "").name = f"load{i}"
        spec.joint(f"copy{i}_leg1").name = f"leg{i}"
        spec.site(f"copy{i}_platform_centre").name = f"leg{i}_site"
    for i in range(1, n + 1):
        spec.add_actuator(name=f"leg{i}_force", target=f"leg{i}", trntype=mujoco.mjtTrn.mjTRN_JOINT)
    for i in range(1, n + 1):
        for kind, obj, suffix, target in ((mujoco.mjtSensor.mjSENS_ACCELEROMETER, mujoco.mjtObj.mjOBJ_SITE, "acc", "_site"),
                                          (mujoco.mjtSensor.mjSENS_JOINTPOS, mujoco.mjtObj.mjOBJ_JOINT, "pos", "")):
            spec.add_sensor(name=f"leg{i}_{suffix}", type=kind, objtype=obj, objname=f"leg{i}{target}")
    spec.add_key(name="neutral", qpos=neutral * n)
    return spec.compile()


@dataclass(frozen=True)
class Windows:
    """Replay windows: first sample index of each (k,) and their common length in samples."""

    starts: np.ndarray
    length: int

    @classmethod
    def tile(cls, n_samples: int, length: int, skip: int = 0) -> "Windows":
        starts = np.arange(skip, n_samples - length + 1, length)
        if len(starts) == 0:
            raise InputError(f"the log has {n_samples} samples, fewer than one replay window of {length}")
        return cls(starts=starts, length=length)

    def take(self, x: np.ndarray) -> np.ndarray:
        """(k, length) samples of a (N,) signal."""
        return x[self.starts[:, None] + np.arange(self.length)[None, :]]


@dataclass(frozen=True)
class PlantModel:
    """The model being confronted with the log: hydraulics, effects and the declared load, and the legs
    whose parameters differ from the others' (hexapod; :class:`hexsim.plant.effects.LegChange`)."""

    hydraulics: HydraulicParams
    effects: Effects
    leg_changes: tuple[LegChange, ...] = ()
    sensors: SensorSpec | None = None  # how the log's sensors were sampled (None: as its machine file says)

    def replace(self, **changes) -> "PlantModel":
        """A copy with ``changes`` (hydraulics, effects, leg_changes, sensors) applied; leg changes are kept."""
        return dataclasses.replace(self, **changes)


@runtime_checkable
class ReplayProblem(Protocol):
    """What the identifier (:mod:`hexsim.measured.identify`), the discovery and ``hexsim validate`` read of a
    log replayed through a model: :class:`hexsim.measured.scoring.Problem` (a single actuator's open-loop
    valve replay in windows) and :class:`hexsim.measured.hexapod_replay.HexapodProblem` (a hexapod's
    closed-loop replay of the whole log, cut into segments).

    Channel arrays are (rows, samples[, signals]) in physical units: a row is a window or a segment, the
    first ``settle`` samples of each not scored; ``fit_rows`` are fitted, ``test_rows`` held out."""

    log: MeasurementLog
    windowed: bool  # each row starts from the measured state (a position offset is then not seen)
    position_offset_limit: float  # [m] most of a position offset calibrated as the sensor's (closed loop)
    focus_leg: int | None  # hexapod: the leg (1..6) the residual analysis looks at; None on a single actuator
    # candidates are screened by their best start on a prefix of the log before the best few are fitted: a
    # hexapod's replay runs the whole log per model; such a problem also has ``segments`` (its rows) and
    # ``prefix(segments)`` (the problem on its first rows, the replay cut short there)
    screens: bool
    model: str  # the formulation the log is replayed on (hexapod: "platform" or "full", plant.model.FORMULATIONS)
    replay_mode: str  # how the log drives the model, for reports
    scored: str  # which samples are scored, for reports
    fit_rows: np.ndarray
    test_rows: np.ndarray
    settle: int
    channels: list[str]
    scales: dict[str, float]
    measured: dict[str, np.ndarray]
    log_noise: dict[str, float]
    nominal: PlantModel

    def simulate(self, model: PlantModel, dt: float = ...) -> dict[str, np.ndarray]:
        """The replayed channels of ``model`` (step ``dt`` [s]), each shaped like :attr:`measured`."""

    def replay_error(self, model: PlantModel) -> dict[str, float]:
        """The replay's own error per channel beyond the model's step (0 where there is none)."""

    def fit_windows(self) -> "ReplayProblem":
        """The problem a least-squares residual replays: the fit rows alone, all of them fit rows, where the
        rows replay independently (a single actuator's windows); the problem itself where one replay makes
        every row (a hexapod's closed loop)."""

    @property
    def units(self) -> dict[str, str]: ...

    @property
    def window_doc(self) -> dict: ...

    def analysis_view(self, res: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Residuals per channel as the residual analysis takes them (scored samples only)."""

    def motion_state(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(u_v, velocity, position, near a reversal) shaped like :meth:`analysis_view`'s arrays."""

    def sample_times(self) -> np.ndarray:
        """Log times [s] of the samples of :meth:`analysis_view`."""


#: Span [s] of the Savitzky–Golay derivative that gives a window's starting velocity (:func:`measured_velocity`).
VELOCITY_SPAN_S = 0.021
#: A jump of the valve command: a change between two samples larger than this share of its range. The motion
#: kinks there, and a derivative whose span reaches over the kink is wrong on both sides of it (at a 10 V step of
#: the reference plant R1, 77 mm/s at the instant before the piston moves).
JUMP_SHARE = 0.02


def measured_velocity(log: MeasurementLog, pos: np.ndarray) -> np.ndarray:
    """Piston velocity [m/s] from the measured position (N,) by a Savitzky–Golay derivative (cubic,
    :data:`VELOCITY_SPAN_S`, 21 samples at 1 kHz: noise of a few µm gives < 1 mm/s). Read-only: the same
    array for the same position array (:func:`_smoothed_position`)."""
    return _smoothed_position(pos, log.sample_rate_hz, 1)


#: The position's smoothing and derivative by the position array they were taken from (:func:`_smoothed_position`)
_SMOOTHED: dict[tuple[int, float, int], tuple[np.ndarray, np.ndarray]] = {}


def _smoothed_position(pos: np.ndarray, fs: float, deriv: int) -> np.ndarray:
    """:func:`~hexsim.signals.savgol` of ``pos`` (N,) over :data:`VELOCITY_SPAN_S` (``deriv`` 0: the position
    [m], 1: the velocity [m/s]), read-only, taken once per array: a calibration replays the same log's windows
    some 900 times a form, each replay starting its windows from the smoothed position and velocity (the two
    filters of the whole log were a tenth of its time). The last few arrays are kept, each with the array it came
    from (the key's id is then never another array's); the logs' columns are not changed in place."""
    key = (id(pos), float(fs), deriv)
    hit = _SMOOTHED.get(key)
    if hit is not None and hit[0] is pos:
        return hit[1]
    out = savgol(pos, fs, VELOCITY_SPAN_S, deriv=deriv)
    out.setflags(write=False)
    while len(_SMOOTHED) >= 8:
        del _SMOOTHED[next(iter(_SMOOTHED))]
    _SMOOTHED[key] = (pos, out)
    return out


def command_jumps(log: MeasurementLog) -> np.ndarray:
    """The samples (indices, ascending) at which the logged valve command has jumped from the sample before
    (:data:`JUMP_SHARE`); none for a log without ``valve_cmd_V``."""
    u = log.columns.get("valve_cmd_V")
    if u is None:
        return np.zeros(0, dtype=int)
    return np.flatnonzero(np.abs(np.diff(u)) > JUMP_SHARE * log.machine.hydraulics.u_v_max) + 1


def near_jumps(log: MeasurementLog, span_s: float) -> np.ndarray:
    """(N,) bool: the samples a centred filter of ``span_s`` [s] at them reaches over a jump of the valve
    command (:func:`command_jumps`): the motion kinks there, and the filter's output is biased."""
    near = np.zeros(len(log.time), dtype=bool)
    half = savgol_length(log.sample_rate_hz, span_s) // 2 + 1
    for j in command_jumps(log):
        near[max(j - half, 0):j + half] = True
    return near


def clear_of_jumps(log: MeasurementLog, windows: Windows) -> Windows:
    """``windows`` with each start that lies within half the velocity derivative's span
    (:data:`VELOCITY_SPAN_S`) of a jump of the logged valve command (:data:`JUMP_SHARE`) moved to just before
    that span reaches the jump: a window starts from the measured velocity, which is right only away from the
    kink a jump makes (a step log's windows that started at a step began 77 mm/s off, and their fitted
    position scale pulled every other window 1 % off). Windows may then overlap by a few samples."""
    jumps = command_jumps(log)
    if jumps.size == 0:
        return windows
    half = savgol_length(log.sample_rate_hz, VELOCITY_SPAN_S) // 2 + 1
    starts = windows.starts.copy()
    for i, s in enumerate(starts):
        near = jumps[(jumps > s - half) & (jumps <= s + half)]
        if near.size:
            starts[i] = max(int(near[0]) - half, 0)
    return Windows(np.unique(starts), windows.length)


def nominal_plant(log: MeasurementLog) -> PlantModel:
    """The model a log is judged against before any effect: its machine's hydraulics and effects
    (:attr:`MeasurementLog.machine`), the supply level the log states (:func:`supply_from_log`) and, on a
    single actuator, the moving mass and inclination the sidecar declares (what it leaves out is the
    machine's, so a calibration's or validation's machine under test reaches the replay with its own); on a
    hexapod, the legs' own values of the machine file (its ``legs`` section, a calibration's per-leg valves)."""
    hyd, eff = log.machine.hydraulics, log.machine.effects
    if log.system == "single-actuator":
        if log.mass_kg is not None and log.mass_kg != eff.mass_kg:
            eff = eff.replace(mass_kg=log.mass_kg)
        if "inclination_deg" in log.sidecar and log.inclination_deg != (eff.inclination_deg or 0.0):
            eff = eff.replace(inclination_deg=log.inclination_deg)
    return PlantModel(supply_from_log(log, hyd), eff, log.machine.leg_changes, log.machine.sensors)


def supply_from_log(log: MeasurementLog, hyd: HydraulicParams) -> HydraulicParams:
    """``hyd`` with the supply pressure P_s0 set to the median of the log's ``ps_Pa`` (an operating
    condition the log states, not a fitted effect); unchanged if the log has no supply pressure."""
    if "ps_Pa" not in log.columns:
        return hyd
    return hyd.replace(supply_pressure=float(np.median(log.columns["ps_Pa"])))


def spool_history(u_log: np.ndarray, fs: float, hyd: HydraulicParams, eff: Effects, rows: np.ndarray):
    """Spool-side state (u_b, x_v, v_v), each (k,), at the sample ``rows`` after the logged valve
    setpoints u_log (N,) [V] from the start of the log: the backlash recursion
    u_b[j] = clip(u_b[j-1], u[j] - h, u[j] + h), then the second-order spool loop as an exact ZOH
    discretisation (scipy.signal.cont2discrete) of x_v'' = w^2 (x_set - x_v) - 2 zeta w x_v' (spool
    travel limits ignored here). With an ideal spool x_v = x_set, v_v = 0."""
    u_b = legs.backlash_history(u_log, eff.spool_play) if eff.spool_play > 0 else u_log.copy()
    x_set = hydraulics.spool_position(u_b, hyd)
    if eff.spool_frequency <= 0:
        return u_b[rows], x_set[rows], np.zeros(len(rows))
    w, z = 2 * np.pi * eff.spool_frequency, eff.spool_damping
    a = np.array([[0.0, 1.0], [-w * w, -2 * z * w]])
    ad, bd, *_ = cont2discrete((a, np.array([[0.0], [w * w]]), np.eye(2), np.zeros((2, 1))), 1.0 / fs, "zoh")
    # the setpoint of row j is held over the period from row j to row j+1 (see replay): from rest at
    # x_set[0], the state at row j is the response to x_set[0 … j-1], each output of the discrete system
    # (ad, bd) with its one-sample delay (ss2tf's leading zero), filtered by scipy.signal.lfilter
    dev = x_set - x_set[0]
    num, den = ss2tf(ad, bd, np.eye(2), np.zeros((2, 1)))
    x_v = x_set[0] + lfilter(num[0], den, dev)
    v_v = lfilter(num[1], den, dev)
    return u_b[rows], x_v[rows], v_v[rows]


#: The channels a replay records at every physics step (:class:`hexsim.engine.native.ReplayOut`).
FINE_CHANNELS = ("position", "p1", "p_s", "acceleration", "p2")


def _at(fine: np.ndarray, index: np.ndarray) -> np.ndarray:
    """``fine`` (k, N) at the fractional step indices ``index`` (n,), linear between steps, clipped to its ends."""
    x = np.clip(index, 0.0, fine.shape[1] - 1.0)
    lo = np.minimum(np.floor(x).astype(int), fine.shape[1] - 1)
    hi = np.minimum(lo + 1, fine.shape[1] - 1)
    w = x - lo
    return fine[:, lo] * (1.0 - w) + fine[:, hi] * w


def sampled(fine: dict[str, np.ndarray], sub: int, dt: float, spec: SensorSpec) -> dict[str, np.ndarray]:
    """A replay's step-by-step channels ``fine`` (name -> (k, n sub), :data:`FINE_CHANNELS`; ``sub`` physics
    steps of ``dt`` [s] per row) sampled as the log's sensors were (``spec``, the machine file's ``sensors``):
    row j's position and pressures at t_j + ``sample_skew`` (linear between steps; hexsim's own logs: the start
    of row j's first step), its acceleration the mean over the steps from t_j-1 to t_j (``mean``, the boxcar of
    hexsim's records; row 0: its own first step's) or the sensor at t_j + ``acceleration_skew`` (``instant``).
    Each (k, n)."""
    n = fine["position"].shape[1] // sub
    rows = np.arange(n) * sub
    out = {ch: _at(fine[ch], rows + spec.sample_skew / dt) for ch in ("position", "p1", "p_s", "p2")}
    acc = fine["acceleration"]
    if spec.acceleration_sampling == "instant":
        out["acceleration"] = _at(acc, rows + spec.acceleration_skew / dt)
    else:
        means = acc.reshape(acc.shape[0], n, sub).mean(axis=2)
        out["acceleration"] = np.concatenate([acc[:, :1], means[:, :-1]], axis=1)
    return out


def replay(log: MeasurementLog, model: PlantModel, windows: Windows, *, dt: float = 1e-4,
           native: bool = True, fine: bool = False) -> dict[str, np.ndarray]:
    """Simulated channels for each window, name -> (k, length) arrays, same names as :data:`CHANNELS`
    plus ``u_v`` (the valve setpoint applied); ``fine``: the channels at every physics step instead
    ((k, length sub), :data:`FINE_CHANNELS`, for :func:`sampled`).

    The u_v of row j is held from t_j to t_j+1. The channels are sampled as ``model.sensors`` (else the log's
    machine file) says its sensors were (:func:`sampled`, :class:`hexsim.plant.params.SensorSpec`): by default
    as hexsim's own logs (:func:`hexsim.engine.runner.simulate`), row j holding the state at its time t_j
    (position, P1, P_s) and the acceleration averaged over the steps from t_j-1 to t_j. The state of row 0 is the measured one;
    the logged u_v drives each window open loop.
    The measured position the log holds is compared with y(t - tau_y) when the model has a sensor delay. ``native``: the valve replay runs in the
    compiled kernel (:mod:`hexsim.engine.native`); False: a Python loop over the same compiled leg step. Single-actuator logs only.
    Raises InputError if the log lacks what the mode needs, PhysicsError on a MuJoCo warning or a
    non-finite state.
    """
    if log.system != "single-actuator":
        raise InputError(f"{log.path}: window replay needs a single-actuator log (this is {log.system})")
    hyd, eff = model.hydraulics, model.effects
    fs = log.sample_rate_hz
    sub = int(round(1.0 / (fs * dt)))
    if abs(sub * dt * fs - 1.0) > 1e-9:
        raise InputError(f"{log.path}: sample rate {fs:g} Hz must divide the physics rate {1 / dt:g} Hz")
    k, n = len(windows.starts), windows.length
    m = batch_model(k, eff, hyd.stroke)
    m.opt.timestep = dt
    d = mujoco.MjData(m)
    idx = PlantIndex.from_model(m)
    spec = model.sensors or log.machine.sensors
    state, y0 = _window_start(log, model, windows, m, d, idx, spec.sample_skew)
    u_log = log.columns["valve_cmd_V"]
    acc_adr = np.array([idx.sensor[f"leg{i + 1}_acc"].start + 2 for i in range(k)])
    u_sched = windows.take(u_log)
    # every step recorded where the sensors' timing asks for it (else the kernel records the rows, as hexsim's logs)
    every_step = fine or not native or spec.sample_skew != 0.0 or spec.acceleration_sampling != "mean"
    steps = {name: np.empty((k, n * sub if every_step else n)) for name in FINE_CHANNELS}
    mujoco.set_mjcb_control(None)
    if native:
        from hexsim.engine import native as kernel

        legs = kernel.Legs(leg_table(hyd, eff, k), dt, state, np.arange(k), np.zeros(k), np.zeros((1, k)), np.zeros(k))
        bad = kernel.valve_replay(kernel.mj_view(m, d, idx), legs, acc_adr, u_sched, sub,
                                  kernel.ReplayOut(*(steps[name] for name in FINE_CHANNELS)))
        if bad >= 0:
            raise PhysicsError(f"replay: non-finite P1 {bad / fs:.3f} s into a window")
    else:
        _python_replay(log, model, windows, (m, d, idx), state, steps)
    check_warnings(m, d)
    if fine:
        return {**steps, "u_v": u_sched}
    out = {**(sampled(steps, sub, dt, spec) if every_step else steps), "u_v": u_sched}
    tau = eff.sensor_delay
    if tau > 0:
        # the log's position is the sensor's: y(t - tau); shift each window's simulated trace by tau
        t, tw = log.time, np.arange(n) / fs
        out["position"] = np.array([np.interp(tw - tau, tw, row, left=y0w) for row, y0w in
                                    zip(out["position"], np.interp(t[windows.starts], t, log.columns["pos_m"]))])
    return out


def _window_start(log: MeasurementLog, model: PlantModel, windows: Windows, m, d, idx,
                  skew: float) -> tuple[PlantState, np.ndarray]:
    """Set the batch model ``m``/``d`` to the measured state at each window's start (position and velocity the
    delayed sensor shows tau_y later), read ``skew`` [s] before the window's first row (the log holds the state at
    t_j + sample_skew, :func:`sampled`), and return the legs' state there (P1 measured or from the
    statics, P_s measured with a supply model, the spool history) and the start positions y0 (k,) [m]."""
    hyd, eff, c, t = model.hydraulics, model.effects, log.columns, log.time
    s0, k = windows.starts, len(windows.starts)
    pos, u_log = c["pos_m"], c["valve_cmd_V"]
    vel = measured_velocity(log, pos)
    tau = eff.sensor_delay
    # row j of the log holds the state at t_j + sample_skew: the state at a window's start t_j is the log's
    # skew earlier (a skew of 0.2 ms put every window's start v 0.2 ms off: 20 µm at 0.1 m/s, kept all window)
    # the position from the same cubic fit as the velocity (21 samples: a third of the sensor's noise), not one
    # noisy sample: the window integrates from it, so its error stays all window (sqrt(2) times the noise); with a
    # sensor delay, the true position is what the delayed sensor shows tau later
    y0 = np.interp(t[s0] + tau - skew, t, _smoothed_position(pos, log.sample_rate_hz, 0))
    d.qpos[idx.qpos_adr] = y0
    d.qvel[idx.dof_adr] = np.interp(t[s0] + tau - skew, t, vel)
    mujoco.mj_forward(m, d)
    g_axis = -float(m.opt.gravity[2])
    mass = float(m.body_mass[1])
    # P_s: with a supply model, the measured level at the window start (mean of 10 samples against the
    # transducer noise); else constant at the supply pressure (the caller sets it, see supply_from_log)
    if "ps_Pa" in c and eff.supply_resistance > 0:
        p_s0 = Windows(s0, 10).take(c["ps_Pa"]).mean(axis=1)
    else:
        p_s0 = np.full(k, hyd.supply_pressure)
    p1_0, p2_0 = hydraulics.rest_pressures(mass * g_axis * np.ones(k), hyd, p_s0)
    if "p1_Pa" in c:
        p1_0 = np.interp(t[s0] - skew, t, c["p1_Pa"])
    if hyd.four_way and "p2_Pa" in c:
        p2_0 = np.interp(t[s0] - skew, t, c["p2_Pa"])
    if hyd.four_way and ("p1_Pa" in c) != ("p2_Pa" in c):
        # one chamber logged: the other from the piston's balance at the window start, P1 A1 - P2 A2 =
        # F_f(ydot) + M g (the acceleration left out), not the at-rest split
        balance = hydraulics.friction_force(d.qvel[idx.dof_adr], hyd) + mass * g_axis
        if "p1_Pa" in c:
            p2_0 = np.clip((p1_0 * hyd.area_bottom - balance) / hyd.area_rod, hyd.cavitation_pressure, p_s0)
        else:
            p1_0 = np.clip((p2_0 * hyd.area_rod + balance) / hyd.area_bottom, hyd.cavitation_pressure, p_s0)
    u_b, x_v, v_v = spool_history(u_log, log.sample_rate_hz, hyd, eff, s0)
    return PlantState.at_rest(p1_0, u_log[s0], hyd, p_s0, p2_0)._replace(u_b=u_b, x_v=x_v, v_v=v_v), y0


def _python_replay(log, model, windows, sim, state, out) -> None:
    """The straightforward Python loop of :func:`replay` over the same compiled leg step on ``sim`` = (the
    batch model, its data, its PlantIndex), filling the step-by-step channels ``out`` (:data:`FINE_CHANNELS`)
    in place. Raises PhysicsError naming the window and the time for a non-finite state."""
    m, d, idx = sim
    dt = m.opt.timestep
    sub = int(round(1.0 / (log.sample_rate_hz * dt)))
    acc_adr = np.array([idx.sensor[f"leg{i + 1}_acc"].start + 2 for i in range(len(windows.starts))])
    u_log, s0, n = log.columns["valve_cmd_V"], windows.starts, windows.length
    for j in range(n):
        u = u_log[s0 + j]
        for s_ in range(sub):
            c = j * sub + s_
            y = d.qpos[idx.qpos_adr].copy()
            ydot = d.qvel[idx.dof_adr].copy()
            out["position"][:, c], out["p1"][:, c], out["p_s"][:, c], out["p2"][:, c] = y, state.p1, state.p_s, state.p2
            state, d.ctrl[idx.actuator_id] = step_plant(state, u, y, ydot, dt, model.hydraulics, model.effects)
            mujoco.mj_step(m, d)
            out["acceleration"][:, c] = d.sensordata[acc_adr]
        if not (np.all(np.isfinite(state.p1)) and np.all(np.isfinite(d.qpos))):
            bad = int(np.flatnonzero(~np.isfinite(state.p1) | ~np.isfinite(d.qpos[idx.qpos_adr]))[0])
            raise PhysicsError(f"replay: non-finite state in the window starting at t = {log.time[s0[bad]]:.3f} s, "
                               f"{j / log.sample_rate_hz:.3f} s into it")
