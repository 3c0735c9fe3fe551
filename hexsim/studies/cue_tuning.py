"""The classical washout fitted to a platform and a set of manoeuvres (``hexsim cue-tune``, issue 55).

The classical washout (:mod:`hexsim.control.washout`, Reid & Nahon 1985) has a dozen hand-set numbers; set for
one platform and one drive they give another platform's drive poor or wrong-way cues (the lane change of
docs/motion-cueing.md is sensed in sway at a correlation of -0.44 with the defaults). Tuning tools fit them
instead (e.g. genetic tuning of the classical filters); this one fits them to the user's manoeuvres and the
machine's platform:

- **what is fitted** (:data:`TUNED`): the specific-force scales and the translational high passes' corners per
  axis (x, y, z), the tilt low pass's corner, one angular-velocity scale and one rotational high-pass corner for
  the three rotations, each inside a plausible bracket; the limits, damping, the tilt's rate limit (below the
  canals' threshold) and the rotation centre stay as given (the start file or the defaults);
- **the cost** of a manoeuvre: on the *ideal* platform (the washout's poses followed exactly,
  :func:`hexsim.studies.cueing.pose_motion` at the driver's head), each axis' sensed-cue error (the
  vestibular models' output, :func:`hexsim.studies.cueing.sensed`) as an rms relative to the larger of the
  vehicle's own sensed rms on that axis and the axis' sensed threshold (Benson et al. 1986/1989, the perception's
  thresholds), squared, plus, on each axis the vehicle moves (its sensed rms above the threshold), one minus the
  correlation of the sensed cues (:data:`CORRELATION_WEIGHT`): the cue's shape and sign count beside its size,
  and every moving axis of every manoeuvre counts alike, however large its cue (a sustained stop's rms error of 45
  thresholds otherwise outweighed everything else, and its tuned surge correlation was 0.26); an axis the vehicle
  does not move costs its rms in thresholds, squared (a false cue). The legs' stroke, through the exact inverse
  kinematics of the machine's geometry, must keep ``margin_m`` to each end: every millimetre beyond costs as much
  as a threshold's rms error on every axis;
- **the search**: scipy's differential evolution (bounded, global, seeded, the start parameters in its first
  population), then the best of it; the manoeuvres' costs are summed.

The hydraulics are not in the loop (a run per candidate would cost minutes); ``hexsim run vehicle:FILE --washout
TUNED.json`` then shows the tuned cues through the legs, the bump and the compensator.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import differential_evolution

from hexsim.control.kinematics import HexapodGeometry
from hexsim.control.washout import VehicleMotion, WashoutParams, washout
from hexsim.errors import InputError
from hexsim.studies.cueing import pose_motion, sensed
from hexsim.studies.perception import (
    AXES,
    DEFAULT_THRESHOLDS,
    Thresholds,
    sensed_threshold,
)

#: The rate the washout and the sensed cues are evaluated at while tuning [Hz].
RATE_HZ = 100.0
#: Weight of an axis' 1 - correlation in the cost beside its relative rms error (module doc). Measured on the
#: manoeuvre library of examples/vehicle_cueing.py (cue-tune on all five, ideal platform), against the rms error
#: alone in thresholds: the stop's surge correlation 0.26 -> 0.80, the take-off's pitch 0.78 -> 0.81 and heave
#: -0.40 -> -0.02, the lane change and slalom's sway 0.96 / 0.88 -> 0.98 / 0.98.
CORRELATION_WEIGHT = 1.0


@dataclass(frozen=True)
class Tuned:
    """One fitted number: its name, the WashoutParams field and the entries of it it sets (one value set into
    each), its bracket and unit."""

    name: str
    field: str
    entries: tuple[int, ...] | None
    lower: float
    upper: float
    unit: str


#: The numbers :func:`tune_washout` fits (module doc).
TUNED = (
    Tuned("scale_f_x", "scale_specific_force", (0,), 0.1, 1.0, "-"),
    Tuned("scale_f_y", "scale_specific_force", (1,), 0.1, 1.0, "-"),
    Tuned("scale_f_z", "scale_specific_force", (2,), 0.1, 1.0, "-"),
    Tuned("hp_omega_x", "hp_omega_radps", (0,), 0.5, 10.0, "rad/s"),
    Tuned("hp_omega_y", "hp_omega_radps", (1,), 0.5, 10.0, "rad/s"),
    Tuned("hp_omega_z", "hp_omega_radps", (2,), 0.5, 10.0, "rad/s"),
    Tuned("tilt_omega", "tilt_omega_radps", None, 0.5, 10.0, "rad/s"),
    Tuned("scale_w", "scale_angular_velocity", (0, 1, 2), 0.1, 1.0, "-"),
    Tuned("rot_omega", "rot_omega_radps", (0, 1, 2), 0.1, 5.0, "rad/s"),
)


def _values(params: WashoutParams) -> np.ndarray:
    """The tuned numbers of ``params`` (:data:`TUNED`'s order; a shared one: the first entry's), clipped into
    their brackets."""
    out = []
    for p in TUNED:
        v = getattr(params, p.field)
        out.append(float(np.clip(v if p.entries is None else v[p.entries[0]], p.lower, p.upper)))
    return np.array(out)


def with_values(params: WashoutParams, values: np.ndarray) -> WashoutParams:
    """``params`` with :data:`TUNED`'s numbers set to ``values`` (len(TUNED),)."""
    changes: dict[str, object] = {}
    for p, v in zip(TUNED, values):
        if p.entries is None:
            changes[p.field] = float(v)
        else:
            current = list(changes.get(p.field, getattr(params, p.field)))
            for e in p.entries:
                current[e] = float(v)
            changes[p.field] = tuple(current)
    return dataclasses.replace(params, **changes, source="hexsim cue-tune")


