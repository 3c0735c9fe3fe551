"""What the occupant senses: the head's and seat's motion, the vestibular organs, whole-body vibration.

The reversal bump matters because a driver feels it (seed ch. 1). This module follows the platform's
motion to the occupant and says whether each bump is above the threshold of perception, on two paths:

* **Vestibular** (at the head): the otoliths sense specific force, the semicircular canals angular
  velocity. Both are linear models in the field's standard forms, normalised to unit gain where the
  organ transmits its stimulus (the otoliths at DC, the canals in their mid band), so their output is in
  the stimulus' own unit:

  - otolith (Young & Meiry 1968, with the parameters Telban & Cardullo 2005, NASA/CR-2005-213747, use):
    ``H(s) = (tau_a s + 1) / ((tau_L s + 1)(tau_s s + 1))``, tau_a = 13.2 s, tau_L = 5.33 s, tau_s = 0.66 s;
  - canal (Fernandez & Goldberg 1971's torsion pendulum with its rate sensitivity and adaptation, the
    form and parameters of Telban & Cardullo 2005):
    ``H(s) = tau_a s/(tau_a s + 1) * tau_1 s/(tau_1 s + 1) * (tau_L s + 1)/(tau_2 s + 1)``,
    tau_a = 80 s, tau_1 = 5.73 s, tau_L = 0.06 s, tau_2 = 0.005 s.

  Detection thresholds (:data:`VESTIBULAR_THRESHOLDS`) are those measured by Benson et al. (1986: surge
  0.063, sway 0.057, heave 0.154 m/s^2) and Benson et al. (1989: about 2 deg/s in roll and pitch, 1.6 in
  yaw), with stimuli of a few seconds (a single cycle of sinusoidal acceleration, 3 s). A reversal bump
  lasts tens of milliseconds, far inside the otoliths' tau_s: the organ integrates it, and what it senses
  is roughly the bump's velocity change times tau_a / (tau_L tau_s) (3.75 s^-1) -- a 0.5 m/s^2 bump of
  30 ms is sensed as a few hundredths of a m/s^2. So the threshold is not compared with the raw acceleration but
  with the model's output: :func:`sensed_threshold` is the model's peak response to Benson's threshold
  stimulus, and a bump is vestibularly perceptible when the model's response to it is larger.

* **Seat** (whole-body vibration, ISO 2631-1:1997): a short bump lies mostly above the vestibular
  bandwidth, and a seated person feels it through the seat. The standard's frequency weightings
  (Annex A: band limiting 0.4-100 Hz, W_k for z, W_d for x and y; :data:`ISO_WEIGHTINGS`) are applied to
  the specific force at the seat, and the weighted peak is compared with the perception threshold of
  Annex C: 50 % of alert, fit persons detect a W_k-weighted peak of 0.015 m/s^2 (interquartile
  0.01-0.02). Annex C gives it for vertical vibration; hexsim applies the same figure to W_d-weighted
  horizontal vibration, where the seated body is no less sensitive below 2 Hz and less above.

A bump is perceptible when either path exceeds its threshold; the report says which. Axes: the head's
axes are the platform frame's (x forward, y left, z up; seated occupant facing +x).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from hexsim.control.vestibular import (  # noqa: F401 (named here too)
    AXES,
    THRESHOLD_STIMULUS_S,
    VESTIBULAR_THRESHOLDS,
    canal,
    otolith,
    sensed_level,
    threshold_stimulus,
    vestibular_model,
)
from hexsim.signals import LinearModel, fit_fundamental, polynomial_product

# the head's and the seat's axes are AXES, in the order of :class:`PointMotion` (translations, then rotations);
# they, the threshold stimulus and the organs are hexsim.control.vestibular's, named here too

#: how long after a reversal the sensed peak is looked for [s] (before: the metrics' 0.1 s window)
SENSED_TAIL = 0.25


def _second_order(f: float, q: float) -> np.ndarray:
    w = 2 * np.pi * f
    return np.array([1.0, w / q, w * w])


def iso2631(weighting: str) -> LinearModel:
    """ISO 2631-1:1997 Annex A frequency weighting ``"Wk"`` (vertical) or ``"Wd"`` (horizontal), the band
    limiting included: H = H_h H_l H_t H_s with the standard's Table A.2 parameters (f1 0.4 Hz, f2 100 Hz,
    Q1 = Q2 = 1/sqrt 2; W_k: f3 = f4 = 12.5 Hz, Q4 0.63, f5 2.37 Hz, Q5 0.91, f6 3.35 Hz, Q6 0.91;
    W_d: f3 = f4 = 2 Hz, Q4 0.63). Raises ValueError for another name."""
    params = {"Wk": (12.5, 12.5, 0.63, (2.37, 0.91, 3.35, 0.91)), "Wd": (2.0, 2.0, 0.63, None)}
    if weighting not in params:
        raise ValueError(f"unknown ISO 2631-1 weighting {weighting!r}; Wk or Wd")
    f3, f4, q4, step = params[weighting]
    q12 = 1 / math.sqrt(2)
    w2, w3, w4 = (2 * np.pi * f for f in (100.0, f3, f4))
    # high pass s^2/(s^2 + w1 s/Q + w1^2); low pass w2^2/(…); transition (1 + s/w3)/(1 + s/(Q4 w4) + s^2/w4^2)
    num = polynomial_product([1.0, 0.0, 0.0], [w2 * w2], [w4 * w4 / w3, w4 * w4])
    den = polynomial_product(_second_order(0.4, q12), _second_order(100.0, q12), _second_order(f4, q4))
    if step is not None:  # upward step (s^2 + w5 s/Q5 + w5^2)/(s^2 + w6 s/Q6 + w6^2): (f5/f6)^2 at DC, 1 above
        f5, q5, f6, q6 = step
        num = polynomial_product(num, _second_order(f5, q5))
        den = polynomial_product(den, _second_order(f6, q6))
    return LinearModel(f"ISO 2631-1 {weighting}", num, den, "m/s^2", "ISO 2631-1:1997 Annex A, Table A.2")


#: ISO 2631-1 weighting per seat axis (x, y: W_d; z: W_k; seated person, health and comfort, 4.2 / Annex A)
ISO_WEIGHTINGS = {"x": "Wd", "y": "Wd", "z": "Wk"}
#: ISO 2631-1:1997 Annex C: weighted peak acceleration that 50 % of alert, fit persons just detect [m/s^2]
ISO_PERCEPTION_THRESHOLD = 0.015


@dataclass(frozen=True)
class Thresholds:
    """The perception thresholds a judgement uses: ``vestibular`` axis -> the stimulus' threshold (m/s^2 for
    x, y, z; rad/s for roll, pitch, yaw), ``stimulus_s`` the duration of the stimulus they were measured
    with, ``seat_mps2`` the weighted peak at the seat; defaults Benson et al. (1986, 1989) and ISO 2631-1
    Annex C (module doc); ``source``: whose they are. A user's file overrides any of them
    (:meth:`from_file`)."""

    vestibular: tuple[tuple[str, float], ...] = tuple(VESTIBULAR_THRESHOLDS.items())
    stimulus_s: float = THRESHOLD_STIMULUS_S
    seat_mps2: float = ISO_PERCEPTION_THRESHOLD
    source: str = "Benson et al. (1986, 1989); ISO 2631-1:1997 Annex C"

    def stimulus(self, axis: str) -> float:
        return dict(self.vestibular)[axis]

    @classmethod
    def from_file(cls, path) -> "Thresholds":
        """A JSON object with any of ``x_mps2``, ``y_mps2``, ``z_mps2``, ``roll_degps``, ``pitch_degps``,
        ``yaw_degps``, ``stimulus_s``, ``seat_mps2`` and ``source``; the rest default. Raises InputError
        naming the file and the key for an unknown key or a value that is not a positive number."""
        from hexsim.errors import InputError
        from hexsim.tables import read_json_object

        doc = read_json_object(path, "perception thresholds")
        keys = {f"{a}_mps2": a for a in AXES[:3]} | {f"{a}_degps": a for a in AXES[3:]}
        vestibular = dict(VESTIBULAR_THRESHOLDS)
        out = {"source": str(doc.get("source", f"{path}"))}
        for key, value in doc.items():
            if key == "source":
                continue
            if key not in (*keys, "stimulus_s", "seat_mps2"):
                raise InputError(f"{path}: unknown threshold key {key!r} ({', '.join(keys)}, stimulus_s, seat_mps2)")
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
                raise InputError(f"{path}: {key}: expected a positive number, got {value!r}")
            if key in keys:
                vestibular[keys[key]] = math.radians(value) if key.endswith("degps") else float(value)
            else:
                out[key] = float(value)
        return cls(vestibular=tuple(vestibular.items()), **out)


#: the defaults
DEFAULT_THRESHOLDS = Thresholds()


def sensed_threshold(axis: str, fs: float = 1000.0, thresholds: Thresholds = DEFAULT_THRESHOLDS) -> float:
    """The vestibular model's peak output to the threshold stimulus of ``axis``
    (:func:`hexsim.control.vestibular.threshold_stimulus` at the ``thresholds``' level), in the stimulus' unit:
    the level the model's output must exceed to be perceived (module doc)."""
    return sensed_level(axis, thresholds.stimulus(axis), fs, thresholds.stimulus_s)


# --------------------------------------------------------------------------------------------- kinematics
def rigid_point_specific_force(f_ref: np.ndarray, omega: np.ndarray, alpha: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Specific force (N, 3) [m/s^2] at a point ``r`` (3,) [m] of a rigid body from the specific force at its
    reference point ``f_ref`` (N, 3), its angular velocity ``omega`` (N, 3) [rad/s] and angular acceleration
    ``alpha`` (N, 3) [rad/s^2], all in one body-fixed frame: f = f_ref + alpha x r + omega x (omega x r)
    (the acceleration of a point of a rigid body; gravity is the same at both points)."""
    r = np.broadcast_to(np.asarray(r, dtype=float), np.shape(omega))
    return f_ref + np.cross(alpha, r) + np.cross(omega, np.cross(omega, r))


@dataclass(frozen=True)
class PointMotion:
    """What an occupant's point senses, in the platform's axes (x forward, y left, z up): t (N,) [s];
    specific_force (N, 3) [m/s^2] (gravity included: +9.81 on z at rest); angular_velocity (N, 3) [rad/s];
    angular_acceleration (N, 3) [rad/s^2]; point (3,) [m, platform frame]."""

    t: np.ndarray
    specific_force: np.ndarray
    angular_velocity: np.ndarray
    angular_acceleration: np.ndarray
    point: np.ndarray

    @property
    def channels(self) -> np.ndarray:
        """(N, 6): specific force x, y, z, then angular velocity roll, pitch, yaw (:data:`AXES`)."""
        return np.concatenate([self.specific_force, self.angular_velocity], axis=1)


def point_motion(result, point_m) -> PointMotion:
    """The motion at ``point_m`` (3,) [m, platform frame] of a hexapod run ``result``
    (:class:`~hexsim.engine.config.SimulationResult`), from the platform's recorded rigid-body state:
    the accelerometer's specific force, the gyro's angular velocity (both in the sensor site's frame) and the
    angular acceleration (world frame, rotated into the site's frame with the site's recorded orientation),
    carried to the point with :func:`rigid_point_specific_force` and expressed in the platform's axes.
    Raises ValueError for a single-actuator run (it has no platform)."""
    if result.angacc is None or result.gyro is None or result.sensor_site is None:
        raise ValueError("the occupant's motion needs a hexapod run (platform gyro, angular acceleration, site)")
    site_pos, site_quat = result.sensor_site
    body_from_site = Rotation.from_quat(np.asarray(site_quat)[[1, 2, 3, 0]])
    world_from_site = Rotation.from_quat(result.platform_quat[:, [1, 2, 3, 0]])
    alpha_site = world_from_site.inv().apply(result.angacc)
    r_site = body_from_site.inv().apply(np.asarray(point_m, dtype=float) - np.asarray(site_pos))
    f_site = rigid_point_specific_force(result.acc, result.gyro, alpha_site, r_site)
    return PointMotion(result.t, body_from_site.apply(f_site), body_from_site.apply(result.gyro),
                       body_from_site.apply(alpha_site), np.asarray(point_m, dtype=float))


# --------------------------------------------------------------------------------------------- bumps
@dataclass(frozen=True)
class BumpPerception:
    """How each reversal bump of a sine run is sensed (module doc).

    reversal_times (R,) [s]; vestibular (R, 6): the vestibular model's peak response to the bump at the
    head within -0.1…+0.25 s of each reversal, per axis of :data:`AXES`, as a multiple of its sensed
    threshold; seat (R, 3): the ISO 2631-1 weighted peak at the seat (x, y, z) as a multiple of 0.015
    m/s^2; vestibular_peak, seat_peak: the same in m/s^2 or rad/s; thresholds: axis -> sensed threshold;
    head_m, seat_m (3,) [m, platform frame]; t, sensed (N, 6) and weighted (N, 3): the sensed and weighted
    false cue over the analysis window (for plots)."""

    reversal_times: np.ndarray
    vestibular: np.ndarray
    seat: np.ndarray
    vestibular_peak: np.ndarray
    seat_peak: np.ndarray
    thresholds: dict
    head_m: np.ndarray
    seat_m: np.ndarray
    t: np.ndarray = field(repr=False)
    seat_threshold: float = ISO_PERCEPTION_THRESHOLD
    sensed: np.ndarray = field(repr=False, default=None)
    weighted: np.ndarray = field(repr=False, default=None)

    @property
    def perceptible(self) -> np.ndarray:
        """(R,) True where either path exceeds its threshold on some axis."""
        return (self.vestibular.max(axis=1, initial=0) > 1) | (self.seat.max(axis=1, initial=0) > 1)

    def figures(self) -> dict:
        """The JSON-ready summary: counts per path and axis, the largest ratios, the thresholds used."""
        n = len(self.reversal_times)
        axes = {}
        for k, axis in enumerate(AXES):
            row = {"vestibular_max_ratio": _max(self.vestibular[:, k]),
                   "vestibular_perceptible": int(np.sum(self.vestibular[:, k] > 1)),
                   "sensed_threshold": self.thresholds[axis]}
            if k < 3:
                row.update(seat_max_ratio=_max(self.seat[:, k]), seat_perceptible=int(np.sum(self.seat[:, k] > 1)),
                           seat_weighting=ISO_WEIGHTINGS[axis], seat_max_weighted_mps2=_max(self.seat_peak[:, k]))
            axes[axis] = row
        return {
            "reversals": n,
            "perceptible": int(np.sum(self.perceptible)),
            "perceptible_vestibular": int(np.sum(self.vestibular.max(axis=1, initial=0) > 1)),
            "perceptible_seat": int(np.sum(self.seat.max(axis=1, initial=0) > 1)),
            "head_at_m": self.head_m.tolist(), "seat_at_m": self.seat_m.tolist(),
            "seat_threshold_mps2": self.seat_threshold,
            "axes": axes,
            "per_reversal": [{"t_s": float(tr), "vestibular_ratio": [round(float(v), 4) for v in self.vestibular[i]],
                              "seat_ratio": [round(float(v), 4) for v in self.seat[i]]}
                             for i, tr in enumerate(self.reversal_times)],
        }

    def summary(self) -> str:
        """One line: how many bumps are felt, on which path, and the worst axis of each."""
        n, felt = len(self.reversal_times), int(np.sum(self.perceptible))
        if n == 0:
            return "no reversal in the analysis window"
        parts = []
        if self.seat.size:
            k = int(np.argmax(self.seat.max(axis=0)))
            parts.append(f"seat {AXES[k]} {self.seat[:, k].max():.2f}x threshold")
        if self.vestibular.size:
            k = int(np.argmax(self.vestibular.max(axis=0)))
            parts.append(f"vestibular {AXES[k]} {self.vestibular[:, k].max():.2f}x")
        return f"{felt} of {n} bumps perceptible ({'; '.join(parts)} at most)"


def _max(x: np.ndarray) -> float | None:
    return float(np.max(x)) if x.size else None


def bump_perception(result, sm=None, head_m=None, seat_m=None, thresholds: Thresholds = DEFAULT_THRESHOLDS) -> BumpPerception:
    """Each reversal bump of a sine run as the occupant senses it (module doc). ``result``: a hexapod
    :class:`~hexsim.engine.config.SimulationResult`; ``sm``: its
    :class:`~hexsim.studies.metrics.Smoothness` (window, frequency, reversal times; None:
    :func:`~hexsim.studies.metrics.run_smoothness` of the result). ``head_m``, ``seat_m``
    (3,) [m, platform frame]: default the machine's (:attr:`hexsim.plant.geometry.Geometry.head_point`);
    ``thresholds``: :class:`Thresholds` (default Benson's and ISO 2631-1's).
    The false cue on each axis is the signal minus its offset and fundamental at the drive frequency over
    the analysis window (as the seed's acceleration noise, §2.3.1). Raises ValueError for a single-actuator
    run."""
    from hexsim.plant.geometry import MICRO_MOTION_SYSTEM
    from hexsim.studies.metrics import run_smoothness

    sm = run_smoothness(result) if sm is None else sm
    geometry = result.config.geometry or MICRO_MOTION_SYSTEM
    head_m = geometry.head_point if head_m is None else np.asarray(head_m, dtype=float)
    seat_m = geometry.seat_point if seat_m is None else np.asarray(seat_m, dtype=float)
    head, seat = point_motion(result, head_m), point_motion(result, seat_m)
    sel = (result.t >= sm.window[0]) & (result.t <= sm.window[1])
    t = result.t[sel]

    def false_cue(x: np.ndarray) -> np.ndarray:
        return np.stack([x[:, k] - fit_fundamental(t, x[:, k], sm.frequency)[3] for k in range(x.shape[1])], axis=1)

    return sense_bumps(t, false_cue(head.channels[sel]), false_cue(seat.specific_force[sel]),
                       np.asarray(sm.reversal_times), head_m, seat_m, thresholds)


def sense_bumps(t: np.ndarray, head_cue: np.ndarray, seat_cue: np.ndarray, reversal_times: np.ndarray,
                head_m=(0.0, 0.0, 0.0), seat_m=(0.0, 0.0, 0.0),
                thresholds: Thresholds = DEFAULT_THRESHOLDS) -> BumpPerception:
    """The sensing of false cues around reversals: ``head_cue`` (N, 6) (specific force [m/s^2] and angular
    velocity [rad/s] at the head, :data:`AXES`) through the vestibular models, ``seat_cue`` (N, 3) [m/s^2]
    through the ISO 2631-1 weightings, both sampled at t (N,) [s] (uniform) from rest; each reversal's
    peak within -0.1…+0.25 s (:data:`SENSED_TAIL`: the models' lag) against the thresholds."""
    fs = 1.0 / float(np.median(np.diff(t)))
    sensed = np.stack([vestibular_model(axis).apply(head_cue[:, k], fs) for k, axis in enumerate(AXES)], axis=1)
    weighted = np.stack([iso2631(ISO_WEIGHTINGS[a]).apply(seat_cue[:, k], fs) for k, a in enumerate("xyz")], axis=1)
    sensed_at = {axis: sensed_threshold(axis, fs, thresholds) for axis in AXES}
    rev = np.asarray(reversal_times, dtype=float)
    v_peak, s_peak = np.zeros((rev.size, 6)), np.zeros((rev.size, 3))
    for i, tr in enumerate(rev):
        win = (t >= tr - 0.1) & (t <= tr + SENSED_TAIL)
        if np.any(win):
            v_peak[i] = np.max(np.abs(sensed[win]), axis=0)
            s_peak[i] = np.max(np.abs(weighted[win]), axis=0)
    v_ratio = v_peak / np.array([sensed_at[a] for a in AXES])
    return BumpPerception(rev, v_ratio, s_peak / thresholds.seat_mps2, v_peak, s_peak, sensed_at,
                          np.asarray(head_m, dtype=float), np.asarray(seat_m, dtype=float), t, thresholds.seat_mps2,
                          sensed, weighted)


# --------------------------------------------------------------------------------------------- live
def _section_ss(sos: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """The state space (A (n, n), B (n,), C (n,), D) of a cascade of second-order sections ``sos`` (k, 6), each
    in the transposed direct form II that :func:`scipy.signal.sosfilt` runs (y = b0 u + s1, s1' = (b1 - a1 b0) u
    - a1 s1 + s2, s2' = (b2 - a2 b0) u - a2 s1), chained section by section: the same outputs to rounding."""
    A, B, C, D = np.zeros((0, 0)), np.zeros(0), np.zeros(0), 1.0
    for b0, b1, b2, _, a1, a2 in sos:
        a = np.array([[-a1, 1.0], [-a2, 0.0]])
        b = np.array([b1 - a1 * b0, b2 - a2 * b0])
        n = len(B)
        A_new = np.zeros((n + 2, n + 2))
        A_new[:n, :n], A_new[n:, :n], A_new[n:, n:] = A, np.outer(b, C), a
        A, B = A_new, np.concatenate([B, b * D])
        C, D = np.concatenate([b0 * C, [1.0, 0.0]]), b0 * D
    return A, B, C, D


class LivePerception:
    """The occupant's perception sample by sample, for a loop that cannot wait for the whole run (``hexsim
    serve``): the vestibular models (module doc: the otoliths on the head's specific force x, y, z, the canals
    on its angular velocity) and the ISO 2631-1 weightings on the seat's specific force (W_d x, y; W_k z),
    discretised at ``fs`` [Hz] as :meth:`~hexsim.signals.LinearModel.apply` is (bilinear, second-order sections),
    run as one state space. It starts settled on its first input (the otoliths sensing gravity, not a step
    into it).

    :meth:`update` takes the head's specific force (3,) [m/s^2] and angular velocity (3,) [rad/s] and the
    seat's specific force (3,) [m/s^2], platform axes, and returns the sensed specific force and angular
    velocity (6,) and the weighted seat acceleration (3,); :meth:`take_seat_peak` the largest weighted seat
    acceleration on any axis [m/s^2] since it was last taken (the threshold of perception:
    :data:`ISO_PERCEPTION_THRESHOLD`)."""

    def __init__(self, fs: float) -> None:
        models = [vestibular_model(axis) for axis in AXES] + [iso2631(ISO_WEIGHTINGS[a]) for a in "xyz"]
        parts = [_section_ss(m.sos(fs)) for m in models]
        sizes = [len(p[1]) for p in parts]
        n, k = sum(sizes), len(parts)
        self.A, self.B, self.C, self.D = np.zeros((n, n)), np.zeros((n, k)), np.zeros((k, n)), np.zeros(k)
        start = 0
        for j, ((a, b, c, d), size) in enumerate(zip(parts, sizes)):
            s = slice(start, start + size)
            self.A[s, s], self.B[s, j], self.C[j, s], self.D[j] = a, b, c, d
            start += size
        self.x: np.ndarray | None = None
        self.seat_peak = 0.0

    def update(self, head_f: np.ndarray, head_w: np.ndarray, seat_f: np.ndarray) -> np.ndarray:
        """One sample: the sensed (6,) then the weighted seat acceleration (3,) (class doc)."""
        u = np.concatenate([head_f, head_w, seat_f])
        if self.x is None:  # settled on the first input: x = A x + B u at rest
            self.x = np.linalg.solve(np.eye(len(self.A)) - self.A, self.B @ u)
        y = self.C @ self.x + self.D * u
        self.x = self.A @ self.x + self.B @ u
        self.seat_peak = max(self.seat_peak, float(np.max(np.abs(y[6:]))))
        return y

    def take_seat_peak(self) -> float:
        """The largest |weighted seat acceleration| [m/s^2] on any axis since the last call; resets it."""
        peak, self.seat_peak = self.seat_peak, 0.0
        return peak
