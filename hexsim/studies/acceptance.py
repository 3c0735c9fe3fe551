"""Objective motion tests of the simulated machine, as training simulators are qualified.

14 CFR Part 60 (FAA, appendices A and C) and ICAO Doc 9625 ask for a motion system's frequency response,
turn-around check, leg balance and repeatability (within ±0.05 g), with tolerances "as specified by the
applicant" where the rule gives none; the Objective Motion Cueing Test (OMCT; Hosman & Advani 2012, ICAO
9625 ed. 4) measures the whole cueing chain. This module runs them on the simulated machine and checks each
measured figure against a tolerance file the user writes (:class:`Tolerances`, ``docs/acceptance.md``):

* **frequency response** per degree of freedom: sines of a small amplitude (at most 10 mm / 1 deg, and an
  acceleration of at most 1 m/s^2 / 2 rad/s^2) at each frequency, the measured pose's fundamental against
  the setpoint's (the describing-function method of AGARD-AR-144, 1979): gain [dB] and phase [deg];
* **turn-around check** per degree of freedom: the seed's slow sine (0.5 Hz, 50 mm / 5 deg), the largest
  reversal bump (acceleration minus its fundamental, g or rad/s^2) and how many bumps a seated occupant
  feels (:mod:`hexsim.studies.perception`);
* **leg balance**: in heave, each leg's force (mean and fundamental) against the six legs' mean [%];
* **repeatability**: the heave test run twice (position-sensor noise of another seed), the largest
  difference of the platform's vertical acceleration [g];
* **motion envelope** per degree of freedom at the neutral pose: the excursion the stroke allows (inverse
  kinematics), the velocity the valves give at full command (the static flow curve, seed eq. 5.1, through the
  legs' Jacobian) and the acceleration the pressures allow (supply or tank against the rest pressure, through
  MuJoCo's inertia of platform and legs);
* **OMCT** with a washout: sines of vehicle specific force or body rate through washout, kinematics,
  hydraulics and compensator, the specific force or rate at the driver's head against the vehicle's
  (direct channels, and surge -> pitch, sway -> roll rate for tilt coordination).
"""

from __future__ import annotations

import dataclasses
import math
import pathlib
from dataclasses import dataclass, field

import numpy as np

from hexsim.control.mpc_cueing import PlatformLimits
from hexsim.control.scenario import SINE_DOFS, make_scenario, vehicle_scenario
from hexsim.engine.config import RunConfig
from hexsim.engine.runner import Simulator, simulate
from hexsim.engine.workers import in_workers, worker_pool
from hexsim.errors import InputError
from hexsim.signals import fit_fundamental
from hexsim.studies.metrics import STANDARD_GRAVITY, run_smoothness
from hexsim.studies.perception import (
    AXES,
    DEFAULT_THRESHOLDS,
    Thresholds,
    bump_perception,
    point_motion,
)
from hexsim.tables import read_json_object

DOFS = ("surge", "sway", "heave", "roll", "pitch", "yaw")
#: test frequencies [Hz]: the OMCT's one-third-decade steps from 0.1 to 15.85 Hz (Hosman & Advani 2012)
FREQUENCIES_HZ = (0.1, 0.158, 0.251, 0.398, 0.631, 1.0, 1.585, 2.512, 3.981, 6.31, 10.0, 15.85)
#: OMCT channels: (vehicle input, simulator output at the head), AXES names
OMCT_CHANNELS = (("x", "x"), ("y", "y"), ("z", "z"), ("roll", "roll"), ("pitch", "pitch"), ("yaw", "yaw"),
                 ("x", "pitch"), ("y", "roll"))
SECTIONS = ("frequency_response", "turn_around", "leg_balance", "repeatability", "envelope", "omct")


# ------------------------------------------------------------------------------------------ tolerances
@dataclass(frozen=True)
class Band:
    """A frequency-response tolerance: gain within ``gain_db`` (lo, hi) [dB] and phase within ``phase_deg``
    (lo, hi) [deg] from ``from_hz`` to ``to_hz``; None: that figure is reported only."""

    gain_db: tuple[float, float] | None = None
    phase_deg: tuple[float, float] | None = None
    from_hz: float = 0.0
    to_hz: float = math.inf


