"""The library of effects the nominal seed model lacks, as the identifier fits them.

Each effect is declared once, as one :class:`Candidate` of :data:`CANDIDATES`: its free parameters (one to
four) with units, the fit's starts, the *physically plausible range* of each parameter written next to it
with its source, the value that means "no effect", how it edits a model, the systems whose logs it applies
to, and how a log narrows its range (:attr:`Candidate.narrow`: no spool frequency above half the sample
rate, a supply set pressure at the top of the logged supply pressure) or floors what it resolves
(:attr:`Candidate.floor`: no sensor delay below one sample period). Everything else is read off these
declarations: the names (:data:`CANDIDATE_NAMES`, :func:`candidates_for` a system), which effects can act on
one hexapod leg alone (:data:`LEG_LEVEL`, from the fields the effect changes) and the plausibility of a fit.
The fit is bounded by the plausible range, and a fitted value at its edge (within :data:`PLAUSIBLE_EDGE` of the
range, of its logarithm where it spans decades, :func:`plausible_edges`: a plausibility margin, wider than the
optimizer's bound, :func:`hexsim.measured.estimates.at_bound`) is flagged and never reported as a finding.

What an effect changes in the plant is the machine's side, not the fit's: its parameters are fields of
:class:`~hexsim.plant.effects.Effects` or :class:`~hexsim.plant.params.HydraulicParams` (whose zero value
is the seed's model), each one key of the machine file (:data:`hexsim.plant.machine_keys.KEYS`, by component:
valve, cylinder, oil, supply, load, sensors), and its equations are in the compiled leg step
(:mod:`hexsim.plant.legs`), written once for simulation and replay alike. A new effect is therefore a
field, its machine-file key, its equations and a :class:`Candidate` here.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, fields, replace

import numpy as np

from hexsim.errors import InputError
from hexsim.measured.measurement import MeasurementLog
from hexsim.measured.parameters import Parameter
from hexsim.measured.replay import PlantModel
from hexsim.plant.effects import SHARED_FIELDS, Effects, LegChange
from hexsim.plant.machine import SYSTEMS
from hexsim.plant.params import HydraulicParams

BAR_PER_LPM = 1e5 / (1e-3 / 60)  # [Pa s/m^3] of 1 bar per L/min
#: A fitted value closer than this fraction of its plausible range to one of its ends is "at a bound of its
#: plausible range": no finding, though the optimizer may not have stopped there (its own rule,
#: :data:`hexsim.measured.estimates.AT_BOUND`, is ten times narrower: a value 0.5 % off the end of what is
#: plausible is as suspect as one on it).
PLAUSIBLE_EDGE = 0.01
#: A plausible range whose ends are this many times apart or more (the supply's tau_s, 1 ms-1 s) spans decades: its
#: edge is :data:`PLAUSIBLE_EDGE` of the range's logarithm (1.07 ms), not of its width (11 ms, which called R1's
#: 5.0 ± 0.02 ms accumulator "at a bound").
DECADES_RATIO = 100.0
#: the words :func:`plausibility` says a value at a bound of its plausible range with
AT_EDGE_WORDS = "at a bound of its plausible range"
#: A fitted value within this many standard errors of the value that switches its effect off is no
#: finding (the discovery's threshold too). A fixed share of the range instead rejected R_s = 0.150 ±
#: 0.00003 bar/(L/min) (under 1 % of its 0-20 range) and C_l = 1.005 ± 0.005 e-12 as "no effect".
NO_EFFECT_SE = 4.0
#: [bar] how far above the highest measured supply pressure (99th percentile) the set pressure P_s0 may lie.
#: The supply only sags under flow and comes back to its set pressure when little oil is drawn, so the
#: truth sits at the top of the measured range; with the former 0.5 bar the true 70 bar of a hexapod log
#: fell inside the "at a bound" zone (1 % of the range) and a correct fit was rejected. 2 bar (3 % of the
#: seed's 70) clears it; a 10 bar margin let the fit trade P_s0 against R_s (78.8 bar with 1.60 instead of
#: 70 with 1.2 bar/(L/min)).
RELIEF_MARGIN_BAR = 2.0


@dataclass(frozen=True)
class Candidate:
    """One effect: its free parameters (:class:`~hexsim.measured.parameters.Parameter`: name, unit, the
    plausible range, the value that means "no effect" (a fit there found nothing) and the one the model
    without it has), where the plausible ranges come from, the fit's starts and how the effect changes a
    model. A parameter declared without a source takes the candidate's."""

    name: str
    parameters: tuple[Parameter, ...]
    starts: Callable[[MeasurementLog], tuple[tuple[float, ...], ...]]  # the fit starts from the best of these
    source: str  # where the plausible ranges come from
    apply: Callable[[PlantModel, np.ndarray], PlantModel]
    physics: str
    #: the systems whose logs the effect applies to ("single-actuator", "hexapod")
    systems: tuple[str, ...] = ("single-actuator", "hexapod")
    #: the valves whose machines the effect applies to ("3-way", "4-way": the B side's edges are the 4-way's)
    valves: tuple[str, ...] = ("3-way", "4-way")
    #: (lower, upper) narrowed to what a log resolves (:func:`plausible_bounds`); None: the plausible range
    narrow: Callable[[MeasurementLog, np.ndarray, np.ndarray], None] | None = None
    #: the smallest value of a parameter a log resolves, name -> value (:func:`resolution_floor`)
    floor: Callable[[MeasurementLog], dict[str, float]] | None = None
    #: per parameter, the values that switch the effect off on a log, together: the effect is absent only where
    #: every one is at its value (a load's declared mass and inclination: a heavier mass on the declared axis is a
    #: load); None: each parameter's own :attr:`Parameter.no_effect`, any one of them alone
    no_effect_of: Callable[[MeasurementLog], tuple[float, ...]] | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "parameters", tuple(p if p.source else replace(p, source=self.source)
                                                     for p in self.parameters))

    @property
    def names(self) -> tuple[str, ...]:
        """The parameters' names, in the order of the fitted vector."""
        return tuple(p.key for p in self.parameters)

    @property
    def units(self) -> tuple[str, ...]:
        return tuple(p.unit for p in self.parameters)

    @property
    def lower(self) -> tuple[float, ...]:
        """The plausible range's lower ends (:func:`plausible_bounds` narrows them to a log)."""
        return tuple(p.lower for p in self.parameters)

    @property
    def upper(self) -> tuple[float, ...]:
        return tuple(p.upper for p in self.parameters)

    @property
    def no_effect(self) -> tuple[float | None, ...]:
        """Per parameter: the value that switches the effect off, or None."""
        return tuple(p.no_effect for p in self.parameters)

    @property
    def origin(self) -> tuple[float | None, ...]:
        """Per parameter, where the screening linearises (identify.linear_start): its neutral value, else its
        no-effect value (:attr:`Parameter.origin <hexsim.measured.parameters.Parameter.origin>`). Unlike
        no_effect, not a verdict on a fitted value: an edge asymmetry with k_PA = 1 and k_AT = 0.9 is an
        effect."""
        return tuple(p.origin for p in self.parameters)


