"""Closed-loop replay of a hexapod measurement log (issue 4): the logged leg setpoints through the
model's own loop, every channel compared.

Why closed loop for the hexapod: the six legs share one platform, so a leg cannot be replayed on its own
the way :func:`hexsim.measured.replay.replay` replays the single actuator in windows, and an open-loop valve
replay of the whole platform drifts within a fraction of a second. The replay therefore runs the full
chain of :func:`hexsim.engine.runner.simulate` (compiled engine, 10 kHz): the piston setpoints are the
logged ``leg{i}_ref_m`` (held between rows), the P controller has the logged K_p and rate, and the
compensation the machine applied is fed forward as logged, U_c = u_v - K_p (r - y) from the logged
valve commands, positions and setpoints (a compensator that acted on the machine is not in the model).
The run starts from the model's neutral pose at rest; the first :data:`SETTLE_S` are not scored.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from hexsim.control.scenario import Scenario
from hexsim.engine.config import RunConfig, SimulationResult
from hexsim.engine.runner import simulate
from hexsim.errors import InputError
from hexsim.measured.measurement import MeasurementLog
from hexsim.measured.residuals import noise_of
from hexsim.plant.effects import Effects, LegChange
from hexsim.plant.model import check_formulation
from hexsim.plant.params import ControllerParams, HydraulicParams
from hexsim.signals import near_reversals, savgol, zero_order_hold

#: Start of the log left out of the error [s]: the model starts at rest in the neutral pose.
SETTLE_S = 0.5
N_LEGS = 6
#: Channel groups: name -> (log columns, unit, floor of the normalising scale).
GROUPS = {
    "position": ([f"leg{i}_pos_m" for i in range(1, N_LEGS + 1)], "m", 1e-4),
    "p1": ([f"leg{i}_p1_Pa" for i in range(1, N_LEGS + 1)], "Pa", 1e4),
    "p2": ([f"leg{i}_p2_Pa" for i in range(1, N_LEGS + 1)], "Pa", 1e4),
    "p_s": (["ps_Pa"], "Pa", 1e4),
    "acceleration": ([f"platform_acc_{a}_mps2" for a in "xyz"], "m/s^2", 0.05),
}


def replay_hexapod(log: MeasurementLog, hydraulics: HydraulicParams | None = None,
                   effects: Effects | None = None, timestep: float | None = None,
                   leg_changes: tuple[LegChange, ...] = (), until_s: float | None = None,
                   model: str = "platform") -> SimulationResult:
    """The closed-loop replay of a hexapod log (see the module doc) as a simulation result sampled at
    t = i ms; ``leg_changes``: legs with their own parameters; ``until_s``: replay only the first this
    many seconds of the log (the replay starts at rest, so a prefix is the same run cut short); ``model``:
    the hexapod formulation (``"platform"`` or ``"full"``). Raises InputError if the log is not a hexapod
    log or lacks the leg setpoints and valve commands, WorkspaceError / PhysicsError as
    :func:`hexsim.engine.runner.simulate`."""
    if log.system != "hexapod":
        raise InputError(f"{log.path}: closed-loop hexapod replay needs a hexapod log (this is {log.system})")
    _check_closed_loop(log)
    c = log.columns
    need = [f"leg{i}_{k}" for i in range(1, N_LEGS + 1) for k in ("ref_m", "valve_cmd_V", "pos_m")]
    missing = [name for name in need if name not in c]
    if missing:
        raise InputError(f"{log.path}: missing column {missing[0]!r}, needed for the closed-loop replay")
    t = log.time - log.time[0]
    ref = np.stack([c[f"leg{i}_ref_m"] for i in range(1, N_LEGS + 1)], axis=1)
    u_v = np.stack([c[f"leg{i}_valve_cmd_V"] for i in range(1, N_LEGS + 1)], axis=1)
    pos = np.stack([c[f"leg{i}_pos_m"] for i in range(1, N_LEGS + 1)], axis=1)
    controller = ControllerParams(kp=log.kp, rate_hz=log.controller_rate_hz, position_noise=0.0)
    duration = math.floor((t[-1] + 1.0 / log.sample_rate_hz) * 1000.0 + 1e-6) / 1000.0
    if until_s is not None:
        duration = min(duration, math.ceil(until_s * 1000.0 - 1e-6) / 1000.0)
    ticks = np.arange(int(math.ceil(duration * controller.rate_hz)) + 1) / controller.rate_hz
    held = lambda x: zero_order_hold(t, x, ticks)  # noqa: E731
    feedforward = held(u_v) - controller.kp * (held(ref) - held(savgol(pos, log.sample_rate_hz, FEEDFORWARD_SMOOTH_S, axis=0)))
    scenario = Scenario(f"log:{log.path.name}", "hexapod", duration, 2, 1.0, 0.0, legs=(t, ref))
    machine = dataclasses.replace(log.machine, hydraulics=hydraulics or log.machine.hydraulics, controller=controller,
                                  effects=effects or log.machine.effects)
    config = RunConfig(scenario, machine, feedforward=feedforward, timestep=timestep, leg_changes=tuple(leg_changes),
                       model=model)
    return simulate(config)


def _check_closed_loop(log: MeasurementLog) -> None:
    """InputError for an open-loop hexapod log: the hexapod replay is closed loop."""
    if log.open_loop:
        raise InputError(f"{log.path}: an open-loop hexapod log (controller type none): the hexapod replay is closed "
                         f"loop; replay it as a run instead: hexsim run valve:{log.path}")


#: [s] Window of the zero-phase smoothing (Savitzky–Golay, cubic) of the logged positions in the
#: feedforward. Unsmoothed, the position sensor's noise enters the replay's valve command as
#: K_p × noise (0.4 mV for 2 µm) and rings the 28–55 Hz oil-spring modes the logged run did not have.
FEEDFORWARD_SMOOTH_S = 0.021


#: Length of the scored segments [s]: even segments fit, odd segments are held out.
SEGMENT_S = 0.25


#: [m] How far a leg's position offset may lie from the legs' common offset (their median) and still be
#: calibrated as the sensor's in a closed-loop replay. The P controller holds the *measured* position on the
#: setpoint on the machine as in the model, so a transducer's offset does not show between log and replay;
#: what does is a static tracking error (a valve null offset u_0 holds the piston u_0 / K_p off, 1 mm at
#: 0.2 V and 200 V/m; a flow the leg needs at rest), which is physics the effects are asked to explain. The
#: common part, alike on all six legs, stays calibrated (the model's common mismatch: an unmodelled spool lag
#: offsets all legs of a heave alike). ``hexsim validate`` sets the limit per log from its nominal replay
#: (:func:`hexsim.measured.identify.static_offset_limit`: :data:`STATIC_SPREAD` times the legs' spread about
#: their median, within :data:`CLOSED_LOOP_OFFSET_FLOOR_M` … this), because within the limit an effect's
#: static part is free (a null offset fitted through a 0.1 mm limit came back 0.018 V high at 200 V/m). A
#: calibration (:mod:`hexsim.measured.calibration`) frees it and turns each leg's static error off the
#: common one into that leg's valve null offset.
CLOSED_LOOP_OFFSET_M = 1e-4
CLOSED_LOOP_OFFSET_FLOOR_M = 1e-5
STATIC_SPREAD = 3.0


class HexapodProblem:
    """The identifier's view of a hexapod log (the interface of :class:`hexsim.measured.scoring.Problem`): one
    closed-loop replay of the whole log per model, its channels cut into consecutive segments of
    :data:`SEGMENT_S` after :data:`SETTLE_S`, each channel an array (segments, samples, signals)
    (signals: the six legs, the supply, the three accelerometer axes). Even segments fit, odd ones are
    held out."""

    windowed = False  # one replay from the neutral pose: a position offset is an offset
    #: [m] how far off the legs' common offset a leg's position offset is calibrated (the rest is left in the
    #: residual); validate sets it per log (:func:`hexsim.measured.identify.static_offset_limit`)
    position_offset_limit = CLOSED_LOOP_OFFSET_M

    def __init__(self, log: MeasurementLog, max_segments: int | None = None, model: str = "platform") -> None:
        from hexsim.measured.replay import nominal_plant

        check_formulation(model)
        _check_closed_loop(log)
        self.log, self.model = log, model
        fs = log.sample_rate_hz
        t = log.time - log.time[0]
        first = int(np.searchsorted(t, SETTLE_S - 1e-9))
        seg = int(round(SEGMENT_S * fs))
        count = (len(t) - 1 - first) // seg  # the last row may fall past the replay's last sample
        if max_segments is not None:
            count = min(count, max_segments)
        if count < 4:
            raise InputError(f"{log.path}: the log is too short to identify from: needs {SETTLE_S:g} s plus four "
                             f"segments of {SEGMENT_S:g} s")
        self.rows = first + np.arange(count * seg)
        self.shape = (count, seg)
        self.fit_rows = np.arange(0, count, 2)
        self.test_rows = np.arange(1, count, 2)
        self.settle = 0
        self.channels = [g for g, (cols, _, _) in GROUPS.items() if all(c in log.columns for c in cols)]
        self.measured = {g: self._cut(np.stack([log.columns[c] for c in GROUPS[g][0]], axis=1))
                         for g in self.channels}
        self.scales = {g: max(float(np.std(self.measured[g])), GROUPS[g][2]) for g in self.channels}
        self.log_noise = {g: noise_of(self.measured[g], g) for g in self.channels}
        self.nominal = nominal_plant(log)
        # the replay runs to the last scored row (a prefix of the log for a view of fewer segments)
        self.until_s = float(t[self.rows[-1]]) + 2.0 / fs

    def prefix(self, segments: int) -> "HexapodProblem":
        """The same problem on the first ``segments`` segments only (the replay cut short there): a
        cheaper problem to search parameters on."""
        short = HexapodProblem(self.log, max_segments=segments, model=self.model)
        short.position_offset_limit = self.position_offset_limit
        return short

    def fit_windows(self) -> "HexapodProblem":
        """Itself: one closed-loop replay of the log makes every segment (:class:`ReplayProblem`)."""
        return self

    @property
    def segments(self) -> int:
        return self.shape[0]

    def _cut(self, x: np.ndarray) -> np.ndarray:
        return x[self.rows].reshape(*self.shape, x.shape[1])

    def simulate(self, model, dt: float = 1e-4) -> dict[str, np.ndarray]:
        """Replayed channels, name -> (segments, samples, signals), physical units."""
        result = replay_hexapod(self.log, model.hydraulics, model.effects, timestep=dt,
                                leg_changes=model.leg_changes, until_s=self.until_s, model=self.model)
        t = self.log.time - self.log.time[0]
        sim = {"position": result.y, "p1": result.p1, "p2": result.p2, "p_s": result.p_s[:, None],
               "acceleration": result.acc}
        return {g: self._cut(np.stack([np.interp(t, result.t, sim[g][:, k]) for k in range(sim[g].shape[1])],
                                      axis=1)) for g in self.channels}

    def replay_error(self, model) -> dict[str, float]:
        """RMS per channel [SI] of the replay's own error, the part of the numerical tolerance a step
        refinement does not see: ``model``'s replay of this log, written as a log (1 kHz) with white noise
        of the log's position noise on its positions (the same noise density: sigma sqrt(1 kHz / the log's
        rate); seeded), replayed again and compared with the noise-free replay over the scored segments.
        The model reproduces that log exactly but for what the replay reconstructs: the controller's
        input from the smoothed logged positions (:data:`FEEDFORWARD_SMOOTH_S`), whose noise the replay's
        valve command carries as K_p times the smoothed noise, and the rows held between controller
        samples. On hexsim's own noise-free 1 Hz heave log: 0.0027 m/s^2 RMS over the accelerometer's
        axes (the step's Richardson estimate 0.0010 m/s^2); with 10 µm of position noise the replay's P1
        scatters by 0.054 bar against 0.02 bar of pressure-sensor noise."""
        import dataclasses

        from hexsim.outputs.logio import log_columns

        own = replay_hexapod(self.log, model.hydraulics, model.effects, leg_changes=model.leg_changes,
                             until_s=self.until_s, model=self.model)
        clean = log_columns(own)
        sigma = self.log_noise["position"] * math.sqrt(1000.0 / self.log.sample_rate_hz)
        rng = np.random.default_rng(0)
        noisy = {name: x + rng.normal(0.0, sigma, x.shape) if name.endswith("_pos_m") else x
                 for name, x in clean.items()}
        truth = HexapodProblem(dataclasses.replace(self.log, columns=clean, sample_rate_hz=1000.0), model=self.model)
        again = HexapodProblem(dataclasses.replace(self.log, columns=noisy, sample_rate_hz=1000.0), model=self.model)
        sim = again.simulate(model)
        return {g: float(np.sqrt(np.mean((sim[g] - truth.measured[g]) ** 2))) for g in self.channels}

    # what the report needs (hexsim.measured.validation); the residual analysis looks at one leg (position, P1:
    # :attr:`focus_leg`, the identifier sets it to the leg that stands out, else leg 1), the supply and the
    # platform's vertical acceleration, with that leg's motion state
    focus_leg = 1
    screens = True  # the whole log per model: candidates screened on the first segments (prefix)
    replay_mode = ("closed loop: the logged leg setpoints through the model's P control (logged K_p and rate) "
                   "plus the logged compensation u_v - K_p (r - y), from the neutral pose at rest")
    scored = f"segments of {SEGMENT_S:g} s after the first {SETTLE_S:g} s, all legs / axes"

    @property
    def units(self) -> dict[str, str]:
        return {g: GROUPS[g][1] for g in self.channels}

    @property
    def window_doc(self) -> dict:
        return {"count": self.shape[0], "length_s": SEGMENT_S, "settle_s": SETTLE_S, "fit": "even segments",
                "held_out": "odd segments"}

    def analysis_view(self, res: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        view = {"position": self.focus_leg - 1, "p1": self.focus_leg - 1, "p2": self.focus_leg - 1, "p_s": 0,
                "acceleration": 2}
        return {g: r[:, :, view[g]] for g, r in res.items()}

    def motion_state(self):
        from hexsim.measured.replay import measured_velocity

        c, leg = self.log.columns, self.focus_leg
        pos = c[f"leg{leg}_pos_m"]
        vel = measured_velocity(self.log, pos)
        near = near_reversals(self.log.time, vel)
        take = lambda x: x[self.rows].reshape(self.shape)  # noqa: E731
        return take(c[f"leg{leg}_valve_cmd_V"]), take(vel), take(pos), take(near)

    def sample_times(self) -> np.ndarray:
        return self.log.time[self.rows].reshape(self.shape)


def payload_from_statics(p1_offsets: np.ndarray, hydraulics: HydraulicParams | None = None, geometry=None) -> dict:
    """The payload change that explains a constant P1 difference per leg, by the statics of the platform
    at its neutral pose: leg forces dF_i = dP1_i A1 along the unit leg vectors n_i must carry the weight
    dm g of a mass at (x, y) in the platform frame: sum dF_i n_i = (0, 0, dm g) and
    sum a_i x dF_i n_i = (y dm g, -x dm g, 0) (a_i: platform anchors relative to the platform origin).

    ``p1_offsets`` (6,) [Pa]: measured minus replayed P1 of each leg (the calibration offsets of the
    nominal model). Returns mass_kg, x_m, y_m and ``inconsistency``: the part of the legs' wrench that no
    payload produces (horizontal force, yaw torque, as a fraction of the vertical force); a small value
    says the six offsets are one load, not six sensor offsets. Geometry and gravity from the MJCF of
    ``geometry`` (a machine file's hexapod section; None: the Micro Motion System)."""
    from hexsim.control.kinematics import HexapodGeometry
    from hexsim.plant.model import load_model

    hyd = hydraulics or HydraulicParams()
    m = load_model("hexapod", geometry=geometry)
    geom = HexapodGeometry.from_model(m)
    legs = geom.leg_vectors(np.zeros(6))[0]
    n = legs / np.linalg.norm(legs, axis=1, keepdims=True)
    arms = geom.platform  # platform frame = world orientation at the neutral pose
    df = np.asarray(p1_offsets, dtype=float) * hyd.area_bottom
    force = (df[:, None] * n).sum(axis=0)
    torque = np.cross(arms, df[:, None] * n).sum(axis=0)
    g = -float(m.opt.gravity[2])
    weight = force[2]
    mass = weight / g
    if abs(weight) < 1e-9:
        return {"mass_kg": 0.0, "x_m": 0.0, "y_m": 0.0, "inconsistency": float("inf")}
    return {"mass_kg": float(mass), "x_m": float(-torque[1] / weight), "y_m": float(torque[0] / weight),
            "inconsistency": float(np.linalg.norm([force[0], force[1], torque[2] / 0.5]) / abs(weight))}
