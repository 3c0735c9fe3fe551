"""Model-predictive motion cueing: the platform's accelerations chosen, step by step, to make the driver
sense what the vehicle gives, within the platform's envelope (Dagdelen, Reymond, Kemeny, Bordier & Maizi
2009, "Model-based predictive motion cueing strategy for vehicle driving simulators", Control Engineering
Practice 17; Garrett & Best 2013; the vestibular models of Telban & Cardullo 2005, NASA/CR-2005-213747).

Per MPC step (``step_s``, default 30 ms) a quadratic programme over ``horizon_s`` chooses the platform's
piecewise-constant accelerations; the first step's are applied and the rest discarded (receding horizon).
Its model, linear about the neutral pose (small angles, Euler rates as body rates):

* **the platform** (16 states): translation (x, y, z) and rotation (roll, pitch, yaw) as double integrators
  of the chosen accelerations, plus a **tilt-coordination** angle in roll and pitch with its own rate and
  acceleration, added to the rotation: gravity along the tilted platform supplies sustained surge and sway
  (f_x = -g pitch, f_y = g roll, the signs of :mod:`hexsim.control.washout`), and the tilt's rate and
  acceleration are held below the canals' threshold as hard constraints (Benson et al. 1989: 2 deg/s; the
  defaults 1.5 deg/s and 4 deg/s^2) so the tilt itself is not sensed as a rotation;
* **the head**: the specific force at ``head_m`` (the origin's acceleration plus the angular acceleration
  times the lever arm) and the body rates;
* **the vestibular organs** (:func:`hexsim.control.vestibular.otolith`, :func:`~.canal`, 15 states): the
  cost is the squared difference between what they sense of the platform and of the vehicle, per axis in
  units of Benson's detection thresholds (:data:`VESTIBULAR_THRESHOLDS`), so that an error is weighed by how
  well it is felt; small weights pull the platform back to neutral (position, velocity, angles) and keep
  the accelerations modest.

Constraints, from the machine (:class:`PlatformLimits`, built by
:func:`hexsim.studies.acceptance.platform_limits` from the machine file as ``hexsim accept``'s envelope
is): each leg's extension through the kinematics' Jacobian at neutral within its stroke, each leg's
velocity within what the flow curve passes at full valve opening against the rest pressures, each leg's
force (the legs' effective inertia times their accelerations) within what the supply and tank pressures
can add or take away, each a ``margin`` of the limit.

**No false cue** (soft constraints, DAQP's: kept where they can be, given up at a cost where the hard ones leave
no room): at every step of the horizon each axis' sensed cue stays within ``threshold_share`` (0.9) of the level
the organ must pass to be perceived (:data:`SENSED_THRESHOLDS`, what the cue report counts false cues against)
wherever the vehicle's own sensed motion is below that level, or on the vehicle's side where it is above it. A
quadratic cost alone trades a false cue for a smaller error elsewhere (a tilt unwound by a pitch rotation the
canals sense, a roll beyond the vehicle's).

The defaults were chosen on the manoeuvre library of ``examples/vehicle_cueing.py`` cued on the ideal platform
(docs/motion-cueing.md gives the table): ``scale_specific_force`` 0.3, because the Micro Motion System's 8 deg of
tilt sustain 1.37 m/s^2 where a car brakes and corners at 3-4 m/s^2 (at full scale the programme spends the
envelope on magnitude it cannot reach); ``horizon_s`` 2.5, because a tilt of 8 deg takes 5 s to unwind below the
canals' threshold and the programme must see a sustained cue's end coming. The library's false cues, summed over
its axes: 21.0 s with full scale, a 1.5 s horizon and no constraints (the defaults before), 5.7 s at 0.3 and
2.5 s without the constraints, 0.3 s with them.

The vehicle's future is known over the horizon (``preview=True``: a recorded or simulated drive, offline)
or held at its present value (``preview=False``: what an online cueing knows). The programme (144 variables at
the default step and horizon, 2136 constraint rows, dense) is solved to optimality by DAQP (Arnström, Bemporad &
Axehill, "A dual active-set solver for embedded quadratic programming using recursive LDLᵀ updates", IEEE TAC
67(8), 2022), a solver made for MPC's small dense programmes (docs/motion-cueing.md gives its times; OSQP, used
first, took 8.5 ms on average and 130 ms at most at a tolerance of 1e-4, at a 50 ms step and a 1.5 s horizon
without the false-cue rows, and its answers left the constraints violated by up to 0.125).

The step: the accelerations are held for a step, so a vehicle's motion faster than the step's Nyquist
frequency is not cued. At 50 ms (80 variables, 1 ms a programme) the road bumps of examples/vehicle_cueing.py
(a car over a rough road and its joints at some 10 Hz) were sensed at a correlation of 0.45 in surge, 0.83 in
heave, 0.50 in pitch; at 40 ms 0.81, 0.90, 0.59; at 30 ms 0.98, 0.97, 0.86 (19x real time with the hydraulics
and the adaptive compensator); at 24 ms 0.99, 0.98, 0.90 (11x). The stop, the lane change, the slalom and the
take-off cue the same at 30 ms as at 50 ms (every correlation within 0.04).
"""