def _p(name: str, unit: str, lower: float, upper: float, no_effect: float | None = None,
       neutral: float | None = None) -> Parameter:
    """A candidate's parameter: ``name`` in ``unit`` within its plausible range [``lower``, ``upper``]."""
    return Parameter(name, lower, upper, unit=unit, no_effect=no_effect, neutral=neutral)


def _eff(model: PlantModel, **kw) -> PlantModel:
    return model.replace(effects=model.effects.replace(**kw))


def _hyd(model: PlantModel, **kw) -> PlantModel:
    return model.replace(hydraulics=model.hydraulics.replace(**kw))


def _supply_set(log: MeasurementLog) -> float:
    """Start of the set pressure [bar]: the 99th percentile of the logged P_s (the supply sags below it
    whenever oil is drawn), or the seed's 70 bar without a P_s column."""
    return float(np.quantile(log.columns["ps_Pa"], 0.99)) / 1e5 if "ps_Pa" in log.columns else 70.0


def _edges(name: str, supply: str, ret: str, physics: str, valves: tuple[str, ...] = ("3-way", "4-way")) -> Candidate:
    """The candidate of a chamber's two metering edges (``supply`` "PA" or "PB", ``ret`` "AT" or "BT"): their flow
    gains k_<edge> relative to eq. (3.4), the :class:`~hexsim.plant.effects.Effects` fields edge_gain_<edge>."""
    fields = (f"edge_gain_{supply.lower()}", f"edge_gain_{ret.lower()}")
    return Candidate(name, (_p(f"k_{supply}", "-", 0.5, 1.5, neutral=1.0), _p(f"k_{ret}", "-", 0.5, 1.5, neutral=1.0)),
                     lambda log: ((1.0, 0.8), (1.0, 1.2), (0.8, 1.0)),
                     "flow gains of the two metering edges within ±50 % of eq. (3.4): datasheets give ±10 % flow "
                     "tolerance for a new valve, worn or damaged edges more",
                     lambda m, x: _eff(m, **{fields[0]: x[0], fields[1]: x[1]}), physics, valves=valves)