@dataclass(frozen=True)
class Tolerances:
    """What the user's tolerance file asks (``docs/acceptance.md``): the tests to run (its sections) with
    their settings and limits; ``source``: whose limits they are (the applicant's statement, a standard)."""

    source: str
    path: str
    dofs: tuple[str, ...] = DOFS
    frequencies_hz: tuple[float, ...] = FREQUENCIES_HZ
    frequency_response: Band | None = None
    turn_around: dict | None = None
    leg_balance: dict | None = None
    repeatability: dict | None = None
    envelope: dict | None = None
    omct: Band | None = None
    run: tuple[str, ...] = ()

    @classmethod
    def read(cls, path: str | pathlib.Path) -> "Tolerances":
        """Read a tolerance file. Raises InputError naming the file and the key for a file that is not
        JSON, an unknown section or key, a bad degree of freedom, frequency or limit."""
        path = pathlib.Path(path)
        doc = read_json_object(path, "acceptance tolerances")
        if doc.get("format") != "hexsim-acceptance" or doc.get("version") != 1:
            raise InputError(f"{path}: not a hexsim acceptance tolerance file (format \"hexsim-acceptance\", version 1)")
        unknown = sorted(set(doc) - {"format", "version", "source", "dofs", "frequencies_hz", *SECTIONS})
        if unknown:
            raise InputError(f"{path}: unknown key {unknown[0]!r} (sections: {', '.join(SECTIONS)})")
        where = str(path)
        dofs = tuple(doc.get("dofs", DOFS))
        bad = [d for d in dofs if d not in DOFS]
        if bad or not dofs:
            raise InputError(f"{where}: dofs: unknown degree of freedom {bad[0] if bad else '(none)'!r}; "
                             f"choose from {', '.join(DOFS)}")
        freqs = doc.get("frequencies_hz", FREQUENCIES_HZ)
        if not (isinstance(freqs, list | tuple) and freqs and all(_number(f) and 0.01 <= f <= 25 for f in freqs)):
            raise InputError(f"{where}: frequencies_hz: expected frequencies within 0.01…25 Hz, got {freqs!r}")
        sections = {name: doc[name] for name in SECTIONS if name in doc}
        for name, body in sections.items():
            if not isinstance(body, dict):
                raise InputError(f"{where}: {name}: expected an object of limits ({{}} to report the figures only)")
        return cls(source=str(doc.get("source", "")), path=where, dofs=dofs, frequencies_hz=tuple(map(float, freqs)),
                   frequency_response=_band(sections.get("frequency_response"), f"{where}: frequency_response"),
                   turn_around=_limits(sections.get("turn_around"), ("max_bump_g", "max_bump_radps2", "max_perceptible"),
                                       f"{where}: turn_around"),
                   leg_balance=_limits(sections.get("leg_balance"), ("max_deviation_pct",), f"{where}: leg_balance"),
                   repeatability=_limits(sections.get("repeatability"), ("max_difference_g",), f"{where}: repeatability"),
                   envelope=_envelope(sections.get("envelope"), f"{where}: envelope"),
                   omct=_band(sections.get("omct"), f"{where}: omct"), run=tuple(sections))


def _number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _pair(value, where: str) -> tuple[float, float]:
    if not (isinstance(value, list) and len(value) == 2 and all(_number(v) for v in value) and value[0] <= value[1]):
        raise InputError(f"{where}: expected [lower, upper], got {value!r}")
    return float(value[0]), float(value[1])


