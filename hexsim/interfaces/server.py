"""``hexsim serve``: a virtual motion system a simulator's host computer drives over UDP, in real time.

The host sends setpoint packets (:mod:`hexsim.interfaces.packets`) at its own rate; every controller period
(the machine's, 500 Hz for the built-in) the server takes the packets that arrived, hands the P loops the
piston setpoints of the operating modes (:mod:`hexsim.interfaces.operating_modes`: engage, neutral, park,
host lost, rejected packets), advances the whole simulation one period — the same
:class:`~hexsim.engine.runner.Simulator` as ``hexsim run`` (hydraulics, the bump, the compensator,
MuJoCo) — and sends the platform's state back at ``state_rate_hz``. What must not stall a tick runs beside the
loop: an adaptive compensator's buffers are taught in a worker process (they take effect the fixed delay later,
:data:`compensation.model_based.AdaptiveFeedforward.LEARN_DELAY_S`, as in a batch run), and the cyclic garbage
collector runs between ticks only (:data:`GC_IDLE_S`). The periods are paced to the wall clock:
between ticks the loop waits in ``select`` on the socket (reading packets as they arrive, their arrival
timed), the last fraction of a millisecond in a spin. A tick that starts late is not skipped: the loop
runs the next ones back to back until it is on time again.

Timing (:class:`Timing`): each tick's start against its deadline (the jitter; a tick more than one period
late is *late*: the simulation has fallen behind the wall clock), and its work (packets, setpoints, the step,
the state packet; more than one period is an *overrun*).

A measurement log and a rerun recording, when asked, are written while the session runs
(:mod:`hexsim.interfaces.session_log`: the whole session, up to a second before now); at the end (the
duration reached, or Ctrl-C) the report (:class:`ServeReport`) is printed and written as JSON. The last
``keep_s`` stay in memory (:meth:`VirtualMotionSystem.result`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import gc
import math
import multiprocessing
import os
import select
import signal
import socket
import sys
import threading
import time
from concurrent.futures import ProcessPoolExecutor

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation
from tqdm import tqdm

from hexsim.control.kinematics import HexapodGeometry
from hexsim.control.scenario import live_scenario
from hexsim.engine.config import RunConfig
from hexsim.engine.runner import Simulator
from hexsim.errors import InputError
from hexsim.interfaces.operating_modes import OVERRUN, ModeSettings, OperatingModes
from hexsim.interfaces.packets import (
    DOF,
    HOST_PACKET,
    LEGS,
    PERCEPTION_FIELDS,
    STATE_PACKET,
    TYPES,
    PacketError,
    PacketLayout,
)
from hexsim.plant.geometry import MICRO_MOTION_SYSTEM
from hexsim.plant.model import PlantIndex, load_model
from hexsim.studies.perception import LivePerception

_LEG_NAMES = [f"leg{i}" for i in range(1, 7)]
_LEG_REF_NAMES = [f"leg{i}_ref" for i in range(1, 7)]
_P1_NAMES = [f"p1_leg{i}" for i in range(1, 7)]
_RATE_NAMES = [f"{n}_rate" for n in DOF]
_HEAD_NAMES = [f"head_f{a}" for a in "xyz"] + [f"head_w{a}" for a in "xyz"]
_SENSED_NAMES = [n for n in PERCEPTION_FIELDS if n != "seat_peak"]

#: the last stretch before a deadline spent spinning instead of in ``select`` [s]
SPIN_S = 3e-4
#: The interpreter's thread switch interval while serving [s] (``sys.setswitchinterval``; Python's default 5 ms
#: is two and a half ticks at 500 Hz that another thread, e.g. the worker pool's feeding a lesson, could hold the
#: loop off for).
SWITCH_INTERVAL_S = 2e-5
#: While serving, the cyclic garbage collector runs only between ticks with at least this long to the deadline
#: [s], on the young generations, once :data:`GC_YOUNG` objects were allocated (Python's own threshold, 700):
#: a full collection in a tick was measured at 70 ms, 35 ticks late.
GC_IDLE_S = 1e-3
GC_YOUNG = 700
#: Niceness of the process an adaptive compensator's buffers are taught in (``os.nice``): the loop first.
WORKER_NICE = 10


@dataclasses.dataclass(frozen=True)
class ServeSettings:
    """Where to listen (``bind``, ``port``; port 0: any free one), where to answer (``reply_to`` (host,
    port); None: the sender of the last accepted packet), the state packets' rate [Hz], the longest session
    [s] (``duration_s``: the recording is set up for it), the recording kept for the outputs [s], the
    operating modes' settings and the two packet layouts; ``priority``: the loop's real-time priority (1…99,
    Linux's SCHED_FIFO, as a motion controller's loop runs; None: the normal scheduler). Raises InputError for a
    bad value."""

    bind: str = "127.0.0.1"
    port: int = 5005
    reply_to: tuple[str, int] | None = None
    state_rate_hz: float = 100.0
    duration_s: float = 3600.0
    keep_s: float = 600.0
    modes: ModeSettings = ModeSettings()
    host_layout: PacketLayout = HOST_PACKET
    state_layout: PacketLayout = STATE_PACKET
    priority: int | None = None

    def __post_init__(self) -> None:
        if not 0 <= self.port < 65536:
            raise InputError(f"port must be 0…65535, got {self.port}")
        if self.priority is not None and not 1 <= self.priority <= 99:
            raise InputError(f"priority must be 1…99 (SCHED_FIFO), got {self.priority}")
        for name in ("state_rate_hz", "duration_s", "keep_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise InputError(f"{name} must be a positive number, got {value!r}")
        self.host_layout.check_host()
        self.state_layout.check_state()


@dataclasses.dataclass
class Timing:
    """Per tick: ``lateness`` (n,) [s] of its start after its deadline, ``work`` (n,) [s] it took; ``period``
    [s]. The figures: :meth:`summary`."""

    period: float
    lateness: np.ndarray
    work: np.ndarray
    ticks: int = 0
    late: int = 0

    def summary(self) -> dict:
        """ticks; jitter p50, p99, max [ms] (start after deadline); late ticks (more than one period late);
        overruns (work over one period); work mean, p99, max [ms]; the work's share of the period (mean)."""
        n = self.ticks
        late, work = self.lateness[:n] * 1e3, self.work[:n] * 1e3
        if n == 0:
            return {"ticks": 0}
        return {"ticks": n, "period_ms": self.period * 1e3,
                "jitter_p50_ms": float(np.percentile(late, 50)), "jitter_p99_ms": float(np.percentile(late, 99)),
                "jitter_max_ms": float(late.max()), "late_ticks": int(np.sum(late > self.period * 1e3)),
                "overruns": int(np.sum(work > self.period * 1e3)), "work_mean_ms": float(work.mean()),
                "work_p99_ms": float(np.percentile(work, 99)), "work_max_ms": float(work.max()),
                "load": float(work.mean() / (self.period * 1e3))}