def supply_start(log: MeasurementLog) -> tuple[float, float, float] | None:
    """A start for the supply candidate (R_s [bar/(L/min)], tau_s [ms], P_s0 [bar]) from the supply
    equation on the measured signals (output error, cheap): the supply flow of the legs,
    phi_s = sum of phi_PA(u_v, P1, P_s) (seed eq. 3.4, nominal valve) - A2 ydot, through the first-order
    supply P_s = P_s0 - R_s phi_s filtered with tau_s, fitted to the logged P_s by
    :func:`hexsim.measured.fitting.bounded_fit`. None without the P_s, P1, position or valve columns. The closed-loop
    fit decides; this only keeps it from starting in a far valley (a 3 s hexapod log with a true
    1.2 bar/(L/min), 30 ms converged to 1.42 from the generic starts)."""
    from scipy.signal import lfilter

    from hexsim.measured.fitting import bounded_fit
    from hexsim.plant import hydraulics
    from hexsim.signals import savgol

    u, y, p1 = (log.leg_array(k) for k in ("valve_cmd_V", "pos_m", "p1_Pa"))
    if "ps_Pa" not in log.columns or u is None or y is None or p1 is None:
        return None
    hyd, fs = log.machine.hydraulics, log.sample_rate_hz
    p_s = log.columns["ps_Pa"]
    ydot = savgol(y, fs, 0.021, deriv=1, axis=0)
    a1, _ = hydraulics.flow_areas(hydraulics.spool_position(u, hyd), hyd)
    dp = p_s[:, None] - p1
    phi = np.sum(hydraulics.edge_flow(a1, dp, hyd) - hyd.area_rod * ydot, axis=1)

    def resid(x):
        a = math.exp(-1.0 / (fs * x[1] * 1e-3))
        lag = lfilter([1.0 - a], [1.0, -a], phi, zi=[a * phi[0]])[0]
        return (x[2] * 1e5 - x[0] * BAR_PER_LPM * lag - p_s) / 1e5

    x0 = (1.0, 30.0, _supply_set(log))
    fit = bounded_fit(resid, [x0], (0.0, 1.0, 20.0), (20.0, 1000.0, 350.0), x_scale=(1.0, 30.0, 1.0))
    return tuple(float(v) for v in fit.x) if fit.success else None


def _supply_starts(log: MeasurementLog) -> tuple[tuple[float, ...], ...]:
    generic = tuple((r, tau, _supply_set(log)) for r, tau in ((0.2, 20.0), (2.0, 20.0), (2.0, 200.0)))
    start = supply_start(log)
    return generic if start is None else (start, *generic)


def _friction(model: PlantModel, x) -> PlantModel:
    h = model.hydraulics
    return _hyd(model, coulomb_pos=h.coulomb_pos * x[0], coulomb_neg=h.coulomb_neg * x[0],
                static_pos=h.static_pos * x[0], static_neg=h.static_neg * x[0],
                viscous_pos=h.viscous_pos * x[1], viscous_neg=h.viscous_neg * x[1])


def _supply(model: PlantModel, x) -> PlantModel:
    return model.replace(hydraulics=model.hydraulics.replace(supply_pressure=x[2] * 1e5),
                         effects=model.effects.replace(supply_resistance=x[0] * BAR_PER_LPM,
                                                       supply_time_constant=x[1] * 1e-3))


