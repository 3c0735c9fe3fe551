"""Calibrating a machine's nominal parameters from calibration experiments: ``hexsim calibrate``.

A data sheet only brackets a real machine's valve flow gain, overlap, edge matching, supply level and
seal friction. Before effects are judged (``hexsim validate``), they are fitted, inside those brackets,
on calibration experiments: open-loop runs at constant valve commands in both directions and at
several commands (as the real servo cylinder's 1, 3 and 5 V runs, ``examples/data/servo_cylinder``).

**Features** (:func:`features`, measured on each log with the same functions a simulated run is read
with): every stretch of constant command (|u_v| > 0.05 V) gives

* a *steady motion* in the middle of the stroke (:func:`hexsim.simulation.metrics.steady_segments`): the
  speed and the median of each logged chamber pressure (p1, p2; ps if logged);
* an *end-stop plateau* where the command holds the piston against a stop: the chamber the valve
  connects to the supply reads P_s, the other the tank (4-way valve; the 3-way valve's cap side reads
  P_s or the tank).

**Model** (:func:`predict`): the steady motion of the machine file at that command against the load
along the axis (:func:`hexsim.plant.hydraulics.steady_state`: flow continuity in each chamber, seed eq.
3.4/3.7 with dP/dt = 0, and the piston's force balance, eq. 3.8 with the friction of eq. 3.9); at an
end stop P_s and P_t.

**Parameters** (:class:`Parameter`, :func:`default_parameters`): machine-file keys, each with bounds, the
bounds' source and the experiment that identifies it. A value edits the machine file by its key, so a
calibrated nominal is a machine file like any other.

**Fit** (:func:`calibrate`): bounded least squares (``scipy.optimize.least_squares``) on the features,
weighted by :data:`SPEED_SIGMA_REL` / :data:`SPEED_SIGMA_ABS` and :data:`PRESSURE_SIGMA`; standard
errors and correlations from the Jacobian, s^2 (J^T J)^-1 with s^2 the residual variance. A parameter
the data cannot separate (a standard error above :data:`MAX_SE_SHARE` of its bound range, or a
correlation beyond :data:`MAX_CORRELATION` with another, whichever has the larger relative error) is held
at its prior and the rest refitted; the report says why and which experiment would identify it. A fit
at a bound is reported as such: a hint that the model lacks something. Held-out logs are predicted, not
fitted; with three or more fitted logs each is also predicted by a fit on the others (leave one log out).
"""

from __future__ import annotations

import dataclasses
import json
import math
import pathlib
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from hexsim.errors import InputError, PhysicsError
from hexsim.measured.measurement import MeasurementLog
from hexsim.plant import hydraulics
from hexsim.plant.machine import KEYS, Machine, get_key, machine_from_document, shared_path, with_keys
from hexsim.plant.model import gravity, moving_mass
from hexsim.simulation.metrics import steady_segments

#: Weight of a steady speed: 1 % of it plus 0.5 mm/s (a line fit over a stretch of 1 kHz positions is far
#: more precise; the weight says how closely the steady model is asked to follow, not the sensor).
SPEED_SIGMA_REL = 0.01
SPEED_SIGMA_ABS = 5e-4
#: Weight of a median pressure [Pa]: 0.3 bar (the real rig's transducer noise; offsets of that size are common).
PRESSURE_SIGMA = 3e4
#: A parameter whose standard error exceeds this share of its bound range is not identified by the data.
MAX_SE_SHARE = 0.25
#: Two parameters this correlated trade against each other: the one known worse is held at its prior.
MAX_CORRELATION = 0.98
#: End-stop plateau: the last share of a stretch, slower than END_SPEED [m/s], its median within END_MARGIN_M
#: [m] of the observed end of the travel.
END_SHARE, END_SPEED, END_MARGIN_M = 0.4, 1e-3, 2e-3
_UNITS = {k.path: k.unit for k in KEYS} | {"valve.opening_table": "-"}


def _unit_of(key: str) -> str:
    """The unit of a parameter's key (a leg's own key: the shared key's; an element: its vector's)."""
    return _UNITS[shared_path(key.split("[")[0])]


@dataclass(frozen=True)
class Parameter:
    """One fitted quantity: its machine-file ``key`` (which sets its field and unit, and edits the model),
    the bounds [lower, upper] in that unit, where the bounds come from, and the experiment that
    identifies it."""

    key: str
    lower: float
    upper: float
    source: str
    experiment: str
    limit: str = ""  # the lower bound is a physical limit, not a bracket (what it is: "the tank at atmosphere")
    null_value: float | None = None  # what the key's null stands for (load.mass_kg null: the model's mass)

    def prior(self, doc: dict) -> float:
        """The parameter's value in the machine-file document ``doc`` (its null's meaning when null)."""
        value = get_key(doc, self.key)
        return float(self.null_value if value is None else value)

    @property
    def unit(self) -> str:
        return _unit_of(self.key)