@dataclasses.dataclass(frozen=True)
class ServeReport:
    """What a session did: the machine and compensator, the simulated time [s], the timing
    (:meth:`Timing.summary`), the packets (received, accepted, rejected by reason, state packets sent and
    failed), the operating modes' transitions ((time [s], status name)), the status at the end and the loop's
    scheduling ("normal" or "SCHED_FIFO N")."""

    machine: str
    compensator: str
    simulated_s: float
    timing: dict
    packets: dict
    transitions: list
    status: str
    scheduling: str = "normal"

    def lines(self) -> list[str]:
        """The report as a user reads it."""
        t, p = self.timing, self.packets
        out = [f"machine {self.machine}, compensator {self.compensator}: {self.simulated_s:.1f} s served, "
               f"ended {self.status}"]
        if t.get("ticks"):
            out.append(f"timing: {t['ticks']} ticks of {t['period_ms']:g} ms; start after deadline p50 "
                       f"{t['jitter_p50_ms']:.3f}, p99 {t['jitter_p99_ms']:.3f}, max {t['jitter_max_ms']:.3f} ms; "
                       f"{t['late_ticks']} late, {t['overruns']} overruns; work mean {t['work_mean_ms']:.3f} ms "
                       f"({t['load']:.0%} of the period), max {t['work_max_ms']:.3f} ms; scheduling "
                       f"{self.scheduling}")
        rejected = ", ".join(f"{n} {k}" for k, n in sorted(p["rejected"].items())) or "none"
        out.append(f"packets: {p['received']} received, {p['accepted']} accepted, rejected: {rejected}; "
                   f"{p['sent']} state packets sent ({p['send_failed']} failed)")
        out.append("modes: " + ", ".join(f"{name} at {when:.2f} s" for when, name in self.transitions))
        return out