def _load(model: PlantModel, x) -> PlantModel:
    return _eff(model, mass_kg=x[0], inclination_deg=x[1])


def _payload(model: PlantModel, x) -> PlantModel:
    """``model`` with a payload change: m_p = x[0] [kg] at (x_p, y_p, z_p) = x[1:4] [m] (platform frame) added
    to the model's payload m_0 at c_0. The two are one point mass m_0 + m_p at their centre of gravity, so
    the weight and its moments are exact; the inertia the two masses have about that centre,
    m_0 m_p / (m_0 + m_p) |c_0 - c_p|^2, is left out (1.3 kg m^2 for 90 kg added 0.2 m from a 51 kg payload,
    against the platform's 80-144). m_p = 0 is the machine as its file describes it, calibrated payload
    included."""
    m0, c0 = model.effects.payload_kg, np.asarray(model.effects.payload_at_m, dtype=float)
    added = np.asarray(x[1:4], dtype=float)
    total = m0 + x[0]
    at = (m0 * c0 + x[0] * added) / total if abs(total) > 1e-9 else added
    return _eff(model, payload_kg=float(total), payload_at_m=tuple(float(v) for v in at))


def _narrow_supply(log: MeasurementLog, lower: np.ndarray, upper: np.ndarray) -> None:
    """The set pressure lies at or above the highest supply measured (the supply only sags under flow, so
    the truth sits at the top of the measured range, not inside it), up to a relief-valve margin."""
    if "ps_Pa" in log.columns:
        lo, hi = np.quantile(log.columns["ps_Pa"], [0.01, 0.99]) / 1e5
        lower[2], upper[2] = lo - 0.5, hi + RELIEF_MARGIN_BAR


def _narrow_spool(log: MeasurementLog, lower: np.ndarray, upper: np.ndarray) -> None:
    """No spool frequency above half the sample rate."""
    upper[0] = min(upper[0], 0.5 * log.sample_rate_hz)


def _narrow_delay(log: MeasurementLog, lower: np.ndarray, upper: np.ndarray) -> None:
    """The fit may go below one sample period; acceptance needs one (:func:`_delay_floor`)."""
    lower[0] = 0.0


def _delay_floor(log: MeasurementLog) -> dict[str, float]:
    """A delay shorter than one sample period is not resolved."""
    return {"tau_y": 1e3 / log.sample_rate_hz}


#: [m] A leg setpoint within this of its first value: the platform is still at rest (:func:`payload_start`).
REST_TOLERANCE_M = 1e-5


def payload_start(log: MeasurementLog) -> tuple[float, float, float] | None:
    """A start for the payload candidate (m_p [kg], x_p, y_p [m]) from statics: the legs' P1 while the
    platform is still at rest (the replay starts at rest in the neutral pose: the rows before any leg's
    setpoint has moved by :data:`REST_TOLERANCE_M`, at most the first 0.1 s, at least three rows) minus
    the model's static P1 there (the machine file's payload included: the start is the change), through :func:`hexsim.measured.hexapod_replay.payload_from_statics`. None
    for a log without the legs' P1 or offsets that are not one load. (Over a fixed 0.1 s, a 1 Hz heave's
    fade-in had already raised P1 by 0.53 bar: a 30 kg payload read as 64 kg.)"""
    p1, ref = log.leg_array("p1_Pa"), log.leg_array("ref_m")
    if log.system != "hexapod" or p1 is None:
        return None
    from hexsim.control.scenario import Scenario
    from hexsim.engine.config import RunConfig
    from hexsim.engine.runner import Simulator
    from hexsim.measured.hexapod_replay import payload_from_statics
    from hexsim.measured.replay import supply_from_log

    hyd = supply_from_log(log, log.machine.hydraulics)
    rest = Simulator(RunConfig(Scenario("rest", "hexapod", 1.0, 2, 0.5, 1.0, 0.0),
                               replace(log.machine, hydraulics=hyd))).p1_initial
    first = log.time - log.time[0] <= 0.1
    if ref is not None:
        first &= np.cumsum(np.any(np.abs(ref - ref[0]) > REST_TOLERANCE_M, axis=1)) == 0
    first[:3] = True
    found = payload_from_statics(p1[first].mean(axis=0) - rest, hyd, log.machine.geometry)
    if found["inconsistency"] > 0.1:
        return None
    return found["mass_kg"], found["x_m"], found["y_m"]