@dataclass(frozen=True)
class ManoeuvreFigures:
    """One manoeuvre under one washout, on the ideal platform: per axis of :data:`AXES` the sensed-cue rms error
    in thresholds and the correlation of the sensed cues (None where either is flat); the smallest stroke
    margin [m] (negative: beyond an end) and the cost (module doc)."""

    name: str
    error_in_thresholds: dict[str, float]
    correlation: dict[str, float | None]
    stroke_margin_m: float
    cost: float


@dataclass(frozen=True)
class WashoutTuning:
    """What :func:`tune_washout` found: the start and tuned parameters, each manoeuvre's figures under both, the
    search's evaluations."""

    start: WashoutParams
    tuned: WashoutParams
    before: list[ManoeuvreFigures]
    after: list[ManoeuvreFigures]
    evaluations: int

    def lines(self) -> list[str]:
        """The report a user reads: the fitted numbers, then per manoeuvre and axis before -> after."""
        out = ["tuned (start -> tuned):"]
        a, b = _values(self.start), _values(self.tuned)
        out += [f"  {p.name:<11} {x:8.3f} -> {y:8.3f} {p.unit}" for p, x, y in zip(TUNED, a, b)]
        for before, after in zip(self.before, self.after):
            out.append(f"{before.name}: cost {before.cost:.3g} -> {after.cost:.3g}; stroke margin "
                       f"{before.stroke_margin_m * 1e3:.1f} -> {after.stroke_margin_m * 1e3:.1f} mm (ideal platform)")
            for axis in AXES:
                c0, c1 = before.correlation[axis], after.correlation[axis]
                corr = "" if c0 is None or c1 is None else f", correlation {c0:+.2f} -> {c1:+.2f}"
                out.append(f"  {axis:<4} sensed error {before.error_in_thresholds[axis]:6.2f} -> "
                           f"{after.error_in_thresholds[axis]:6.2f} thresholds (rms){corr}")
        out.append(f"{self.evaluations} washouts evaluated")
        return out


