"""What a run is and what it gives: :class:`RunConfig`, :class:`SimulationResult`, the coupling of the
leg hydraulics to MuJoCo (:class:`HydraulicCoupling`, the control callback of the ``python`` engine and
the controller sample of both), the start-up statics and the piston setpoints. The loop that steps a
run is :mod:`hexsim.engine.runner`.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
from dataclasses import dataclass, field
from typing import Callable, NamedTuple

import mujoco
import numpy as np

from compensation import CompensatorSettings, PlantTruth
from compensation.base import Compensator
from compensation.leg_model import LegModel, Reference
from hexsim.control.controller import PController
from hexsim.control.feedforward import LiveDerivatives, setpoint_derivatives
from hexsim.control.kinematics import HexapodGeometry
from hexsim.control.scenario import Scenario, make_scenario
from hexsim.errors import InputError, WorkspaceError
from hexsim.plant import hydraulics
from hexsim.plant.effects import Effects, LegChange, merge_leg_changes
from hexsim.plant.faults import Fault, FaultInjector
from hexsim.plant.geometry import Geometry
from hexsim.plant.legs import PlantState, advance_legs, leg_table
from hexsim.plant.machine import Machine, load_machine
from hexsim.plant.model import PlantIndex, check_formulation
from hexsim.plant.params import ControllerParams, HydraulicParams
from hexsim.plant.platform import leg_jacobian, leg_wrench
from hexsim.plant.temperature import WarmUp
from hexsim.signals import zero_order_hold

#: Ways to run the loop: the compiled runner (hexsim.engine.native) and the Python control callback, a
#: straightforward loop over the same compiled leg step (hexsim.plant.legs) that also runs Python compensators.
ENGINES = ("native", "python")


@functools.lru_cache(maxsize=8)
def _built_in(name: str) -> Machine:
    return load_machine(name)


def _as_built(machine: Machine) -> bool:
    """Whether ``machine`` (not read from a file) is its built-in as shipped (not edited in Python)."""
    try:
        built = _built_in(machine.name)
    except InputError:
        return False
    return (machine.hydraulics, machine.controller, machine.effects, machine.legs, machine.geometry) == (
        built.hydraulics, built.controller, built.effects, built.legs, built.geometry)


@dataclass(frozen=True)
class RunConfig:
    """Everything that defines one run: a ``scenario`` on a ``machine``, with a compensator and the run's own
    options. ``scenario``: a :class:`Scenario`, or a name as on the command line (``"heave"`` … ``"yaw"``,
    ``"actuator"``, ``"file:PATH"``) built with its defaults. ``machine``: a
    :class:`hexsim.plant.machine.Machine` (its hydraulics, controller, effects, legs and hexapod geometry are the
    run's; edit them with :meth:`with_machine`), a built-in's name or a machine file's path (read with
    :func:`hexsim.plant.machine.load_machine`); default (or None) the built-in Micro Motion System (seed appendix A).
    ``record_rate_hz`` None: 1 kHz, the rate of the measurement-log example (``docs/measurement-log.md``); it
    must divide the 10 kHz physics rate. Raises InputError naming the setting that is wrong."""

    scenario: Scenario | str
    machine: Machine | str | None = field(default_factory=Machine)
    # a built-in by name (compensation.COMPENSATORS), or a class/factory called as
    # cls(n_legs, rate_hz, u_v_max, settings) returning a compensation.Compensator (runs in Python)
    compensator: str | Callable[..., Compensator] = "none"
    compensator_settings: CompensatorSettings = field(default_factory=CompensatorSettings)
    # the leg model a model-based compensator inverts (a tuned file's, hexsim.studies.tuning.read_tuned);
    # None: built from the machine (hexsim.control.feedforward.leg_model)
    compensator_model: LegModel | None = field(default=None, repr=False, compare=False)
    warm_up: WarmUp | None = None  # oil warming during the run (seed §5.5); None: constant 35 °C
    seed: int = 0
    record_rate_hz: float | None = None
    progress: bool = False
    engine: str = "native"  # "native": compiled runner (hexsim.engine.native); "python": the control callback
    timestep: float | None = None  # physics step [s]; None: the model's 1e-4 s (the seed's 10 kHz)
    keep_last_s: float | None = None  # keep only the last this many seconds of the recording (long runs:
    # memory stays flat; metrics and outputs cover that window); None: the whole run
    faults: tuple[Fault, ...] = ()  # injected faults (hexsim.plant.faults); default none
    # U_c per controller sample (n_ticks, n_legs) [V] replayed instead of a compensator (measured-data
    # replay, hexsim.measured.hexapod_replay); None: the compensator named above
    feedforward: np.ndarray | None = field(default=None, repr=False, compare=False)
    # the run's own changes to single legs on top of the machine's (a leaking seal, a worn edge on one leg in
    # a study or a validation candidate); the run's legs are :attr:`legs`
    leg_changes: tuple[LegChange, ...] = ()
    # the hexapod's formulation (hexsim.plant.model.FORMULATIONS): "platform" (default), the platform-only
    # model built from the MJCF (hexsim.plant.platform), ~4x faster; "full", the multi-body MJCF with leg
    # bodies and closing constraints, the reference it is tested against (tests/plant/test_platform.py)
    model: str = "platform"

    def __post_init__(self) -> None:
        if isinstance(self.scenario, str):
            object.__setattr__(self, "scenario", make_scenario(self.scenario))
        if not isinstance(self.scenario, Scenario):
            raise InputError(f"scenario must be a Scenario or a scenario name, got {self.scenario!r}")
        if not isinstance(self.machine, Machine):
            if not (self.machine is None or isinstance(self.machine, (str, os.PathLike))):
                raise InputError(f"machine must be a Machine, a built-in's name or a machine file, "
                                 f"got {self.machine!r}")
            object.__setattr__(self, "machine", load_machine(self.machine))
        check_formulation(self.model)
        if not (isinstance(self.compensator, str) or callable(self.compensator)):
            raise InputError(f"compensator must be a name or a Compensator class, got {self.compensator!r}")
        if self.engine not in ENGINES:
            raise InputError(f"engine must be one of {', '.join(ENGINES)}, got {self.engine!r}")
        if self.keep_last_s is not None and not (math.isfinite(self.keep_last_s) and self.keep_last_s > 0):
            raise InputError(f"keep_last_s must be a positive number of seconds, got {self.keep_last_s!r}")
        if self.timestep is not None:
            if not (math.isfinite(self.timestep) and 1e-6 <= self.timestep <= 1e-3):
                raise InputError(f"timestep must be within 1e-6…1e-3 s, got {self.timestep!r}")
            divider(self.controller.rate_hz, self.timestep, f"controller rate (timestep {self.timestep:g} s)")
            divider(self.record_rate_hz or 1000.0, self.timestep, f"record rate (timestep {self.timestep:g} s)")

    @classmethod
    def from_machine(cls, machine, scenario: Scenario | str, **options) -> "RunConfig":
        """A run of ``scenario`` on ``machine`` (a :class:`hexsim.plant.machine.Machine`, a machine file or a
        built-in's name); ``options`` are the other fields (compensator, seed, timestep, …). Raises InputError
        for a machine file that is not valid."""
        return cls(scenario, machine=machine, **options)

    def with_machine(self, **parts) -> "RunConfig":
        """This run on its machine with ``parts`` replaced (``hydraulics``, ``controller``, ``effects``,
        ``sensors``, ``geometry``, … :class:`hexsim.plant.machine.Machine`'s fields): the one way a study or a
        test edits the machine a run is on."""
        return dataclasses.replace(self, machine=dataclasses.replace(self.machine, **parts))

    @property
    def hydraulics(self) -> HydraulicParams:
        """The machine's valve, cylinder, oil and supply (seed appendix A's parameters)."""
        return self.machine.hydraulics

    @property
    def controller(self) -> ControllerParams:
        """The machine's controller (K_p, rate, position noise)."""
        return self.machine.controller

    @property
    def effects(self) -> Effects:
        """The machine's effects beyond the seed model (load, sensors, leakage, …)."""
        return self.machine.effects

    @property
    def geometry(self) -> Geometry | None:
        """The hexapod's geometry and masses (its machine file's ``hexapod`` section); None on a single
        actuator."""
        return self.machine.geometry if self.machine.system == "hexapod" else None

    @property
    def legs(self) -> tuple[LegChange, ...]:
        """Every leg's own values: the machine file's ``legs`` with the run's :attr:`leg_changes` on top."""
        return merge_leg_changes(self.machine.leg_changes, self.leg_changes)

    @property
    def machine_label(self) -> str:
        """The machine as outputs name it: the machine file or built-in the run came from, or for a machine
        edited in Python or by options "NAME with parameters changed"."""
        return self.machine_spec or f"{self.machine.name} with parameters changed"

    @property
    def machine_spec(self) -> str | None:
        """What :func:`hexsim.plant.machine.load_machine` reads the run's machine back from (the file's path,
        a built-in's name), None for a built-in edited in Python."""
        m = self.machine
        return str(m.path) if m.path is not None else (m.name if _as_built(m) else None)

    @property
    def compensator_name(self) -> str:
        """The compensator's name for reports: the built-in's, or a user class's ``name`` (else its
        class name)."""
        c = self.compensator
        if isinstance(c, str):
            return c
        name = getattr(c, "name", None)
        return name if isinstance(name, str) and name != "base" else getattr(c, "__name__", type(c).__name__)


@dataclass
class SimulationResult:
    """Recorded signals of a run, sampled at ``record_rate_hz``; arrays (N,) or (N, n_legs) or (N, 3).

    t [s]; y, ydot: measured piston position [m] / velocity [m/s] at t_k (the slide joints', or on the
    platform-only model the legs' computed from the platform's pose and velocity); y_ref:
    piston setpoint in force (ZOH) [m] (with a sensor delay, y is the delayed measurement and ydot the
    true velocity); u_v: valve setpoint [V]; u_c: compensation voltage [V]; p1: bottom-chamber pressure
    [Pa] (cap side); p2: rod-side pressure [Pa] (integrated with a 4-way valve, P_s with the seed's 3-way);
    p_s: supply pressure (N,) [Pa] (of the first manifold); force: hydraulic leg force [N]; acc:
    accelerometer, site frame, specific force [m/s^2]; gyro [rad/s] and angacc [rad/s^2] (world) of the
    platform (hexapod only); pose: measured platform pose (N, 6) rel. neutral; pose_ref: commanded pose;
    constraint_violation: largest connect violation [m] per sample (0 on the platform-only model, which
    has no connects); oil_temperature [°C];
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
    p2: np.ndarray
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
    # the platform sensor site's orientation in the world (N, 4) [w, x, y, z] (hexapod only)
    platform_quat: np.ndarray | None = None
    # the sensor site in the platform body: position (3,) [m] and orientation (4,) [w, x, y, z] (hexapod only)
    sensor_site: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def n_legs(self) -> int:
        return self.y.shape[1]

    @property
    def realtime_factor(self) -> float:
        return self.config.scenario.duration / self.wall_time_s


class ControlSchedule(NamedTuple):
    """What the P controller reads at its samples: setpoints and sensor noise, each (n_ticks, n_legs) [m],
    and ``ctrl_div``, the physics steps per controller sample; ``valve`` (n_ticks, n_legs) [V]: the valve
    setpoints of an open-loop run, which replace the controller (None: the P controller runs)."""

    setpoints: np.ndarray
    noise: np.ndarray
    ctrl_div: int
    valve: np.ndarray | None = None


class HydraulicCoupling:
    """The MuJoCo control callback: valve, chamber and friction of every leg, once per physics step.

    At step k (time t_k): every ``ctrl_div``-th step the controller samples the measured piston positions
    (plus sensor noise; delayed by tau_y with a sensor-delay effect) and updates u_v (held in between:
    ZOH); then the leg hydraulics advance to t_k+1 with the piston velocity at t_k
    (:func:`hexsim.plant.legs.step_plant`, the compiled :func:`hexsim.plant.legs.step_legs` with any
    :class:`~hexsim.plant.effects.Effects`) and the leg force P1 A1 - P_s A2 - F_f(ydot) is written to
    ``data.ctrl``. Repeated calls at the same time (an extra ``mj_forward``) rewrite the same
    force without integrating twice. An exception is kept in :attr:`error` for the runner to raise, since
    it cannot cross MuJoCo's C loop.
    """

    def __init__(self, idx: PlantIndex, config: RunConfig, controller: PController, schedule: ControlSchedule,
                 p1_initial: np.ndarray, plant: PlantTruth | None = None, faults: FaultInjector | None = None,
                 p2_initial: np.ndarray | None = None) -> None:
        """``config`` gives the plant (hydraulics, effects, leg changes, warm-up); ``schedule`` the
        controller's setpoints and sensor noise (or an open-loop run's valve setpoints); ``p1_initial``,
        ``p2_initial`` (n_legs,) [Pa] the start pressures (P2 default: P_s, the 3-way valve's); the pistons start
        at the scenario's ``start`` (None: the neutral pose);
        ``plant`` the truth an oracle compensator reads (updated as the oil warms)."""
        hyd, warm_up = config.hydraulics, config.warm_up
        self.idx = idx
        self.hyd = hyd
        self.base_hyd = hyd
        self.warm_up = warm_up
        self.plant = plant
        self.temperature = float(warm_up.temperature(0.0)) if warm_up else 35.0
        self.controller = controller
        self.setpoints, self.noise, self.ctrl_div, self.valve = schedule
        # the reference's derivatives, only for a compensator that observes them (compensation.model_based):
        # three more arrays the size of the setpoint table on a long run; sample by sample where the rows are
        # written while the run goes (hexsim serve, the FMUs)
        observes = type(controller.compensator).observe is not Compensator.observe
        live = observes and config.scenario.live
        self.derivatives = setpoint_derivatives(self.setpoints, self.ctrl_div * idx.dt) if observes and not live \
            else None
        self.live = LiveDerivatives(idx.n_legs, self.ctrl_div * idx.dt) if live else None
        self.dt = idx.dt
        self.effects = config.effects
        self.faults = faults
        self.leg_changes = config.legs
        self.groups = np.zeros(idx.n_legs, dtype=np.intp)  # one supply manifold for all legs
        n = idx.n_legs
        self.state = PlantState.at_rest(p1_initial, np.zeros(n), hyd, p2=p2_initial)
        delay_steps = int(round(self.effects.sensor_delay / self.dt))
        start = idx.neutral_y if config.scenario.start is None else config.scenario.start
        self._y_history = np.tile(np.asarray(start, dtype=float), (delay_steps + 1, 1))
        self.y_measured = self._y_history[0].copy()
        self.u_v = np.zeros(n)
        self.u_c = np.zeros(n)
        self.r = self.setpoints[0].copy()
        self.force = np.zeros(n)
        self.ydot = np.zeros(n)  # the pistons' velocities at the last step [m/s]
        self._last_step = -1
        self.supply_level: float | None = None
        self.error: BaseException | None = None

    def __call__(self, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        try:
            k = int(round(d.time / self.dt))
            if k != self._last_step:
                self._last_step = k
                y, ydot = self.idx.positions(d)
                self.ydot = ydot
                hist = self._y_history
                hist[k % len(hist)] = y
                self.y_measured = hist[(k + 1) % len(hist)]  # y(t_k - tau_y); itself without delay
                if k % self.ctrl_div == 0:
                    self.hyd = self.tick(k, self.y_measured, self.state.p1)
                    if self.supply_level is not None:
                        self.state.p_s[:] = self.supply_level
                self.state, self.force = advance_legs(self.state, self.u_v, y, ydot, self.dt, self.leg_table(),
                                                      self.groups)
            apply_leg_forces(d, self.idx, self.force)
        except Exception as exc:  # noqa: BLE001 - re-raised by simulate() after the step
            self.error = exc
            d.ctrl[self.idx.actuator_id] = 0.0
            d.xfrc_applied[:] = 0.0


    def leg_table(self) -> np.ndarray:
        """The legs' parameters now in force (:func:`hexsim.plant.legs.leg_table`), rebuilt when the oil warms."""
        if getattr(self, "_table_of", None) is not self.hyd:
            self._table = leg_table(self.hyd, self.effects, self.idx.n_legs, self.leg_changes)
            self._table_of = self.hyd
        return self._table

    def tick(self, k: int, y_measured: np.ndarray, p1: np.ndarray | None = None) -> HydraulicParams:
        """The controller sample at step ``k`` (both engines): oil temperature, setpoint, P control with
        the compensator (handed the reference's derivatives and the bottom pressures ``p1`` (n_legs,) [Pa]
        as the pressure transducers read them), faults. Sets :attr:`r`, :attr:`u_v`, :attr:`u_c`, :attr:`supply_level` (P_s
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
        if self.valve is None:
            reference = None
            if self.derivatives is not None or self.live is not None:
                d1, d2, d3 = (d[j] for d in self.derivatives) if self.live is None else self.live(self.r)
                reference = Reference(self.r, d1, d2, d3, None if p1 is None else p1.copy())
            self.u_v, self.u_c = self.controller.sample(self.r, seen, reference)
        else:  # open loop: the given command, saturated like the controller's
            u_max = hyd.u_v_max
            self.u_v, self.u_c = np.clip(self.valve[j], -u_max, u_max), np.zeros(self.idx.n_legs)
        self.supply_level = None
        if inj:
            self.u_v = inj.valve(t_k, self.u_v)
            self.supply_level = inj.supply(t_k)
        return hyd


def apply_leg_forces(d: mujoco.MjData, idx: PlantIndex, force: np.ndarray) -> None:
    """Put the leg forces ``force`` (n_legs,) [N] on the model: the motors' ``ctrl`` (slide-joint legs) or
    the platform's ``xfrc_applied`` with end stops and the legs' weight (a platform-only model,
    :func:`hexsim.plant.platform.leg_wrench`)."""
    if not idx.platform_only:
        d.ctrl[idx.actuator_id] = force
        return
    y, yd = idx.positions(d)
    leg_wrench(idx.legs, d.qpos, y, yd, np.asarray(force, dtype=float), d.xfrc_applied)


def leg_mobility(m: mujoco.MjModel, d: mujoco.MjData, idx: PlantIndex) -> tuple[np.ndarray, np.ndarray]:
    """(A, a0) at the current configuration at rest: the slide accelerations (n_legs,) [m/s^2] are
    a0 + A f for leg forces f (n_legs,) [N]; A (n_legs, n_legs) [1/kg] is the inverse of the legs'
    effective inertia, constraints included (equality constraints only, so the map is affine: one
    ``mj_forward`` with zero force and one per unit force; on a platform-only model A = J M⁻¹ Jᵀ with J
    the legs' Jacobian; with a weld, from the rigid constraints, :func:`_rigid_mobility`). Call with no
    control callback installed."""
    n = idx.n_legs
    apply_leg_forces(d, idx, np.zeros(n))
    mujoco.mj_forward(m, d)
    if idx.platform_only:
        jac = leg_jacobian(m, d, idx.legs)
        inv_m_jt = np.empty((n, m.nv))
        mujoco.mj_solveM(m, d, inv_m_jt, jac)
        return jac @ inv_m_jt.T, jac @ d.qacc
    if np.any((m.eq_type == mujoco.mjtEq.mjEQ_WELD) & (m.eq_active0 != 0)):
        return _rigid_mobility(m, d, idx)
    acc0 = d.qacc[idx.dof_adr].copy()
    sens = np.empty((n, n))
    for j in range(n):
        unit = np.zeros(n)
        unit[j] = 1.0
        apply_leg_forces(d, idx, unit)
        mujoco.mj_forward(m, d)
        sens[:, j] = d.qacc[idx.dof_adr] - acc0
    apply_leg_forces(d, idx, np.zeros(n))
    mujoco.mj_forward(m, d)
    return sens, acc0


def _rigid_mobility(m: mujoco.MjModel, d: mujoco.MjData, idx: PlantIndex) -> tuple[np.ndarray, np.ndarray]:
    """:func:`leg_mobility` with the equality constraints rigid (after ``mj_forward`` at rest, zero leg force):
    the constrained inverse inertia P = M⁻¹ - M⁻¹ Jᵀ (J M⁻¹ Jᵀ)⁻¹ J M⁻¹ with J the equality rows of the
    constraint Jacobian, A = S P Sᵀ and a0 = S P M a_smooth (S selects the slides). A user MJCF's cardan closed
    by a weld needs it: MuJoCo regularises the weld's rotation against the cardan's small bodies, and that
    compliance (not in the machine) put the modes 2-10 % high on a public hexapod with 29.5 mm cardans."""
    mass = np.empty((m.nv, m.nv))
    mujoco.mj_fullM(m, d, mass)
    jac = np.empty((d.nefc, m.nv))
    if mujoco.mj_isSparse(m):
        mujoco.mju_sparse2dense(jac, d.efc_J, d.efc_J_rownnz, d.efc_J_rowadr, d.efc_J_colind)
    else:
        jac[:] = d.efc_J.reshape(d.nefc, m.nv)
    jac = jac[d.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY]
    inv = np.linalg.inv(mass)
    inv_jt = inv @ jac.T
    projected = inv - inv_jt @ np.linalg.solve(jac @ inv_jt, inv_jt.T)
    rows = projected[idx.dof_adr]
    return rows[:, idx.dof_adr], rows @ mass @ d.qacc_smooth


def static_leg_forces(m: mujoco.MjModel, d: mujoco.MjData, idx: PlantIndex) -> np.ndarray:
    """Leg forces f (n_legs,) [N] that hold the current configuration at rest with rigid closed-loop
    constraints: the static balance of every degree of freedom, B f + J_cᵀ λ = ``qfrc_bias`` -
    ``qfrc_passive`` at qvel = 0, solved for f and the connect forces λ (3 per connect) together. B
    (nv, n_legs) is the generalised force of a unit force of each leg's motor, J_c (3 n_connect, nv) the
    connects' Jacobian (difference of the two sites' translational Jacobians, ``mj_jacSite``; a weld adds
    its two bodies' translation at one point and their rotation, 6 rows). For the
    hexapod this is Jᵀf = m g with the legs' own weight (40.55 bar per leg at rest). Zeroing the slide
    accelerations through MuJoCo's soft constraints instead (:func:`leg_mobility`) gives forces 0.4 %
    apart from leg to leg and jolts the platform at t = 0. Connects between sites or between bodies (at
    their anchors). Raises PhysicsError if the balance has no exact solution."""
    from hexsim.errors import PhysicsError

    d.qvel[:] = 0.0
    d.ctrl[:] = 0.0
    n = idx.n_legs
    if idx.platform_only:
        return _platform_static_forces(m, d, idx)
    mujoco.mj_forward(m, d)
    moment = np.empty((m.nv, n))
    for j, a in enumerate(idx.actuator_id):
        d.ctrl[:] = 0.0
        d.ctrl[a] = 1.0
        mujoco.mj_forward(m, d)
        moment[:, j] = d.qfrc_actuator
    d.ctrl[:] = 0.0
    mujoco.mj_forward(m, d)
    rows = []
    jac1, jac2 = np.empty((3, m.nv)), np.empty((3, m.nv))
    for e in np.flatnonzero((m.eq_type == mujoco.mjtEq.mjEQ_CONNECT) & (m.eq_active0 != 0)):
        if m.eq_objtype[e] == mujoco.mjtObj.mjOBJ_SITE:
            mujoco.mj_jacSite(m, d, jac1, None, int(m.eq_obj1id[e]))
            mujoco.mj_jacSite(m, d, jac2, None, int(m.eq_obj2id[e]))
        else:  # between bodies: each at its anchor (eq_data, body frames), the user MJCF's usual form
            for jac, body, local in ((jac1, m.eq_obj1id[e], m.eq_data[e, :3]), (jac2, m.eq_obj2id[e], m.eq_data[e, 3:6])):
                point = d.xpos[body] + d.xmat[body].reshape(3, 3) @ local
                mujoco.mj_jac(m, d, jac, None, point, int(body))
        rows.append(jac1 - jac2)
    rot1, rot2 = np.empty((3, m.nv)), np.empty((3, m.nv))
    for e in np.flatnonzero((m.eq_type == mujoco.mjtEq.mjEQ_WELD) & (m.eq_active0 != 0)):
        # a weld (a user MJCF's cardan closed to the platform): both bodies' translation at one point and rotation
        b1, b2 = ((int(m.site_bodyid[o]) if m.eq_objtype[e] == mujoco.mjtObj.mjOBJ_SITE else int(o))
                  for o in (m.eq_obj1id[e], m.eq_obj2id[e]))
        point = d.xpos[b1].copy()
        mujoco.mj_jac(m, d, jac1, rot1, point, b1)
        mujoco.mj_jac(m, d, jac2, rot2, point, b2)
        rows += [jac1 - jac2, rot1 - rot2]
    a = np.hstack([moment] + [r.T for r in rows])
    rhs = d.qfrc_bias - d.qfrc_passive
    sol, *_ = np.linalg.lstsq(a, rhs, rcond=None)
    if np.linalg.norm(a @ sol - rhs) > 1e-9 * max(1.0, np.linalg.norm(rhs)):
        raise PhysicsError("the legs and constraints cannot hold the platform at rest in this configuration")
    return sol[:n]


def _platform_static_forces(m: mujoco.MjModel, d: mujoco.MjData, idx: PlantIndex) -> np.ndarray:
    """Leg forces f (n_legs,) [N] that hold a platform-only model at rest: Jᵀ f = ``qfrc_bias`` -
    ``qfrc_passive`` - Q_w, Q_w the generalised force of the legs' weight correction (the wrench at
    zero leg force). Raises PhysicsError for a singular configuration."""
    from hexsim.errors import PhysicsError

    d.xfrc_applied[:] = 0.0
    apply_leg_forces(d, idx, np.zeros(idx.n_legs))
    mujoco.mj_forward(m, d)
    weight = np.zeros(m.nv)
    body = idx.legs.body
    mujoco.mj_applyFT(m, d, d.xfrc_applied[body, :3].copy(), d.xfrc_applied[body, 3:].copy(),
                      d.xipos[body].copy(), body, weight)
    jac = leg_jacobian(m, d, idx.legs)
    try:
        return np.linalg.solve(jac.T, d.qfrc_bias - d.qfrc_passive - weight)
    except np.linalg.LinAlgError:
        raise PhysicsError("the legs cannot hold the platform at rest in this configuration") from None


#: Largest ω·dt hexsim allows for the stiffest oil-spring mode of a run: the explicit (semi-implicit
#: Euler) mechanics step is stable below 2; 1.5 leaves room for the piston passing its setpoint.
OMEGA_DT_LIMIT = 1.5


def check_timestep(mobility: np.ndarray, y_min: np.ndarray, hyd: HydraulicParams, dt: float,
                   y_max: np.ndarray | None = None) -> None:
    """InputError if the step dt [s] cannot integrate the oil springs of the legs at their lowest piston
    setpoints y_min (n_legs,) [m]: stiffness E A1^2 / (y A1 + V_pl) per leg (seed eq. 3.7; with a 4-way
    valve plus the rod side's E A2^2 / ((L_s - y_max) A2 + V_pl,B) at the highest setpoints y_max), stiffest mode
    ω = sqrt(max eig(A K)) with A the legs' mobility (:func:`leg_mobility`); refused if ω dt exceeds
    :data:`OMEGA_DT_LIMIT`. The message names the bound, the leg, its lowest setpoint and the step that
    would do."""
    stiffness = hyd.bulk_modulus * hyd.area_bottom**2 / hydraulics.chamber_volume(y_min, hyd)
    if hyd.four_way:
        y_max = y_min if y_max is None else y_max
        rod_volume = np.maximum(hyd.stroke - np.asarray(y_max, dtype=float), 0.0) * hyd.area_rod + hyd.pipeline_volume_rod
        stiffness = stiffness + hyd.bulk_modulus * hyd.area_rod**2 / rod_volume
    modes, shapes = np.linalg.eig(mobility @ np.diag(stiffness))
    k = int(np.argmax(modes.real))
    omega = float(np.sqrt(max(modes.real[k], 0.0)))
    if omega * dt <= OMEGA_DT_LIMIT:
        return
    leg = int(np.argmax(np.abs(shapes[:, k])))
    raise InputError(
        f"timestep {dt:g} s is too long for this motion: the oil springs stiffen as the pistons retract, and "
        f"at leg{leg + 1}'s lowest setpoint y = {1e3 * y_min[leg]:.1f} mm the stiffest mode is "
        f"{omega / (2 * math.pi):.0f} Hz (ω·dt = {omega * dt:.2f}; the explicit mechanics step is stable "
        f"below 2, hexsim allows {OMEGA_DT_LIMIT}); use --timestep {_shorter_step(omega):g} or less, or keep "
        f"the pistons farther from the retracted end")


def _shorter_step(omega: float) -> float:
    """The longest of 5e-4, 2e-4, 1e-4, 5e-5, … s within :data:`OMEGA_DT_LIMIT` at ω [rad/s]."""
    for dt in (5e-4, 2.5e-4, 2e-4, 1e-4, 5e-5, 2e-5, 1e-5):
        if omega * dt <= OMEGA_DT_LIMIT:
            return dt
    return 1e-6


def piston_setpoints(m: mujoco.MjModel, idx: PlantIndex, scenario: Scenario, t: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """Piston setpoints (N, n_legs) [m] at times t (N,) [s], and the platform poses (N, 6) (hexapod) or None.

    Open loop (a ``valve:`` scenario): no setpoint, NaN.
    Raises WorkspaceError naming the leg and length if a setpoint leaves the stroke.
    """
    if scenario.open_loop:
        return np.full((len(t), idx.n_legs), np.nan), None
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


def divider(rate_hz: float, dt: float, what: str) -> int:
    """Physics steps per period of ``rate_hz`` [Hz] at step dt [s]; InputError naming ``what`` if the
    rate does not divide the physics rate."""
    div = 1.0 / (rate_hz * dt)
    if div < 1 or abs(div - round(div)) > 1e-9:
        raise InputError(f"{what} {rate_hz:g} Hz must divide the physics rate {1 / dt:g} Hz")
    return int(round(div))