def _band(body: dict | None, where: str) -> Band | None:
    if body is None:
        return None
    unknown = sorted(set(body) - {"gain_db", "phase_deg", "from_hz", "to_hz"})
    if unknown:
        raise InputError(f"{where}: unknown key {unknown[0]!r} (gain_db, phase_deg, from_hz, to_hz)")
    for key in ("from_hz", "to_hz"):
        if key in body and not (_number(body[key]) and body[key] >= 0):
            raise InputError(f"{where}.{key}: expected a frequency in Hz, got {body[key]!r}")
    return Band(_pair(body["gain_db"], f"{where}.gain_db") if "gain_db" in body else None,
                _pair(body["phase_deg"], f"{where}.phase_deg") if "phase_deg" in body else None,
                float(body.get("from_hz", 0.0)), float(body.get("to_hz", math.inf)))


def _limits(body: dict | None, keys: tuple[str, ...], where: str) -> dict | None:
    if body is None:
        return None
    for key, value in body.items():
        if key not in keys:
            raise InputError(f"{where}: unknown key {key!r} ({', '.join(keys)})")
        if not (_number(value) and value >= 0):
            raise InputError(f"{where}.{key}: expected a non-negative number, got {value!r}")
    return dict(body)


def _envelope(body: dict | None, where: str) -> dict | None:
    if body is None:
        return None
    for dof, limits in body.items():
        if dof not in DOFS:
            raise InputError(f"{where}: unknown degree of freedom {dof!r}; choose from {', '.join(DOFS)}")
        if not isinstance(limits, dict):
            raise InputError(f"{where}.{dof}: expected an object of limits (excursion, velocity, acceleration)")
        _limits(limits, ("excursion", "velocity", "acceleration"), f"{where}.{dof}")
    return dict(body)


# ------------------------------------------------------------------------------------------ checks
@dataclass(frozen=True)
class Check:
    """One measured figure of a test against its tolerance: ``test`` (section), ``item`` (e.g. "heave at
    1 Hz, gain"), ``value`` in ``unit``, ``limit`` (text, "" when the file gives none) and ``passed``
    (None: no tolerance)."""

    test: str
    item: str
    value: float
    unit: str
    limit: str = ""
    passed: bool | None = None


def within(test: str, item: str, value: float, unit: str, bounds: tuple[float, float] | None) -> Check:
    """``value`` checked to lie within ``bounds`` (lower, upper) in ``unit``; None: reported only."""
    if bounds is None:
        return Check(test, item, value, unit)
    lo, hi = bounds
    return Check(test, item, value, unit, f"{lo:g} … {hi:g} {unit}", bool(lo <= value <= hi))


def at_most(test: str, item: str, value: float, unit: str, limit: float | None) -> Check:
    """``value`` checked to be at most ``limit`` in ``unit``; None: reported only."""
    if limit is None:
        return Check(test, item, value, unit)
    return Check(test, item, value, unit, f"≤ {limit:g} {unit}", bool(value <= limit))


def at_least(test: str, item: str, value: float, unit: str, limit: float | None) -> Check:
    """``value`` checked to be at least ``limit`` in ``unit``; None: reported only."""
    if limit is None:
        return Check(test, item, value, unit)
    return Check(test, item, value, unit, f"≥ {limit:g} {unit}", bool(value >= limit))


@dataclass
class AcceptanceResult:
    """The tests' figures and checks for one compensator: ``bode`` dof -> (frequencies (F,) [Hz], gain (F,)
    [dB], phase (F,) [deg]); ``omct`` "in->out" -> the same; ``turn_around`` dof -> figures; ``leg_balance``,
    ``repeatability``, ``envelope``: figures; ``logs``: each measured log's test, measured and simulated;
    ``checks``: every figure against its tolerance."""

    machine: str
    compensator: str
    bode: dict = field(default_factory=dict)
    omct: dict = field(default_factory=dict)
    turn_around: dict = field(default_factory=dict)
    leg_balance: dict = field(default_factory=dict)
    repeatability: dict = field(default_factory=dict)
    envelope: dict = field(default_factory=dict)
    logs: list[dict] = field(default_factory=list)  # measured logs' tests (hexsim.measured.acceptance_logs)
    checks: list[Check] = field(default_factory=list)

    @property
    def passed(self) -> bool | None:
        """All checks with a tolerance passed (None: no check had one)."""
        judged = [c.passed for c in self.checks if c.passed is not None]
        return all(judged) if judged else None

    def document(self) -> dict:
        """JSON-ready."""
        def arrays(d):
            return {k: {"frequency_hz": list(v[0]), "gain_db": list(v[1]), "phase_deg": list(v[2])} for k, v in d.items()}

        return {"machine": self.machine, "compensator": self.compensator, "passed": self.passed,
                "frequency_response": arrays(self.bode), "omct": arrays(self.omct), "turn_around": self.turn_around,
                "leg_balance": self.leg_balance, "repeatability": self.repeatability, "envelope": self.envelope,
                "logs": self.logs,
                "checks": [dataclasses.asdict(c) for c in self.checks]}


