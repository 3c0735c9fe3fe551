"""The one vocabulary of a fitted quantity (:class:`Parameter`), and the parameters a calibration fits
(:mod:`hexsim.measured.calibration`).

A :class:`Parameter` is a name (a machine-file key, or an effect's or friction's parameter name), its unit, the
range [lower, upper] it is fitted in with where that range comes from, the experiment that identifies it and
what its values mean (a physical limit at the lower bound, the value that switches its effect off, the value
the model without it has); :meth:`Parameter.estimate` turns a fitted value into an
:class:`~hexsim.measured.estimates.Estimate` by the one rule for "at a bound". The calibration
(:func:`default_parameters`, :func:`hexapod_parameters`), the identifier's candidates
(:data:`hexsim.measured.candidates.CANDIDATES`) and friction (:data:`hexsim.measured.friction_id.PARAMETERS`)
declare theirs with it.

A calibration parameter's key sets its field, its unit (the machine file's, :data:`hexsim.plant.machine_keys.KEYS`)
and how it edits the model (:func:`hexsim.plant.machine.with_keys`): a calibrated nominal is a machine file like
any other; a :class:`ParameterSet` reads their priors from a machine (the nominal,
:class:`hexsim.plant.machine.Machine`) and writes values into one. :func:`default_parameters` is what a data
sheet brackets on one actuator, :func:`hexapod_parameters` on a hexapod (docs/calibration.md lists both with
their sources).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import numpy as np

from hexsim.measured.estimates import Estimate
from hexsim.plant.machine import Machine, get_key, shared_path, with_keys
from hexsim.plant.machine_keys import KEYS

_UNITS = {k.path: k.unit for k in KEYS} | {"valve.opening_table": "-"}


def _unit_of(key: str) -> str:
    """The unit of a parameter's key (a leg's own key: the shared key's; an element: its vector's)."""
    return _UNITS[shared_path(key.split("[")[0])]


@dataclass(frozen=True)
class Parameter:
    """One fitted quantity: its ``key`` (a machine-file key, which sets its field and unit and edits the model;
    or an effect's or friction's parameter name), the range [``lower``, ``upper``] it is fitted in, in ``unit``
    (default: the machine file's unit of ``key``; a name that is no machine-file key must give one), where the
    range comes from (``source``) and the experiment that identifies it. What its values mean:
    ``limit``, the lower bound is a physical limit, not a bracket (what it is: "the tank at atmosphere");
    ``null_value``, what the key's null stands for (load.mass_kg null: the model's mass); ``no_effect``, the
    value that switches an effect off (a fit there found nothing); ``neutral``, the value the model without the
    effect has, where a screening linearises (default ``no_effect``; an edge gain of 1 is neutral but a fitted
    1.0 next to a 0.9 is still an effect); ``scale``, its typical size where the range is only a limit (the
    fit's x_scale and the scale of "at a bound", :func:`hexsim.measured.estimates.at_bound`).
    Raises KeyError for a ``key`` without a unit that is no machine-file key."""

    key: str
    lower: float
    upper: float
    source: str = ""
    experiment: str = ""
    limit: str = ""
    null_value: float | None = None
    unit: str = ""
    no_effect: float | None = None
    neutral: float | None = None
    scale: float | None = None

    def __post_init__(self) -> None:
        if not self.unit:
            object.__setattr__(self, "unit", _unit_of(self.key))

    def prior(self, doc: dict) -> float:
        """The parameter's value in the machine-file document ``doc`` (its null's meaning when null)."""
        value = get_key(doc, self.key)
        return float(self.null_value if value is None else value)

    @property
    def origin(self) -> float | None:
        """Where a screening linearises: :attr:`neutral`, else :attr:`no_effect` (None: nowhere in particular)."""
        return self.no_effect if self.neutral is None else self.neutral

    def estimate(self, value: float, std_error: float, held: str | None = None,
                 bounds: tuple[float, float] | None = None) -> Estimate:
        """The :class:`~hexsim.measured.estimates.Estimate` of a fit that left this parameter at ``value`` ±
        ``std_error`` (:meth:`Estimate.judged <hexsim.measured.estimates.Estimate.judged>`: ``held`` (why) at
        its prior, at its physical :attr:`limit`, at a bound of the range or fitted). ``bounds``: the range the
        fit ran in where a log narrowed it (:func:`hexsim.measured.candidates.plausible_bounds`); default
        [lower, upper]."""
        lower, upper = (self.lower, self.upper) if bounds is None else bounds
        return Estimate.judged(self.key, value, std_error, self.unit, lower, upper, held=held, limit=self.limit,
                               scale=self.scale)

    def row(self, estimate: Estimate) -> dict:
        """A report row of this parameter's ``estimate`` (:meth:`Estimate.as_row
        <hexsim.measured.estimates.Estimate.as_row>`) with where its bounds come from and the experiment that
        identifies it (``bounds_source``, ``experiment``)."""
        return estimate.as_row() | {"bounds_source": self.source, "experiment": self.experiment}


class ParameterSet:
    """The parameters of one fit, in order: their keys, bounds (k,) in the keys' units, their priors in a
    machine and the machine a vector of values makes. Raises ValueError for a key given twice."""

    def __init__(self, members: Iterable[Parameter]) -> None:
        self.members = tuple(members)
        keys = [p.key for p in self.members]
        if len(set(keys)) != len(keys):
            raise ValueError(f"a parameter given twice: {sorted(k for k in set(keys) if keys.count(k) > 1)}")
        self.lower = np.array([p.lower for p in self.members], dtype=float)
        self.upper = np.array([p.upper for p in self.members], dtype=float)

    def __iter__(self) -> Iterator[Parameter]:
        return iter(self.members)

    def __len__(self) -> int:
        return len(self.members)

    def __getitem__(self, i: int) -> Parameter:
        return self.members[i]

    @property
    def keys(self) -> list[str]:
        return [p.key for p in self.members]

    @property
    def span(self) -> np.ndarray:
        """(k,) upper - lower, in the keys' units."""
        return self.upper - self.lower

    def priors(self, machine: Machine) -> np.ndarray:
        """(k,) each parameter's value in ``machine`` (its null's meaning where the file says null)."""
        doc = machine.document()
        return np.array([p.prior(doc) for p in self.members], dtype=float)

    def apply(self, machine: Machine, values) -> Machine:
        """``machine`` with each parameter's key set to its value in ``values`` (k,)
        (:func:`hexsim.plant.machine.with_keys`: the file's own checks apply; InputError if one fails)."""
        return with_keys(machine, {p.key: float(v) for p, v in zip(self.members, values)})


#: A valve's null offset is bracketed as a servo-valve data sheet's zero point: ±3 % of the command range
#: (the machine's ``valve.null_offset_V``, and each hexapod leg's, :func:`leg_null_parameter`).
NULL_RANGE = 0.03

#: The experiments that identify what only transients show.
_TRANSIENTS = "transients: reversals and steps of a closed loop, or the switches of an open-loop experiment"


def _relative(doc: dict, key: str, lo: float, hi: float, source: str, experiment: str) -> Parameter:
    """The parameter ``key`` bracketed by ``lo`` and ``hi`` times its value in the machine-file document ``doc``."""
    value = float(get_key(doc, key))
    return Parameter(key, lo * value, hi * value, source, experiment)


def default_parameters(machine: Machine, dynamics: bool = False, hexapod: bool = False, timing: bool = False
                       ) -> ParameterSet:
    """What a data sheet brackets and constant-command experiments identify, for ``machine``: the valve's
    flow gain (rated flow or port), overlap, null offset and the edges' matching (k_AT; with a 4-way
    valve k_PB, k_BT: k_PA is the reference the flow gain carries), the supply and tank pressures, the Coulomb
    friction per direction and, on an axis with weight along it, the moving mass. ``dynamics`` (evidence from
    transients, :mod:`hexsim.measured.dynamics`): also the smooth area's gain k_a (3.11) beside the port, the
    overlap of the port-limited area, the bulk modulus and dead volumes (3.7), the viscous and static friction
    per direction (3.9), the moving mass on any axis (its inertia, 3.8) and, with ``timing`` (logs whose valve
    command jumps, which alone show it), when the logs' sensors were read (:func:`_timing_parameters`).
    ``hexapod`` (the logs are a hexapod's): :func:`hexapod_parameters` instead."""
    if hexapod:
        return hexapod_parameters(machine)
    doc = machine.document()
    params = [*_valve_parameters(machine, doc, dynamics), *_supply_parameters(doc),
              *_friction_and_oil_parameters(machine, doc, dynamics),
              *(_timing_parameters(machine) if dynamics and timing else ())]
    eff = machine.effects
    if dynamics or eff.inclination_deg is None or eff.inclination_deg < 80.0:
        mass = machine.moving_mass_kg
        params.append(Parameter("load.mass_kg", 0.5 * mass, 2.0 * mass, "the moving mass within half to twice the "
                                "guess (not weighed)", "the piston held at rest (P1 then carries the weight alone: at "
                                "speed the weight trades against the Coulomb friction), or weighing it",
                                null_value=mass))
    return ParameterSet(p for p in params if p.upper > p.lower)


#: The acquisition's timing is fitted within this much [s] either way: a sample of a 1 kHz log.
SKEW_RANGE = 1e-3


def _timing_parameters(machine: Machine) -> list[Parameter]:
    """When the logs' sensors were read against their valve command (:mod:`hexsim.measured.acquisition`): the
    position's and pressures' skew and, for an accelerometer sampled at an instant, that instant."""
    why = ("within a sample of a 1 kHz log either way (converters that read after the command goes out, or a "
           "command that reaches the valve after the sensors were read)")
    steps = "steps of the valve command (the pressure's first millisecond, the oil spring's ringing)"
    params = [Parameter("sensors.sample_skew_s", -SKEW_RANGE, SKEW_RANGE, why, steps)]
    if machine.sensors.acceleration_sampling == "instant":
        params.append(Parameter("sensors.acceleration_skew_s", -SKEW_RANGE, SKEW_RANGE, why, steps))
    return params


def _valve_parameters(machine: Machine, doc: dict, dynamics: bool) -> list[Parameter]:
    """The valve's part of :func:`default_parameters`: flow gain (or each table point), the smooth area's gain,
    overlap, null offset, the edges' matching."""
    hyd, eff = machine.hydraulics, machine.effects
    big = "large commands in both directions (beyond half the range)"
    small = "small commands (a few % of the range) in both directions"
    if hyd.flow_area == "table":  # each point's opening (the port's width only scales them all: not fitted)
        params = [Parameter(f"valve.opening_table[{i}]", 0.7 * f, 1.3 * f, "the data sheet's flow curve within ±30 %",
                            f"commands near {u:g} V in both directions") for i, (u, f) in enumerate(hyd.opening_table)]
    elif not dynamics:
        key = "valve.rated_flow_m3ps" if machine.rated_flow is not None else "valve.spool_diameter_m"
        params = [_relative(doc, key, 0.7, 1.3, "an unknown valve's flow gain within ±30 % of the guess (data sheets "
                            "state ±10 %)", big)]
    else:  # the flow gain in the supply edge (the port's size the reference the shape is told against)
        params = [Parameter("valve.edge_gain_PA", 0.7 * eff.edge_gain_pa, 1.3 * eff.edge_gain_pa,
                            "an unknown valve's flow gain within ±30 % of the guess (data sheets state ±10 %)", big)]
    x_max = hyd.x_v_max
    if dynamics and hyd.flow_area in ("smooth", "port", "rounded"):  # the shape: where (3.11) meets the port
        params.append(_relative(doc, "valve.smooth_area_gain", 0.7, 1.3, "the flow curve's gain at small openings "
                                "(3.11) within ±30 % of the port's (data sheets state ±10 % flow tolerance)",
                                f"reversals and commands beyond 1 V ({_TRANSIENTS})"))
    if hyd.flow_area == "sharp":
        params.append(Parameter("valve.overlap_m", -0.03 * x_max, 0.10 * x_max,
                                "−3 % (underlap) to +10 % of the spool stroke (servo valves ±0.5 %, proportional "
                                "valves up to 10 %)", small))
    elif dynamics and hyd.flow_area in ("port", "rounded"):  # its dead band (port) or where the port's line
        # lies (rounded: its corner); the smooth area must still meet the port
        limit = math.pi * hyd.spool_diameter / (4.0 * hyd.smooth_area_gain * 1.3)
        params.append(Parameter("valve.overlap_m", 0.0, min(0.10 * x_max, 0.9 * limit),
                                "0 to 10 % of the spool stroke (proportional valves up to 10 %), below where (3.11) "
                                "no longer meets the port", f"reversals ({_TRANSIENTS})"))
    params.append(Parameter("valve.null_offset_V", -NULL_RANGE * hyd.u_v_max, NULL_RANGE * hyd.u_v_max,
                            "±3 % of the command range (servo-valve data sheets: ≤ 2–3 %)", small))
    both = "both directions at several commands, with every chamber pressure logged"
    for edge in ("AT", "PB", "BT") if hyd.four_way else ("AT",):
        params.append(Parameter(f"valve.edge_gain_{edge}", 0.8, 1.25,
                                "control edges matched within ±20 % (grinding tolerance, wear)", both))
    return params


def _supply_parameters(doc: dict) -> list[Parameter]:
    """The supply's part of :func:`default_parameters`: its set pressure and the tank's back pressure."""
    return [_relative(doc, "supply.pressure_Pa", 0.9, 1.1, "±10 % of the set pressure (relief valve, gauge)",
                      "the piston held against an end stop with the valve open (that chamber reads P_s), or ps_Pa "
                      "logged"),
            Parameter("supply.tank_pressure_Pa", 0.0, 3e5, "return-line back pressure 0–3 bar (filter, "
                      "cooler, lines)", "the piston held against an end stop (the other chamber reads the "
                      "tank)", limit="the tank at atmospheric pressure")]


def _friction_and_oil_parameters(machine: Machine, doc: dict, dynamics: bool) -> list[Parameter]:
    """The seal friction per direction (Coulomb; with ``dynamics`` viscous and static too) and, with
    ``dynamics``, the oil spring: bulk modulus and dead volumes."""
    speeds = "several speeds in each direction"
    params = [_relative(doc, f"friction.{side}.coulomb_N", 0.5, 2.0, "seal friction half to twice the guess (wear, "
                        "temperature, seal type)", speeds) for side in ("positive", "negative")]
    if not dynamics:
        return params
    for side in ("positive", "negative"):
        params.append(_relative(doc, f"friction.{side}.viscous_Nspm", 0.5, 2.0, "viscous seal friction half to twice "
                                "the guess (oil viscosity with temperature, seal type)",
                                f"a range of speeds ({_TRANSIENTS})"))
        params.append(_relative(doc, f"friction.{side}.static_N", 0.5, 2.0, "static (Stribeck) level half to twice "
                                "the guess", f"slow reversals ({_TRANSIENTS})"))
    params.append(_relative(doc, "oil.bulk_modulus_Pa", 0.4, 1.4, "effective bulk modulus: mineral oil 1.4–2.0 GPa, "
                            "down to less than half with hoses and undissolved air (Merritt §2.5)",
                            f"the oil spring's ringing and P1's rise ({_TRANSIENTS})"))
    for side in ("cap", "rod") if machine.hydraulics.four_way else ("cap",):
        params.append(_relative(doc, f"cylinder.dead_volume_{side}_m3", 0.5, 4.0, "hoses, manifold bores and the "
                                "valve's own volume, half to four times the drawing's", "the oil spring at both ends "
                                "of the stroke (it trades against the bulk modulus in mid-stroke)"))
    return params


def leg_null_parameter(machine: Machine, leg: int) -> Parameter:
    """Hexapod leg ``leg``'s valve null offset (``legs.legN.valve.null_offset_V``), found from its static tracking
    error after the other parameters are fitted (:func:`hexsim.measured.calibration.leg_null_offsets`), within
    ±:data:`NULL_RANGE` of the command range."""
    bound = NULL_RANGE * machine.hydraulics.u_v_max
    return Parameter(f"legs.leg{leg}.valve.null_offset_V", -bound, bound,
                     "servo-valve data sheets: zero point within 2–3 % of the command range",
                     "closed-loop motion of that leg (its static tracking error)")


def hexapod_parameters(machine: Machine) -> ParameterSet:
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
            params.append(_relative(doc, f"legs.leg{leg}.valve.edge_gain_{edge}", 0.6, 1.5, f"leg {leg}'s valve, "
                                    f"its {what}: flow gain within ±30 % of the guess, edges matched within ±20 % "
                                    f"(data sheets: ±10 %)", f"{motion}: leg {leg} extending and retracting"))
    for key, lo, hi, source, experiment in (
            ("oil.bulk_modulus_Pa", 0.4, 1.4, "effective bulk modulus: mineral oil 1.4–2.0 GPa, down to less than "
             "half with hoses and undissolved air (Merritt §2.5)", f"reversals ({motion}): the oil spring's ringing"),
            ("friction.positive.coulomb_N", 0.5, 2.0, "seal friction half to twice the guess", motion),
            ("friction.negative.coulomb_N", 0.5, 2.0, "seal friction half to twice the guess", motion)):
        params.append(_relative(doc, key, lo, hi, source, experiment))
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
    return ParameterSet(params)


def _platform(machine: Machine) -> tuple[float, np.ndarray]:
    """(the platform's mass [kg], its joints (6, 3) [m] in the platform frame) in the hexapod's model (the
    built geometry's, or the user's MJCF's)."""
    from hexsim.control.kinematics import HexapodGeometry
    from hexsim.plant.model import load_model

    model = load_model("hexapod", geometry=machine.geometry)
    return float(model.body("platform").mass[0]), HexapodGeometry.from_model(model).platform
