"""The one runner: scenario → IK → P control → compensator → faults → leg plant → ``mj_step`` → recorder.

:class:`Simulator` sets a run up from a :class:`~hexsim.engine.config.RunConfig`, advances it in steps
(:meth:`Simulator.step`) or to the end (:meth:`Simulator.run`) and hands back what it recorded so far
(:meth:`Simulator.result`); :func:`simulate` is the one-call form every command uses (``run``,
``compare``, ``sweep``, the hexapod log replay, the identifier). Two loops drive the same stages:

* ``engine="native"`` (default): :func:`hexsim.engine.native.run_block` steps legs and MuJoCo in compiled code;
  the P controller and the built-in buffered/directional compensators run inside it, any other
  compensator (a user's own, the iterative ones, the oracle), faults and warming oil are sampled in
  Python at every controller tick between kernel calls;
* ``engine="python"``: :class:`~hexsim.engine.config.HydraulicCoupling` as MuJoCo's control callback
  (``mujoco.set_mjcb_control``), the straightforward loop over the same compiled leg step that the
  tests hold the compiled loop against. The callback is process-global; it is installed only while a
  step runs and always removed.
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time

import mujoco
import numpy as np
from tqdm import tqdm

from compensation import MODEL_BASED, PlantTruth, SettingsError, make_compensator
from compensation.base import Compensator, ReplayedCompensation
from hexsim.control.controller import PController
from hexsim.control.feedforward import check_loop, leg_model
from hexsim.control.kinematics import HexapodGeometry
from hexsim.engine import native
from hexsim.engine.config import (
    ControlSchedule,
    HydraulicCoupling,
    RunConfig,
    SimulationResult,
    check_timestep,
    divider,
    leg_mobility,
    piston_setpoints,
    static_leg_forces,
)
from hexsim.errors import InputError, PhysicsError, WorkspaceError
from hexsim.plant import hydraulics
from hexsim.plant.faults import FaultInjector
from hexsim.plant.legs import PlantState
from hexsim.plant.model import (
    PlantIndex,
    check_warnings,
    load_model,
    reset_neutral,
)
from hexsim.plant.platform import with_end_stops
from hexsim.signals import zero_order_hold

#: recorded channels of shape (samples, n_legs)
_LEG_CHANNELS = ("y", "ydot", "y_ref", "u_v", "u_c", "p1", "p2", "force")


class Simulator:
    """One run that can be stepped: ``Simulator(config).step(0.5)``, then :meth:`result` at any time.

    Attributes a user may read between steps: :attr:`model` / :attr:`data` (MuJoCo), :attr:`time` [s],
    :attr:`state` (:class:`~hexsim.plant.legs.PlantState` of the legs), :attr:`compensator`. Raises
    WorkspaceError for an unreachable setpoint, InputError for inconsistent settings (compensator
    settings included) and PhysicsError for a start pressure outside tank…supply.
    """

    def __init__(self, config: RunConfig) -> None:
        self.config = config
        self._setup_model()
        self._setup_control()
        self._setup_recording()
        self.k = 0  # physics steps done
        self.rows = 0  # samples recorded
        self.wall_time_s = 0.0  # stepping only (compilation excluded)
        self._geometry = None  # a hexapod's kinematics for the results' poses, made at the first result
        if config.engine == "native":
            self._setup_kernel()

    # ------------------------------------------------------------------ set-up
    def _setup_model(self) -> None:
        cfg = self.config
        # the single actuator's slide travels the machine's stroke (a hexapod's legs: its geometry's)
        single = cfg.scenario.system == "actuator"
        m = load_model(cfg.scenario.system, cfg.model, cfg.effects, cfg.geometry,
                       cfg.hydraulics.stroke if single else None)
        if cfg.timestep is not None:
            m.opt.timestep = cfg.timestep
        self.model, self.data = m, mujoco.MjData(m)
        self.idx = PlantIndex.from_model(m)
        if cfg.scenario.system == "hexapod" and cfg.model == "platform" and not self.idx.platform_only:
            # a user MJCF the platform-only model cannot represent (cardans with their hinges apart,
            # hexsim.plant.model.model_spec said so): the run and its outputs name the full model it ran
            self.config = cfg = dataclasses.replace(cfg, model="full")
        self.dt = self.idx.dt
        self.ctrl_div = divider(cfg.controller.rate_hz, self.dt, "controller rate")
        self.record_rate = cfg.record_rate_hz or 1000.0
        self.rec_div = divider(self.record_rate, self.dt, "record rate")
        self.total = int(round(cfg.scenario.duration / self.dt)) // self.rec_div * self.rec_div

    def _setup_control(self) -> None:
        cfg, m, d, idx = self.config, self.model, self.data, self.idx
        sc, hyd, cp = cfg.scenario, cfg.hydraulics, cfg.controller
        n_ticks = int(math.ceil(sc.duration * cp.rate_hz)) + 1
        ticks = np.arange(n_ticks) / cp.rate_hz
        setpoints, _ = piston_setpoints(m, idx, sc, ticks)
        noise = np.random.default_rng(cfg.seed).normal(0.0, cp.position_noise, size=setpoints.shape)
        valve = None
        if sc.open_loop:
            if cfg.compensator != "none" or cfg.feedforward is not None:
                raise InputError(f"scenario {sc.name} is open loop (valve setpoints given): no compensator applies")
            times, values = sc.valve
            if values.shape[1] != idx.n_legs:
                raise InputError(f"scenario {sc.name} has {values.shape[1]} valve columns, the model {idx.n_legs} legs")
            valve = zero_order_hold(times, values, ticks)
        mujoco.set_mjcb_control(None)
        reset_neutral(m, d)
        if sc.start is not None:
            lo, hi = idx.stroke[:, 0], idx.stroke[:, 1]
            if np.any((sc.start < lo) | (sc.start > hi)):
                raise WorkspaceError(f"scenario {sc.name} starts at piston position {sc.start[0]:.4f} m, outside the "
                                     f"stroke {lo[0]:g}…{hi[0]:g} m")
            d.qpos[idx.qpos_adr] = sc.start
            mujoco.mj_forward(m, d)
        mobility, _ = leg_mobility(m, d, idx)
        if idx.platform_only:  # end stops as stiff as the full model's limits on the legs' effective mass
            self.idx = idx = dataclasses.replace(idx, legs=with_end_stops(m, idx.legs, 1.0 / np.diag(mobility)))
        travel = idx.stroke[:, 1] - idx.stroke[:, 0]
        if np.any(np.abs(travel - hyd.stroke) > 1e-6 * hyd.stroke):
            leg = int(np.argmax(np.abs(travel - hyd.stroke)))
            raise InputError(f"cylinder stroke {hyd.stroke:g} m (machine {cfg.machine_label}) is not the model's: leg{leg + 1} "
                             f"travels {travel[leg]:g} m (its joint range); the machine file's cylinder.stroke_m must "
                             f"match the model it runs on")
        if sc.open_loop:  # anywhere in the stroke
            check_timestep(mobility, idx.stroke[:, 0], hyd, self.dt, idx.stroke[:, 1])
        else:
            check_timestep(mobility, setpoints.min(axis=0), hyd, self.dt, setpoints.max(axis=0))
        p1_0, p2_0 = hydraulics.rest_pressures(static_leg_forces(m, d, idx), hyd)
        chambers = (("P1", p1_0), ("P2", p2_0)) if hyd.four_way else (("P1", p1_0),)
        for name, pressures in chambers:
            for i, p in enumerate(pressures):
                if not hyd.tank_pressure < p < hyd.supply_pressure:
                    raise PhysicsError(
                        f"leg{i + 1} needs {name} = {p / 1e5:.1f} bar to hold the neutral pose, outside "
                        f"tank…supply ({hyd.tank_pressure / 1e5:g}…{hyd.supply_pressure / 1e5:g} bar)")
        self.p1_initial, self.p2_initial = p1_0, p2_0
        plant = PlantTruth(params=hyd, p1_static=p1_0.copy(), flow_curve=hydraulics.static_velocity)
        self.compensator = _make_compensator(cfg, idx.n_legs, plant, lambda: _leg_model(cfg, mobility, p1_0, m, d, idx))
        controller = PController(cp, hyd.u_v_max, self.compensator)
        injector = FaultInjector(cfg.faults, idx.n_legs, idx.stroke, hyd.supply_pressure, hyd.tank_pressure)
        self.coupling = HydraulicCoupling(idx, cfg, controller, ControlSchedule(setpoints, noise, self.ctrl_div, valve),
                                          p1_0, plant, injector, p2_0)

    def _setup_recording(self) -> None:
        cfg, n = self.config, self.idx.n_legs
        n_total = self.total // self.rec_div
        keep = cfg.keep_last_s
        n_rec = n_total if keep is None else min(n_total, max(1, int(round(keep * self.record_rate))))
        self.n_total = n_total
        self.rec = {k: np.empty((n_rec, n)) for k in _LEG_CHANNELS}
        self.rec.update(t=np.empty(n_rec), p_s=np.empty(n_rec), acc=np.empty((n_rec, 3)), viol=np.zeros(n_rec),
                        temperature=np.empty(n_rec))
        self.sensors = {"platform_acc": self.rec["acc"]}
        # accelerations are recorded as the mean over the sample interval (a boxcar anti-alias filter)
        averaged = ("platform_acc", "platform_angacc") if cfg.scenario.system == "hexapod" else ("platform_acc",)
        self._acc_adr = np.concatenate([np.arange(self.idx.sensor[name].start, self.idx.sensor[name].stop)
                                        for name in averaged]).astype(np.int64)
        widths = [self.idx.sensor[name].stop - self.idx.sensor[name].start for name in averaged]
        ends = np.cumsum(widths)  # each sensor's entries in _acc_adr / _acc_sum
        self._averaged = [(name, slice(int(e - w), int(e))) for name, w, e in zip(averaged, widths, ends)]
        self._acc_sum = np.zeros(len(self._acc_adr) + 1)  # python engine: running sum, count
        if cfg.scenario.system == "hexapod":
            for name, width in (("platform_gyro", 3), ("platform_angacc", 3), ("platform_pos", 3),
                                ("platform_quat", 4)):
                self.sensors[name] = self.rec[name] = np.empty((n_rec, width))
        self.comp_state = {k: np.empty((n_rec, n)) for k in self.compensator.state()}

    def _setup_kernel(self) -> None:
        m, d, idx, coupling, n = self.model, self.data, self.idx, self.coupling, self.idx.n_legs
        # the closures' gap recorded per sample: the connects, and the welds between sites (a user MJCF's
        # cardans, hexsim.plant.user_model); a weld of the user's own between bodies is not a leg's closure
        eq = np.flatnonzero(m.eq_type == mujoco.mjtEq.mjEQ_CONNECT)
        if np.any(m.eq_objtype[eq] != mujoco.mjtObj.mjOBJ_SITE):
            raise InputError("the native engine needs connect constraints between sites")
        eq = np.union1d(eq, np.flatnonzero((m.eq_type == mujoco.mjtEq.mjEQ_WELD)
                                           & (m.eq_objtype == mujoco.mjtObj.mjOBJ_SITE)))
        self.mj = native.mj_view(m, d, idx, m.eq_obj1id[eq].astype(np.int64), m.eq_obj2id[eq].astype(np.int64))
        self._hyd = coupling.hyd  # the parameters the kernel has
        self.legs = native.Legs(coupling.leg_table(), self.dt, coupling.state.copy(),
                                coupling.groups, np.zeros(n), coupling._y_history, np.zeros(n))
        # without faults or warming oil, the P controller and the compensator run inside the kernel as well
        mode = native.comp_mode(self.compensator)
        self.inner = mode is not None and not coupling.faults and coupling.warm_up is None and coupling.valve is None
        comp = self.compensator
        self.ctl = native.Control(self.ctrl_div if self.inner else 0, coupling.controller.params.kp,
                                  coupling.setpoints, coupling.noise, mode or 0, native.kernel_state(comp, n),
                                  comp.table if mode == 2 else np.zeros((1, n)), np.zeros(1, dtype=np.int64))
        n_rec, rec = len(self.rec["t"]), self.rec
        self.recorder = native.Recorder(
            self.rec_div, self.n_total, np.zeros(n_rec, dtype=np.int64), np.zeros((n_rec, m.nsensordata)), rec["p1"],
            rec["p_s"], rec["p2"], rec["force"], rec["y"], rec["ydot"], rec["viol"], rec["y_ref"], rec["u_v"], rec["u_c"],
            np.empty((n_rec if self.inner and mode == 1 else 1, 4, n)), np.full(1, -1, dtype=np.int64),
            self._acc_adr, np.zeros(len(self._acc_adr) + 1))
        mujoco.mj_forward(m, d)
        if self.config.progress and not native.kernels_cached():
            print("hexsim: compiling the simulation kernels (once, about 15 s; cached on disk)", file=sys.stderr,
                  flush=True)
        # the controller's last outputs (u_v, U_c, the compensator's statistics, y_m, u_p), kept between blocks
        self._out = (np.zeros(n), np.zeros(n), np.zeros((4, n)), np.zeros(n), np.zeros(n))
        native.run_block(self.mj, self.legs, self.ctl, self.recorder, self._out, 0, 0, 0)  # compile / load

    # ------------------------------------------------------------------ stepping
    @property
    def time(self) -> float:
        """Simulated time reached [s]."""
        return self.k * self.dt

    @property
    def done(self) -> bool:
        return self.k >= self.total

    @property
    def state(self) -> PlantState:
        """The legs' hydraulic state now (arrays (n_legs,), live: do not change them)."""
        return self.legs.state if self.config.engine == "native" else self.coupling.state

    def step(self, seconds: float | None = None) -> "Simulator":
        """Advance by ``seconds`` [s] (rounded up to whole record periods, which may end between two
        controller samples; None: to the end of the scenario). Returns self. Raises PhysicsError naming the
        time and the leg for a non-finite state or a MuJoCo warning."""
        unit = self.rec_div
        if seconds is None:
            k_end = self.total
        else:
            if not (math.isfinite(seconds) and seconds >= 0):
                raise InputError(f"step: seconds must be a finite number >= 0, got {seconds!r}")
            k_end = min(self.total, self.k + math.ceil(round(seconds / self.dt, 6) / unit) * unit)
        if k_end <= self.k:
            return self
        bar = tqdm(total=round(self.config.scenario.duration, 3), initial=round(self.time, 3), unit="sim s",
                   disable=not self.config.progress, leave=False,
                   bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} sim s [{elapsed}<{remaining}]")
        start = time.perf_counter()
        try:
            if self.config.engine == "python":
                self._loop_python(k_end, bar)
            elif self.inner:
                self._run_inner(k_end, bar)
            else:
                self._run_ticks(k_end, bar)
        finally:
            self.wall_time_s += time.perf_counter() - start
            bar.close()
        _check_finite(self.state.p1, self.data, self.idx, self.data.time)  # the platform too
        return self

    def run(self) -> SimulationResult:
        """Step to the end of the scenario and return the result."""
        return self.step().result()

    def _loop_python(self, k_end: int, bar) -> None:
        """Samples self.rows … k_end / rec_div with :class:`HydraulicCoupling` as MuJoCo's control
        callback: every ``rec_div``-th step k records the state at t_k (the sensors MuJoCo evaluates at the
        start of the step, P1 before the step's update; the accelerometer as its mean over the steps
        k-rec_div … k-1, as the kernel's :class:`~hexsim.engine.native.Recorder`), kept in the arrays as a ring."""
        d, idx, coupling, rec = self.data, self.idx, self.coupling, self.rec
        mujoco.set_mjcb_control(coupling)
        try:
            for i in range(self.rows, k_end // self.rec_div):
                w = i % len(rec["t"])
                p1_before, p_s_before, p2_before = coupling.state.p1.copy(), coupling.state.p_s[0], coupling.state.p2.copy()
                self._python_steps(1)  # step k = i * rec_div: the sensors see t_k
                sd = d.sensordata
                rec["t"][w] = i * self.rec_div * self.dt
                rec["y"][w] = coupling.y_measured  # the position sensor, y(t_k - tau_y)
                rec["ydot"][w] = coupling.ydot
                rec["y_ref"][w], rec["u_v"][w], rec["u_c"][w] = coupling.r, coupling.u_v, coupling.u_c
                rec["p1"][w], rec["p_s"][w], rec["force"][w] = p1_before, p_s_before, coupling.force
                rec["p2"][w] = p2_before
                rec["temperature"][w] = coupling.temperature
                for key, value in self.compensator.state().items():
                    self.comp_state[key][w] = value
                for name, out in self.sensors.items():
                    out[w] = sd[idx.sensor[name]]
                acc = self._acc_sum  # the mean over the interval's steps (the first record: its own)
                if acc[-1] > 0:
                    for name, entries in self._averaged:
                        self.sensors[name][w] = acc[entries] / acc[-1]
                acc[:] = 0.0
                self._add_acc()
                eq = d.efc_type[: d.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY
                if np.any(eq):
                    rec["viol"][w] = np.linalg.norm(d.efc_pos[: d.nefc][eq].reshape(-1, 3), axis=1).max()
                if i % 100 == 0:
                    bar.update(round(d.time - bar.n, 3))
                for _ in range(self.rec_div - 1):
                    self._python_steps(1)
                    self._add_acc()
                self.rows, self.k = i + 1, (i + 1) * self.rec_div
        finally:
            mujoco.set_mjcb_control(None)

    def _add_acc(self) -> None:
        """Add the step's accelerometer reading to the running sum the records average."""
        acc = self._acc_sum
        for c, adr in enumerate(self._acc_adr):
            acc[c] += self.data.sensordata[adr]
        acc[-1] += 1.0

    def _python_steps(self, steps: int) -> None:
        mujoco.mj_step(self.model, self.data, steps)
        if self.coupling.error is not None:
            raise self.coupling.error
        _check_finite(self.coupling.state.p1, self.data, self.idx, self.data.time)
        check_warnings(self.model, self.data)

    def _run_inner(self, k_end: int, bar) -> None:
        """Steps self.k … k_end with the controller in the kernel, in chunks of about 0.5 s (progress,
        checks)."""
        ctl, dt = self.ctl, self.dt
        warnings = self.data.warning.number  # a view of MuJoCo's warning counters
        chunk = max(1, int(round(0.5 / (ctl.div * dt)))) * ctl.div
        k0 = self.k
        while self.k < k_end:
            steps = min(chunk, k_end - self.k)
            self.rows = native.run_block(self.mj, self.legs, ctl, self.recorder, self._out, self.k, steps, self.rows)
            _check_block(self.model, self.data, self.idx, self.recorder.status, self.legs.state.p1, warnings)
            self.k += steps
            bar.update(round(self.time - bar.n, 3))
        self.coupling.controller.saturated_samples += int(ctl.saturated[0])
        ctl.saturated[0] = 0
        if ctl.mode == 2:
            self.compensator.advance(-(-self.k // ctl.div) - -(-k0 // ctl.div))

    def _run_ticks(self, k_end: int, bar) -> None:
        """Steps self.k … k_end with the controller sampled in Python (:meth:`HydraulicCoupling.tick`:
        warming oil, faults, any compensator) and the kernel run from one controller tick to the next."""
        coupling, legs, recorder, idx = self.coupling, self.legs, self.recorder, self.idx
        warnings = self.data.warning.number
        hist = legs.history
        L, n_rec = len(hist), len(recorder.k)
        while self.k < k_end:
            k = self.k
            if k % self.ctrl_div == 0:  # a controller sample (a step may have ended between two)
                hist[k % L] = idx.positions(self.data)[0]
                hyd = coupling.tick(k, hist[(k + 1) % L].copy(), legs.state.p1)
                if hyd is not self._hyd:  # the oil warmed: new parameters
                    self._hyd = coupling.hyd = hyd
                    legs = self.legs = legs._replace(params=coupling.leg_table())
                if coupling.supply_level is not None:
                    legs.state.p_s[:] = coupling.supply_level
            steps = min(self.ctrl_div - k % self.ctrl_div, k_end - k)
            r_next = native.run_block(self.mj, legs, self.ctl, recorder, (coupling.u_v, *self._out[1:]), k, steps,
                                      self.rows)
            _check_block(self.model, self.data, idx, recorder.status, legs.state.p1, warnings)
            rows = np.arange(self.rows, r_next) % n_rec
            recorder.ref[rows], recorder.u[rows], recorder.uc[rows] = coupling.r, coupling.u_v, coupling.u_c
            self.rec["temperature"][rows] = coupling.temperature
            for key, value in self.compensator.state().items():
                self.comp_state[key][rows] = value
            self.rows, self.k = r_next, k + steps
            if self.k % (50 * self.ctrl_div) == 0:
                bar.update(round(self.time - bar.n, 3))

    # ------------------------------------------------------------------ results
    def result(self, last: int | None = None, since: int | None = None) -> SimulationResult:
        """What was recorded so far, in time order (copies; the run can go on). With ``keep_last_s`` the
        last that many seconds; with ``last`` the last that many samples at most; with ``since`` the samples
        from that one on (a count of samples since the start, as :attr:`rows`; those the ring still holds).
        Only the samples returned are unpacked from the kernel's rows, so a live reader asking for the latest
        ones pays for those alone."""
        cfg, idx = self.config, self.idx
        n_rec = len(self.rec["t"])
        keep = min(self.rows, n_rec)
        if last is not None:
            keep = min(keep, last)
        if since is not None:
            keep = min(keep, max(0, self.rows - since))
        rows = np.arange(self.rows - keep, self.rows) % n_rec  # the ring's positions of the samples kept
        if cfg.engine == "native":
            self._unpack_kernel_rows(rows)

        def ordered(a):
            return a[rows]

        rec = {k: ordered(v) for k, v in self.rec.items()}
        comp_state = {k: ordered(v) for k, v in self.comp_state.items()}
        t = rec["t"]
        pose = pose_ref = None
        if cfg.scenario.system == "hexapod":
            if self._geometry is None:
                self._geometry = HexapodGeometry.from_model(self.model)
            pose = self._geometry.pose_of(rec["platform_pos"], rec["platform_quat"])
            given = cfg.scenario.legs is not None or cfg.scenario.open_loop  # no platform setpoint then
            pose_ref = None if given else cfg.scenario.poses(t)
        return SimulationResult(
            config=cfg, t=t, **{k: rec[k] for k in _LEG_CHANNELS}, p_s=rec["p_s"], acc=rec["acc"],
            gyro=rec.get("platform_gyro"), angacc=rec.get("platform_angacc"), pose=pose, pose_ref=pose_ref,
            constraint_violation=rec["viol"], oil_temperature=rec["temperature"], compensator_state=comp_state,
            p1_initial=self.p1_initial, saturated_samples=self.coupling.controller.saturated_samples,
            wall_time_s=self.wall_time_s, gravity=float(-self.model.opt.gravity[2]), stroke=idx.stroke.copy(),
            timestep=self.dt, platform_quat=rec.get("platform_quat"), sensor_site=self.sensor_site())

    def recorded_mean(self, names: tuple[str, ...], since: int) -> list[np.ndarray] | None:
        """The mean of each sensor in ``names``' samples recorded from sample ``since`` on (a count of samples
        since the start, as :attr:`rows`; at least the last one, at most those the ring still holds), each (width,)
        in the sensor's units and frame; None before the first sample. The accelerometers' samples are each the
        mean over their interval (the boxcar of :class:`~hexsim.engine.native.Recorder`: Δv/Δt), so the mean of
        consecutive ones is the mean over their whole interval, the interval ending one sample before
        :attr:`time`. Raises KeyError for a sensor the model does not have."""
        if self.rows == 0:
            return None
        n_rec = len(self.rec["t"])
        rows = np.arange(max(min(since, self.rows - 1), self.rows - n_rec, 0), self.rows) % n_rec
        if self.config.engine == "native":
            sens = self.recorder.sens[rows]
            return [sens[:, self.idx.sensor[name]].mean(axis=0) for name in names]
        return [self.sensors[name][rows].mean(axis=0) for name in names]

    def sensor_site(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The platform accelerometer's site in its body: position (3,) [m], orientation (4,) [w, x, y, z];
        None for a single actuator."""
        if self.config.scenario.system != "hexapod":
            return None
        m = self.model
        site = int(m.sensor_objid[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, "platform_acc")])
        return m.site_pos[site].copy(), m.site_quat[site].copy()

    def _unpack_kernel_rows(self, rows: np.ndarray) -> None:
        """Fill, at the ring's positions ``rows`` (int array), the channels the kernel keeps in its own rows:
        time, sensors, and (with the controller inside) the oil temperature and the compensator's (a, b, c, s)."""
        rec, recorder, s = self.rec, self.recorder, self.idx.sensor
        rec["t"][rows] = recorder.k[rows] * self.dt
        for name, out in self.sensors.items():
            out[rows] = recorder.sens[rows, s[name]]
        if self.inner:
            rec["temperature"][rows] = self.coupling.temperature
            if self.ctl.mode == 1:
                for c, key in enumerate(("a", "b", "c", "s")):  # as BufferedCompensator.state()
                    self.comp_state[key][rows] = recorder.comp[rows, c]


def simulate(config: RunConfig) -> SimulationResult:
    """Run one scenario headless and record it: ``Simulator(config).run()``.

    Raises WorkspaceError for an unreachable setpoint, InputError for inconsistent settings and
    PhysicsError for a MuJoCo warning or a non-finite state (naming the time and the leg).
    """
    return Simulator(config).run()


def _leg_model(cfg: RunConfig, mobility: np.ndarray, p1_0: np.ndarray, m, d, idx: PlantIndex):
    """The machine's leg model at the run's start (hexsim.control.feedforward.leg_model): its hydraulics and
    effects, the rest pressures, the legs' inertia (the inverse of their mobility)."""
    model = leg_model(cfg.hydraulics, p1_0, np.linalg.inv(mobility), eff=cfg.effects,
                      load=static_leg_forces(m, d, idx) if cfg.hydraulics.four_way else None,
                      u_ref=cfg.compensator_settings.oracle_u_ref, kp=cfg.controller.kp,
                      source=f"machine {cfg.machine_label}")
    check_loop(model, cfg.controller.kp, cfg.controller.rate_hz)
    return model


def _make_compensator(cfg: RunConfig, n_legs: int, plant: PlantTruth, model) -> Compensator:
    """The run's compensator: a replayed U_c table, a built-in by name, or the user's class (called as
    ``cls(n_legs, rate_hz, u_v_max, settings)``). A model-based one gets the config's leg model (a tuned
    file's) or ``model()``, the machine's. Raises InputError for a bad name or setting."""
    cp, hyd = cfg.controller, cfg.hydraulics
    try:
        if cfg.feedforward is not None:
            return ReplayedCompensation(np.ascontiguousarray(cfg.feedforward, dtype=float), cp.rate_hz, hyd.u_v_max)
        if isinstance(cfg.compensator, str):
            if cfg.compensator in MODEL_BASED:
                model = cfg.compensator_model or model()
            return make_compensator(cfg.compensator, n_legs, cp.rate_hz, u_v_max=hyd.u_v_max,
                                    settings=cfg.compensator_settings, plant=plant,
                                    model=model if cfg.compensator in MODEL_BASED else None)
        return cfg.compensator(n_legs, cp.rate_hz, hyd.u_v_max, cfg.compensator_settings)
    except SettingsError as exc:
        raise InputError(str(exc)) from None


def _check_block(m, d, idx: PlantIndex, status: np.ndarray, p1: np.ndarray, warnings: np.ndarray) -> None:
    """After a kernel call: raise PhysicsError for the non-finite state the kernel stopped at (naming
    the leg and the time of the step, :func:`_check_finite`) or for a MuJoCo warning."""
    if status[0] >= 0:
        t = status[0] * idx.dt
        _check_finite(p1, d, idx, t)
        raise PhysicsError(f"non-finite state at t = {t:.4f} s")  # the kernel saw it; the arrays hold it
    if warnings.any():
        check_warnings(m, d)


def _check_finite(p1: np.ndarray, d: mujoco.MjData, idx: PlantIndex, t: float) -> None:
    """PhysicsError naming the first leg whose P1 (n_legs,) [Pa] or piston position/velocity is not
    finite, or the platform, at time ``t`` [s]; nothing if all is finite."""
    bad_p1 = ~np.isfinite(p1)
    bad_q = np.zeros(idx.n_legs, dtype=bool)
    if not idx.platform_only:
        bad_q = ~np.isfinite(d.qpos[idx.qpos_adr]) | ~np.isfinite(d.qvel[idx.dof_adr])
    if np.any(bad_p1 | bad_q):
        leg = int(np.flatnonzero(bad_p1 | bad_q)[0]) + 1
        what = "P1" if bad_p1[leg - 1] else "piston position/velocity"
        raise PhysicsError(f"non-finite {what} of leg{leg} at t = {t:.4f} s")
    if not (np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel))):
        raise PhysicsError(f"non-finite platform state at t = {t:.4f} s")