class _Problem:
    """The manoeuvres' sensed vehicle cues and the platform, set up once; :meth:`figures` per washout."""

    def __init__(self, vehicles: list[VehicleMotion], geometry: HexapodGeometry, head_m, margin_m: float,
                 thresholds: Thresholds) -> None:
        if not vehicles:
            raise InputError("hexsim cue-tune: give at least one vehicle file")
        if not (math.isfinite(margin_m) and margin_m >= 0):
            raise InputError(f"--margin must be a number >= 0 m, got {margin_m!r}")
        self.vehicles, self.geometry, self.head, self.margin = vehicles, geometry, np.asarray(head_m, float), margin_m
        self.threshold = np.array([sensed_threshold(a, RATE_HZ, thresholds) for a in AXES])
        self.sensed_vehicle = []
        for v in vehicles:
            t = np.arange(int(math.floor(float(v.t[-1]) * RATE_HZ)) + 1) / RATE_HZ
            f, w = v.at(t)
            self.sensed_vehicle.append(sensed(np.concatenate([f, w], axis=1), RATE_HZ, 9.81))
        self.evaluations = 0

    def figures(self, params: WashoutParams) -> list[ManoeuvreFigures]:
        self.evaluations += 1
        out = []
        lo, hi = self.geometry.stroke[:, 0] + self.margin, self.geometry.stroke[:, 1] - self.margin
        for v, s_veh in zip(self.vehicles, self.sensed_vehicle):
            cue = washout(v, params, RATE_HZ)
            s_ideal = sensed(pose_motion(cue.t, cue.poses, self.head).channels, RATE_HZ, 9.81)
            err = s_ideal - s_veh
            rms = np.sqrt(np.mean(err**2, axis=0)) / self.threshold
            scale = np.maximum(np.sqrt(np.mean(s_veh**2, axis=0)) / self.threshold, 1.0)  # 1: the axis does not move
            y = self.geometry.inverse(cue.poses, check=False)
            margin = float(min(np.min(y - self.geometry.stroke[:, 0]), np.min(self.geometry.stroke[:, 1] - y)))
            beyond = float(np.max(np.maximum(lo - y, y - hi).clip(min=0.0)))
            corr = {}
            for k, axis in enumerate(AXES):
                a, b = s_veh[:, k], s_ideal[:, k]
                corr[axis] = float(np.corrcoef(a, b)[0, 1]) if np.std(a) > 1e-12 and np.std(b) > 1e-12 else None
            shape = sum(1.0 - (corr[axis] or 0.0) for k, axis in enumerate(AXES) if scale[k] > 1.0)
            cost = float(np.sum((rms / scale) ** 2) + CORRELATION_WEIGHT * shape + len(AXES) * (beyond / 1e-3) ** 2)
            out.append(ManoeuvreFigures(v.source, dict(zip(AXES, rms.tolist())), corr, margin, cost))
        return out


def tune_washout(vehicles: list[VehicleMotion], geometry: HexapodGeometry, head_m, *,
                 start: WashoutParams = WashoutParams(), margin_m: float = 0.01, seed: int = 0, maxiter: int = 30,
                 popsize: int = 6, thresholds: Thresholds = DEFAULT_THRESHOLDS) -> WashoutTuning:
    """Fit :data:`TUNED` of ``start`` to ``vehicles`` (module doc) on the platform of ``geometry`` (its stroke
    and inverse kinematics) with the driver's head at ``head_m`` (3,) [m, platform frame], each leg kept
    ``margin_m`` [m] inside its stroke; ``seed``, ``maxiter`` and ``popsize`` (per tuned number) of the
    differential evolution. The tuned washout is never worse than the start on the summed cost (it is in the
    first population). Raises InputError for no vehicle or a bad margin."""
    problem = _Problem(list(vehicles), geometry, head_m, margin_m, thresholds)
    x0 = _values(start)
    bounds = [(p.lower, p.upper) for p in TUNED]

    def cost(x: np.ndarray) -> float:
        return sum(f.cost for f in problem.figures(with_values(start, x)))

    rng = np.random.default_rng(seed)
    n = len(TUNED)
    init = rng.uniform([b[0] for b in bounds], [b[1] for b in bounds], size=(max(5, popsize * n), n))
    init[0] = x0  # the start is a member: the result is never worse than it
    result = differential_evolution(cost, bounds, init=init, maxiter=maxiter, seed=seed, polish=False, tol=1e-6)
    best = result.x if result.fun <= cost(x0) else x0
    tuned = with_values(start, best)
    return WashoutTuning(start, tuned, problem.figures(start), problem.figures(tuned), problem.evaluations)
