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
from hexsim import hydraulics
from hexsim.controller import PController
from hexsim.effects import Effects, PlantState, step_plant
from hexsim.errors import InputError, PhysicsError, WorkspaceError
from hexsim.kinematics import HexapodGeometry
from hexsim.model import PlantIndex, apply_load, check_warnings, load_model, reset_neutral
from hexsim.params import ControllerParams, HydraulicParams
from hexsim.scenario import Scenario
from hexsim.temperature import WarmUp


@dataclass(frozen=True)
class RunConfig:
    """Everything that defines one run. ``record_rate_hz`` None: 1 kHz, the rate of the measurement-log
    example (``../shared/measurement-log.md``); it must divide the 10 kHz physics rate."""

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
    (:func:`hexsim.effects.step_plant`: :func:`hexsim.hydraulics.step_pressure` plus any
    :class:`~hexsim.effects.Effects`) and the leg force P1 A1 - P_s A2 - F_f(ydot) is written to
    ``data.ctrl``. Repeated calls at the same time (an extra ``mj_forward``) rewrite the same
    force without integrating twice. An exception is kept in :attr:`error` for the runner to raise, since
    it cannot cross MuJoCo's C loop.
    """

    def __init__(self, idx: PlantIndex, hyd: HydraulicParams, controller: PController, setpoints: np.ndarray,
                 noise: np.ndarray, p1_initial: np.ndarray, ctrl_div: int, warm_up: WarmUp | None = None,
                 plant: PlantTruth | None = None, effects: Effects | None = None) -> None:
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
                    if self.warm_up is not None:
                        self.temperature = float(self.warm_up.temperature(k * self.dt))
                        self.hyd = self.warm_up.params_at(self.base_hyd, self.temperature)
                        if self.plant is not None:
                            self.plant.params = self.hyd
                    j = min(k // self.ctrl_div, len(self.setpoints) - 1)
                    self.r = self.setpoints[j]
                    self.u_v, self.u_c = self.controller.sample(self.r, self.y_measured + self.noise[j])
                self.state = step_plant(self.state, self.u_v, y, ydot, self.dt, self.hyd, self.effects, self.groups)
                self.force = hydraulics.leg_force(self.state.p1, ydot, self.hyd, self.state.p_s)
            d.ctrl[self.idx.actuator_id] = self.force
        except Exception as exc:  # noqa: BLE001 - re-raised by simulate() after the step
            self.error = exc
            d.ctrl[self.idx.actuator_id] = 0.0


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
    if scenario.system == "hexapod":
        if idx.n_legs != 6:
            raise InputError(f"scenario {scenario.name} needs the hexapod model, this model has {idx.n_legs} legs")
        poses = scenario.poses(t)
        return HexapodGeometry.from_model(m).inverse(poses, t), poses
    y = idx.neutral_y[None, :] + scenario.axis_setpoint(t)[:, None]
    lo, hi = idx.stroke[0]
    bad = (y[:, 0] < lo) | (y[:, 0] > hi)
    if np.any(bad):
        n = int(np.argmax(bad))
        raise WorkspaceError(
            f"setpoint at t = {t[n]:.3f} s needs leg1 piston position {y[n, 0]:.4f} m, outside its stroke {lo:g}…{hi:g} m"
        )
    return y, None


def simulate(config: RunConfig) -> SimulationResult:
    """Run one scenario headless and record it. See the module doc for the chain.

    Raises WorkspaceError for an unreachable setpoint, InputError for inconsistent settings and
    PhysicsError for a MuJoCo warning or a non-finite state (naming the time and the leg).
    """
    sc, hyd, cp = config.scenario, config.hydraulics, config.controller
    m = load_model(sc.system)
    apply_load(m, config.effects)
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
        compensator = make_compensator(config.compensator, idx.n_legs, cp.rate_hz, u_v_max=hyd.u_v_max,
                                       settings=config.compensator_settings, plant=plant)
    except SettingsError as exc:
        raise InputError(str(exc)) from None
    controller = PController(cp, hyd.u_v_max, compensator)
    coupling = HydraulicCoupling(idx, hyd, controller, setpoints, noise, p1_0, ctrl_div, config.warm_up, plant,
                                 config.effects)

    n_rec = int(round(sc.duration / dt)) // rec_div
    n = idx.n_legs
    rec = {k: np.empty((n_rec, n)) for k in ("y", "ydot", "y_ref", "u_v", "u_c", "p1", "force")}
    t = np.empty(n_rec)
    p_s = np.empty(n_rec)
    delayed = config.effects.sensor_delay > 0
    acc = np.empty((n_rec, 3))
    hexapod = sc.system == "hexapod"
    gyro, angacc = (np.empty((n_rec, 3)), np.empty((n_rec, 3))) if hexapod else (None, None)
    pos, quat = (np.empty((n_rec, 3)), np.empty((n_rec, 4))) if hexapod else (None, None)
    viol = np.zeros(n_rec)
    temperature = np.empty(n_rec)
    comp_state = {k: np.empty((n_rec, n)) for k in compensator.state()}
    s = idx.sensor
    leg_pos = np.array([s[f"leg{i + 1}_pos"].start for i in range(n)])
    leg_vel = np.array([s[f"leg{i + 1}_vel"].start for i in range(n)])

    start = time.perf_counter()
    mujoco.set_mjcb_control(coupling)
    try:
        mujoco.mj_forward(m, d)
        bar = tqdm(total=round(sc.duration, 3), unit="sim s", disable=not config.progress, leave=False,
                   bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} sim s [{elapsed}<{remaining}]")
        for i in range(n_rec):
            mujoco.mj_step(m, d, rec_div)
            if coupling.error is not None:
                raise coupling.error
            _check_state(m, d, idx, coupling)
            sd = d.sensordata
            t[i] = d.time - dt  # sensors were evaluated at the start of the last step
            rec["y"][i] = coupling.y_measured if delayed else sd[leg_pos]
            rec["ydot"][i] = sd[leg_vel]
            rec["y_ref"][i] = coupling.r
            rec["u_v"][i] = coupling.u_v
            rec["u_c"][i] = coupling.u_c
            rec["p1"][i] = coupling.state.p1
            p_s[i] = coupling.state.p_s[0]
            rec["force"][i] = coupling.force
            temperature[i] = coupling.temperature
            for key, value in compensator.state().items():
                comp_state[key][i] = value
            acc[i] = sd[s["platform_acc"]]
            if hexapod:
                gyro[i] = sd[s["platform_gyro"]]
                angacc[i] = sd[s["platform_angacc"]]
                pos[i] = sd[s["platform_pos"]]
                quat[i] = sd[s["platform_quat"]]
                eq = d.efc_type[: d.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY
                if np.any(eq):
                    viol[i] = np.linalg.norm(d.efc_pos[: d.nefc][eq].reshape(-1, 3), axis=1).max()
            if config.progress and i % 100 == 0:
                bar.update(round(d.time - bar.n, 3))
        bar.close()
    finally:
        mujoco.set_mjcb_control(None)
    wall = time.perf_counter() - start

    pose = pose_ref = None
    if hexapod:
        geom = HexapodGeometry.from_model(m)
        rpy = Rotation.from_quat(quat[:, [1, 2, 3, 0]]).as_euler("ZYX")[:, ::-1]
        pose = np.concatenate([pos - geom.neutral_position, rpy], axis=1)
        pose_ref = sc.poses(t)
    return SimulationResult(
        config=config, t=t, **rec, p_s=p_s, acc=acc, gyro=gyro, angacc=angacc,
        pose=pose, pose_ref=pose_ref, constraint_violation=viol, oil_temperature=temperature,
        compensator_state=comp_state, p1_initial=p1_0,
        saturated_samples=controller.saturated_samples, wall_time_s=wall, gravity=float(-m.opt.gravity[2]),
    )


def _divider(rate_hz: float, dt: float, what: str) -> int:
    div = 1.0 / (rate_hz * dt)
    if div < 1 or abs(div - round(div)) > 1e-9:
        raise InputError(f"{what} {rate_hz:g} Hz must divide the physics rate {1 / dt:g} Hz")
    return int(round(div))


def _check_state(m: mujoco.MjModel, d: mujoco.MjData, idx: PlantIndex, coupling: HydraulicCoupling) -> None:
    bad_p1 = ~np.isfinite(coupling.state.p1)
    bad_q = ~np.isfinite(d.qpos[idx.qpos_adr]) | ~np.isfinite(d.qvel[idx.dof_adr])
    if np.any(bad_p1 | bad_q):
        leg = int(np.flatnonzero(bad_p1 | bad_q)[0]) + 1
        what = "P1" if bad_p1[leg - 1] else "piston position/velocity"
        raise PhysicsError(f"non-finite {what} of leg{leg} at t = {d.time:.4f} s")
    if not (np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel))):
        raise PhysicsError(f"non-finite platform state at t = {d.time:.4f} s")
    check_warnings(m, d)