# ------------------------------------------------------------------------------------------ the tests
def sine_amplitude(dof: str, frequency: float) -> float:
    """The frequency-response test's amplitude [m or rad] (module doc)."""
    w = 2 * np.pi * frequency
    if SINE_DOFS[dof] < 3:
        return min(0.01, 1.0 / (w * w))
    return min(math.radians(1.0), 2.0 / (w * w))


def _duration(frequency: float) -> float:
    """Fade-in, one settling and three analysed periods, at least 2 s."""
    return max(2.0, 5.0 / frequency)


def describing_function(base: RunConfig, dof: str, frequency: float) -> tuple[float, float]:
    """Gain [dB] and phase [deg] of the measured pose of ``dof`` against its setpoint in a sine at
    ``frequency`` [Hz] of :func:`sine_amplitude` (runs in a worker process)."""
    sc = make_scenario(dof, amplitude=sine_amplitude(dof, frequency), frequency=frequency,
                       duration=_duration(frequency), controller_rate_hz=base.controller.rate_hz)
    r = simulate(dataclasses.replace(base, scenario=sc, progress=False))
    k = SINE_DOFS[dof]
    sel = r.t >= 2.0 / frequency
    _, a_out, ph_out, _ = fit_fundamental(r.t[sel], r.pose[sel, k], frequency)
    _, a_in, ph_in, _ = fit_fundamental(r.t[sel], r.pose_ref[sel, k], frequency)
    return 20 * math.log10(a_out / a_in), wrap_deg(math.degrees(ph_out - ph_in))


def wrap_deg(x: float) -> float:
    """An angle [deg] wrapped into -180 … 180."""
    return (x + 180.0) % 360.0 - 180.0


def omct_response(base: RunConfig, washout, channel: tuple[str, str], frequency: float) -> tuple[float, float]:
    """OMCT: gain [dB] and phase [deg] of the simulator's specific force or body rate at the driver's head
    (``channel[1]``) against a vehicle sine of specific force (1 m/s^2) or body rate (0.1 rad/s) in
    ``channel[0]`` at ``frequency`` [Hz]; cross channels' gain in (rad/s)/(m/s^2) as dB."""
    from hexsim.control.washout import VehicleMotion
    from hexsim.plant.geometry import MICRO_MOTION_SYSTEM

    source, out = AXES.index(channel[0]), AXES.index(channel[1])
    duration = _duration(frequency)
    t = np.arange(int(duration * 1000) + 1) / 1000.0
    amplitude = 1.0 if source < 3 else 0.1
    x = amplitude * np.sin(2 * np.pi * frequency * t)
    f = np.tile([0.0, 0.0, 9.81], (t.size, 1))
    w = np.zeros((t.size, 3))
    (f if source < 3 else w)[:, source % 3] += x
    sc = vehicle_scenario(VehicleMotion(t, f, w, f"OMCT {channel[0]}->{channel[1]} {frequency:g} Hz"), washout,
                          controller_rate_hz=base.controller.rate_hz)
    r = simulate(dataclasses.replace(base, scenario=sc, progress=False))
    head = (base.geometry or MICRO_MOTION_SYSTEM).head_point
    y = point_motion(r, head).channels[:, out]
    sel = r.t >= 2.0 / frequency
    _, a_out, ph_out, _ = fit_fundamental(r.t[sel], y[sel], frequency)
    _, a_in, ph_in, _ = fit_fundamental(r.t[sel], np.interp(r.t[sel], t, x), frequency)
    return 20 * math.log10(max(a_out, 1e-12) / a_in), wrap_deg(math.degrees(ph_out - ph_in))