class VirtualMotionSystem:
    """The simulation behind ``hexsim serve`` (module doc): ``base`` gives the machine, controller and
    compensator (its scenario is replaced), ``settings`` the socket, layouts and modes. :meth:`run` serves
    until the duration or :meth:`stop`; :meth:`result` is the recording, :meth:`report` the figures.
    Raises InputError for a machine that is not a hexapod or a port in use."""

    def __init__(self, base: RunConfig, settings: ServeSettings = ServeSettings()) -> None:
        if base.scenario.system != "hexapod":
            raise InputError(f"hexsim serve needs a hexapod machine; {base.machine_label} is a single actuator")
        self.settings = settings
        neutral = PlantIndex.from_model(load_model("hexapod", base.model, base.effects, base.geometry)).neutral_y
        config = dataclasses.replace(base, scenario=live_scenario("hexapod", neutral, settings.duration_s, name="serve"),
                                     record_rate_hz=base.controller.rate_hz, keep_last_s=settings.keep_s,
                                     progress=False)
        self.config = config
        self.sim = sim = Simulator(config)
        self.period = sim.ctrl_div * sim.dt
        self.geometry = geo = HexapodGeometry.from_model(sim.model)
        if settings.host_layout.setpoints == "dof":
            def to_legs(q: np.ndarray) -> np.ndarray:
                return geo.inverse(q, check=False)
        else:
            def to_legs(q: np.ndarray) -> np.ndarray:
                return q[: len(neutral)]
        frame = next(f for f in settings.host_layout.fields if f.name == "frame")
        self.modes = OperatingModes(neutral, sim.idx.stroke, to_legs, settings.modes,
                                    1 << (8 * np.dtype(TYPES[frame.type]).itemsize))
        self._setpoint_names = DOF if settings.host_layout.setpoints == "dof" else LEGS
        n_ticks = int(math.ceil(settings.duration_s / self.period))
        self.timing = Timing(self.period, np.zeros(n_ticks), np.zeros(n_ticks))
        self.transitions: list[tuple[float, str]] = [(0.0, self.modes.status.name.lower())]
        self.packets = {"received": 0, "accepted": 0, "sent": 0, "send_failed": 0}
        self._reply = settings.reply_to
        self._send_div = max(1, int(round(1.0 / (settings.state_rate_hz * self.period))))
        self._stop = threading.Event()
        self._t0 = 0.0
        self._scheduling = "normal"
        if settings.priority is not None:  # refused now, before listening, rather than when the clock starts
            os.sched_setscheduler(0, *self._real_time())
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self.sock.bind((settings.bind, settings.port))
        except OSError as exc:
            self.sock.close()
            raise InputError(f"cannot listen on {settings.bind}:{settings.port}: {exc.strerror}") from None
        self.sock.setblocking(False)
        self.address = self.sock.getsockname()
        self._platform = mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_BODY, "platform")
        self._vel = np.zeros(6)
        self._sent_rows = 0  # the samples recorded when the last state packet went (the next one's mean from there)
        self._occupant(config, settings)
        self._worker = None
        self._log = None  # the files written as the session runs (log_to)
        if hasattr(sim.compensator, "learn_in"):  # an adaptive compensator's buffers: taught beside the loop
            # in a process of its own (a thread would hold the interpreter's lock from the loop for tens of ms),
            # forked (it has the modules already), at a lower priority than the loop
            self._worker = ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("fork"),
                                               initializer=_learning_worker)
            sim.compensator.learn_in(self._worker)

    def _occupant(self, config: RunConfig, settings: ServeSettings) -> None:
        """The occupant's points in the accelerometer's site frame (the head; with the seat, stacked, for the
        perception) and the perception itself where the state packet sends it."""
        sim = self.sim
        site_pos, site_quat = sim.sensor_site()  # the accelerometer's site in the platform body
        self._body_from_site = Rotation.from_quat(site_quat[[1, 2, 3, 0]]).as_matrix()  # (3, 3)
        self._world_from_body = np.zeros(9)
        geometry = config.geometry or MICRO_MOTION_SYSTEM
        self._points_in_site = np.stack([self._body_from_site.T @ (np.asarray(p) - site_pos)  # (2, 3): head, seat
                                         for p in (geometry.head_point, geometry.seat_point)])
        # for each point the matrix K of a -> a x r (its columns e_i x r): alpha x r = K alpha
        self._points_cross = np.stack([np.cross(np.eye(3), p).T for p in self._points_in_site])
        # the occupant's perception, every tick, where the state packet sends it
        perceived = any(f.name in PERCEPTION_FIELDS for f in settings.state_layout.fields)
        self.perception = LivePerception(1.0 / self.period) if perceived else None
        self._sensed = np.zeros(len(_SENSED_NAMES))

    # ------------------------------------------------------------------ packets
    def _drain(self) -> None:
        """Take every packet waiting on the socket, each timed at its reading [s since the start]."""
        layout = self.settings.host_layout
        while True:
            try:
                data, sender = self.sock.recvfrom(65536)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:  # e.g. an ICMP port-unreachable of a state packet, reported on this socket
                continue
            self.packets["received"] += 1
            now = time.perf_counter() - self._t0
            try:
                fields = layout.unpack(data)
            except PacketError as exc:
                self.modes.reject(exc.reason)
                continue
            fields["setpoint"] = np.array([fields[n] for n in self._setpoint_names])
            if self.modes.receive(now, fields):
                self.packets["accepted"] += 1
                if self.settings.reply_to is None:
                    self._reply = sender

    def state(self) -> dict[str, float]:
        """The platform's state now as the state packet's fields (:data:`~hexsim.interfaces.packets.STATE_FIELDS`)."""
        sim, m, d, modes = self.sim, self.sim.model, self.sim.data, self.modes
        y, _ = sim.idx.positions(d)
        out = {"status": int(modes.status), "frame": modes.last_frame or 0, "faults": modes.take_faults(),
               "time": sim.time, "received": self.packets["received"], "rejected": sum(modes.rejected.values()),
               "late": self.timing.late, "p_s": float(sim.state.p_s[0])}
        out.update(zip(_LEG_NAMES, y.tolist()))
        out.update(zip(_LEG_REF_NAMES, np.asarray(modes.cmd, dtype=float).tolist()))
        out.update(zip(_P1_NAMES, np.asarray(sim.state.p1, dtype=float).tolist()))
        s = sim.idx.sensor
        quat = d.sensordata[s["platform_quat"]]
        pose = self.geometry.pose_of(d.sensordata[s["platform_pos"]][None], quat[None])[0]
        mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, self._platform, self._vel, 0)
        out.update(zip(DOF, pose.tolist()))
        out.update(zip(_RATE_NAMES, self._vel[[3, 4, 5, 0, 1, 2]].tolist()))
        points, omega = self._occupant_motion(self._sent_rows)
        out.update(zip(_HEAD_NAMES, points[0].tolist() + omega.tolist()))
        if self.perception is not None:
            out.update(zip(_SENSED_NAMES, self._sensed.tolist()))
            out["seat_peak"] = self.perception.take_seat_peak()
        return out

    def _occupant_motion(self, since: int) -> tuple[np.ndarray, np.ndarray]:
        """The specific force (2, 3) [m/s^2] at the occupant's head and seat (rows), the mean over the recorded
        samples from ``since`` on (:meth:`~hexsim.engine.runner.Simulator.recorded_mean`: the accelerations' boxcar,
        Δv/Δt over the interval ending one controller tick ago), and the angular velocity (3,) [rad/s] now,
        platform axes: the rigid body's f = f_site + alpha x r + omega x (omega x r) from the accelerometer's site,
        as :func:`~hexsim.studies.perception.rigid_point_specific_force` gives it for a recorded run
        (:func:`~hexsim.studies.perception.point_motion`), written out for the two fixed points r (stacked (2, 3),
        site frame: alpha x r = K alpha with K the matrix of a -> a x r, omega x (omega x r) = omega (omega . r) -
        r |omega|^2): every tick with the perception on, where np.cross costs some 20 us a call. A state packet
        so carries the mean over its own period, as an integrating DAQ samples an accelerometer: the platform's
        ringing does not alias into it (with the whole process stalled 0.3 s three times, the host's samples of
        the instantaneous value averaged 9.63 m/s^2 on z over the engaged heave, the means 9.81)."""
        sim = self.sim
        d, s = sim.data, sim.idx.sensor
        means = sim.recorded_mean(("platform_acc", "platform_angacc"), since)
        acc, angacc = means if means is not None else (  # nothing recorded yet: the sensors now
            d.sensordata[s["platform_acc"]], d.sensordata[s["platform_angacc"]])
        mujoco.mju_quat2Mat(self._world_from_body, d.sensordata[s["platform_quat"]])
        omega = d.sensordata[s["platform_gyro"]]
        alpha = (self._world_from_body.reshape(3, 3) @ self._body_from_site).T @ angacc
        r = self._points_in_site
        f = acc + self._points_cross @ alpha + np.outer(r @ omega, omega) - r * (omega @ omega)
        return f @ self._body_from_site.T, self._body_from_site @ omega

    def _perceive(self) -> None:
        """One sample of the occupant's perception (:class:`~hexsim.studies.perception.LivePerception`) at the
        platform's state now (:meth:`_occupant_motion` over the last controller tick)."""
        (head, seat), omega = self._occupant_motion(self.sim.rows - 1)
        self._sensed = self.perception.update(head, omega, seat)

    def _send(self) -> None:
        if self._reply is None:
            return
        try:
            self.sock.sendto(self.settings.state_layout.pack(self.state()), self._reply)
            self.packets["sent"] += 1
        except OSError:
            self.packets["send_failed"] += 1

    # ------------------------------------------------------------------ ticks
    def tick(self, n: int) -> None:
        """Controller tick ``n``: the operating modes' setpoints at t = n x period into the P loops, one period
        of simulation, the occupant's perception where the state packet sends it, the state packet when due."""
        sim, modes = self.sim, self.modes
        before = modes.status
        sim.coupling.setpoints[sim.k // sim.ctrl_div] = modes.setpoint(n * self.period)
        if modes.status != before:
            self.transitions.append((n * self.period, modes.status.name.lower()))
        sim.step(self.period)
        if self.perception is not None:
            self._perceive()
        if n % self._send_div == 0:
            self._send()
            self._sent_rows = sim.rows  # the next state packet's accelerations: the mean from here on

    def _wait(self, deadline: float) -> None:
        """Until ``deadline`` (perf_counter [s]): in ``select`` on the socket, reading packets as they come,
        then spinning the last :data:`SPIN_S`."""
        while True:
            remain = deadline - time.perf_counter()
            if remain <= 0:
                return
            if remain > GC_IDLE_S and gc.get_count()[0] > GC_YOUNG:
                gc.collect(1)
                continue
            if remain > GC_IDLE_S and self._log is not None and self._log.due():
                self._log.send()
                continue
            if remain > SPIN_S:
                ready, _, _ = select.select([self.sock], [], [], remain - SPIN_S)
                if ready:
                    self._drain()

    def run(self, duration_s: float | None = None) -> ServeReport:
        """Serve in real time for ``duration_s`` [s] (None: the settings' duration) or until :meth:`stop` (or
        Ctrl-C, which ends the session the same way). Returns the report."""
        timing, sim = self.timing, self.sim
        last = len(timing.lateness) if duration_s is None else min(len(timing.lateness),
                                                                     int(round(duration_s / self.period)))
        self.state()  # the first call of each path is slow (lazy set-up): before the clock starts
        if timing.ticks == 0:  # and the first tick's (the compensator's first update: some 7 ms)
            self.tick(0)
            timing.ticks = 1
        tqdm(disable=True).close()  # the step's progress bar: its first instance creates tqdm's lock (ms)
        policy = self._real_time()
        if policy is not None:
            self._scheduling = f"SCHED_FIFO {self.settings.priority}"
        gc.freeze()  # the objects of the set-up out of the collector's way (its pauses would be ticks late)
        collecting = gc.isenabled()
        gc.disable()  # the collector runs between ticks instead (_wait), the young objects only
        self._t0 = time.perf_counter() - timing.ticks * self.period
        switch = sys.getswitchinterval()
        sys.setswitchinterval(SWITCH_INTERVAL_S)
        try:
            for n in range(timing.ticks, last):
                if self._stop.is_set() or sim.done:
                    break
                deadline = self._t0 + n * self.period
                self._wait(deadline)
                start = time.perf_counter()
                self._drain()
                self.tick(n)
                done = time.perf_counter()
                timing.lateness[n], timing.work[n] = start - deadline, done - start
                timing.late += start - deadline > self.period
                if done - start > self.period:
                    self.modes.faults |= OVERRUN
                timing.ticks = n + 1
        except KeyboardInterrupt:
            pass
        finally:
            sys.setswitchinterval(switch)
            if policy is not None:
                os.sched_setscheduler(0, *policy)
            if collecting:
                gc.enable()
        return self.report()

    def _real_time(self) -> tuple[int, os.sched_param] | None:
        """The loop's thread to SCHED_FIFO at the settings' priority (None: nothing to do); the policy it had, to
        restore. Raises InputError where the process may not (not root, no CAP_SYS_NICE, no rtprio limit)."""
        if self.settings.priority is None:
            return None
        before = (os.sched_getscheduler(0), os.sched_getparam(0))
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(self.settings.priority))
        except (PermissionError, OSError) as exc:
            raise InputError(f"--priority {self.settings.priority}: real-time scheduling refused ({exc.strerror}); "
                             "it needs root, CAP_SYS_NICE or an rtprio limit (/etc/security/limits.conf)") from None
        return before

    def log_to(self, log=None, rrd=None) -> None:
        """Write the session as it runs (:mod:`hexsim.interfaces.session_log`): ``log`` a measurement log .csv
        (its sidecar beside it), ``rrd`` a rerun recording; their paths come back from :meth:`close`. Call
        before :meth:`run`. Raises InputError when the writer cannot start."""
        if log is None and rrd is None:
            return
        from hexsim.interfaces.session_log import SessionLog

        named = dataclasses.replace(self.config, scenario=live_scenario("hexapod", self.sim.idx.neutral_y,
                                                                        self.period, name="serve"))
        self._log = SessionLog(self.sim, named, log, rrd)

    def stop(self) -> None:
        """End :meth:`run` at its next tick (from another thread)."""
        self._stop.set()

    def close(self) -> list:
        """End the session: the socket, the learning worker, the files written as it ran (their paths,
        returned; InputError where the writer failed)."""
        self.sock.close()
        if self._worker is not None:
            self._worker.shutdown(wait=True)
        log, self._log = self._log, None
        return [] if log is None else log.close()

    def result(self):
        """The recording (:class:`~hexsim.engine.config.SimulationResult`, the last ``keep_s``)."""
        return self.sim.result()

    def report(self) -> ServeReport:
        packets = {**self.packets, "rejected": dict(self.modes.rejected)}
        return ServeReport(self.config.machine_label, self.config.compensator_name, self.sim.time,
                           self.timing.summary(), packets, list(self.transitions), self.modes.status.name.lower(),
                           self._scheduling)


