"""A hexsim run stepped by a co-simulation master: the engine of ``hexsim fmu``'s FMUs (:mod:`hexsim.interfaces.fmu`).

The master sets the inputs at each communication point t_n and asks for a step of h to t_n + h. Inside, the
run is the same :class:`~hexsim.engine.runner.Simulator` as ``hexsim run`` (hydraulics, P controller at the
machine's rate, compensator, MuJoCo), its setpoint rows written per controller sample:

- **setpoints** between communication points are played one communication step behind (as a motion
  controller plays its host's frames, and as ``hexsim serve`` does): over the step from t_n the setpoint runs
  from the input set at t_(n-1) to the one set at t_n, on a cubic (:data:`INTERPOLATIONS`: ``"cubic"``, the
  default, continuous in position and velocity, its slopes the backward differences of the last three inputs;
  a step input overshoots by about 15 %), a straight line (``"linear"``: its velocity jumps at every
  communication point, which a light actuator answers with a small acceleration step), or the input held from
  t_n without delay (``"hold"``: a staircase, what a master without interpolation gives). A 10 ms staircase
  makes the P loop answer every step with an acceleration spike;
- **outputs** are read after the step: the recorder's last 1 kHz sample, taken at t_n + h - 1 ms (as
  ``hexsim run`` logs it: the position as its sensor reads it, the accelerometer as its mean over the
  millisecond before), and the largest and smallest acceleration sample within the step (a peak hold: a
  reversal bump is 10-30 ms long and a master stepping 10 ms would otherwise see it only by chance).

A step must be a whole number of the 1 ms record period (1-10 ms is what the FMUs are checked at) and must
start where the last one ended; the run lasts at most ``duration_s`` (set it to the master's stop time).
"""

from __future__ import annotations

import dataclasses
import math

import mujoco
import numpy as np

from hexsim.control.kinematics import HexapodGeometry
from hexsim.control.scenario import live_scenario
from hexsim.engine.config import RunConfig
from hexsim.engine.runner import Simulator
from hexsim.errors import InputError
from hexsim.plant.geometry import MICRO_MOTION_SYSTEM
from hexsim.plant.model import PlantIndex, load_model
from hexsim.studies.metrics import run_smoothness
from hexsim.studies.perception import point_motion

#: How inputs become setpoints between communication points (module doc), with the FMU's integer for each.
INTERPOLATIONS = {"hold": 0, "linear": 1, "cubic": 2}
#: The record period [s]: the outputs' sampling inside a step and the unit of a communication step.
RECORD_PERIOD_S = 1e-3
#: The longest piece a step is cut into [s] (the recorder's ring holds one piece).
_PIECE_S = 0.02