def _task(args):
    kind, base, a, b, c = args
    if kind == "fr":
        return describing_function(base, a, b)
    return omct_response(base, c, a, b)


def _bode_checks(test: str, name: str, freqs, gains, phases, band: Band | None) -> list[Check]:
    out = []
    for f, g, p in zip(freqs, gains, phases):
        inside = band is not None and band.from_hz <= f <= band.to_hz
        out.append(within(test, f"{name} at {f:g} Hz, gain", g, "dB", band.gain_db if inside else None))
        out.append(within(test, f"{name} at {f:g} Hz, phase", p, "deg", band.phase_deg if inside else None))
    return out


def turn_around(base: RunConfig, dof: str, frequency: float = 0.5, seed: int = 0,
                thresholds: Thresholds = DEFAULT_THRESHOLDS):
    """The seed's sine in ``dof`` at ``frequency`` (default amplitude), 4 periods: the run, its smoothness
    and its bumps' perception."""
    sc = make_scenario(dof, frequency=frequency, duration=4.0 / frequency + 1.0 / frequency,
                       controller_rate_hz=base.controller.rate_hz)
    r = simulate(dataclasses.replace(base, scenario=sc, seed=seed, progress=False))
    sm = run_smoothness(r)
    return r, sm, bump_perception(r, sm, thresholds=thresholds)


def platform_limits(base: RunConfig) -> PlatformLimits:
    """The platform's envelope at the neutral pose as the legs see it (:func:`_at_rest`)."""
    return _at_rest(base)[1]


def _at_rest(base: RunConfig):
    """The platform's envelope at the neutral pose as the legs see it (module doc, motion envelope): the
    kinematics' Jacobian, each leg's stroke about its neutral extension, its speed at full valve opening
    against the rest pressure (the flow curve's static velocity), the legs' forces per unit pose acceleration
    (their effective inertia, constraints included) and the force each can add or take away with the supply
    and tank pressures. The model and its rest pressures are set up once. Returns (the geometry,
    :class:`hexsim.control.mpc_cueing.PlatformLimits`)."""
    from hexsim.control.kinematics import HexapodGeometry
    from hexsim.engine.config import leg_mobility
    from hexsim.plant import hydraulics

    sim = Simulator(dataclasses.replace(base, scenario=make_scenario("heave", duration=6.0), progress=False))
    geo = HexapodGeometry.from_model(sim.model)
    hyd, p1 = base.hydraulics, sim.p1_initial
    neutral = geo.inverse(np.zeros(6), check=False)
    jac = np.empty((6, 6))
    for k in range(6):
        dp = np.zeros(6)
        dp[k] = 1e-6
        jac[:, k] = (geo.inverse(dp, check=False) - geo.inverse(-dp, check=False)) / 2e-6  # dy/dq
    mobility, _ = leg_mobility(sim.model, sim.data, sim.idx)
    return geo, PlatformLimits(
        jacobian=jac, stroke_lo=geo.stroke[:, 0] - neutral, stroke_hi=geo.stroke[:, 1] - neutral,
        velocity_extend=hydraulics.static_velocity(hyd.u_v_max, p1, hyd) * np.ones(6),
        velocity_retract=-hydraulics.static_velocity(-hyd.u_v_max, p1, hyd) * np.ones(6),
        force_map=np.linalg.solve(mobility, jac),  # leg forces per unit pose acceleration [N/(m/s^2)]
        force_up=(hyd.supply_pressure - p1) * hyd.area_bottom * np.ones(6),
        force_down=(p1 - hyd.tank_pressure) * hyd.area_bottom * np.ones(6),
        source=f"machine {base.machine_label}")