def _learning_worker() -> None:
    """The learning worker's start: at :data:`WORKER_NICE`, and deaf to SIGINT (the Ctrl-C that ends a session
    reaches the whole process group; the server ends the worker itself, where the worker would have printed a
    KeyboardInterrupt traceback)."""
    os.nice(WORKER_NICE)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def serve_session(base: RunConfig, settings: ServeSettings, *, log=None, rrd=None, json_path=None,
                  out=print) -> list:
    """``hexsim serve``: set up, say where it listens, serve until the duration or Ctrl-C, then print the
    report and end the outputs asked for: ``log`` (a measurement log .csv with its sidecar) and ``rrd`` (a
    rerun recording), both written while the session runs (:mod:`hexsim.interfaces.session_log`);
    ``json_path``: the report. Returns the paths written. Raises InputError for a port in use, a machine
    the layout cannot drive, or a log the writer could not write."""
    from hexsim.tables import write_json

    vms = VirtualMotionSystem(base, settings)
    host, state = settings.host_layout, settings.state_layout
    try:
        vms.log_to(log, rrd)
        out(f"hexsim serve: {vms.config.machine_label}, compensator {vms.config.compensator_name}, controller "
            f"{1 / vms.period:g} Hz; listening on {vms.address[0]}:{vms.address[1]} for {host.source} host packets "
            f"({host.size} bytes, setpoints {host.setpoints}); {state.source} state packets ({state.size} bytes) at "
            f"{settings.state_rate_hz:g} Hz; {settings.duration_s:g} s at most, Ctrl-C ends", flush=True)
        report = vms.run()
    except BaseException:
        with contextlib.suppress(InputError):
            vms.close()
        raise
    for line in report.lines():
        out(line)
    written = vms.close()  # the files the session wrote as it ran (InputError where they failed)
    if json_path is not None:
        write_json(json_path, dataclasses.asdict(report))
        written.append(json_path)
    return written