def default_parameters(machine: Machine, dynamics: bool = False, hexapod: bool = False) -> list[Parameter]:
    """What a data sheet brackets and constant-command experiments identify, for ``machine``: the valve's
    flow gain (rated flow or port), overlap, null offset and the edges' matching (k_AT; with a 4-way
    valve k_PB, k_BT: k_PA is the reference the flow gain carries), the supply and tank pressures, the Coulomb
    friction per direction and, on an axis with weight along it, the moving mass. ``dynamics`` (evidence from
    transients, :mod:`hexsim.measured.dynamics`): also the smooth area's gain k_a (3.11) beside the port, the
    overlap of the port-limited area, the bulk modulus and dead volumes (3.7), the viscous and static friction
    per direction (3.9) and the moving mass on any axis (its inertia, 3.8). ``hexapod`` (the logs are a
    hexapod's): :func:`hexapod_parameters` instead."""
    if hexapod:
        return hexapod_parameters(machine)
    hyd, eff = machine.hydraulics, machine.effects
    doc = machine.document()

    def rel(key: str, lo: float, hi: float, source: str, experiment: str) -> Parameter:
        value = get_key(doc, key)
        return Parameter(key, lo * value, hi * value, source, experiment)

    big = "large commands in both directions (beyond half the range)"
    small = "small commands (a few % of the range) in both directions"
    if hyd.flow_area == "table":  # each point's opening (the port's width only scales them all: not fitted)
        params = [Parameter(f"valve.opening_table[{i}]", 0.7 * f, 1.3 * f, "the data sheet's flow curve within ±30 %",
                            f"commands near {u:g} V in both directions") for i, (u, f) in enumerate(hyd.opening_table)]
    elif not dynamics:
        params = [rel("valve.rated_flow_m3ps" if machine.rated_flow is not None else "valve.spool_diameter_m", 0.7,
                      1.3, "an unknown valve's flow gain within ±30 % of the guess (data sheets state ±10 %)", big)]
    else:  # the flow gain in the supply edge (the port's size the reference the shape is told against)
        params = [Parameter("valve.edge_gain_PA", 0.7 * eff.edge_gain_pa, 1.3 * eff.edge_gain_pa,
                            "an unknown valve's flow gain within ±30 % of the guess (data sheets state ±10 %)", big)]
    x_max = hyd.x_v_max
    transients = "transients: reversals and steps of a closed loop, or the switches of an open-loop experiment"
    if dynamics and hyd.flow_area in ("smooth", "port"):  # the shape: where (3.11) meets the port
        params.append(rel("valve.smooth_area_gain", 0.7, 1.3, "the flow curve's gain at small openings (3.11) "
                          "within ±30 % of the port's (data sheets state ±10 % flow tolerance)",
                          f"reversals and commands beyond 1 V ({transients})"))
    if hyd.flow_area == "sharp":
        params.append(Parameter("valve.overlap_m", -0.03 * x_max, 0.10 * x_max,
                                "−3 % (underlap) to +10 % of the spool stroke (servo valves ±0.5 %, proportional "
                                "valves up to 10 %)", small))
    elif dynamics and hyd.flow_area == "port":  # its dead band; the smooth area must still meet the port
        limit = math.pi * hyd.spool_diameter / (4.0 * hyd.smooth_area_gain * 1.3)
        params.append(Parameter("valve.overlap_m", 0.0, min(0.10 * x_max, 0.9 * limit),
                                "0 to 10 % of the spool stroke (proportional valves up to 10 %), below where (3.11) "
                                "no longer meets the port", f"reversals ({transients})"))
    params.append(Parameter("valve.null_offset_V", -0.03 * hyd.u_v_max, 0.03 * hyd.u_v_max,
                            "±3 % of the command range (servo-valve data sheets: ≤ 2–3 %)", small))
    edges = ("AT", "PB", "BT") if hyd.four_way else ("AT",)
    both = "both directions at several commands, with every chamber pressure logged"
    for edge in edges:
        params.append(Parameter(f"valve.edge_gain_{edge}", 0.8, 1.25,
                                "control edges matched within ±20 % (grinding tolerance, wear)", both))
    params.append(rel("supply.pressure_Pa", 0.9, 1.1, "±10 % of the set pressure (relief valve, gauge)",
                      "the piston held against an end stop with the valve open (that chamber reads P_s), or ps_Pa "
                      "logged"))
    params.append(Parameter("supply.tank_pressure_Pa", 0.0, 3e5, "return-line back pressure 0–3 bar (filter, "
                            "cooler, lines)", "the piston held against an end stop (the other chamber reads the "
                            "tank)", limit="the tank at atmospheric pressure"))
    speeds = "several speeds in each direction"
    for side in ("positive", "negative"):
        params.append(rel(f"friction.{side}.coulomb_N", 0.5, 2.0, "seal friction half to twice the guess (wear, "
                          "temperature, seal type)", speeds))
    if dynamics:
        for side in ("positive", "negative"):
            params.append(rel(f"friction.{side}.viscous_Nspm", 0.5, 2.0, "viscous seal friction half to twice the "
                              "guess (oil viscosity with temperature, seal type)", f"a range of speeds ({transients})"))
            params.append(rel(f"friction.{side}.static_N", 0.5, 2.0, "static (Stribeck) level half to twice the "
                              "guess", f"slow reversals ({transients})"))
        params.append(rel("oil.bulk_modulus_Pa", 0.4, 1.4, "effective bulk modulus: mineral oil 1.4–2.0 GPa, down to "
                          "less than half with hoses and undissolved air (Merritt §2.5)",
                          f"the oil spring's ringing and P1's rise ({transients})"))
        for side in ("cap", "rod") if hyd.four_way else ("cap",):
            params.append(rel(f"cylinder.dead_volume_{side}_m3", 0.5, 4.0, "hoses, manifold bores and the valve's "
                              "own volume, half to four times the drawing's", "the oil spring at both ends of the "
                              "stroke (it trades against the bulk modulus in mid-stroke)"))
    if dynamics or eff.inclination_deg is None or eff.inclination_deg < 80.0:
        mass = eff.mass_kg if eff.mass_kg is not None else moving_mass()
        params.append(Parameter("load.mass_kg", 0.5 * mass, 2.0 * mass, "the moving mass within half to twice the "
                                "guess (not weighed)", "the piston held at rest (P1 then carries the weight alone: at speed "
                                "the weight trades against the Coulomb friction), or weighing it", null_value=mass))
    return [p for p in params if p.upper > p.lower]


def hexapod_parameters(machine: Machine) -> list[Parameter]:
    """What a hexapod's closed-loop log identifies, for the hexapod ``machine``: each leg's valve, its supply
    and return edges' flow gains (k_PA, k_AT of that leg, the ``legs`` section: six valves are six data
    sheets' tolerances), the oil's bulk modulus, the legs' Coulomb friction per direction (one seal type),
    the payload (mass, and centre of gravity x, y, z in the platform frame) and the supply pressure (a log
    with ``ps_Pa`` states it: then not fitted)."""
    doc = machine.document()
    motion = "closed-loop motion of every leg in both directions (heave, roll, pitch, …)"
    params = []
    for leg in range(1, 7):
        for edge, what in (("PA", "supply edge P→A"), ("AT", "return edge A→T")):
            key = f"legs.leg{leg}.valve.edge_gain_{edge}"
            value = float(get_key(doc, key))
            params.append(Parameter(key, 0.6 * value, 1.5 * value, f"leg {leg}'s valve, its {what}: flow gain within "
                                    f"±30 % of the guess, edges matched within ±20 % (data sheets: ±10 %)",
                                    f"{motion}: leg {leg} extending and retracting"))
    for key, lo, hi, source, experiment in (
            ("oil.bulk_modulus_Pa", 0.4, 1.4, "effective bulk modulus: mineral oil 1.4–2.0 GPa, down to less than "
             "half with hoses and undissolved air (Merritt §2.5)", f"reversals ({motion}): the oil spring's ringing"),
            ("friction.positive.coulomb_N", 0.5, 2.0, "seal friction half to twice the guess", motion),
            ("friction.negative.coulomb_N", 0.5, 2.0, "seal friction half to twice the guess", motion)):
        value = float(get_key(doc, key))
        params.append(Parameter(key, lo * value, hi * value, source, experiment))
    platform, joints = _platform(machine)
    payload = machine.effects.payload_kg
    params.append(Parameter("load.payload_kg", payload - 0.3 * platform, payload + platform,
                            f"the platform's mass ({platform:.0f} kg in the model) −30 % to +100 % (not weighed, "
                            f"a payload on it)", "the platform at rest at the neutral pose (each leg's P1)"))
    radius = max(0.25, float(np.max(np.linalg.norm(joints[:, :2], axis=1))))
    for i in range(2):
        params.append(Parameter(f"load.payload_at_m[{i}]", -radius, radius, "within the platform joints' circle",
                                "the platform at rest (P1 of each leg), and a roll and a pitch"))
    params.append(Parameter("load.payload_at_m[2]", -0.2, 0.6, "0.2 m below to 0.6 m above the platform frame's "
                            "origin (a seat, a cockpit)", "surge and sway (the payload's height tilts the legs' "
                            "forces as the platform accelerates)"))
    params.append(Parameter("supply.pressure_Pa", 0.9 * machine.hydraulics.supply_pressure,
                            1.1 * machine.hydraulics.supply_pressure, "±10 % of the set pressure (relief valve, gauge)",
                            "ps_Pa logged"))
    return params