def _payload_starts(log: MeasurementLog) -> tuple[tuple[float, ...], ...]:
    """The statics' mass and position (:func:`payload_start`) and two generic masses, each at the height of
    the machine's payload (the platform frame's origin without one): a change of what is on the platform
    sits where it sits until the motion says otherwise (heave alone cannot: the height only tilts the legs'
    forces under surge, sway, roll and pitch)."""
    eff = log.machine.effects
    z0 = float(eff.payload_at_m[2]) if eff.payload_kg else 0.0
    start = payload_start(log)
    generic = ((100.0, 0.0, 0.0, z0), (-100.0, 0.0, 0.0, z0))
    return generic if start is None else ((*start, z0), *generic)


CANDIDATES: dict[str, Candidate] = {c.name: c for c in (
    Candidate("supply_pressure", (_p("R_s", "bar/(L/min)", 0.0, 20.0, no_effect=0.0), _p("tau_s", "ms", 1.0, 1000.0),
                                  _p("P_s0", "bar", 20.0, 350.0)),
              _supply_starts,
              "set pressure 20-350 bar: industrial power units (ISO 4413); R_s up to 20 bar/(L/min) is a "
              "supply line and accumulator far too small for the flow; tau_s 1 ms-1 s (Jelali & Kroll §3.7)",
              _supply,
              "pump + accumulator behind a supply line: P_s sags from the set pressure P_s0 by R_s phi_s, "
              "time constant tau_s", narrow=_narrow_supply),
    Candidate("spool_dynamics", (_p("f_v", "Hz", 5.0, 300.0), _p("zeta_v", "-", 0.3, 1.5)),
              lambda log: ((20.0, 0.7), (50.0, 0.7), (120.0, 0.7)),
              "-90° frequency of proportional and servo valves 5-300 Hz, damping 0.3-1.5 (manufacturers' "
              "frequency responses, e.g. Rexroth 4WRPEH, Moog D633; Jelali & Kroll §3.4)",
              lambda m, x: _eff(m, spool_frequency=x[0], spool_damping=x[1]),
              "second-order spool position loop (natural frequency f_v, damping zeta_v)", narrow=_narrow_spool),
    Candidate("null_offset", (_p("u_0", "V", -2.0, 2.0, no_effect=0.0),), lambda log: ((-0.2,), (0.0,), (0.2,)),
              "zero point within ±20 % of u_v,max (datasheets adjust it to a few % and give drifts of "
              "< 1 %/10 K; seed §5.3)",
              lambda m, x: _hyd(m, null_offset=x[0]),
              "valve setpoint u_0 that centres the spool is not 0 (seed §5.3: drifts with temperature)"),
    Candidate("hysteresis", (_p("h", "V", 0.0, 1.0, no_effect=0.0),), lambda log: ((0.05,), (0.2,), (0.6,)),
              "hysteresis of proportional valves up to 10 % of u_v,max (datasheets give 0.1-5 %; seed §4.2)",
              lambda m, x: _eff(m, spool_play=x[0]),
              "spool play: backlash of half width h between setpoint and spool (seed §4.2, hysteresis of "
              "the flow curve)"),
    Candidate("leakage", (_p("C_l", "1e-12 m^3/(s Pa)", 0.0, 200.0, no_effect=0.0),),
              lambda log: ((0.5,), (5.0,), (50.0,)),
              "internal leakage of a worn piston seal: up to ~1 L/min at 70 bar, 2e-10 m^3/(s Pa) "
              "(Merritt §3.4; a new seal leaks < 1e-12)",
              lambda m, x: _eff(m, leakage=x[0] * 1e-12),
              "internal leakage across the piston, C_l (P_s - P1) into the bottom chamber (a 4-way valve: "
              "C_l (P2 - P1), from the rod side)"),
    Candidate("load", (_p("M", "kg", 5.0, 400.0), _p("inclination", "deg", 0.0, 89.0, neutral=0.0)),
              lambda log: ((log.moving_mass_kg, max(log.inclination_deg, 1.0)),
                           (1.5 * log.moving_mass_kg, 30.0)),
              "a moving mass of 5-400 kg per axis (seed app. A: 40 kg) and any inclination short of "
              "horizontal",
              _load, "moving mass and inclination of the axis differ from the declared (seed ch. 4: gravity not "
              "along the actuator)", systems=("single-actuator",),
              no_effect_of=lambda log: (log.moving_mass_kg, log.inclination_deg)),
    Candidate("friction", (_p("k_c", "-", 0.0, 10.0, neutral=1.0), _p("k_sigma", "-", 0.0, 10.0, neutral=1.0)),
              lambda log: ((1.0, 1.0), (0.5, 1.0), (2.5, 1.0)),
              "Coulomb/static and viscous levels within 0-10x the seed's identified ones (seed §2.3.3, "
              "app. A)", _friction,
              "Stribeck friction (seed eq. 3.9) with Coulomb + static levels scaled by k_c, viscous by k_sigma"),
    Candidate("bulk_modulus", (_p("E", "GPa", 0.1, 2.0),), lambda log: ((0.3,), (1.0,), (1.5,)),
              "effective bulk modulus of mineral oil 1.4-2.0 GPa, down to ~0.1 GPa with hoses and "
              "entrained air (Merritt §2.5)",
              lambda m, x: _hyd(m, bulk_modulus=x[0] * 1e9),
              "effective bulk modulus of the oil (entrained air lowers it; seed eq. 3.7)"),
    Candidate("sensor_delay", (_p("tau_y", "ms", 0.0, 50.0, no_effect=0.0),), lambda log: ((1.0,), (5.0,), (20.0,)),
              "a position transducer and its filter lag 0-50 ms; below one sample period the log cannot "
              "resolve a delay",
              lambda m, x: _eff(m, sensor_delay=x[0] * 1e-3),
              "the position measurement lags the piston by tau_y", narrow=_narrow_delay, floor=_delay_floor),
    _edges("edge_asymmetry", "PA", "AT", "valve edge asymmetry: the supply edge P→A and the return edge A→T pass "
           "k_PA and k_AT times the flow of eq. (3.4)"),
    _edges("edge_asymmetry_B", "PB", "BT", "a 4-way valve's rod-side edge asymmetry: the supply edge P→B and the "
           "return edge B→T pass k_PB and k_BT times the flow of eq. (3.4) (the rod chamber's P2 shows it)",
           valves=("4-way",)),
    Candidate("entrained_air", (_p("a", "%", 0.0, 20.0, no_effect=0.0),), lambda log: ((0.2,), (1.0,), (5.0,)),
              "undissolved air in mineral oil: well bled systems well under 1 %, aerated oil up to ~10-20 % "
              "by volume at atmospheric pressure (Gholizadeh, Burton & Schoenau, Int. J. Fluid Power 12(3), "
              "2011)",
              lambda m, x: _eff(m, air_fraction=x[0] * 1e-2),
              "entrained air: a volume fraction a of air at atmospheric pressure (adiabatic, n = 1.4) makes the "
              "oil's bulk modulus fall at low pressure (hexsim.plant.legs.bulk_modulus)"),
    Candidate("payload", (_p("m_p", "kg", -200.0, 600.0, no_effect=0.0), _p("x_p", "m", -0.6, 0.6),
                          _p("y_p", "m", -0.6, 0.6), _p("z_p", "m", -0.2, 0.6)),
              _payload_starts,
              "the Micro Motion System carries a payload of up to about 600 kg (seed §2.2.1); a "
              "centre of gravity inside the platform (1.2 m square), from 0.2 m below its joints' plane to 0.6 m "
              "above it (a seat, a cockpit); down to -200 kg: a platform lighter than modelled", _payload,
              "hexapod: a payload change m_p at (x_p, y_p, z_p) on the platform (platform frame), added to the "
              "machine's payload, its weight and inertia through MuJoCo", systems=("hexapod",)),
)}
#: Every candidate's name, in the order they are tried.
CANDIDATE_NAMES = tuple(CANDIDATES)


