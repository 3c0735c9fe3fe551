"""Coupling of the hydraulics to MuJoCo and the simulation run: scenario → IK → P control → valve →
chamber → leg force (MuJoCo control callback at every 10 kHz physics step) → rigid bodies → sensors.

The control callback (``mujoco.set_mjcb_control``) is process-global; :func:`simulate` installs it for
the duration of one run and always removes it.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation
from tqdm import tqdm

from compensation import CompensatorSettings, PlantTruth, SettingsError, make_compensator
from compensation.base import ReplayedCompensation
from hexsim import hydraulics
from hexsim.controller import PController
from hexsim.effects import Effects
from hexsim.errors import InputError, PhysicsError, WorkspaceError
from hexsim.faults import Fault, FaultInjector
from hexsim.kinematics import HexapodGeometry
from hexsim.model import PlantIndex, apply_load, check_warnings, load_model, reset_neutral
from hexsim.params import ControllerParams, HydraulicParams
from hexsim.plant import PlantState, leg_params, step_plant
from hexsim.scenario import Scenario
from hexsim.signals import zero_order_hold
from hexsim.temperature import WarmUp


#: Ways to run the loop: the compiled runner (hexsim.native) and the Python control callback, a
#: straightforward loop over the same compiled leg step (hexsim.plant) that also runs Python compensators.
ENGINES = ("native", "python")


@dataclass(frozen=True)
class RunConfig:
    """Everything that defines one run. ``record_rate_hz`` None: 1 kHz, the rate of the measurement-log
    example (``docs/measurement-log.md``); it must divide the 10 kHz physics rate."""

    scenario: Scenario
    hydraulics: HydraulicParams = field(default_factory=HydraulicParams)
    controller: ControllerParams = field(default_factory=ControllerParams)
    compensator: str = "none"
    compensator_settings: CompensatorSettings = field(default_factory=CompensatorSettings)
    warm_up: WarmUp | None = None  # oil warming during the run (seed §5.5); None: constant 35 °C
    effects: Effects = field(default_factory=Effects)  # extensions of the seed model; default: none
    seed: int = 0
    record_rate_hz: float | None = None
    progress: bool = False
    engine: str = "native"  # "native": compiled runner (hexsim.native); "python": the control callback
    timestep: float | None = None  # physics step [s]; None: the model's 1e-4 s (the seed's 10 kHz)
    keep_last_s: float | None = None  # keep only the last this many seconds of the recording (long runs:
    # memory stays flat; metrics and outputs cover that window); None: the whole run
    faults: tuple[Fault, ...] = ()  # injected faults (hexsim.faults); default none
    # U_c per controller sample (n_ticks, n_legs) [V] replayed instead of a compensator (measured-data
    # replay, hexsim.hexapod_replay); None: the compensator named above
    feedforward: np.ndarray | None = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.engine not in ENGINES:
            raise InputError(f"engine must be one of {', '.join(ENGINES)}, got {self.engine!r}")
        if self.keep_last_s is not None and not (math.isfinite(self.keep_last_s) and self.keep_last_s > 0):
            raise InputError(f"keep_last_s must be a positive number of seconds, got {self.keep_last_s!r}")
        if self.timestep is not None:
            if not (math.isfinite(self.timestep) and 1e-6 <= self.timestep <= 1e-3):
                raise InputError(f"timestep must be within 1e-6…1e-3 s, got {self.timestep!r}")
            _divider(self.controller.rate_hz, self.timestep, f"controller rate (timestep {self.timestep:g} s)")
            _divider(self.record_rate_hz or 1000.0, self.timestep, f"record rate (timestep {self.timestep:g} s)")


@dataclass
class SimulationResult:
    """Recorded signals of a run, sampled at ``record_rate_hz``; arrays (N,) or (N, n_legs) or (N, 3).

    t [s]; y, ydot: measured piston position [m] / velocity [m/s] (jointpos/jointvel sensors); y_ref:
    piston setpoint in force (ZOH) [m] (with a sensor delay, y is the delayed measurement and ydot the
    true velocity); u_v: valve setpoint [V]; u_c: compensation voltage [V]; p1: bottom-chamber pressure
    [Pa]; p_s: supply pressure (N,) [Pa] (of the first manifold); force: hydraulic leg force [N]; acc:
    accelerometer, site frame, specific force [m/s^2]; gyro [rad/s] and angacc [rad/s^2] (world) of the
    platform (hexapod only); pose: measured platform pose (N, 6) rel. neutral; pose_ref: commanded pose;
    constraint_violation: largest connect violation [m] per sample; oil_temperature [°C];
    compensator_state: the compensator's logged parameters, name -> (N, n_legs).
    """

    config: RunConfig
    t: np.ndarray
    y: np.ndarray
    ydot: np.ndarray
    y_ref: np.ndarray
    u_v: np.ndarray
    u_c: np.ndarray
    p1: np.ndarray
    p_s: np.ndarray
    force: np.ndarray
    acc: np.ndarray
    gyro: np.ndarray | None
    angacc: np.ndarray | None
    pose: np.ndarray | None
    pose_ref: np.ndarray | None
    constraint_violation: np.ndarray
    oil_temperature: np.ndarray
    compensator_state: dict[str, np.ndarray]
    p1_initial: np.ndarray
    saturated_samples: int
    wall_time_s: float
    gravity: float
    stroke: np.ndarray  # (n_legs, 2) joint range of each piston [m]
    timestep: float  # physics step [s]

    @property
    def n_legs(self) -> int:
        return self.y.shape[1]

    @property
    def realtime_factor(self) -> float:
        return self.config.scenario.duration / self.wall_time_s


class HydraulicCoupling:
    """The MuJoCo control callback: valve, chamber and friction of every leg, once per physics step.

    At step k (time t_k): every ``ctrl_div``-th step the controller samples the measured piston positions
    (plus sensor noise; delayed by tau_y with a sensor-delay effect) and updates u_v (held in between:
    ZOH); then the leg hydraulics advance to t_k+1 with the piston velocity at t_k
    (:func:`hexsim.plant.step_plant`, the compiled :func:`hexsim.plant.step_legs` with any
    :class:`~hexsim.effects.Effects`) and the leg force P1 A1 - P_s A2 - F_f(ydot) is written to
    ``data.ctrl``. Repeated calls at the same time (an extra ``mj_forward``) rewrite the same
    force without integrating twice. An exception is kept in :attr:`error` for the runner to raise, since
    it cannot cross MuJoCo's C loop.
    """

    def __init__(self, idx: PlantIndex, hyd: HydraulicParams, controller: PController, setpoints: np.ndarray,
                 noise: np.ndarray, p1_initial: np.ndarray, ctrl_div: int, warm_up: WarmUp | None = None,
                 plant: PlantTruth | None = None, effects: Effects | None = None,
                 faults: FaultInjector | None = None) -> None:
        self.idx = idx
        self.hyd = hyd
        self.base_hyd = hyd
        self.warm_up = warm_up
        self.plant = plant
        self.temperature = float(warm_up.temperature(0.0)) if warm_up else 35.0
        self.controller = controller
        self.setpoints = setpoints
        self.noise = noise
        self.ctrl_div = ctrl_div
        self.dt = idx.dt
        self.effects = effects or Effects()
        self.faults = faults
        self.groups = np.zeros(idx.n_legs, dtype=np.intp)  # one supply manifold for all legs
        n = idx.n_legs
        self.state = PlantState.at_rest(p1_initial, np.zeros(n), hyd)
        delay_steps = int(round(self.effects.sensor_delay / self.dt))
        self._y_history = np.tile(np.asarray(idx.neutral_y, dtype=float), (delay_steps + 1, 1))
        self.y_measured = self._y_history[0].copy()
        self.u_v = np.zeros(n)
        self.u_c = np.zeros(n)
        self.r = setpoints[0].copy()
        self.force = np.zeros(n)
        self._last_step = -1
        self.supply_level: float | None = None
        self.error: BaseException | None = None

    def __call__(self, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        try:
            k = int(round(d.time / self.dt))
            if k != self._last_step:
                self._last_step = k
                y = d.qpos[self.idx.qpos_adr]
                ydot = d.qvel[self.idx.dof_adr]
                hist = self._y_history
                hist[k % len(hist)] = y
                self.y_measured = hist[(k + 1) % len(hist)]  # y(t_k - tau_y); itself without delay
                if k % self.ctrl_div == 0:
                    self.hyd = self.tick(k, self.y_measured)
                    if self.supply_level is not None:
                        self.state.p_s[:] = self.supply_level
                self.state, self.force = step_plant(self.state, self.u_v, y, ydot, self.dt, self.hyd, self.effects,
                                                    self.groups)
            d.ctrl[self.idx.actuator_id] = self.force
        except Exception as exc:  # noqa: BLE001 - re-raised by simulate() after the step
            self.error = exc
            d.ctrl[self.idx.actuator_id] = 0.0


    def tick(self, k: int, y_measured: np.ndarray) -> HydraulicParams:
        """The controller sample at step ``k`` (both engines): oil temperature, setpoint, P control with
        the compensator, faults. Sets :attr:`r`, :attr:`u_v`, :attr:`u_c`, :attr:`supply_level` (P_s
        imposed by a supply-loss fault, else None); returns the hydraulic parameters now in force."""
        t_k = k * self.dt
        hyd = self.hyd
        if self.warm_up is not None:
            self.temperature = float(self.warm_up.temperature(t_k))
            hyd = self.warm_up.params_at(self.base_hyd, self.temperature)
            if self.plant is not None:
                self.plant.params = hyd
        j = min(k // self.ctrl_div, len(self.setpoints) - 1)
        self.r = self.setpoints[j]
        seen = y_measured + self.noise[j]
        inj = self.faults
        if inj:
            self.r = inj.setpoint(t_k, self.r)
            seen = inj.measured(t_k, seen)
        self.u_v, self.u_c = self.controller.sample(self.r, seen)
        self.supply_level = None
        if inj:
            self.u_v = inj.valve(t_k, self.u_v)
            self.supply_level = inj.supply(t_k)
        return hyd


def static_leg_forces(m: mujoco.MjModel, d: mujoco.MjData, idx: PlantIndex) -> np.ndarray:
    """Leg forces (n_legs,) [N] that hold the current configuration at rest (slide accelerations zero).

    The slide accelerations are affine in the actuator forces (equality constraints only), so one
    ``mj_forward`` with zero force and one per unit force give the linear system. Gravity, the legs' own
    weight and the closed-loop constraints are all MuJoCo's. Call with no control callback installed.
    """
    d.ctrl[:] = 0.0
    mujoco.mj_forward(m, d)
    acc0 = d.qacc[idx.dof_adr].copy()
    sens = np.empty((idx.n_legs, idx.n_legs))
    for j, a in enumerate(idx.actuator_id):
        d.ctrl[:] = 0.0
        d.ctrl[a] = 1.0
        mujoco.mj_forward(m, d)
        sens[:, j] = d.qacc[idx.dof_adr] - acc0
    d.ctrl[:] = 0.0
    mujoco.mj_forward(m, d)
    return np.linalg.solve(sens, -acc0)


def piston_setpoints(m: mujoco.MjModel, idx: PlantIndex, scenario: Scenario, t: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """Piston setpoints (N, n_legs) [m] at times t (N,) [s], and the platform poses (N, 6) (hexapod) or None.

    Raises WorkspaceError naming the leg and length if a setpoint leaves the stroke.
    """
    if scenario.legs is not None:
        times, values = scenario.legs
        if values.shape[1] != idx.n_legs:
            raise InputError(f"scenario {scenario.name} has {values.shape[1]} legs, the model {idx.n_legs}")
        return _within_stroke(zero_order_hold(times, values, t), t, idx), None
    if scenario.system == "hexapod":
        if idx.n_legs != 6:
            raise InputError(f"scenario {scenario.name} needs the hexapod model, this model has {idx.n_legs} legs")
        poses = scenario.poses(t)
        return HexapodGeometry.from_model(m).inverse(poses, t), poses
    return _within_stroke(idx.neutral_y[None, :] + scenario.axis_setpoint(t)[:, None], t, idx), None


def _within_stroke(y: np.ndarray, t: np.ndarray, idx: PlantIndex) -> np.ndarray:
    """``y`` (N, n_legs) [m] unchanged, or WorkspaceError naming the first time and leg outside its stroke."""
    for i, (lo, hi) in enumerate(idx.stroke):
        bad = (y[:, i] < lo) | (y[:, i] > hi)
        if np.any(bad):
            n = int(np.argmax(bad))
            raise WorkspaceError(f"setpoint at t = {t[n]:.3f} s needs leg{i + 1} piston position {y[n, i]:.4f} m, "
                                 f"outside its stroke {lo:g}…{hi:g} m")
    return y


def simulate(config: RunConfig) -> SimulationResult:
    """Run one scenario headless and record it. See the module doc for the chain.

    Raises WorkspaceError for an unreachable setpoint, InputError for inconsistent settings and
    PhysicsError for a MuJoCo warning or a non-finite state (naming the time and the leg).
    """
    sc, hyd, cp = config.scenario, config.hydraulics, config.controller
    m = load_model(sc.system)
    apply_load(m, config.effects)
    if config.timestep is not None:
        m.opt.timestep = config.timestep
    d = mujoco.MjData(m)
    idx = PlantIndex.from_model(m)
    dt = idx.dt
    ctrl_div = _divider(cp.rate_hz, dt, "controller rate")
    record_rate = config.record_rate_hz or 1000.0
    rec_div = _divider(record_rate, dt, "record rate")

    n_ticks = int(math.ceil(sc.duration * cp.rate_hz)) + 1
    t_ticks = np.arange(n_ticks) / cp.rate_hz
    setpoints, _ = piston_setpoints(m, idx, sc, t_ticks)
    rng = np.random.default_rng(config.seed)
    noise = rng.normal(0.0, cp.position_noise, size=setpoints.shape)

    mujoco.set_mjcb_control(None)
    reset_neutral(m, d)
    p1_0 = hydraulics.equilibrium_pressure(static_leg_forces(m, d, idx), hyd)
    for i, p in enumerate(p1_0):
        if not hyd.tank_pressure < p < hyd.supply_pressure:
            raise PhysicsError(
                f"leg{i + 1} needs P1 = {p / 1e5:.1f} bar to hold the neutral pose, outside tank…supply "
                f"({hyd.tank_pressure / 1e5:g}…{hyd.supply_pressure / 1e5:g} bar)"
            )
    plant = PlantTruth(params=hyd, p1_static=p1_0.copy())
    try:
        if config.feedforward is not None:
            compensator = ReplayedCompensation(np.ascontiguousarray(config.feedforward, dtype=float), cp.rate_hz,
                                               hyd.u_v_max)
        else:
            compensator = make_compensator(config.compensator, idx.n_legs, cp.rate_hz, u_v_max=hyd.u_v_max,
                                           settings=config.compensator_settings, plant=plant)
    except SettingsError as exc:
        raise InputError(str(exc)) from None
    controller = PController(cp, hyd.u_v_max, compensator)
    injector = FaultInjector(config.faults, idx.n_legs, idx.stroke, hyd.supply_pressure, hyd.tank_pressure)
    coupling = HydraulicCoupling(idx, hyd, controller, setpoints, noise, p1_0, ctrl_div, config.warm_up, plant,
                                 config.effects, injector)

    n_total = int(round(sc.duration / dt)) // rec_div  # samples the run records
    n_rec = n_total if config.keep_last_s is None else min(n_total, max(1, int(round(config.keep_last_s * record_rate))))
    n = idx.n_legs
    rec = {k: np.empty((n_rec, n)) for k in ("y", "ydot", "y_ref", "u_v", "u_c", "p1", "force")}
    t = np.empty(n_rec)
    p_s = np.empty(n_rec)
    acc = np.empty((n_rec, 3))
    hexapod = sc.system == "hexapod"
    gyro, angacc = (np.empty((n_rec, 3)), np.empty((n_rec, 3))) if hexapod else (None, None)
    pos, quat = (np.empty((n_rec, 3)), np.empty((n_rec, 4))) if hexapod else (None, None)
    viol = np.zeros(n_rec)
    temperature = np.empty(n_rec)
    comp_state = {k: np.empty((n_rec, n)) for k in compensator.state()}

    rec_sensors = {"platform_acc": acc}
    if hexapod:
        rec_sensors.update(platform_gyro=gyro, platform_angacc=angacc, platform_pos=pos, platform_quat=quat)
    bar = tqdm(total=round(sc.duration, 3), unit="sim s", disable=not config.progress, leave=False,
               bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} sim s [{elapsed}<{remaining}]")
    if config.engine == "python":
        wall = _loop_python(m, d, idx, coupling, compensator, rec_div, t, rec, p_s, temperature, comp_state, rec_sensors,
                           viol, bar, n_total)
    else:
        wall = _loop_native(m, d, idx, coupling, compensator, config, rec_div, t, rec, p_s, temperature, comp_state,
                            rec_sensors, viol, bar, n_total)
    bar.close()
    if n_total > n_rec:  # a ring of the last n_rec samples: put them in time order
        shift = n_total % n_rec
        kept = [t, p_s, acc, viol, temperature, *rec.values(), *comp_state.values()]
        for arr in kept + [x for x in (gyro, angacc, pos, quat) if x is not None]:
            arr[:] = np.roll(arr, -shift, axis=0)

    pose = pose_ref = None
    if hexapod:
        geom = HexapodGeometry.from_model(m)
        rpy = Rotation.from_quat(quat[:, [1, 2, 3, 0]]).as_euler("ZYX")[:, ::-1]
        pose = np.concatenate([pos - geom.neutral_position, rpy], axis=1)
        pose_ref = sc.poses(t) if sc.legs is None else None
    return SimulationResult(
        config=config, t=t, **rec, p_s=p_s, acc=acc, gyro=gyro, angacc=angacc,
        pose=pose, pose_ref=pose_ref, constraint_violation=viol, oil_temperature=temperature,
        compensator_state=comp_state, p1_initial=p1_0,
        saturated_samples=controller.saturated_samples, wall_time_s=wall, gravity=float(-m.opt.gravity[2]),
        stroke=idx.stroke.copy(), timestep=dt,
    )


def _loop_python(m, d, idx, coupling, compensator, rec_div, t, rec, p_s, temperature, comp_state, rec_sensors,
                viol, bar, n_total) -> float:
    """The straightforward loop: :class:`HydraulicCoupling` as MuJoCo's control callback; every ``rec_div``-th
    step k records the state at t_k (the sensors MuJoCo evaluates at the start of the step, P1 before
    the step's update); ``n_total`` samples, kept in the arrays as a ring (row i % len(t)). Returns the
    wall time [s]."""
    s = idx.sensor
    n = idx.n_legs
    dt = idx.dt
    leg_vel = np.array([s[f"leg{i + 1}_vel"].start for i in range(n)])
    start = time.perf_counter()
    mujoco.set_mjcb_control(coupling)
    try:
        for i in range(n_total):
            w = i % len(t)
            p1_before, p_s_before = coupling.state.p1.copy(), coupling.state.p_s[0]
            mujoco.mj_step(m, d)  # step k = i * rec_div: the sensors see t_k
            if coupling.error is not None:
                raise coupling.error
            _check_state(m, d, idx, coupling)
            sd = d.sensordata
            t[w] = i * rec_div * dt
            rec["y"][w] = coupling.y_measured  # the position sensor, y(t_k - tau_y)
            rec["ydot"][w] = sd[leg_vel]
            rec["y_ref"][w] = coupling.r
            rec["u_v"][w] = coupling.u_v
            rec["u_c"][w] = coupling.u_c
            rec["p1"][w] = p1_before
            p_s[w] = p_s_before
            rec["force"][w] = coupling.force
            temperature[w] = coupling.temperature
            for key, value in compensator.state().items():
                comp_state[key][w] = value
            for name, out in rec_sensors.items():
                out[w] = sd[s[name]]
            eq = d.efc_type[: d.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY
            if np.any(eq):
                viol[w] = np.linalg.norm(d.efc_pos[: d.nefc][eq].reshape(-1, 3), axis=1).max()
            if i % 100 == 0:
                bar.update(round(d.time - bar.n, 3))
            if rec_div > 1:
                mujoco.mj_step(m, d, rec_div - 1)
                if coupling.error is not None:
                    raise coupling.error
                _check_state(m, d, idx, coupling)
    finally:
        mujoco.set_mjcb_control(None)
    return time.perf_counter() - start


def _loop_native(m, d, idx, coupling, compensator, config, rec_div, t, rec, p_s, temperature, comp_state,
                 rec_sensors, viol, bar, n_total) -> float:
    """The compiled path: :func:`hexsim.native.run_block` steps the legs and MuJoCo, recording into the
    rows of a :class:`hexsim.native.Recorder`. Without faults or warming oil, and with no compensator,
    the buffered or the directional one (:func:`compensation.buffered.buffered_tick`, on the
    compensator's own state records) or a replayed compensation table, the kernel runs the P controller
    and the compensator too and Python calls it every 0.5 s (:func:`_run_inner`); otherwise Python
    samples controller and compensator (any Python compensator) at every controller tick and the kernel
    runs until the next tick (:func:`_run_ticks`). Same order of operations as
    :class:`HydraulicCoupling` (tests/test_native.py checks the trajectories agree). Returns the wall
    time [s], compilation (or loading from numba's cache) excluded."""
    from hexsim import native

    n, dt = idx.n_legs, idx.dt
    eq = np.flatnonzero(m.eq_type == mujoco.mjtEq.mjEQ_CONNECT)
    if np.any(m.eq_objtype[eq] != mujoco.mjtObj.mjOBJ_SITE):
        raise InputError("the native engine needs connect constraints between sites")
    mj = native.mj_view(m, d, idx, m.eq_obj1id[eq].astype(np.int64), m.eq_obj2id[eq].astype(np.int64))
    legs = native.Legs(leg_params(coupling.hyd, coupling.effects), dt, coupling.state.copy(), coupling.groups,
                       np.zeros(n), coupling._y_history)
    # without faults or warming oil, the P controller and the compensator run inside the kernel as well
    mode = native.comp_mode(compensator)
    inner = mode is not None and not coupling.faults and coupling.warm_up is None
    ctl = native.Control(coupling.ctrl_div if inner else 0, coupling.controller.params.kp, coupling.setpoints,
                         coupling.noise, mode or 0, native.kernel_state(compensator, n),
                         compensator.table if mode == 2 else np.zeros((1, n)), np.zeros(1, dtype=np.int64))
    n_rec = len(t)  # rows kept: the last n_rec of the n_total samples, as a ring
    recorder = native.Recorder(rec_div, n_total, np.empty(n_rec, dtype=np.int64), np.empty((n_rec, m.nsensordata)),
                               rec["p1"], p_s, rec["force"], rec["y"], viol, rec["y_ref"], rec["u_v"], rec["u_c"],
                               np.empty((n_rec if inner and mode == 1 else 1, 4, n)), np.full(1, -1, dtype=np.int64))
    mujoco.mj_forward(m, d)
    native.run_block(mj, legs, ctl, recorder, np.zeros(n), 0, 0, 0)  # compile or load from the cache first
    start = time.perf_counter()
    if inner:
        _run_inner(m, d, idx, mj, legs, ctl, recorder, coupling, compensator, n_total * rec_div, bar)
        temperature[:] = coupling.temperature
        if mode == 1:
            for c, key in enumerate(("a", "b", "c", "s")):  # as BufferedCompensator.state()
                comp_state[key][:] = recorder.comp[:, c]
    else:
        _run_ticks(m, d, idx, mj, legs, ctl, recorder, coupling, compensator, n_total * rec_div, bar, temperature,
                   comp_state)
    wall = time.perf_counter() - start
    _check_finite(legs.state.p1, d, idx, d.time)  # the kernel checks the legs at every step, this the platform too
    t[:] = recorder.k * dt
    s = idx.sensor
    rec["ydot"][:] = recorder.sens[:, [s[f"leg{i + 1}_vel"].start for i in range(n)]]
    for name, out in rec_sensors.items():
        out[:] = recorder.sens[:, s[name]]
    coupling.state = legs.state
    coupling.force = legs.force
    return wall


def _run_inner(m, d, idx, mj, legs, ctl, recorder, coupling, compensator, total, bar) -> None:
    """``total`` steps with the controller in the kernel, in chunks of about 0.5 s (progress, checks)."""
    from hexsim import native

    warnings = d.warning.number  # a view of MuJoCo's warning counters
    u_v = np.zeros(idx.n_legs)
    chunk = max(1, int(round(0.5 / (ctl.div * idx.dt)))) * ctl.div
    k = r = 0
    while k < total:
        steps = min(chunk, total - k)
        r = native.run_block(mj, legs, ctl, recorder, u_v, k, steps, r)
        _check_block(m, d, idx, recorder.status, legs.state.p1, warnings)
        k += steps
        bar.update(round(k * idx.dt - bar.n, 3))
    coupling.controller.saturated_samples += int(ctl.saturated[0])
    if ctl.mode == 2:
        compensator.advance(-(-total // ctl.div))


def _run_ticks(m, d, idx, mj, legs, ctl, recorder, coupling, compensator, total, bar, temperature,
               comp_state) -> None:
    """``total`` steps with the controller sampled in Python (:meth:`HydraulicCoupling.tick`: warming oil,
    faults, any compensator) and the kernel run from one controller tick to the next."""
    from hexsim import native

    warnings = d.warning.number
    hist, ctrl_div = legs.history, coupling.ctrl_div
    L, n_rec = len(hist), len(recorder.k)
    hyd = coupling.hyd
    k = r = 0
    while k < total:
        hist[k % L] = d.qpos[idx.qpos_adr]
        new_hyd = coupling.tick(k, hist[(k + 1) % L].copy())
        if new_hyd is not hyd:
            hyd = new_hyd
            legs = legs._replace(params=leg_params(hyd, coupling.effects))
        if coupling.supply_level is not None:
            legs.state.p_s[:] = coupling.supply_level
        steps = min(ctrl_div, total - k)
        r_next = native.run_block(mj, legs, ctl, recorder, coupling.u_v, k, steps, r)
        _check_block(m, d, idx, recorder.status, legs.state.p1, warnings)
        rows = np.arange(r, r_next) % n_rec
        recorder.ref[rows] = coupling.r
        recorder.u[rows] = coupling.u_v
        recorder.uc[rows] = coupling.u_c
        temperature[rows] = coupling.temperature
        for key, value in compensator.state().items():
            comp_state[key][rows] = value
        r = r_next
        k += steps
        if k % (50 * ctrl_div) == 0:
            bar.update(round(k * idx.dt - bar.n, 3))


def _check_block(m, d, idx: PlantIndex, status: np.ndarray, p1: np.ndarray, warnings: np.ndarray) -> None:
    """After a kernel call: raise PhysicsError for the non-finite state the kernel stopped at (naming
    the leg and the time of the step, :func:`_check_finite`) or for a MuJoCo warning."""
    if status[0] >= 0:
        t = status[0] * idx.dt
        _check_finite(p1, d, idx, t)
        raise PhysicsError(f"non-finite state at t = {t:.4f} s")  # the kernel saw it; the arrays hold it
    if warnings.any():
        check_warnings(m, d)


def _divider(rate_hz: float, dt: float, what: str) -> int:
    div = 1.0 / (rate_hz * dt)
    if div < 1 or abs(div - round(div)) > 1e-9:
        raise InputError(f"{what} {rate_hz:g} Hz must divide the physics rate {1 / dt:g} Hz")
    return int(round(div))


def _check_state(m: mujoco.MjModel, d: mujoco.MjData, idx: PlantIndex, coupling: HydraulicCoupling) -> None:
    """After a step of the Python engine: :func:`_check_finite`, then MuJoCo's warnings."""
    _check_finite(coupling.state.p1, d, idx, d.time)
    check_warnings(m, d)


def _check_finite(p1: np.ndarray, d: mujoco.MjData, idx: PlantIndex, t: float) -> None:
    """PhysicsError naming the first leg whose P1 (n_legs,) [Pa] or piston position/velocity is not
    finite, or the platform, at time ``t`` [s]; nothing if all is finite."""
    bad_p1 = ~np.isfinite(p1)
    bad_q = ~np.isfinite(d.qpos[idx.qpos_adr]) | ~np.isfinite(d.qvel[idx.dof_adr])
    if np.any(bad_p1 | bad_q):
        leg = int(np.flatnonzero(bad_p1 | bad_q)[0]) + 1
        what = "P1" if bad_p1[leg - 1] else "piston position/velocity"
        raise PhysicsError(f"non-finite {what} of leg{leg} at t = {t:.4f} s")
    if not (np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel))):
        raise PhysicsError(f"non-finite platform state at t = {t:.4f} s")