def _platform(machine: Machine) -> tuple[float, np.ndarray]:
    """(the platform's mass [kg], its joints (6, 3) [m] in the platform frame) in the hexapod's model (the
    built geometry's, or the user's MJCF's)."""
    from hexsim.control.kinematics import HexapodGeometry
    from hexsim.plant.model import load_model

    model = load_model("hexapod", geometry=machine.geometry)
    return float(model.body("platform").mass[0]), HexapodGeometry.from_model(model).platform


@dataclass(frozen=True)
class Feature:
    """One measured quantity of a calibration experiment: which log, the stretch's command u_V [V] and
    time span, ``kind`` ("steady" or "end stop"), ``quantity`` ("velocity", "p1", "p2", "ps"), the measured
    value (m/s or Pa) and its weight ``sigma`` (same unit)."""

    log: str
    kind: str
    u_V: float
    t_start_s: float
    t_end_s: float
    quantity: str
    measured: float
    sigma: float


_PRESSURES = (("p1", "p1_Pa"), ("p2", "p2_Pa"), ("ps", "ps_Pa"))


def features(log: MeasurementLog) -> list[Feature]:
    """The calibration features of an open-loop constant-command log (module doc). Raises InputError for a
    log without a valve command or without a stretch of constant command that moves the piston."""
    if log.system != "single-actuator":
        raise InputError(f"{log.path}: calibration reads single-actuator logs (this is {log.system})")
    c = log.columns
    t, u, y = log.time, c["valve_cmd_V"], c["pos_m"]
    pressures = {name: c[col] for name, col in _PRESSURES if col in c}
    name = log.path.name
    out = []
    for row in steady_segments(t, u, y, pressures):
        v = row["velocity_mps"]
        out.append(Feature(name, "steady", row["u_V"], row["t_start_s"], row["t_end_s"], "velocity", v,
                           SPEED_SIGMA_REL * abs(v) + SPEED_SIGMA_ABS))
        out += [Feature(name, "steady", row["u_V"], row["t_start_s"], row["t_end_s"], q, row[q], PRESSURE_SIGMA)
                for q in pressures]
    lo, hi = float(np.min(y)), float(np.max(y))
    change = np.flatnonzero(np.diff(u) != 0) + 1
    bounds = np.concatenate([[0], change, [len(t)]])
    fs = log.sample_rate_hz
    for a, b in zip(bounds[:-1], bounds[1:]):
        if abs(u[a]) <= 0.05 or b - a < 0.2 * fs:
            continue
        tail = np.arange(int(b - END_SHARE * (b - a)), b)
        stop = hi if u[a] > 0 else lo
        speed = abs(np.polynomial.polynomial.polyfit(t[tail], y[tail], 1)[1])
        if speed > END_SPEED or abs(float(np.median(y[tail])) - stop) > END_MARGIN_M:
            continue
        out += [Feature(name, "end stop", float(u[a]), float(t[tail[0]]), float(t[tail[-1]]), q,
                        float(np.median(p[tail])), PRESSURE_SIGMA) for q, p in pressures.items()]
    if not any(f.kind == "steady" for f in out):
        raise InputError(f"{log.path}: no stretch of constant valve command moves the piston through mid-stroke; "
                         f"calibration needs open-loop runs at constant commands (docs/calibration.md)")
    return out


def axis_load(log: MeasurementLog) -> tuple[float | None, float]:
    """(the moving mass the log's sidecar declares [kg] or None, g cos(inclination) along its axis
    [m/s^2]): what :func:`predict` needs of a log to compute the weight the piston lifts."""
    declared = log.mass_kg if "mass_kg" in log.sidecar else None
    return declared, gravity() * math.cos(math.radians(log.inclination_deg))


def _load_force(machine: Machine, load: tuple[float | None, float]) -> float:
    """M g cos(inclination) [N] with M the mass the log declares (that experiment's stated condition),
    else the machine's (the one being calibrated), else the model's."""
    declared, g_axis = load
    mass = declared if declared is not None else machine.effects.mass_kg
    return (mass if mass is not None else moving_mass()) * g_axis


def predict(feats: list[Feature], machine: Machine, loads: dict[str, float]) -> np.ndarray:
    """The model's value of each feature (same order, same units) on ``machine``; ``loads``: each log's
    :func:`axis_load` (the weight along the axis is the machine's mass on it). A stretch the valve cannot move against its load predicts
    no motion (velocity 0, pressures at their limits)."""
    hyd, eff = machine.hydraulics, machine.effects
    cache: dict[tuple[str, float], hydraulics.SteadyState | None] = {}
    out = np.empty(len(feats))
    for i, f in enumerate(feats):
        if f.kind == "end stop":
            feeds = "p1" if f.u_V > 0 else "p2"
            if f.quantity == "ps":
                out[i] = hyd.supply_pressure
            elif not hyd.four_way:
                out[i] = hyd.supply_pressure if f.u_V > 0 else hyd.tank_pressure
            else:
                out[i] = hyd.supply_pressure if f.quantity == feeds else hyd.tank_pressure
            continue
        key = (f.log, f.u_V)
        if key not in cache:
            try:
                cache[key] = hydraulics.steady_state(f.u_V, _load_force(machine, loads[f.log]), hyd, eff=eff)
            except ValueError:
                cache[key] = None
        s = cache[key]
        if s is None:
            out[i] = 0.0 if f.quantity == "velocity" else hyd.supply_pressure
        else:
            out[i] = {"velocity": s.velocity, "p1": s.p1, "p2": s.p2, "ps": hyd.supply_pressure}[f.quantity]
    return out


def with_values(machine: Machine, params: list[Parameter], values) -> Machine:
    """``machine`` with each parameter's key set to its value (:func:`hexsim.plant.machine.with_keys`)."""
    return with_keys(machine, {p.key: float(v) for p, v in zip(params, values)})


@dataclass
class Fit:
    """The outcome of one least-squares fit: values (len(params),) in the keys' units, standard errors,
    correlation matrix, weighted residuals, and the parameters held at their prior with the reason."""

    params: list[Parameter]
    values: np.ndarray
    std_errors: np.ndarray
    correlation: np.ndarray
    residuals: np.ndarray
    held: dict[str, str]