def envelope(base: RunConfig, dofs: tuple[str, ...]) -> dict[str, dict]:
    """The motion envelope of each of ``dofs`` at the neutral pose (module doc): excursion [m or rad] each way,
    velocity [m/s or rad/s] and acceleration [m/s^2 or rad/s^2] (the smaller of the two directions), from
    :func:`platform_limits`."""
    geo, lim = _at_rest(base)
    lo, hi = geo.stroke[:, 0], geo.stroke[:, 1]

    def reach(k: int, sign: float) -> float:  # the kinematics are not linear that far: bisect on them
        a, b = 0.0, 1.0 if k < 3 else math.radians(60)
        for _ in range(50):
            mid = 0.5 * (a + b)
            pose = np.zeros(6)
            pose[k] = sign * mid
            y = geo.inverse(pose, check=False)
            a, b = (mid, b) if np.all((y >= lo) & (y <= hi)) else (a, mid)
        return a

    out = {}
    for dof in dofs:
        k = SINE_DOFS[dof]
        jac, force = lim.jacobian[:, k], lim.force_map[:, k]
        speed = np.where(jac > 0, lim.velocity_extend, lim.velocity_retract)
        up, down = lim.force_up, lim.force_down
        accel = min(float(np.min(np.where(force > 0, up, down) / np.maximum(np.abs(force), 1e-12))),
                    float(np.min(np.where(force > 0, down, up) / np.maximum(np.abs(force), 1e-12))))
        out[dof] = {"excursion": [-reach(k, -1.0), reach(k, 1.0)],
                    "velocity": float(np.min(speed / np.maximum(np.abs(jac), 1e-12))), "acceleration": accel,
                    "unit": "m" if k < 3 else "rad"}
    return out


def run_acceptance(base: RunConfig, tol: Tolerances, washout=None, jobs: int = 1, progress=None,
                   thresholds: Thresholds = DEFAULT_THRESHOLDS) -> AcceptanceResult:
    """Every test the tolerance file asks for (its sections) on the machine and compensator of ``base`` (a
    hexapod's RunConfig; its scenario is replaced), the OMCT with ``washout`` (WashoutParams, None: the
    defaults); ``jobs`` worker processes for the sine runs; ``progress(text)`` is told each test as it
    starts; the turn-around's bumps felt judged with the perception ``thresholds``. The heave turn-around
    run serves the turn-around check, leg balance and repeatability alike. Raises InputError for a single
    actuator."""
    if base.scenario.system != "hexapod":
        raise InputError("the motion acceptance tests need a hexapod machine")
    say = progress or (lambda text: None)
    res = AcceptanceResult(base.machine_label, base.compensator_name)
    runs: dict[str, tuple] = {}

    def turn(dof: str):
        if dof not in runs:
            runs[dof] = turn_around(base, dof, thresholds=thresholds)
        return runs[dof]

    if tol.frequency_response is not None or tol.omct is not None:
        _sine_tests(res, base, tol, washout, jobs, say)
    if tol.turn_around is not None:
        say("turn-around check")
        for dof in tol.dofs:
            _turn_around_checks(res, dof, *turn(dof)[1:], tol.turn_around)
    if tol.leg_balance is not None or tol.repeatability is not None:
        say("leg balance and repeatability (heave)")
        _balance_checks(res, base, tol, *turn("heave")[:2])
    if tol.envelope is not None:
        say("motion envelope")
        for dof, env in envelope(base, tol.dofs).items():
            res.envelope[dof] = env
            lim, unit = tol.envelope.get(dof, {}), env["unit"]
            res.checks += [at_least("envelope", f"{dof}, excursion", min(-env["excursion"][0], env["excursion"][1]),
                                    unit, lim.get("excursion")),
                           at_least("envelope", f"{dof}, velocity", env["velocity"], f"{unit}/s", lim.get("velocity")),
                           at_least("envelope", f"{dof}, acceleration", env["acceleration"], f"{unit}/s^2",
                                    lim.get("acceleration"))]
    return res