from __future__ import annotations

import math
import pathlib
import time
from dataclasses import asdict, dataclass, field, fields

import numpy as np
from scipy.linalg import block_diag
from scipy.signal import cont2discrete, tf2ss

from hexsim.control.vestibular import (
    AXES,
    VESTIBULAR_THRESHOLDS,
    canal,
    otolith,
    sensed_level,
)
from hexsim.errors import InputError
from hexsim.tables import read_settings

G = 9.81  # [m/s^2] the vehicle's 1 g, as the classical washout's

#: the sensed error's units per axis (x, y, z, roll, pitch, yaw): Benson's detection thresholds
SENSED_SCALE = np.array([VESTIBULAR_THRESHOLDS[axis] for axis in AXES])
#: the level each organ's output must exceed to be perceived (its peak output to Benson's threshold stimulus,
#: :func:`hexsim.control.vestibular.sensed_level`): what the cue report counts a false cue against
SENSED_THRESHOLDS = np.array([sensed_level(axis, VESTIBULAR_THRESHOLDS[axis]) for axis in AXES])
#: DAQP's sense of a soft constraint (allowed to be violated where it must, at a cost)
DAQP_SOFT = 8


@dataclass(frozen=True)
class PlatformLimits:
    """The platform's envelope about its neutral pose as the MPC's linear constraints.

    ``jacobian`` (6, 6): the legs' extension per unit pose (x, y, z [m]; roll, pitch, yaw [rad]) at neutral;
    ``stroke_lo``, ``stroke_hi`` (6,) [m]: each leg's extension range about its neutral length (lo < 0 < hi);
    ``velocity_extend``, ``velocity_retract`` (6,) [m/s] > 0: each leg's speed at full valve opening;
    ``force_map`` (6, 6) [N per m/s^2 or rad/s^2]: the legs' forces per unit pose acceleration (their
    effective inertia times the Jacobian); ``force_up``, ``force_down`` (6,) [N] > 0: the force each leg can
    add to and take away from its static load; ``source``: the machine they come from."""

    jacobian: np.ndarray
    stroke_lo: np.ndarray
    stroke_hi: np.ndarray
    velocity_extend: np.ndarray
    velocity_retract: np.ndarray
    force_map: np.ndarray
    force_up: np.ndarray
    force_down: np.ndarray
    source: str = "python"

    def __post_init__(self) -> None:
        shapes = {"jacobian": (6, 6), "force_map": (6, 6)}
        for f in fields(self):
            if f.name == "source":
                continue
            value = np.asarray(getattr(self, f.name), dtype=float)
            if value.shape != shapes.get(f.name, (6,)) or not np.all(np.isfinite(value)):
                raise InputError(f"platform limits {f.name}: expected finite numbers of shape "
                                 f"{shapes.get(f.name, (6,))}, got shape {value.shape}")
            object.__setattr__(self, f.name, value)
        for name in ("velocity_extend", "velocity_retract", "force_up", "force_down", "stroke_hi"):
            if np.any(getattr(self, name) <= 0):
                raise InputError(f"platform limits {name}: every leg's must be positive, got {getattr(self, name)}")
        if np.any(self.stroke_lo >= 0):
            raise InputError(f"platform limits stroke_lo: every leg's must be below its neutral (< 0), "
                             f"got {self.stroke_lo}")