def steady_residual(feats: list[Feature], loads: dict) -> Callable[[Machine], np.ndarray]:
    """The weighted residual (predicted - measured) / sigma of the steady ``feats`` as a function of the machine."""
    measured = np.array([f.measured for f in feats])
    sigma = np.array([f.sigma for f in feats])
    return lambda m: (predict(feats, m, loads) - measured) / sigma


def _fit(residual_of: Callable[[Machine], np.ndarray], machine: Machine, params: list[Parameter],
         held: dict[str, str] | None = None, independent_share: Callable[[Machine], float] | None = None,
         diff_step: float = 1e-4, x_scale=1.0, warm: bool = False, initial: Machine | None = None,
         max_nfev: int | None = None, rule: bool = True, correlated_se: float = 0.0,
         notify=lambda text: None) -> Fit:
    """Bounded least squares of the free parameters (those not in ``held``) in normalised coordinates
    z = (x - lower) / (upper - lower) on the weighted residual ``residual_of(machine)``; then the
    held-at-prior rule of the module doc, refitting until no free parameter breaks it.
    ``independent_share``: independent samples per residual at a machine (replay residuals are not white;
    default all). ``warm``: after a parameter is held, refit from the values the others reached (the replay's
    cost is not convex: from the prior again it can fall into another valley), else from the prior.
    ``initial``: a machine whose values of ``params`` the search starts from (inside the brackets), instead
    of the prior's. ``max_nfev``: the most evaluations of one least-squares run (scipy's default without).
    ``rule`` False: one least-squares run of every parameter, no statistics and nothing held (a screening).
    ``correlated_se``: two parameters correlated beyond MAX_CORRELATION are both kept while the worse known
    has a standard error within this share of its bracket (:func:`_unidentified`).
    A machine the residual cannot be computed for (a physics error, an invalid file) costs
    as a residual of 1e3 per entry."""
    held = dict(held or {})
    n_res = len(residual_of(machine))

    def safe(m_values):
        try:
            return residual_of(with_values(machine, params, m_values))
        except (InputError, PhysicsError, FloatingPointError, ValueError):
            return np.full(n_res, 1e3)

    doc = machine.document()
    prior = np.array([p.prior(doc) for p in params], dtype=float)
    lo = np.array([p.lower for p in params])
    span = np.array([p.upper - p.lower for p in params])
    start = prior.copy() if initial is None else np.clip(
        [p.prior(initial.document()) for p in params], lo, lo + span)
    for i, p in enumerate(params):  # a parameter no feature sees across its whole bracket (a table point beyond
        if p.key in held or not rule:  # every command of the experiments, the mass of a horizontal axis) is not fitted
            continue
        # at the prior, and with the others at three quarters of their brackets (a payload's centre of gravity
        # moves nothing while its mass is the prior's 0)
        for others in (prior, lo + 0.75 * span):
            ends = []
            for value in (p.lower, p.upper):
                x = others.copy()
                x[i] = value
                ends.append(safe(x))
            if np.max(np.abs(ends[1] - ends[0])) >= 1e-3:
                break
        else:
            held[p.key] = "the features do not depend on it across its bracket"
    while True:
        free = [i for i, p in enumerate(params) if p.key not in held]
        x = prior.copy()
        if not free:
            return Fit(params, x, np.zeros(len(params)), np.eye(len(params)), residual_of(machine), held)

        def residual(z, free=free):
            x[free] = lo[free] + z * span[free]
            return safe(x)

        # from the previous fit's values (the prior the first time): holding one parameter should not throw
        # away where the others went
        z0 = np.clip((start[free] - lo[free]) / span[free], 0.0, 1.0)
        sol = least_squares(residual, z0, bounds=(0.0, 1.0), diff_step=diff_step, x_scale=x_scale,
                            max_nfev=max_nfev)
        notify(f"fitted {len(free)} parameters: {sol.nfev} evaluations, {sol.njev} Jacobians, cost {2 * sol.cost:.4g}")
        x[free] = lo[free] + sol.x * span[free]
        if warm:
            start = x.copy()
        if not rule:
            return Fit(params, x, np.zeros(len(params)), np.eye(len(params)), sol.fun, held)
        share = 1.0 if independent_share is None else independent_share(with_values(machine, params, x))
        se_z, corr = _statistics(sol, share)
        worst, why = _unidentified(sol, se_z, corr, [params[i].key for i in free], correlated_se)
        if worst is None:
            se = np.zeros(len(params))
            se[free] = se_z * span[free]
            full = np.eye(len(params))
            full[np.ix_(free, free)] = corr
            return Fit(params, x, se, full, sol.fun, held)
        notify(f"held at its prior: {params[free[worst]].key} ({why})")
        held[params[free[worst]].key] = why