def candidates_for(system: str, valve: str | None = None) -> tuple[str, ...]:
    """The names of the candidates that apply to a log of ``system`` (``hexapod`` or ``single-actuator``) on a
    machine with ``valve`` (``3-way`` or ``4-way``; None: either), read off each candidate's
    :attr:`Candidate.systems` and :attr:`Candidate.valves`: the load (mass, inclination) is a single axis's,
    the payload the hexapod's, the B side's edges a 4-way valve's. Raises InputError for another system."""
    if system not in SYSTEMS:
        raise InputError(f"unknown system {system!r} ({' or '.join(SYSTEMS)})")
    return tuple(name for name, cand in CANDIDATES.items()
                 if system in cand.systems and (valve is None or valve in cand.valves))


#: The effects of the seed's single actuator's leg model (a 3-way valve: every candidate but the hexapod's
#: payload and the 4-way valve's B side).
EFFECT_NAMES = candidates_for("single-actuator", "3-way")


def plausible_bounds(cand: Candidate, log: MeasurementLog) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) of ``cand``'s parameters for this log: the plausible range, narrowed by the
    candidate's own :attr:`Candidate.narrow` to what the log resolves (see the module doc)."""
    lower, upper = np.array(cand.lower, dtype=float), np.array(cand.upper, dtype=float)
    if cand.narrow is not None:
        cand.narrow(log, lower, upper)
    return lower, upper