def _sine_tests(res: AcceptanceResult, base: RunConfig, tol: Tolerances, washout, jobs: int, say) -> None:
    """The frequency response and the OMCT: every (test, frequency) sine run, in ``jobs`` workers."""
    tasks = []
    if tol.frequency_response is not None:
        tasks += [("fr", base, dof, f, None) for dof in tol.dofs for f in tol.frequencies_hz]
    if tol.omct is not None:
        tasks += [("omct", base, ch, f, washout) for ch in OMCT_CHANNELS for f in tol.frequencies_hz]
    say(f"{len(tasks)} sine runs (frequency response{', OMCT' if tol.omct is not None else ''})")
    if in_workers(jobs):
        with worker_pool(jobs) as pool:
            answers = list(pool.map(_task, tasks))
    else:
        answers = [_task(t) for t in tasks]
    freqs = np.array(tol.frequencies_hz)
    for i, (kind, _, key, _, _) in enumerate(tasks[::len(freqs)]):
        gp = np.array(answers[i * len(freqs):(i + 1) * len(freqs)])
        name = key if kind == "fr" else f"{key[0]}->{key[1]}"
        target = res.bode if kind == "fr" else res.omct
        target[name] = (freqs, gp[:, 0], gp[:, 1])
        band = tol.frequency_response if kind == "fr" else tol.omct
        res.checks += _bode_checks("frequency_response" if kind == "fr" else "omct", name, freqs, gp[:, 0],
                                   gp[:, 1], band)


def _turn_around_checks(res: AcceptanceResult, dof: str, sm, bp, lim: dict) -> None:
    """One DOF's turn-around figures (its smoothness ``sm`` and bumps' perception ``bp``) and checks."""
    peak = float(np.max(sm.reversal_peaks))
    felt = int(np.sum(bp.perceptible))
    res.turn_around[dof] = {"max_bump": peak, "unit": sm.unit, "mean_bump": sm.mean_reversal_peak,
                            "perceptible": felt, "reversals": int(len(sm.reversal_peaks)),
                            "seat_max_ratio": float(bp.seat.max())}
    if SINE_DOFS[dof] >= 3:
        res.checks.append(at_most("turn_around", f"{dof}, largest bump", peak, "rad/s^2", lim.get("max_bump_radps2")))
    else:
        res.checks.append(at_most("turn_around", f"{dof}, largest bump", peak / STANDARD_GRAVITY, "g",
                                  lim.get("max_bump_g")))
    res.checks.append(at_most("turn_around", f"{dof}, bumps felt (of {len(sm.reversal_peaks)})", felt, "",
                              lim.get("max_perceptible")))


def _balance_checks(res: AcceptanceResult, base: RunConfig, tol: Tolerances, r0, sm0) -> None:
    """Leg balance from the heave turn-around run ``r0`` (its smoothness ``sm0``), and repeatability: the same
    run with another noise seed against it."""
    sel = r0.t >= sm0.window[0]
    fits = [fit_fundamental(r0.t[sel], r0.force[sel, i], sm0.frequency) for i in range(r0.n_legs)]
    mean_f = np.array([f[0] for f in fits])
    amp_f = np.array([f[1] for f in fits])
    dev = 100 * np.maximum(np.abs(mean_f / mean_f.mean() - 1), np.abs(amp_f / amp_f.mean() - 1))
    if tol.leg_balance is not None:
        res.leg_balance = {"force_mean_N": mean_f.tolist(), "force_amplitude_N": amp_f.tolist(),
                           "deviation_pct": dev.tolist()}
        res.checks.append(at_most("leg_balance", f"largest leg deviation (leg {int(np.argmax(dev)) + 1})",
                                  float(dev.max()), "%", tol.leg_balance.get("max_deviation_pct")))
    if tol.repeatability is not None:
        r1, _, _ = turn_around(base, "heave", seed=1)
        diff = float(np.max(np.abs(r0.acc[sel, 2] - r1.acc[sel, 2]))) / STANDARD_GRAVITY
        res.repeatability = {"max_difference_g": diff, "runs": 2, "differ_by": "position-sensor noise seed"}
        res.checks.append(at_most("repeatability", "heave, largest acceleration difference", diff, "g",
                                  tol.repeatability.get("max_difference_g")))