def _statistics(sol, independent_share: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """(standard errors (k,) as shares of each bound range, correlations (k, k)) of a least-squares
    solution in bracket-normalised coordinates: s^2 (J^T J)^-1, s^2 the residual variance per independent
    residual (``independent_share`` of the residuals are independent: s^2 = SSR / (share n - k)). A parameter the
    fit pins at a bound is reported as at a bound and has no standard error (0); scipy's trf also returns
    its Jacobian column zeroed (the modified Jacobian of an active bound): statistics of the parameters
    inside their bounds only."""
    n, k = len(sol.fun), len(sol.x)
    s2 = float(sol.fun @ sol.fun) / max(independent_share * n - k, 1)
    inside = _inside(sol)
    jac = sol.jac[:, inside]
    se_z, corr = np.zeros(k), np.eye(k)
    if inside.any():
        cov = np.linalg.pinv(jac.T @ jac) * s2
        se_in = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        se_z[inside] = se_in
        unit = np.where(se_in > 0, se_in, 1.0)
        corr[np.ix_(inside, inside)] = cov / np.outer(unit, unit)
    return se_z, corr


def _inside(sol) -> np.ndarray:
    """(k,) bool: the parameters the fit left inside their bounds (normalised coordinates)."""
    return (sol.x > 1e-3) & (sol.x < 1 - 1e-3)


def _unidentified(sol, se_z: np.ndarray, corr: np.ndarray, keys: list[str],
                  correlated_se: float = 0.0) -> tuple[int | None, str]:
    """The free parameter the features cannot identify, and why (module doc: no sensitivity, a standard
    error above MAX_SE_SHARE of its bracket, or a correlation beyond MAX_CORRELATION, the worse known of
    the two, if its standard error is above ``correlated_se`` of its bracket: thousands of replayed samples
    separate two parameters correlated at 0.997 to 1e-4 of their brackets); (None, "") if every one is
    identified. ``keys``: the free parameters' keys."""
    inside = _inside(sol)
    norms = np.linalg.norm(sol.jac, axis=0)
    blind = inside & (norms < 1e-9 * max(float(norms.max()), 1e-300))
    if blind.any():
        return int(np.argmax(blind)), "the features do not depend on it"
    if inside.any():
        j = int(np.argmax(se_z))  # the standard error as a share of the bound range
        if se_z[j] > MAX_SE_SHARE:
            return j, f"its standard error is {se_z[j]:.0%} of its bound range"
    if inside.sum() > 1:
        c = np.abs(corr - np.eye(len(keys)))
        a, b = np.unravel_index(int(np.argmax(c)), c.shape)
        if c[a, b] > MAX_CORRELATION and max(se_z[a], se_z[b]) > correlated_se:
            worst = a if se_z[a] >= se_z[b] else b
            other = b if worst == a else a
            return worst, (f"it trades against {keys[other]} (correlation {corr[a, b]:+.3f}): the features cannot "
                           f"separate the two")
    return None, ""


def _errors(feats: list[Feature], predicted: np.ndarray) -> dict:
    """Speed errors (relative) and pressure errors [Pa] of predictions against the features."""
    speed = [abs(p / f.measured - 1.0) for f, p in zip(feats, predicted) if f.quantity == "velocity" and f.measured]
    press = [abs(p - f.measured) for f, p in zip(feats, predicted) if f.quantity != "velocity"]
    return {"speeds": len(speed), "speed_error_mean": float(np.mean(speed)) if speed else None,
            "speed_error_max": float(np.max(speed)) if speed else None, "pressures": len(press),
            "pressure_error_mean_Pa": float(np.mean(press)) if press else None,
            "pressure_error_max_Pa": float(np.max(press)) if press else None}


#: Evaluations of one least-squares run on transients (each a replay of the fit windows and a Jacobian of as
#: many replays as parameters): a full calibration, and the screening of a flow-area form (far from an
#: optimum, but it ranked the forms right on every machine measured, docs/calibration.md; the chosen form
#: then goes on from there).
FIT_NFEV, SCREEN_NFEV = 40, 10
#: Evaluations of one least-squares run on hexapod logs: each is a closed-loop replay of the whole log (0.8 s
#: for 20 s of the Micro Motion System) and a Jacobian of as many replays as parameters (20); the fit is
#: nearly linear in the legs' flow gains and converges in a few steps (docs/calibration.md).
HEXAPOD_NFEV = 8
#: A hexapod's flow-area forms are screened on the first this many segments of each log (0.25 s each, after
#: the first 0.5 s), with at most this many evaluations each.
HEXAPOD_SCREEN_SEGMENTS, HEXAPOD_SCREEN_NFEV = 24, 3
#: The flow-area forms of seed eq. (3.11) and (3.3) a calibration from transients tries for a valve of that
#: family (the seed's 300 x_v^2 and its port), keeping the one that predicts the held-out windows best.
SEED_FORMS = ("smooth", "port", "quadratic", "sharp")
DYNAMICS = ("auto", "always", "never")


def _is_steady(log: MeasurementLog) -> bool:
    """An open-loop constant-command experiment (:func:`features` finds a steady motion in it)."""
    if not log.open_loop:
        return False
    try:
        features(log)
    except InputError:
        return False
    return True


def _forms(machine: Machine, flow_areas: tuple[str, ...] | None) -> tuple[str, ...]:
    """The flow-area forms to calibrate: those asked for, else the machine's own and, for a valve of the
    seed's (3.11) family, the others of :data:`SEED_FORMS`."""
    own = machine.hydraulics.flow_area
    if flow_areas:
        return tuple(flow_areas)
    if own in SEED_FORMS[:3]:
        return (own, *(f for f in SEED_FORMS if f != own))
    return (own,)


def with_flow_area(machine: Machine, form: str) -> Machine:
    """``machine`` with its valve's flow-area form set to ``form`` (checked as any machine file: an underlap
    needs the sharp area). Raises InputError for a form the machine's valve cannot take."""
    doc = json.loads(json.dumps(machine.document()))
    doc["valve"]["flow_area"] = form
    if form != "table":
        doc["valve"]["opening_table"] = []
    return dataclasses.replace(machine_from_document(doc, machine.label), path=machine.path)


def calibrate(logs: list[MeasurementLog], machine: Machine, *, held_out: list[MeasurementLog] = (),
              params: list[Parameter] | None = None, cross_validate: bool = True, dynamics: str = "auto",
              flow_areas: tuple[str, ...] | None = None, notify=None) -> tuple[Machine, dict]:
    """Fit ``params`` (default :func:`default_parameters`) of ``machine`` to the evidence of ``logs`` (module
    doc); predict ``held_out``. Evidence: the steady features of open-loop constant-command experiments, and
    the transients of every other single-actuator log (:class:`hexsim.measured.dynamics.ReplayEvidence`:
    closed-loop motions, steps); ``dynamics`` "always" adds the transients of the constant-command
    experiments too, "never" reads steady features only. With transients the valve's flow-area form is
    chosen among ``flow_areas`` (default :func:`_forms`) by the held-out windows' cost, each form calibrated.

    Returns the calibrated machine (its ``calibration`` the report without the feature rows) and the
    report: per parameter prior, value, standard error, bounds and their source, status (fitted, at a bound,
    held at its prior: why, and the experiment that would identify it), the correlations of the fitted ones,
    the errors before/after on the fitted features and held-out windows, on each held-out log and
    (``cross_validate``, three or more steady logs) on each log left out of a refit, and the feature rows.
    Raises InputError for a log that is not evidence of either kind, or an unknown ``dynamics``."""
    from hexsim.measured.dynamics import ReplayEvidence

    if dynamics not in DYNAMICS:
        raise InputError(f"dynamics {dynamics!r}: expected one of {', '.join(DYNAMICS)}")
    notify = notify or (lambda text: None)
    systems = {log.system for log in (*logs, *held_out)}
    if len(systems) > 1:
        raise InputError("hexapod and single-actuator logs together: a calibration reads the logs of one machine")
    hexapod = systems == {"hexapod"}
    if hexapod and dynamics == "never":
        raise InputError("a hexapod is calibrated from its logs' transients (its closed-loop replay); dynamics "
                         "'never' reads only single-actuator constant-command experiments")
    steady = list(logs) if dynamics == "never" else [log for log in logs if _is_steady(log)]
    moving = [] if dynamics == "never" else list(logs) if dynamics == "always" else [
        log for log in logs if log not in steady]
    feats = [f for log in steady for f in features(log)]
    loads = {log.path.name: axis_load(log) for log in (*logs, *held_out)}
    if len(loads) < len(logs) + len(held_out):
        raise InputError("two logs of the same file name: calibration names features by their log's file name")
    evidence = [ReplayEvidence.of(log, machine) for log in moving]
    steady_of = steady_residual(feats, loads)

    def residual_over(evs: list[ReplayEvidence]) -> Callable[[Machine], np.ndarray]:
        return lambda m: np.concatenate([steady_of(m), *(ev.residual(m) for ev in evs)])

    residual_of = residual_over(evidence)

    def independent_share(m: Machine) -> float:
        sizes = [len(feats)] + [ev.residual_size for ev in evidence]
        shares = [1.0] + [ev.effective_share(m) for ev in evidence]
        return float(np.dot(sizes, shares) / max(sum(sizes), 1))

    forms = _forms(machine, flow_areas) if evidence else (machine.hydraulics.flow_area,)
    # a hexapod's forms are screened on the first segments of its logs (each replay is the whole log's)
    screened = [ev.prefix(HEXAPOD_SCREEN_SEGMENTS) for ev in evidence] if hexapod else evidence
    screen_nfev = HEXAPOD_SCREEN_NFEV if hexapod else SCREEN_NFEV
    replay = dict(independent_share=independent_share, diff_step=1e-3, x_scale="jac", warm=True,
                  max_nfev=HEXAPOD_NFEV if hexapod else FIT_NFEV, correlated_se=0.01,
                  notify=notify) if evidence else {"notify": notify}
    screen = len(forms) > 1
    tried: list[dict] = []
    for form in forms:  # each form from the prior: a form's calibrated values are another form's far valley
        try:
            start = machine if form == machine.hydraulics.flow_area else with_flow_area(machine, form)
        except InputError as exc:
            tried.append({"flow_area": form, "refused": str(exc)})
            continue
        form_params = list(params if params is not None else default_parameters(start, dynamics=bool(evidence),
                                                                                     hexapod=hexapod))
        notify(f"{'screening' if screen else 'calibrating'} {len(form_params)} parameters with the {form} flow area")
        judged = screened if screen else evidence
        fit = _fit(residual_over(judged), start, form_params,
                   **(replay | ({"max_nfev": screen_nfev, "rule": False} if screen else {})))
        result = with_values(start, form_params, fit.values)
        cost = sum(ev.errors(result)["held_out_cost"] for ev in judged)
        tried.append({"flow_area": form, "held_out_cost": cost, "start": start, "params": form_params, "fit": fit,
                      "machine": result})
    usable = [t for t in tried if "fit" in t]
    if not usable:
        raise InputError(f"{machine.label}: no flow-area form could be calibrated ({tried[0]['refused']})")
    best = min(usable, key=lambda t: t["held_out_cost"])
    start, params, fit, calibrated = best["start"], best["params"], best["fit"], best["machine"]
    if screen:  # the chosen form calibrated in full from where its screening ended
        notify(f"calibrating {len(params)} parameters with the {best['flow_area']} flow area")
        fit = _fit(residual_of, start, params, initial=calibrated, **replay)
        calibrated = with_values(start, params, fit.values)
    methods = []
    if feats:
        methods.append("steady motions and end-stop pressures")
    if evidence:
        methods.append("transients (closed-loop replay of the whole log, hexsim.measured.hexapod_replay)" if hexapod
                       else "transients (windowed valve replay, hexsim.measured.dynamics)")
    report = {"machine": machine.label, "logs": [str(log.path) for log in logs],
              "method": "bounded least squares of " + " and ".join(methods) + " (hexsim.measured.calibration)",
              "weights": {"speed": f"{SPEED_SIGMA_REL:.0%} + {SPEED_SIGMA_ABS * 1e3:g} mm/s",
                          "pressure_Pa": PRESSURE_SIGMA, "transients": "each channel's noise budget"},
              "parameters": _parameter_rows(fit),
              "correlation": {"keys": [p.key for p in params if p.key not in fit.held],
                              "matrix": _free_block(fit).round(4).tolist()}}
    if evidence:
        after = [ev.errors(calibrated) for ev in evidence]  # each log replayed once for the report
        report["flow_area"] = {"chosen": best["flow_area"], "prior": machine.hydraulics.flow_area,
                               "held_out_cost": sum(e["held_out_cost"] for e in after),
                               "tried": [{"flow_area": t["flow_area"], **({"held_out_cost": t["held_out_cost"]}
                                         if "fit" in t else {"refused": t["refused"]})} for t in tried]}
        report["transients"] = [{"before": ev.errors(machine), "after": a} for ev, a in zip(evidence, after)]
    _add_priors(report, start, params)
    if feats:
        before, after = predict(feats, machine, loads), predict(feats, calibrated, loads)
        report["fit"] = {"before": _errors(feats, before), "after": _errors(feats, after)}
    if held_out:
        report["held_out"] = _held_out(held_out, machine, calibrated, loads)
    steady_names = {log.path.name for log in steady}
    if cross_validate and len(steady) >= 3 and not evidence:
        rows = []
        for log in steady:
            rest = [f for f in feats if f.log != log.path.name]
            mine = [f for f in feats if f.log == log.path.name]
            refit = _fit(steady_residual(rest, loads), calibrated, params, fit.held)
            rows.append({"log": str(log.path), **_errors(mine, predict(mine, with_values(calibrated, params,
                                                                                           refit.values), loads))})
        report["leave_one_log_out"] = rows
    if feats:
        report["rows"] = [{**f.__dict__, "before": float(b), "after": float(a)}
                          for f, b, a in zip(feats, before, after) if f.log in steady_names]
    provenance = {k: v for k, v in report.items() if k != "rows"}
    sources = dict(calibrated.sources)
    if evidence and best["flow_area"] != machine.hydraulics.flow_area:
        sources["valve.flow_area"] = (f"hexsim calibrate from {len(logs)} log(s): {best['flow_area']} predicts the "
                                      f"held-out windows best (prior {machine.hydraulics.flow_area})")
    for row in report["parameters"]:
        if row["status"] != "held at its prior":
            key, _, index = row["key"].partition("[")  # a table point's source is its table's
            text = (f"{'point ' + index[:-1] + ': ' if index else ''}{row['value']:.6g} ± {row['std_error']:.2g} "
                    f"{row['unit']} (prior {row['prior']:.6g})")
            earlier = sources.get(key, "") if index else ""
            sources[key] = (f"{earlier}; {text}" if earlier.startswith("hexsim calibrate") else
                            f"hexsim calibrate from {len(logs)} log(s): {text}")
    calibrated = dataclasses.replace(calibrated, calibration=provenance, sources=tuple(sources.items()),
                                     description=(calibrated.description + " Calibrated by hexsim calibrate.").strip())
    return calibrated, report


def _held_out(logs: list[MeasurementLog], prior: Machine, calibrated: Machine, loads: dict) -> dict:
    """Held-out logs predicted by the prior and the calibrated machine: the steady features of the
    constant-command experiments (``before``/``after``), every window of the others
    (``transients``: held-out RMS in budgets)."""
    from hexsim.measured.dynamics import ReplayEvidence

    steady = [log for log in logs if _is_steady(log)]
    out: dict = {"logs": [str(log.path) for log in logs]}
    if steady:
        out_feats = [f for log in steady for f in features(log)]
        out["before"] = _errors(out_feats, predict(out_feats, prior, loads))
        out["after"] = _errors(out_feats, predict(out_feats, calibrated, loads))
    moving = [ReplayEvidence.of(log, prior, every_window=True) for log in logs if log not in steady]
    if moving:
        out["transients"] = [{"before": ev.errors(prior), "after": ev.errors(calibrated)} for ev in moving]
    return out


def _free_block(fit: Fit) -> np.ndarray:
    free = [i for i, p in enumerate(fit.params) if p.key not in fit.held]
    return fit.correlation[np.ix_(free, free)]


def _parameter_rows(fit: Fit) -> list[dict]:
    rows = []
    for p, value, se in zip(fit.params, fit.values, fit.std_errors):
        row = {"key": p.key, "unit": p.unit, "value": float(value), "std_error": float(se),
               "lower": p.lower, "upper": p.upper, "bounds_source": p.source, "experiment": p.experiment}
        span = p.upper - p.lower
        if p.key in fit.held:
            row.update(status="held at its prior", why=fit.held[p.key])
        elif p.limit and value - p.lower <= 1e-3 * span:
            row.update(status="at its physical limit", why=p.limit)
        elif min(value - p.lower, p.upper - value) <= 1e-3 * span:
            row.update(status="at a bound", why="the fit ran into the bound: the data asks for more than the "
                       "bracket allows, a hint that the model lacks an effect or the bracket is wrong")
        else:
            row["status"] = "fitted"
        rows.append(row)
    return rows


def _add_priors(report: dict, machine: Machine, params: list[Parameter]) -> None:
    """Each parameter row's prior (the machine's value before calibration), in place."""
    doc = machine.document()
    for row, p in zip(report["parameters"], params):
        row["prior"] = p.prior(doc)


def table(report: dict) -> str:
    """The report as lines for stdout: parameters, then errors before/after, held out, left out."""
    lines = [f"{'parameter':30s} {'prior':>11s} {'calibrated':>11s} {'± s.e.':>9s}  status"]
    for r in report["parameters"]:
        tail = r["status"] if r["status"] == "fitted" else f"{r['status']}: {r['why']}"
        if r["status"] == "held at its prior":
            tail += f"; identify it with {r['experiment']}"
        lines.append(f"{r['key']:30s} {r['prior']:11.5g} {r['value']:11.5g} {r['std_error']:9.2g}  {tail}")

    def errs(e: dict) -> str:
        s = (f"speed {e['speed_error_mean']:.1%} mean, {e['speed_error_max']:.1%} worst ({e['speeds']})"
             if e["speeds"] else "no speed")
        if e["pressures"]:
            s += (f"; pressure {e['pressure_error_mean_Pa'] / 1e5:.2f} bar mean, "
                  f"{e['pressure_error_max_Pa'] / 1e5:.2f} bar worst ({e['pressures']})")
        return s

    def budgets(e: dict) -> str:
        return ", ".join(f"{ch} {v:.3g}" for ch, v in e["held_out_rms_in_budgets"].items() if ch != "p_s")

    def transients(rows: list[dict], what: str) -> None:
        for row in rows:
            head = f"{what} {pathlib.Path(row['before']['log']).name} (RMS / budget) before: "
            lines.extend([head + budgets(row["before"]), f"{'after: ':>{len(head)}s}{budgets(row['after'])}"])

    if "flow_area" in report:
        fa = report["flow_area"]
        lines.append(f"flow area        {fa['chosen']} (prior {fa['prior']}; held-out cost {fa['held_out_cost']:.4g}); "
                     f"{'screened' if len(fa['tried']) > 1 else 'held-out cost'}: " + ", ".join(
            f"{t['flow_area']} {t['held_out_cost']:.4g}" if "held_out_cost" in t else f"{t['flow_area']} refused"
            for t in fa["tried"]))
    if "fit" in report:
        lines.append(f"fitted features  before: {errs(report['fit']['before'])}")
        lines.append(f"                 after:  {errs(report['fit']['after'])}")
    transients(report.get("transients", []), "held-out windows of")
    held = report.get("held_out", {})
    if "before" in held:
        lines.append(f"held-out logs    before: {errs(held['before'])}")
        lines.append(f"                 after:  {errs(held['after'])}")
    transients(held.get("transients", []), "held-out log")
    for row in report.get("leave_one_log_out", []):
        lines.append(f"left out {pathlib.Path(row['log']).name:22s} {errs(row)}")
    return "\n".join(lines)


#: A nominal this far off a log's steady motions is "visibly off": validate says to calibrate first.
OFF_SPEED, OFF_PRESSURE = 0.03, 1e5


def nominal_check(log: MeasurementLog) -> dict | None:
    """How far an uncalibrated machine is from an open-loop constant-command log's steady motions, and, if
    visibly off (speeds beyond :data:`OFF_SPEED` or pressures beyond :data:`OFF_PRESSURE` [Pa]), which
    parameters a calibration on this log alone moves beyond two standard errors and 5 % of their
    bracket: the ``sentence`` that
    ``hexsim validate`` puts first ("calibrate first"). None for a machine that was calibrated, or a
    log without a steady motion."""
    if log.machine.calibration is not None or log.system != "single-actuator" or "valve_cmd_V" not in log.columns:
        return None
    try:
        feats = features(log)
    except InputError:
        return None
    loads = {log.path.name: axis_load(log)}
    err = _errors(feats, predict(feats, log.machine, loads))
    off = (err["speed_error_max"] or 0.0) > OFF_SPEED or (err["pressure_error_max_Pa"] or 0.0) > OFF_PRESSURE
    out = {"off": bool(off), **err}
    if not off:
        return out
    _, report = calibrate([log], log.machine, cross_validate=False, dynamics="never")
    moved = _moved(report)
    out["moved"] = moved
    what = []
    if err["speed_error_max"]:
        what.append(f"speeds up to {err['speed_error_max']:.1%} off")
    if err["pressure_error_max_Pa"]:
        what.append(f"pressures up to {err['pressure_error_max_Pa'] / 1e5:.2f} bar off")
    changes = _changes(moved)
    out["sentence"] = (f"The machine's nominal is visibly off this log's steady motions ({', '.join(what)}): calibrate "
                       f"first (hexsim calibrate, docs/calibration.md), then judge effects on the calibrated machine"
                       + (f"; a calibration on this log alone moves {changes}" if changes else "") + ".")
    return out


def _moved(report: dict) -> list[dict]:
    """The parameters a calibration moved beyond two standard errors and 5 % of their bracket."""
    return [{k: r[k] for k in ("key", "prior", "value", "std_error", "unit", "status")} for r in report["parameters"]
            if r["status"] != "held at its prior"
            and abs(r["value"] - r["prior"]) > max(2.0 * r["std_error"], 0.05 * (r["upper"] - r["lower"]))]


def _changes(moved: list[dict]) -> str:
    return ", ".join(f"{r['key']} {r['prior']:.4g} → {r['value']:.4g} {r['unit']}"
                     + (" (at a bound)" if r["status"] == "at a bound" else "") for r in moved)


def transient_check(log: MeasurementLog) -> dict | None:
    """For a log that is no constant-command experiment, judged against a machine that was never calibrated:
    what a calibration from this log's own transients (:mod:`hexsim.measured.dynamics`, the machine's own
    flow-area form) moves and how far it brings the held-out windows, as the ``sentence`` ``hexsim
    validate`` puts first when its verdict is not ``none``: the nominal may be what is off, not an effect.
    None for a calibrated machine, a hexapod log, or a log the replay cannot use."""
    if log.machine.calibration is not None or log.system != "single-actuator":
        return None
    try:
        _, report = calibrate([log], log.machine, flow_areas=(log.machine.hydraulics.flow_area,),
                              cross_validate=False, dynamics="always")
    except (InputError, PhysicsError):  # a log the replay cannot use: validate's own answer stands alone
        return None
    before = report["transients"][0]["before"]["held_out_rms_in_budgets"]
    after = report["transients"][0]["after"]["held_out_rms_in_budgets"]
    moved = _moved(report)
    worst = max(before, key=lambda ch: before[ch])
    sentence = (f"This machine was never calibrated, and a calibration of its nominal from this log's own transients "
                f"brings the held-out {worst} from {before[worst]:.3g} to {after[worst]:.3g} budgets"
                + (f", moving {_changes(moved)}" if moved else "") + ": calibrate on calibration experiments of the "
                "machine first (hexsim calibrate, docs/calibration.md), then judge effects on the calibrated machine; "
                "an effect found on the uncalibrated file may be the nominal's error.")
    return {"off": bool(moved), "moved": moved, "held_out_rms_in_budgets": {"before": before, "after": after},
            "sentence": sentence}


def hexapod_hint(log: MeasurementLog) -> dict:
    """For a hexapod log judged against a machine that was never calibrated: the sentence ``hexsim validate``
    puts first when its verdict is not ``none``. Not measured (a hexapod's calibration takes minutes,
    :func:`calibrate`): six valves each within their data sheet's tolerance, a payload and the oil are
    the first suspects of a replay that misses on every leg."""
    return {"off": True, "moved": {}, "sentence": (
        f"The machine {log.machine.label} was never calibrated: each leg's valve (its edges' flow gains within a "
        f"data sheet's ±10 %), the oil's bulk modulus, the seals' friction and the payload may be what is off, not an "
        f"effect. Calibrate it first on a closed-loop log of the machine (hexsim calibrate LOG --out CAL.json, "
        f"docs/calibration.md), then judge effects with --machine CAL.json.")}


def markdown(report: dict, figure: str | None = None) -> str:
    """report.md of a calibration: the machine and logs, the parameters (prior, value, standard error,
    bounds and their source, status and why), the errors before and after, held out and left out."""
    lines = [f"# Calibration of {report['machine']}", "", f"Method: {report['method']}; weights: speed "
             f"{report['weights']['speed']}, pressure {report['weights']['pressure_Pa'] / 1e5:g} bar.", "",
             "Logs fitted: " + ", ".join(f"`{pathlib.Path(p).name}`" for p in report["logs"]), ""]
    if "held_out" in report:
        lines += ["Logs held out: " + ", ".join(f"`{pathlib.Path(p).name}`" for p in report["held_out"]["logs"]), ""]
    lines += ["| key | unit | prior | calibrated | ± s.e. | bounds | bounds from | status |", "|---|---|---|---|---|---|---|---|"]
    for r in report["parameters"]:
        status = r["status"] + (f": {r['why']}" if "why" in r else "")
        if r["status"] == "held at its prior":
            status += f"; identify it with {r['experiment']}"
        lines.append(f"| `{r['key']}` | {r['unit']} | {r['prior']:.5g} | {r['value']:.5g} | {r['std_error']:.2g} | "
                     f"{r['lower']:.4g} … {r['upper']:.4g} | {r['bounds_source']} | {status} |")
    lines += ["", "```", table(report).split("\n", len(report["parameters"]) + 1)[-1], "```", ""]
    if figure:
        lines += [f"![measured against predicted features]({figure})", ""]
    return "\n".join(lines)


def plot_features(report: dict, path) -> None:
    """Each fitted feature's error, before (the machine file) and after calibration, against its measured
    value: speeds as relative errors [%], pressures in bar; and, with transients, each log's held-out
    windows' RMS per channel in budgets before and after; written atomically (.png, .pdf or .svg)."""
    from matplotlib.figure import Figure  # no pyplot: the user's backend is never switched

    from hexsim.outputs.plotting import save_figure

    rows = report.get("rows", [])
    transients = report.get("transients", [])
    fig = Figure(figsize=(5.5 * (2 * bool(rows) + bool(transients)), 4.5), layout="constrained")
    axes = list(fig.subplots(1, 2 * bool(rows) + bool(transients), squeeze=False)[0])
    if transients:
        ax = axes.pop()
        labels, before, after = [], [], []
        for row in transients:
            name = pathlib.Path(row["before"]["log"]).stem
            for ch, v in row["before"]["held_out_rms_in_budgets"].items():
                if ch != "p_s":
                    labels.append(f"{name}\n{ch}")
                    before.append(v)
                    after.append(row["after"]["held_out_rms_in_budgets"][ch])
        x = np.arange(len(labels))
        ax.bar(x - 0.2, before, 0.4, label="the machine file")
        ax.bar(x + 0.2, after, 0.4, label="calibrated")
        ax.axhline(math.sqrt(2.0), color="k", lw=0.6, ls="--")
        ax.set_yscale("log")
        ax.set_xticks(x, labels, fontsize=7, rotation=60)
        ax.set(title="transients: held-out windows", ylabel="RMS / budget (dashed: √2)")
        ax.legend(fontsize=8)
    if not rows:
        fig.suptitle(f"hexsim calibrate: {report['machine']}")
        save_figure(fig, path, dpi=90)
        return
    speed_ax, press_ax = axes
    panels = ((speed_ax, lambda r: r["quantity"] == "velocity", "steady speeds", "measured speed [mm/s]",
               "predicted / measured − 1 [%]", lambda r, k: 100.0 * (r[k] / r["measured"] - 1.0), 1e3),
              (press_ax, lambda r: r["quantity"] != "velocity", "chamber pressures (steady, end stops)",
               "measured pressure [bar]", "predicted − measured [bar]", lambda r, k: (r[k] - r["measured"]) / 1e5, 1e-5))
    for ax, pick, title, xlabel, ylabel, error, scale in panels:
        sel = [r for r in rows if pick(r)]
        x = np.array([r["measured"] for r in sel]) * scale
        for key, marker, label in (("before", "x", "the machine file"), ("after", "o", "calibrated")):
            ax.plot(x, [error(r, key) for r in sel], marker, ms=5, ls="none", label=label)
        ax.axhline(0.0, color="k", lw=0.6)
        ax.set(title=title, xlabel=xlabel, ylabel=ylabel)
        ax.legend(fontsize=8)
    fig.suptitle(f"hexsim calibrate: {report['machine']}, fitted features")
    save_figure(fig, path, dpi=90)