@dataclass(frozen=True)
class MPCParams:
    """The MPC cueing's parameters (module doc); a JSON object with any subset of them (:meth:`from_file`).

    ``step_s`` [s] the MPC step, ``horizon_s`` [s] its horizon; ``scale_specific_force``,
    ``scale_angular_velocity`` [-] (x, y, z) / (roll, pitch, yaw): the vehicle's motion scaled before it is
    the reference (1: the vehicle's own); ``weight_sensed`` (6,) [-] on the sensed error in threshold units
    (x, y, z, roll, pitch, yaw); ``weight_position`` [1/m^2], ``weight_velocity`` [s^2/m^2],
    ``weight_angle`` [1/rad^2], ``weight_acceleration`` [s^4/m^2]: the pull back to neutral and the effort;
    ``tilt_rate_limit_degps``, ``tilt_acceleration_limit_degps2``, ``tilt_limit_deg``: the tilt channel's
    bounds; ``margin`` (0, 1]: the share of each leg's stroke, speed and force the cueing may use;
    ``threshold_share`` [0, 1]: the share of each axis' perception threshold the platform's sensed cue may reach
    where the vehicle's is below it or of the other sign (soft constraints, module doc; 0: none);
    ``head_m`` (3,) [m, platform frame]: the driver's head (None: the machine's); ``preview``: the vehicle's
    future over the horizon known (offline) or held (online)."""

    step_s: float = 0.03
    horizon_s: float = 2.5
    scale_specific_force: tuple[float, float, float] = (0.3, 0.3, 0.3)
    scale_angular_velocity: tuple[float, float, float] = (1.0, 1.0, 1.0)
    weight_sensed: tuple[float, ...] = (1.0, 1.0, 1.0, 10.0, 10.0, 10.0)
    weight_position: float = 2000.0
    weight_velocity: float = 20.0
    weight_angle: float = 20.0
    weight_acceleration: float = 0.01
    tilt_rate_limit_degps: float = 1.5
    tilt_acceleration_limit_degps2: float = 4.0
    tilt_limit_deg: float = 8.0
    margin: float = 0.8
    threshold_share: float = 0.9
    head_m: tuple[float, float, float] | None = None
    preview: bool = True
    source: str = field(default="defaults", compare=False)

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name in ("source", "preview") or (f.name == "head_m" and value is None):
                continue
            size = {"scale_specific_force": 3, "scale_angular_velocity": 3, "weight_sensed": 6, "head_m": 3}.get(f.name)
            if size is not None:
                if not (isinstance(value, (list, tuple)) and len(value) == size and all(
                        isinstance(v, (int, float)) and math.isfinite(v) for v in value)):
                    raise InputError(f"mpc cueing {f.name}: expected {size} numbers, got {value!r}")
                if f.name != "head_m" and any(v < 0 for v in value):
                    raise InputError(f"mpc cueing {f.name}: expected non-negative numbers, got {list(value)!r}")
                object.__setattr__(self, f.name, tuple(float(v) for v in value))
            elif f.name == "threshold_share":
                if not (isinstance(value, (int, float)) and 0.0 <= value <= 1.0):
                    raise InputError(f"mpc cueing threshold_share: expected a number from 0 (no constraint) to 1, "
                                     f"got {value!r}")
            elif not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise InputError(f"mpc cueing {f.name}: expected a positive number, got {value!r}")
        if not isinstance(self.preview, bool):
            raise InputError(f"mpc cueing preview: expected true or false, got {self.preview!r}")
        if self.margin > 1:
            raise InputError(f"mpc cueing margin: {self.margin:g} is more than the whole envelope (at most 1)")
        if self.horizon_s < 2 * self.step_s:
            raise InputError(f"mpc cueing horizon_s: {self.horizon_s:g} s is shorter than two steps of {self.step_s:g} s")
        if self.tilt_limit_deg >= 30:
            raise InputError(f"mpc cueing tilt_limit_deg: {self.tilt_limit_deg:g} deg is beyond tilt coordination's "
                             f"small-angle use (< 30)")

    @property
    def steps(self) -> int:
        """Steps in the horizon."""
        return int(round(self.horizon_s / self.step_s))

    @classmethod
    def from_file(cls, path: str | pathlib.Path) -> "MPCParams":
        """The parameters a JSON object gives (any subset; the rest default). Raises InputError naming the
        file and the key for an unknown key or a bad value."""
        return read_settings(cls, path, "mpc cueing")

    def document(self) -> dict:
        """The parameters as a JSON-ready dict (the file's form), with the algorithm's name."""
        doc = {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items() if k != "source"}
        return {"algorithm": "mpc", **doc}