class CoSimulation:
    """One run of ``base`` (its machine, controller, compensator; its scenario replaced by one written live)
    for at most ``duration_s`` [s], stepped by :meth:`advance`. ``open_loop`` (a single actuator only):
    the input is the valve setpoint [V] instead of the piston setpoint. Raises InputError for an open loop
    on a hexapod or a duration that is not positive; whatever :class:`Simulator` raises."""

    def __init__(self, base: RunConfig, duration_s: float, *, open_loop: bool = False,
                 interpolation: str = "cubic") -> None:
        if not (math.isfinite(duration_s) and duration_s > 0):
            raise InputError(f"the co-simulation's duration_s must be a number > 0 s, got {duration_s!r}")
        system = base.scenario.system
        if interpolation not in INTERPOLATIONS:
            raise InputError(f"interpolation {interpolation!r}: one of {', '.join(INTERPOLATIONS)}")
        if open_loop and system == "hexapod":
            raise InputError("an open-loop FMU (valve setpoints in) is a single actuator's; the platform takes "
                             "DOF setpoints")
        neutral = PlantIndex.from_model(load_model(system, base.model, base.effects, base.geometry)).neutral_y
        scenario = live_scenario(system, neutral, duration_s, open_loop=open_loop, name="fmu")
        self.config = config = dataclasses.replace(
            base, scenario=scenario, record_rate_hz=1.0 / RECORD_PERIOD_S, keep_last_s=_PIECE_S, progress=False)
        self.sim = sim = Simulator(config)
        self.system, self.open_loop, self.interpolation = system, open_loop, interpolation
        self.period = sim.ctrl_div * sim.dt  # the controller's sample period [s]
        self.rows = sim.coupling.valve if open_loop else sim.coupling.setpoints  # one row per controller sample
        self.geometry = HexapodGeometry.from_model(sim.model) if system == "hexapod" else None
        self.head = np.asarray((config.geometry or MICRO_MOTION_SYSTEM).head_point) if system == "hexapod" else None
        self.neutral = neutral
        self._inputs: list[np.ndarray] = []  # the inputs at the last three communication points, oldest first
        self._slope: np.ndarray | None = None  # the setpoint's slope [per step] where the last piece ended
        self._piece: tuple = ()
        self.last: dict[str, np.ndarray] = {}

    def initial(self) -> dict[str, np.ndarray]:
        """The outputs before the first step (:attr:`last`'s keys): the neutral pose at rest, the start
        pressures, the accelerometer reading gravity alone."""
        sim, n = self.sim, self.sim.idx.n_legs
        hyd = self.config.hydraulics
        zeros = np.zeros(n)
        m = sim.model
        site = int(m.sensor_objid[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, "platform_acc")])
        rest = -m.opt.gravity @ sim.data.site_xmat[site].reshape(3, 3)  # gravity's specific force, sensor frame
        out = {"y": self.neutral.copy(), "ydot": zeros, "y_ref": self.neutral.copy(), "p1": sim.p1_initial.copy(),
               "p2": sim.p2_initial.copy(), "p_s": np.array([hyd.supply_pressure]), "u_v": zeros, "u_c": zeros,
               "force": sim.p1_initial * hyd.area_bottom - sim.p2_initial * (hyd.area_bottom - hyd.area_rod),
               "acc": rest, "acc_max": rest, "acc_min": rest, "sample_time": np.zeros(1)}
        if self.system == "hexapod":
            out.update(pose=np.zeros(6), head_f=rest.copy(), head_w=np.zeros(3))
        self.last = dict(out)
        return out

    @property
    def time(self) -> float:
        """The simulated time reached [s]."""
        return self.sim.time

    def _to_rows(self, value: np.ndarray) -> np.ndarray:
        """An input (DOF (6,) [m, rad] for a hexapod, the piston setpoint (1,) [m] or the valve setpoint (1,)
        [V] for an actuator) as the controller's row (n_legs,)."""
        if self.geometry is not None:
            return self.geometry.inverse(value, check=False)
        return np.asarray(value, dtype=float)

    def advance(self, t: float, h: float, value: np.ndarray, force: float = 0.0) -> dict[str, np.ndarray]:
        """Step from ``t`` [s] to t + ``h`` [s] with the input ``value`` set at t (DOF setpoints (6,) [m, rad]
        for a hexapod; for an actuator the piston setpoint (1,) [m], or the valve setpoint (1,) [V] open loop)
        and an external force ``force`` [N] along an actuator's axis (extending positive). Returns the
        outputs (:meth:`outputs`). Raises InputError for a step that is not a whole number of
        milliseconds, one that does not start where the last ended, or one past ``duration_s``."""
        sim = self.sim
        n_records = round(h / RECORD_PERIOD_S)
        if n_records < 1 or abs(n_records * RECORD_PERIOD_S - h) > 1e-9:
            raise InputError(f"communication step {h * 1e3:g} ms: it must be a whole number of the "
                             f"{RECORD_PERIOD_S * 1e3:g} ms record period")
        if abs(t - sim.time) > 0.5 * sim.dt:
            raise InputError(f"communication step from t = {t:g} s, but the run is at {sim.time:g} s (steps must follow "
                             f"each other; no rewinding)")
        k_end = sim.k + n_records * sim.rec_div
        if k_end > sim.total:
            raise InputError(f"a step to t = {t + h:g} s goes past the FMU's duration_s ({sim.total * sim.dt:g} s): "
                             f"set duration_s to the simulation's stop time")
        value = np.atleast_1d(np.asarray(value, dtype=float))
        if not np.all(np.isfinite(value)):
            raise InputError(f"input at t = {t:g} s is not finite: {value.tolist()}")
        self._inputs = (self._inputs + [value])[-3:]
        self._segment()
        first, last = -(-sim.k // sim.ctrl_div), -(-k_end // sim.ctrl_div)  # the controller samples in [t, t + h)
        for j in range(first, last):
            self.rows[j] = self._to_rows(self._played((j * sim.ctrl_div - sim.k) / (k_end - sim.k)))
        if self.system != "hexapod":
            sim.data.qfrc_applied[sim.idx.dof_adr] = force
        peaks = []
        while sim.k < k_end:
            before = sim.rows
            sim.step(min(_PIECE_S, (k_end - sim.k) * sim.dt))
            peaks.append(self._read(sim.rows - before))
        self.last["acc_max"] = np.max([p[0] for p in peaks], axis=0)
        self.last["acc_min"] = np.min([p[1] for p in peaks], axis=0)
        return self.last

    def _segment(self) -> None:
        """The setpoint's piece over the coming step from the inputs so far: (start, slope at start, end, slope at
        end), the slopes per step; the end slope is kept as the next piece's start slope."""
        u = self._inputs
        if self.interpolation == "hold" or len(u) == 1:
            self._piece = (u[-1], 0.0 * u[-1], u[-1], 0.0 * u[-1])
            self._slope = None
            return
        secant = u[-1] - u[-2]
        if self.interpolation == "linear":
            self._piece = (u[-2], secant, u[-1], secant)
            return
        end = 0.5 * (3.0 * u[-1] - 4.0 * u[-2] + u[-3]) if len(u) == 3 else secant
        start = self._slope if self._slope is not None else secant
        self._piece, self._slope = (u[-2], start, u[-1], end), end

    def _played(self, s: float) -> np.ndarray:
        """The setpoint at the fraction ``s`` (0 <= s < 1) of the current step (module doc): the cubic Hermite
        of the piece: a straight line where both slopes are its secant ("linear"), a constant where they are 0
        and its ends equal ("hold")."""
        p0, m0, p1, m1 = self._piece
        h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
        return h00 * p0 + h10 * m0 + h01 * p1 + h11 * m1

    def _read(self, count: int) -> tuple[np.ndarray, np.ndarray]:
        """Read the last ``count`` records into :attr:`last`; (largest, smallest) acceleration sample among them."""
        result = self.sim.result(last=count)
        acc = result.acc
        out = self.last
        out["sample_time"] = np.array([result.t[-1]])
        out["y"], out["ydot"], out["y_ref"] = result.y[-1], result.ydot[-1], result.y_ref[-1]
        out["p1"], out["p2"], out["p_s"] = result.p1[-1], result.p2[-1], result.p_s[-1:]
        out["force"], out["u_v"], out["u_c"] = result.force[-1], result.u_v[-1], result.u_c[-1]
        out["acc"] = acc[-1]
        if self.system == "hexapod":
            out["pose"] = result.pose[-1]
            motion = point_motion(result, self.head)
            out["head_f"], out["head_w"] = motion.specific_force[-1], motion.angular_velocity[-1]
        return acc.max(axis=0), acc.min(axis=0)


def peak_hold_reversal_peaks(sample_time: np.ndarray, acc_max: np.ndarray, acc_min: np.ndarray, run,
                             delay: float) -> tuple[np.ndarray, np.ndarray]:
    """Each reversal's peak as a master stepping an FMU sees it, beside the run's: the largest distance of the
    steps' acceleration extremes ``acc_max``, ``acc_min`` (M,) [m/s^2] (the peak hold, sampled at
    ``sample_time`` (M,) [s]) from the fitted fundamental of ``run`` (a SimulationResult of the same motion,
    :func:`hexsim.studies.metrics.run_smoothness`), within the metrics' ±0.1 s of each of its reversals, the
    FMU's samples moved back by ``delay`` [s] (one communication step when the setpoints are interpolated).
    Returns (the FMU's peaks (R,), the run's peaks (R,)) [m/s^2]."""
    smooth = run_smoothness(run)
    t = np.asarray(sample_time) - delay
    fit = np.interp(t, smooth.t, smooth.fit)
    distance = np.maximum(np.abs(np.asarray(acc_max) - fit), np.abs(np.asarray(acc_min) - fit))
    return np.array([distance[np.abs(t - tr) <= 0.1].max() for tr in smooth.reversal_times]), smooth.reversal_peaks