def resolution_floor(cand: Candidate, log: MeasurementLog) -> dict[str, float]:
    """Smallest value of a parameter the log can resolve, name -> value (in the candidate's units): the
    candidate's :attr:`Candidate.floor`, none without one."""
    return {} if cand.floor is None else cand.floor(log)


def plausible_edges(lower: np.ndarray, upper: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(k,) each: the values at and below / at and above which a parameter within [``lower``, ``upper``] (k,) is at
    a bound of its plausible range: :data:`PLAUSIBLE_EDGE` of the range in from each end, of its logarithm where the
    range spans decades (both ends positive, :data:`DECADES_RATIO` apart or more)."""
    lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    decades = (lower > 0) & (upper >= DECADES_RATIO * lower)
    ratio = np.where(decades, upper / np.where(decades, lower, 1.0), 1.0) ** PLAUSIBLE_EDGE
    span = PLAUSIBLE_EDGE * (upper - lower)
    return np.where(decades, lower * ratio, lower + span), np.where(decades, upper / ratio, upper - span)


def plausibility(cand: Candidate, log: MeasurementLog, x: np.ndarray, se: np.ndarray | None = None) -> list[str]:
    """Why the fitted parameters ``x`` are not a finding (empty if they are): a value at a bound of its
    plausible range, at the value that means no effect, or finer than the log resolves. ``se``: the
    parameters' standard errors (same units; nan where the fit held a parameter at a bound). A value is
    at the no-effect value when it lies within :data:`NO_EFFECT_SE` standard errors of it (without a
    standard error: within :data:`PLAUSIBLE_EDGE` of the range); a no-effect value that is also a bound of the
    range (R_s >= 0, C_l >= 0) is the physical limit, not a bound the fit ran into. A candidate whose no-effect
    values come from the log together (:attr:`Candidate.no_effect_of`, the load) is no finding only where all of
    them are at theirs."""
    lower, upper = plausible_bounds(cand, log)
    span = upper - lower
    low_edge, high_edge = plausible_edges(lower, upper)
    se = np.full(len(x), np.nan) if se is None else np.asarray(se, dtype=float)
    problems = []
    offs = cand.no_effect if cand.no_effect_of is None else cand.no_effect_of(log)
    at_off = []  # the parameters at their no-effect value, and the words that say so
    for i, (name, unit) in enumerate(zip(cand.names, cand.units)):
        off = offs[i]
        v = float(x[i])
        by_se = bool(np.isfinite(se[i]) and se[i] > 0)
        near = NO_EFFECT_SE * se[i] if by_se else PLAUSIBLE_EDGE * span[i]
        if off is not None and abs(v - off) <= near:
            within = f" (within {NO_EFFECT_SE:g} standard errors)" if by_se else ""
            at_off.append(f"{name} = {v:.4g} {unit}{within}")
            if cand.no_effect_of is None:
                problems.append(f"{name} = {v:.4g} {unit} is the value without the effect{within}")
        elif ((v <= low_edge[i] and off != lower[i]) or (v >= high_edge[i] and off != upper[i])):
            problems.append(f"{name} = {v:.4g} {unit} {AT_EDGE_WORDS} "
                            f"{lower[i]:.4g}…{upper[i]:.4g}")
    if cand.no_effect_of is not None and len(at_off) == len(offs):
        problems.append(" and ".join(at_off) + " are the values without the effect")
    for name, floor in resolution_floor(cand, log).items():
        i = cand.names.index(name)
        if float(x[i]) < floor:
            problems.append(f"{name} = {float(x[i]):.3g} {cand.units[i]} is finer than the log resolves "
                            f"({floor:.3g} {cand.units[i]}, one sample)")
    return problems


def touched_fields(cand: Candidate) -> frozenset[str]:
    """The :class:`~hexsim.plant.params.HydraulicParams` and :class:`~hexsim.plant.effects.Effects` fields the
    candidate's ``apply`` changes, probed on the seed's model at three tenths of its plausible range (not the
    middle: an edge asymmetry's middle is the seed's 1.0)."""
    base = PlantModel(HydraulicParams(), Effects())
    probe = np.array(cand.lower) + 0.3 * (np.array(cand.upper) - np.array(cand.lower))
    return frozenset(changed_values(base, cand.apply(base, probe)))


def changed_values(model: PlantModel, changed: PlantModel) -> dict:
    """The :class:`~hexsim.plant.params.HydraulicParams` and :class:`~hexsim.plant.effects.Effects` fields whose
    value in ``changed`` differs from ``model``'s: name -> ``changed``'s value."""
    return {f.name: getattr(getattr(changed, part), f.name) for part in ("hydraulics", "effects")
            for f in fields(getattr(model, part))
            if getattr(getattr(changed, part), f.name) != getattr(getattr(model, part), f.name)}


#: Candidates that can act on one leg of a hexapod alone: those that change no field the legs share (the
#: supply, the sensor delay (the motion computer's) and the load, :data:`hexsim.plant.effects.SHARED_FIELDS`),
#: read off each candidate's own declaration, not listed a second time.
LEG_LEVEL = tuple(name for name, cand in CANDIDATES.items() if not touched_fields(cand) & SHARED_FIELDS)


def candidate_key(name: str, leg: int | None = None) -> str:
    """The identifier's name of a candidate: ``leakage`` (all legs / the single actuator) or
    ``leakage@leg3`` (leg 3 alone)."""
    return name if leg is None else f"{name}@leg{leg}"


def parse_key(key: str) -> tuple[Candidate, int | None]:
    """(candidate, leg or None) of a :func:`candidate_key`. Raises KeyError for an unknown name."""
    name, _, leg = key.partition("@leg")
    return CANDIDATES[name], (int(leg) if leg else None)


def applier(cand: Candidate, leg: int | None) -> Callable[[PlantModel, np.ndarray], PlantModel]:
    """How the candidate changes a model: on all legs (``cand.apply``), or on leg ``leg`` alone, as a
    :class:`~hexsim.plant.effects.LegChange` holding every value of that leg that differs from the shared
    model's (a change the model already had for that leg is kept and extended)."""
    if leg is None:
        return cand.apply

    def apply(model: PlantModel, x: np.ndarray) -> PlantModel:
        return with_leg(model, leg, cand.apply(leg_model(model, leg), x))

    return apply


def leg_model(model: PlantModel, leg: int) -> PlantModel:
    """The parameters leg ``leg`` (1…n) runs with: the shared ones with its :class:`LegChange`, if any."""
    own = [c for c in model.leg_changes if c.leg == leg]
    return PlantModel(*own[0].apply(model.hydraulics, model.effects)) if own else PlantModel(model.hydraulics,
                                                                                              model.effects)


def with_leg(model: PlantModel, leg: int, changed: PlantModel) -> PlantModel:
    """``model`` with leg ``leg`` running ``changed``'s parameters: a :class:`LegChange` holding every value
    that differs from the shared model's (replacing the leg's former change)."""
    others = tuple(c for c in model.leg_changes if c.leg != leg)
    values = changed_values(model, changed)
    return model.replace(leg_changes=others + ((LegChange.of(leg, **values),) if values else ()))