# -- the linear model -----------------------------------------------------------------------------------------

#: state layout: translation position (0:3), velocity (3:6); rotation angle (6:9), rate (9:12); tilt angle
#: (12:14, roll and pitch), tilt rate (14:16); then the otoliths (3 x 2) and the canals (3 x 3)
N_PLATFORM = 16
#: input layout: translational acceleration (0:3), rotational acceleration (3:6), tilt acceleration (6:8)
N_INPUT = 8


def _head_force(head: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(Sx (3, 16), Su (3, 8)): the specific force less 1 g at the head, linear in the platform's state and
    input: a + alpha x r (alpha the rotation's and the tilt's), plus gravity along the tilted axes."""
    sx, su = np.zeros((3, N_PLATFORM)), np.zeros((3, N_INPUT))
    su[:, 0:3] = np.eye(3)
    rx, ry, rz = head
    cross = np.array([[0.0, rz, -ry], [-rz, 0.0, rx], [ry, -rx, 0.0]])  # alpha x r = cross @ alpha
    su[:, 3:6] = cross
    su[:, 6:8] = cross[:, 0:2]
    sx[0, 7], sx[0, 13] = -G, -G  # f_x = -g pitch (rotation and tilt)
    sx[1, 6], sx[1, 12] = G, G  # f_y = g roll
    return sx, su


def continuous_model(head: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A (n, n), B (n, 8), C (6, n)) of the platform, head and vestibular organs (module doc): C gives the
    sensed specific force (3, m/s^2 less 1 g) and the sensed body rates (3, rad/s)."""
    oa, ob, oc, od = tf2ss(otolith().num, otolith().den)
    ca, cb, cc, cd = tf2ss(canal().num, canal().den)
    if np.any(od):
        raise AssertionError("the otolith model must be strictly proper")
    n_o, n_c = oa.shape[0], ca.shape[0]
    n = N_PLATFORM + 3 * n_o + 3 * n_c
    a, b, c = np.zeros((n, n)), np.zeros((n, N_INPUT)), np.zeros((6, n))
    for k in range(3):
        a[k, 3 + k] = a[6 + k, 9 + k] = 1.0
        b[3 + k, k] = b[9 + k, 3 + k] = 1.0
    for k in range(2):
        a[12 + k, 14 + k] = 1.0
        b[14 + k, 6 + k] = 1.0
    sx, su = _head_force(head)
    rate = np.zeros((3, n))  # body rates: rotation rate plus tilt rate
    rate[:, 9:12] = np.eye(3)
    rate[0, 14] = rate[1, 15] = 1.0
    for k in range(3):
        o = slice(N_PLATFORM + n_o * k, N_PLATFORM + n_o * (k + 1))
        a[o, o] = oa
        a[o, :N_PLATFORM] += ob @ sx[k:k + 1]
        b[o] += ob @ su[k:k + 1]
        c[k, o] = oc[0]  # strictly proper (od = 0)
        q = slice(N_PLATFORM + 3 * n_o + n_c * k, N_PLATFORM + 3 * n_o + n_c * (k + 1))
        a[q, q] = ca
        a[q] += cb @ rate[k:k + 1]
        c[3 + k, q] = cc[0]
        c[3 + k] += cd[0, 0] * rate[k]
    return a, b, c


@dataclass
class _Prediction:
    """Condensed prediction over the horizon: a quantity z stacked over steps 1..N is F x0 + H U."""

    phi: np.ndarray  # (N n, n)
    gamma: np.ndarray  # (N n, N m)

    def of(self, rows: np.ndarray, steps: int) -> tuple[np.ndarray, np.ndarray]:
        """(F, H) of the output rows (p, n) stacked over the steps."""
        n = rows.shape[1]
        f = np.vstack([rows @ self.phi[k * n:(k + 1) * n] for k in range(steps)])
        h = np.vstack([rows @ self.gamma[k * n:(k + 1) * n] for k in range(steps)])
        return f, h


def _prediction(ad: np.ndarray, bd: np.ndarray, steps: int) -> _Prediction:
    n, m = bd.shape
    phi = np.zeros((steps * n, n))
    gamma = np.zeros((steps * n, steps * m))
    power = np.eye(n)
    blocks = []
    for k in range(steps):
        blocks.append(power @ bd)  # A^k B
        power = ad @ power
        phi[k * n:(k + 1) * n] = power  # x_{k+1} = A^{k+1} x0 + sum_j A^{k-j} B u_j
        for j in range(k + 1):
            gamma[k * n:(k + 1) * n, j * m:(j + 1) * m] = blocks[k - j]
    return _Prediction(phi, gamma)


#: A bound DAQP takes as none (its DAQP_INF).
DAQP_INFINITY = 1e30


def move_blocks(steps: int) -> list[tuple[int, int]]:
    """(first step, length) of the blocks the horizon's ``steps`` are held in: single steps first, then blocks
    one step longer every second block, the last cut to fit."""
    out, first, length = [], 0, 1
    while first < steps:
        take = min(length, steps - first)
        out.append((first, take))
        first += take
        length += len(out) % 2 == 0 and len(out) >= 2
    return out


class MPCCueing:
    """The receding-horizon controller (module doc) for one platform and parameter set: :meth:`step` takes the
    state and the sensed reference over the horizon and returns the accelerations to apply."""

    def __init__(self, limits: PlatformLimits, params: MPCParams, head_m) -> None:
        self.limits, self.params = limits, params
        head = np.asarray(head_m if params.head_m is None else params.head_m, dtype=float)
        a, b, self.c = continuous_model(head)
        self.continuous = (a, b)
        self.n = a.shape[0]
        ad, bd, *_ = cont2discrete((a, b, np.eye(self.n), np.zeros((self.n, N_INPUT))), params.step_s, "zoh")
        pred = _prediction(ad, bd, params.steps)
        # move blocking (Cagienard et al. 2007): the accelerations held over blocks that lengthen along the
        # horizon, U = T V, so the programme has a few dozen variables rather than steps x 8
        self.blocks = move_blocks(params.steps)
        m = N_INPUT
        hold = np.zeros((params.steps * m, len(self.blocks) * m))
        for b, (first, length) in enumerate(self.blocks):
            for k in range(first, first + length):
                hold[k * m:(k + 1) * m, b * m:(b + 1) * m] = np.eye(m)
        self.variables = len(self.blocks) * m
        self.hessian = np.ascontiguousarray(self._cost(pred, hold))
        self.constraint = np.ascontiguousarray(self._constraints(pred, hold))
        self.infeasible = 0

    def _cost(self, pred: _Prediction, hold: np.ndarray) -> np.ndarray:
        """The programme's Hessian (variables, variables); keeps the maps its gradient needs per step: the
        sensed error in threshold units, the pull of position, velocity and angles to neutral, the effort."""
        params, steps = self.params, self.params.steps
        self.w_sensed = np.asarray(params.weight_sensed) / SENSED_SCALE
        self.f_sensed, h_sensed = pred.of(np.diag(self.w_sensed) @ self.c, steps)
        pull = np.zeros((14, self.n))  # translation, its velocity, rotation, its rate, tilt (not its rate)
        pull[0:3, 0:3] = math.sqrt(params.weight_position) * np.eye(3)
        pull[3:6, 3:6] = math.sqrt(params.weight_velocity) * np.eye(3)
        pull[6:9, 6:9] = math.sqrt(params.weight_angle) * np.eye(3)
        pull[9:12, 9:12] = math.sqrt(params.weight_velocity) * np.eye(3)
        pull[12:14, 12:14] = math.sqrt(params.weight_angle) * np.eye(2)
        self.f_pull, h_pull = pred.of(pull, steps)
        self.h_sensed, self.h_pull = h_sensed @ hold, h_pull @ hold
        effort = np.diag(np.repeat([length for _, length in self.blocks], N_INPUT).astype(float))
        return self.h_sensed.T @ self.h_sensed + self.h_pull.T @ self.h_pull + params.weight_acceleration * effort

    def _constraints(self, pred: _Prediction, hold: np.ndarray) -> np.ndarray:
        """The programme's constraint matrix (rows, variables), its bounds kept: the legs' extension and
        velocity and the tilt's angle, rate and whole roll and pitch at every step (their free response moves
        the bounds per step); the legs' forces and the tilt's acceleration per block."""
        lim, params, share, m = self.limits, self.params, self.params.margin, N_INPUT
        pose, pose_rate = np.zeros((6, self.n)), np.zeros((6, self.n))
        pose[0:3, 0:3], pose[3:6, 6:9] = np.eye(3), np.eye(3)
        pose[3, 12] = pose[4, 13] = 1.0
        pose_rate[0:3, 3:6], pose_rate[3:6, 9:12] = np.eye(3), np.eye(3)
        pose_rate[3, 14] = pose_rate[4, 15] = 1.0
        tilt = np.zeros((6, self.n))  # tilt angle, tilt rate, and the whole roll and pitch angle
        tilt[0:2, 12:14], tilt[2:4, 14:16] = np.eye(2), np.eye(2)
        tilt[4:6, 6:8], tilt[4:6, 12:14] = np.eye(2), np.eye(2)
        self.f_state, h_state = pred.of(np.vstack([lim.jacobian @ pose, lim.jacobian @ pose_rate, tilt]), params.steps)
        angle, rate = math.radians(params.tilt_limit_deg), math.radians(params.tilt_rate_limit_degps)
        hi_state = np.concatenate([share * lim.stroke_hi, share * lim.velocity_extend, [angle, angle, rate, rate],
                                   [angle, angle]])
        lo_state = np.concatenate([share * lim.stroke_lo, -share * lim.velocity_retract, -hi_state[12:]])
        self.lo_state, self.hi_state = np.tile(lo_state, params.steps), np.tile(hi_state, params.steps)
        acc_to_pose = np.zeros((6, m))
        acc_to_pose[0:3, 0:3], acc_to_pose[3:6, 3:6] = np.eye(3), np.eye(3)
        acc_to_pose[3, 6] = acc_to_pose[4, 7] = 1.0
        per_input = np.vstack([lim.force_map @ acc_to_pose, np.eye(m)[6:8]])
        acc = math.radians(params.tilt_acceleration_limit_degps2)
        self.lo_in = np.tile(np.concatenate([-share * lim.force_down, [-acc, -acc]]), len(self.blocks))
        self.hi_in = np.tile(np.concatenate([share * lim.force_up, [acc, acc]]), len(self.blocks))
        rows = [h_state @ hold, block_diag(*[per_input] * len(self.blocks))]
        self.hard = sum(r.shape[0] for r in rows)
        if params.threshold_share > 0:  # the sensed cue at every step, held to the thresholds by :meth:`step`
            self.f_cue, h_cue = pred.of(self.c, params.steps)
            rows.append(h_cue @ hold)
            self.threshold = np.tile(SENSED_THRESHOLDS, params.steps)
        return np.vstack(rows)

    def step(self, x0: np.ndarray, reference: np.ndarray) -> np.ndarray:
        """The accelerations (8,) to apply over the next MPC step from state ``x0`` (n,) for the vehicle's
        sensed motion ``reference`` (N, 6) over the horizon's steps 1..N (m/s^2 less 1 g, rad/s). A programme
        the solver cannot solve to optimality (infeasible bounds, its iteration limit) applies no acceleration
        and is counted."""
        import daqp

        target = (reference * self.w_sensed).ravel()
        e_sensed = self.f_sensed @ x0 - target
        grad = self.h_sensed.T @ e_sensed + self.h_pull.T @ (self.f_pull @ x0)
        free = self.f_state @ x0
        lower, upper = [self.lo_state - free, self.lo_in], [self.hi_state - free, self.hi_in]
        if self.params.threshold_share > 0:
            lo, hi = self._false_cue_bounds(reference)
            free_cue = self.f_cue @ x0  # the sensed cue's free response over the horizon
            lower.append(lo - free_cue)
            upper.append(hi - free_cue)
        lower = np.maximum(np.concatenate(lower), -DAQP_INFINITY)
        upper = np.minimum(np.concatenate(upper), DAQP_INFINITY)
        sense = np.zeros(len(lower), dtype=np.int32)
        sense[self.hard:] = DAQP_SOFT
        x, _, flag, _ = daqp.solve(self.hessian, grad, self.constraint, upper, lower, sense)
        x = np.asarray(x, dtype=float)
        if flag < 1 or not np.all(np.isfinite(x)):  # 1: optimal, 2: optimal with soft constraints
            self.infeasible += 1
            return np.zeros(N_INPUT)
        return x[:N_INPUT]

    def _false_cue_bounds(self, reference: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) (N 6,) of the platform's sensed cue over the horizon for the vehicle's ``reference``
        (N, 6; scaled as the programme is given it, so a cue the scale takes below its threshold is held below it
        too): within ``threshold_share`` of each axis' perception threshold (:data:`SENSED_THRESHOLDS`), except
        on the vehicle's side where its own cue passes the threshold (there any size: a cue smaller than the
        vehicle's is no false cue, and a larger one of the same sign is weighed by the cost)."""
        vehicle, threshold = reference.ravel(), self.threshold
        allowed = self.params.threshold_share * threshold
        lower = np.where(vehicle <= -threshold, -DAQP_INFINITY, -allowed)
        upper = np.where(vehicle >= threshold, DAQP_INFINITY, allowed)
        return lower, upper


def vehicle_reference(vehicle, params: MPCParams, t: np.ndarray, rate_hz: float) -> np.ndarray:
    """What the driver senses of the scaled vehicle motion at times t (N,) [s] on a grid of ``rate_hz``:
    (N, 6) specific force less 1 g [m/s^2] and body rates [rad/s] through the otolith and canal models, from
    rest."""
    f, w = vehicle.at(t)
    stimulus = np.concatenate([(f - np.array([0.0, 0.0, G])) * np.array(params.scale_specific_force),
                               w * np.array(params.scale_angular_velocity)], axis=1)
    return np.concatenate([otolith().apply(stimulus[:, :3], rate_hz), canal().apply(stimulus[:, 3:], rate_hz)], axis=1)


def mpc_washout(vehicle, limits: PlatformLimits, params: MPCParams, head_m, rate_hz: float = 500.0,
                duration: float | None = None):
    """The MPC cueing (module doc) of ``vehicle`` (:class:`hexsim.control.washout.VehicleMotion`) on a platform
    of ``limits`` with the driver's head at ``head_m`` (3,) [m, platform frame] (``params.head_m`` if given),
    sampled at ``rate_hz`` [Hz] (a multiple of 1 / ``params.step_s``) over ``duration`` [s] (default the
    vehicle's). Returns a :class:`hexsim.control.washout.WashoutOutput`: poses (N, 6) relative to neutral, the
    translation, the tilt (roll, pitch) and the rotation; ``limited`` zeros (no saturation stage);
    ``tilt_rate_limited`` the samples at the tilt's rate limit; ``solver``: the programmes solved, those the
    solver left unsolved, the mean and largest solve time [ms] and the real-time factor (MPC step over mean
    solve time). Raises InputError for a rate the MPC step
    does not divide."""
    from hexsim.control.washout import WashoutOutput

    duration = float(vehicle.t[-1]) if duration is None else duration
    sub = int(round(params.step_s * rate_hz))
    if sub < 1 or abs(sub / rate_hz - params.step_s) > 1e-9:
        raise InputError(f"mpc cueing step_s: {params.step_s:g} s is not a whole number of controller samples "
                         f"at {rate_hz:g} Hz")
    t = np.arange(int(math.floor(duration * rate_hz)) + 1) / rate_hz
    steps = params.steps
    t_ref = np.arange(t.size + steps * sub) / rate_hz  # the reference beyond the end: the vehicle's last motion
    reference = vehicle_reference(vehicle, params, np.minimum(t_ref, float(vehicle.t[-1])), rate_hz)
    mpc = MPCCueing(limits, params, head_m)
    fine_a, fine_b, *_ = cont2discrete((*mpc.continuous, np.eye(mpc.n), np.zeros((mpc.n, N_INPUT))), 1.0 / rate_hz,
                                       "zoh")
    x = np.zeros(mpc.n)
    states = np.empty((t.size, mpc.n))
    u = np.zeros(N_INPUT)
    solve_s = []
    for i in range(t.size):
        if i % sub == 0:
            ahead = i + sub * np.arange(1, steps + 1) if params.preview else np.full(steps, i)
            start = time.perf_counter()
            u = mpc.step(x, reference[ahead])
            solve_s.append(time.perf_counter() - start)
        states[i] = x
        x = fine_a @ x + fine_b @ u
    translation, rotation, tilt = states[:, 0:3], states[:, 6:9], states[:, 12:14]
    poses = np.concatenate([translation, rotation], axis=1)
    poses[:, 3:5] += tilt
    rate_lim = math.radians(params.tilt_rate_limit_degps)
    at_rate = int(np.count_nonzero(np.any(np.abs(states[:, 14:16]) > 0.99 * rate_lim, axis=1)))
    solver = {"programmes": len(solve_s), "unsolved": mpc.infeasible, "variables": mpc.variables,
              "solve_ms_mean": 1e3 * float(np.mean(solve_s)), "solve_ms_max": 1e3 * float(np.max(solve_s)),
              "real_time_factor": params.step_s / float(np.mean(solve_s))}
    return WashoutOutput(t, poses, translation, tilt, rotation, np.zeros(6, dtype=int), at_rate, solver)
