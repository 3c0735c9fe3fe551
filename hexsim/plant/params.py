"""Hydraulic and controller parameters: frozen dataclasses with symbol, unit, default and source.

Rigid-body facts (masses, stroke, gravity, timestep) live in the MJCF and are read from ``MjModel``
(STYLE.md §2); only the hydraulics and the controller are described here. Every default is the seed's
appendix A ("Compensation of the reversal bump", Rexroth-Hydraudyne / TU Eindhoven, 2005) unless the
comment says otherwise. Each dataclass validates itself on construction and raises
:class:`~hexsim.errors.InputError` naming the parameter and the value.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np

from hexsim.errors import InputError

FlowArea = Literal["smooth", "port", "quadratic", "sharp", "rounded", "table", "curve"]
#: The valve's flow-area forms (:func:`hexsim.plant.hydraulics.flow_areas`), declared once: the machine
#: file's ``valve.flow_area`` choices, the command line's, and (all but the table) the forms a calibration
#: from transients tries (:data:`hexsim.measured.calibration.SEED_FORMS`). A new form is a name here, its
#: opening in the compiled leg step (:mod:`hexsim.plant.legs`) and its data-sheet brackets
#: (:mod:`hexsim.measured.parameters`).
FLOW_AREAS: tuple[str, ...] = get_args(FlowArea)
#: Most points an opening table may have above null (besides the origin, or the one point below null where an
#: underlapped edge opens): the compiled leg step holds twelve as fields.
MAX_TABLE_POINTS = 11
#: Most points of one edge's flow curve (flow area "curve", :attr:`HydraulicParams.flow_curve_pa`), the first
#: where the edge opens: the compiled leg step holds them as arrays of this length.
MAX_CURVE_POINTS = 48
ValveType = Literal["3-way", "4-way"]


#: A curve's points follow the curve they are taken from within this share of its value plus this share of its
#: largest value (:func:`thin_curve`): an open-loop replay's position integrates the flow, and 1 % of flow is
#: tens of a position transducer's noise over a replay window; near null, where the reversals happen, the
#: openings are small and their shape is the flow gain the reversal sees, so the second share is small: a
#: metering edge opening as x_v^2 is followed to within 10 % from 5 mV of a 10 V valve (at 2e-5 the points
#: jumped from null to 35 mV, a straight line 40 % above the edge at 5-20 mV, and a compensator inverting it
#: left the reference plant R1's reversal peaks 1.6x those of the curve it was read from).
CURVE_TOLERANCE = (2e-3, 2e-7)


def thin_curve(u: np.ndarray, value: np.ndarray) -> list[list[float]]:
    """At most :data:`MAX_CURVE_POINTS` points [[u V, opening], …] of the curve ``value`` (n,) (non-decreasing)
    sampled at ``u`` (n,) [V], from where it opens (its last zero) to its end, through which the monotone cubic
    of flow area "curve" (scipy's PchipInterpolator) stays within :data:`CURVE_TOLERANCE`: the worst-followed
    sample added, one at a time."""
    from scipy.interpolate import PchipInterpolator

    start = int(np.flatnonzero(value <= 0.0)[-1]) if np.any(value <= 0.0) else 0
    u, value = np.asarray(u[start:], dtype=float), np.asarray(value[start:], dtype=float)
    chosen = [0, len(u) - 1]
    tol = CURVE_TOLERANCE[0] * value + CURVE_TOLERANCE[1] * float(value[-1] if value[-1] > 0 else 1.0)
    while len(chosen) < MAX_CURVE_POINTS:
        idx = sorted(chosen)
        excess = np.abs(PchipInterpolator(u[idx], value[idx])(u) - value) / tol
        worst = int(np.argmax(excess))
        if excess[worst] <= 1.0:
            break
        chosen.append(worst)
    return [[round(float(u[i]), 6), round(float(value[i]), 7)] for i in sorted(set(chosen))]


def _check_positive(obj, *names: str) -> None:
    for name in names:
        value = getattr(obj, name)
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise InputError(f"{type(obj).__name__}.{name} must be a finite positive number, got {value!r}")


def _check_nonnegative(obj, *names: str) -> None:
    for name in names:
        value = getattr(obj, name)
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
            raise InputError(f"{type(obj).__name__}.{name} must be a finite number >= 0, got {value!r}")


def _frozen(curve) -> tuple:
    """A flow curve as a tuple of point tuples (hashable, for the memoised functions below)."""
    if isinstance(curve, tuple) and all(isinstance(p, tuple) for p in curve):
        return curve
    return tuple(tuple(p) if isinstance(p, (list, tuple, np.ndarray)) else p for p in curve)


@functools.lru_cache(maxsize=256)
def _curves_fault(flow_area: str, curve_pa: tuple, curve_at: tuple, u_v_max: float) -> str:
    """Why the edges' flow curves do not suit the flow area (the fields' comment), or "": each at least two
    points, commands increasing, the first opening 0 within 20 % of the command range of null, openings not
    decreasing (at most 2), the last command at u_v_max or beyond. Memoised: warming oil makes a new parameter
    set every controller tick, with the curves checked already."""
    curves = {"flow_curve_pa": curve_pa, "flow_curve_at": curve_at}
    if flow_area != "curve":
        for name, curve in curves.items():
            if curve:
                return (f"HydraulicParams.{name} is given but flow_area is {flow_area!r}: set flow_area to "
                        f"'curve' to use it")
        return ""
    if not curve_pa:
        return "HydraulicParams.flow_curve_pa is needed for flow_area 'curve'"
    for name, curve in curves.items():
        if not curve and name == "flow_curve_at":
            continue
        if not 2 <= len(curve) <= MAX_CURVE_POINTS:
            return (f"HydraulicParams.{name} needs 2…{MAX_CURVE_POINTS} points (u_v V, opening fraction), got "
                    f"{len(curve)}")
        for i, point in enumerate(curve):
            if not (len(point) == 2 and all(isinstance(v, (int, float)) and math.isfinite(v) for v in point)):
                return f"HydraulicParams.{name} point {i + 1} must be two finite numbers, got {point!r}"
        if curve[0][1] != 0.0 or abs(curve[0][0]) > 0.2 * u_v_max:
            return (f"HydraulicParams.{name} point 1 ({curve[0][0]:g} V, {curve[0][1]:g}): the first point is "
                    f"where the edge opens: opening 0, within 20 % of the command range of null")
        for i in range(1, len(curve)):
            (u0, f0), (u1, f1) = curve[i - 1], curve[i]
            if u1 <= u0 or f1 < f0 or f1 > 2.0:
                return (f"HydraulicParams.{name} point {i + 1} ({u1:g} V, {f1:g}): commands must increase and "
                        f"openings must not decrease (fractions of the full opening, at most 2)")
        if curve[-1][0] < u_v_max * (1.0 - 1e-9):
            return f"HydraulicParams.{name} must reach u_v_max ({u_v_max:g} V), ends at {curve[-1][0]:g} V"
    return ""


@functools.lru_cache(maxsize=64)
def _edge_curves(flow_area: str, curve_pa: tuple, curve_at: tuple) -> tuple[tuple[np.ndarray, ...], ...]:
    """:attr:`HydraulicParams.edge_curves` of these curves (memoised; the arrays read-only, shared)."""
    from scipy.interpolate import PchipInterpolator

    out = []
    for curve in (curve_pa, curve_at or curve_pa):
        if flow_area != "curve" or not curve:
            arrays = (np.zeros(0), np.zeros(0), np.zeros(0))
        else:
            u, f = (np.array([p[i] for p in curve], dtype=float) for i in (0, 1))
            arrays = (u, f, PchipInterpolator(u, f).derivative()(u))
        for a in arrays:
            a.setflags(write=False)
        out.append(arrays)
    return tuple(out)


@dataclass(frozen=True)
class HydraulicParams:
    """One valve-controlled asymmetric cylinder of the Micro Motion System (seed ch. 3, app. A).

    ``valve_type="3-way"`` (the seed's, default): the 3/3 proportional valve feeds the bottom chamber
    (area A1); the rod side (area A2) sees the supply pressure P_s directly (seed Fig. 3.1).
    ``valve_type="4-way"``: a 4/3 valve on a differential cylinder, as most servo-hydraulic rigs: the
    spool that opens P→A opens B→T with the same area, and A→T with P→B; both chamber pressures P1 (cap
    side, A) and P2 (rod side, B) are integrated (eq. 3.7 for each chamber, the rod side's volume
    (L_s - y) A2 + V_pl,B). Its port, overlap and flow area are the same fields as the 3-way valve's
    (a symmetric, matched spool); for ``flow_area="sharp"`` a negative ``overlap`` is an underlap.
    A data sheet's rated flow converts to these fields in :mod:`hexsim.machine`.
    """

    supply_pressure: float = 7.0e6  # P_s [Pa], seed app. A (70 bar, seed §2.2.2)
    tank_pressure: float = 0.0  # P_t [Pa], seed app. A
    discharge_coefficient: float = math.pi / (math.pi + 2)  # C_d [-] = 0.61, seed app. A
    density: float = 860.0  # rho [kg/m^3], Shell Tellus T46 at 35 °C, seed app. A
    bore_diameter: float = 0.04  # D [m]: A1 = pi/4 D^2, seed app. A
    rod_diameter: float = 0.03  # d_r [m]: A2 = pi/4 (D^2 - d_r^2), seed app. A
    bulk_modulus: float = 1.5e9  # E [Pa], seed app. A
    pipeline_volume: float = 5e-7  # V_pl [m^3], seed app. A (l = 65 mm, seed eq. 3.1)
    # 3-way: the seed's valve, rod side at supply; 4-way: both chambers fed and drained by the valve
    valve_type: ValveType = "3-way"
    pipeline_volume_rod: float = 5e-7  # V_pl,B [m^3], dead volume of the rod side (4-way only); the cap
    # side's pipeline volume repeated, as the seed gives one line length (seed eq. 3.1)
    stroke: float = 0.2  # L_s [m], cylinder stroke: the rod side's volume (L_s - y) A2 + V_pl,B (4-way
    # only); seed app. A (0.2 m). The MJCF's joint range is the rigid-body stroke.
    u_v_max: float = 10.0  # u_v,max [V], seed app. A
    x_v_max: float = 1.1e-3  # x_v,max [m], seed app. A
    overlap: float = 5e-6  # O_l [m], overlap at mid-position, seed app. A
    null_offset: float = 0.0  # u_0 [V], valve setpoint that centres the spool; 0 in the seed, drifts with
    # temperature (seed §5.3: "a larger or smaller input voltage is required to reach a specific valve
    # spool position")
    spool_diameter: float = 1e-2  # d [m], seed app. A
    smooth_area_gain: float = 300.0  # [m^2/m^2 -> 1/m]: a = 300 x_v^2, seed eq. (3.11)
    # "smooth": seed eq. (3.11) blended C^1 onto the port's opening (3.3) above 0.78 V (smooth_blend);
    # "quadratic": (3.11) at every opening, as the seed simulated (§3.3 on); "port": the smaller of (3.11) and
    # the port's opening (3.3), a kink where they cross (0.90 V) and the overlap a dead band (a real spool, no
    # blend); "sharp": (3.3); "rounded": (3.11) from null, no dead band (a rounded metering edge that passes
    # flow as soon as the spool moves), until it meets the port's opening (3.3), the port beyond: a kink where
    # they cross (rounded_corner); "table": the opening against the command as a data sheet or a
    # measurement gives it (opening_table); "curve": each edge's opening against the command as a monotone
    # cubic (PCHIP) through points read from a machine's own flows (flow_curve_pa, flow_curve_at)
    flow_area: FlowArea = "smooth"
    # (u_v [V], opening as a fraction of the full port opening pi d x_v,max) points of the edge the command
    # opens (P→A; A→T at -u_v alike), commands increasing to u_v,max, openings non-decreasing, linear in
    # between from (0, 0); an overlap is in the table (zero opening up to it), an underlap a first point
    # below null with opening 0 (the edge opens there: both edges open around null). Used with flow_area
    # "table" only.
    opening_table: tuple[tuple[float, float], ...] = ()
    # flow_area "curve": (u_v [V], opening as a fraction of pi d x_v,max) points of the P→A edge at the command
    # that opens it and of the A→T edge at minus the command (at u = -u_v: an edge's own command), each a
    # piecewise cubic Hermite curve through its points with the monotone slopes of Fritsch & Carlson (SIAM J.
    # Numer. Anal. 17(2), 1980; scipy's PchipInterpolator): C^1, no overshoot, a corner (a rounded metering edge
    # meeting the full port) kept within the points either side of it. The first point is where the edge
    # opens (opening 0; below null: an underlap, above: an overlap), the last at u_v_max or beyond; at most
    # MAX_CURVE_POINTS each; flow_curve_at empty: the P→A edge's curve. Used with flow_area "curve" only.
    flow_curve_pa: tuple[tuple[float, float], ...] = ()
    flow_curve_at: tuple[tuple[float, float], ...] = ()
    # Lowest pressure the bottom chamber's oil holds [Pa, gauge]: 0.1 bar absolute, where dissolved air comes
    # out of mineral oil and the oil cavitates (air-release pressures 0.1–0.3 bar abs.; the vapour pressure is
    # lower still; Gholizadeh, Burton & Schoenau, Int. J. Fluid Power 12(3), 2011). Not in the seed, whose
    # chamber never falls that low; the pressure stays there while a cavity opens (hexsim.plant.legs.pressure_step).
    cavitation_pressure: float = 1.0e4 - 101325.0
    # Asymmetric Stribeck friction, seed eq. (3.9) and app. A.
    arctan_gain: float = 100.0  # k [s/m], seed app. A
    viscous_pos: float = 2200.0  # sigma+ [N s/m]
    viscous_neg: float = 1800.0  # sigma- [N s/m]
    coulomb_pos: float = 65.0  # F_c0+ [N]
    coulomb_neg: float = 60.0  # F_c0- [N]
    static_pos: float = 30.0  # F_s0+ [N]
    static_neg: float = 30.0  # F_s0- [N]
    stribeck_velocity_pos: float = 0.005  # c_s+ [m/s]
    stribeck_velocity_neg: float = 0.005  # c_s- [m/s]
    # Seed eq. (3.9) multiplies by arctan(k ydot), which tends to ±pi/2, not ±1: with the published
    # formula the Coulomb + static level at speed is pi/2 times F_c0 + F_s0 (e.g. 102 N, not 65 N, for
    # F_c0+). False (default) implements (3.9) as published; True uses (2/pi) arctan, a smoothed sign()
    # that reproduces (2.4) and the friction-velocity map the parameters were identified from.
    arctan_normalised: bool = False

    def __post_init__(self) -> None:
        _check_positive(
            self,
            "supply_pressure",
            "discharge_coefficient",
            "density",
            "bore_diameter",
            "bulk_modulus",
            "pipeline_volume",
            "pipeline_volume_rod",
            "stroke",
            "u_v_max",
            "x_v_max",
            "spool_diameter",
            "smooth_area_gain",
            "arctan_gain",
            "stribeck_velocity_pos",
            "stribeck_velocity_neg",
        )
        _check_nonnegative(
            self,
            "tank_pressure",
            "rod_diameter",
            "viscous_pos",
            "viscous_neg",
            "coulomb_pos",
            "coulomb_neg",
            "static_pos",
            "static_neg",
        )
        if self.rod_diameter >= self.bore_diameter:
            raise InputError(
                f"HydraulicParams.rod_diameter ({self.rod_diameter} m) must be smaller than bore_diameter "
                f"({self.bore_diameter} m)"
            )
        if not (math.isfinite(self.null_offset) and abs(self.null_offset) < self.u_v_max):
            raise InputError(f"HydraulicParams.null_offset must be inside ±u_v_max, got {self.null_offset!r}")
        if self.valve_type not in ("3-way", "4-way"):
            raise InputError(f"HydraulicParams.valve_type must be '3-way' or '4-way', got {self.valve_type!r}")
        if not (math.isfinite(self.cavitation_pressure) and -101325.0 <= self.cavitation_pressure < self.tank_pressure):
            raise InputError(
                f"HydraulicParams.cavitation_pressure ({self.cavitation_pressure} Pa, gauge) must be between absolute "
                f"vacuum (-101325 Pa) and the tank pressure ({self.tank_pressure} Pa)")
        if self.tank_pressure >= self.supply_pressure:
            raise InputError(
                f"HydraulicParams.tank_pressure ({self.tank_pressure} Pa) must be below supply_pressure "
                f"({self.supply_pressure} Pa)"
            )
        if self.flow_area not in FLOW_AREAS:
            raise InputError(f"HydraulicParams.flow_area must be one of {', '.join(FLOW_AREAS)}, got {self.flow_area!r}")
        self._check_overlap()
        self._check_table()
        self._check_curves()

    def _check_overlap(self) -> None:
        """InputError unless the overlap O_l suits the spool stroke and the flow area (an underlap needs the
        sharp edge, eq. 3.3; the smooth area's k_a x_v^2, eq. 3.11, must meet the port's opening)."""
        if not (isinstance(self.overlap, (int, float)) and math.isfinite(self.overlap)):
            raise InputError(f"HydraulicParams.overlap must be a finite number, got {self.overlap!r}")
        if self.overlap < 0 and self.flow_area != "sharp":
            raise InputError(
                f"HydraulicParams.overlap {self.overlap!r} m: an underlap (negative overlap) needs the sharp-edged "
                f"flow area (flow_area='sharp', eq. 3.3); the smooth area (3.11) has no opening at x_v = 0")
        if self.overlap <= -self.x_v_max:
            raise InputError(f"HydraulicParams.overlap ({self.overlap} m): an underlap must be smaller than the "
                             f"spool stroke x_v_max ({self.x_v_max} m)")
        if self.overlap >= self.x_v_max:
            raise InputError(
                f"HydraulicParams.overlap ({self.overlap} m) must be smaller than the spool stroke x_v_max "
                f"({self.x_v_max} m)"
            )
        limit = math.pi * self.spool_diameter / (4.0 * self.smooth_area_gain)
        if self.flow_area in ("smooth", "port", "rounded") and self.overlap >= limit:
            raise InputError(
                f"HydraulicParams.overlap ({self.overlap} m) must be below pi d / (4 k_a) = {limit:.3g} m for the "
                f"{self.flow_area} flow area: above it k_a x_v^2 (eq. 3.11, k_a = smooth_area_gain) never meets the "
                f"port's opening pi d (x_v - O_l) (eq. 3.3)")

    def _check_table(self) -> None:
        """InputError unless the opening table suits the flow area (module doc of the field)."""
        table = self.opening_table
        if self.flow_area != "table":
            if table:
                raise InputError(f"HydraulicParams.opening_table is given but flow_area is {self.flow_area!r}: set "
                                 f"flow_area to 'table' to use it")
            return
        for i, point in enumerate(table):
            if not (len(point) == 2 and all(isinstance(v, (int, float)) and math.isfinite(v) for v in point)):
                raise InputError(f"HydraulicParams.opening_table point {i + 1} must be two finite numbers, got {point!r}")
        below = 1 if table and table[0][0] <= 0.0 else 0
        if not (1 <= len(table) - below <= MAX_TABLE_POINTS):
            raise InputError(f"HydraulicParams.opening_table needs 1…{MAX_TABLE_POINTS} points (u_v V, opening "
                             f"fraction) above null for flow_area 'table' (and at most one at or below it), got "
                             f"{len(table) - below}")
        if below and (table[0][1] != 0.0 or table[0][0] < -0.2 * self.u_v_max):
            raise InputError(f"HydraulicParams.opening_table point 1 ({table[0][0]:g} V, {table[0][1]:g}): a point at "
                             f"or below null is where an underlapped edge opens: opening 0, within 20 % of the "
                             f"command range below null")
        prev_u, prev_f = (table[0][0] - 1.0, 0.0) if below else (0.0, 0.0)
        for i, (u, f) in enumerate(table):
            if u <= prev_u or f < prev_f or f > 2.0:
                raise InputError(
                    f"HydraulicParams.opening_table point {i + 1} ({u:g} V, {f:g}): commands must increase from 0 and "
                    f"openings must not decrease (fractions of the full opening, at most 2)")
            prev_u, prev_f = u, f
        if abs(prev_u - self.u_v_max) > 1e-9 * self.u_v_max:
            raise InputError(f"HydraulicParams.opening_table must end at u_v_max ({self.u_v_max:g} V), ends at {prev_u:g} V")

    def _check_curves(self) -> None:
        """InputError unless the edges' flow curves suit the flow area (:func:`_curves_fault`)."""
        args = self.flow_area, _frozen(self.flow_curve_pa), _frozen(self.flow_curve_at), self.u_v_max
        try:
            fault = _curves_fault(*args)
        except TypeError:  # a point that is not a number pair (unhashable): checked, not memoised
            fault = _curves_fault.__wrapped__(*args)
        if fault:
            raise InputError(fault)

    @property
    def edge_curves(self) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], ...]:
        """((u [V], opening [-], slope [1/V]) of the P→A edge, the same of the A→T edge), each (k,), read-only:
        the flow curves' points and the monotone cubic's slopes at them (scipy's PchipInterpolator, Fritsch &
        Carlson); empty arrays unless the flow area is "curve". Computed once per set of curves
        (:func:`_edge_curves`), not per parameter set: warming oil moves the parameters every controller tick,
        never the curves (a warming neighbour of ``hexsim tune`` built the cubics 30 000 times, 40 % of its run)."""
        return _edge_curves(self.flow_area, _frozen(self.flow_curve_pa), _frozen(self.flow_curve_at))

    # Derived constants, computed once per parameter set (the dataclass is frozen).
    @functools.cached_property
    def smooth_blend(self) -> tuple[float, float]:
        """(x_a, x_b) [m]: the smooth flow area k_a x_v^2 (seed eq. 3.11) holds for |x_v| <= x_a; from x_b
        on the opening is the sharp-edged port's pi d (|x_v| - O_l) (eq. 3.3), the geometric limit a
        spool of diameter d opens; in between, pi d (|x_v| - O_l) - k_a (|x_v| - x_b)^2, which meets both
        with the same value and slope (C^1) and bends with the same |curvature| 2 k_a as (3.11).

        With w = pi d and x_t = w / (2 k_a) (where (3.11) has the port's slope w): x_a is the larger root
        of 2 k_a x^2 - 2 w x + k_a x_t^2 + w O_l = 0 and x_b = 2 x_a - x_t. Seed values: x_a = 85.7 µm
        (0.78 V), x_b = 119 µm (1.08 V); (3.11) alone would cross the port's opening at 99.5 µm (0.90 V)
        and exceed it 10.5× at full spool stroke."""
        w, k = math.pi * self.spool_diameter, self.smooth_area_gain
        x_t = w / (2.0 * k)
        x_a = (2.0 * w + math.sqrt(max(4.0 * w * w - 8.0 * k * (k * x_t * x_t + w * self.overlap), 0.0))) / (4.0 * k)
        return x_a, 2.0 * x_a - x_t

    @functools.cached_property
    def rounded_corner(self) -> float:
        """x_c [m]: where the rounded edge's opening k_a x_v^2 (seed eq. 3.11) meets the port's pi d (x_v - O_l)
        (eq. 3.3) from below, the larger root of k_a x^2 - pi d x + pi d O_l = 0 (flow area "rounded": (3.11)
        up to it, the port beyond). The seed's values: 99.5 µm (0.90 V); with O_l at its limit pi d / (4 k_a)
        the two meet tangentially, at pi d / (2 k_a)."""
        w, k = math.pi * self.spool_diameter, self.smooth_area_gain
        return (w + math.sqrt(max(w * w - 4.0 * k * w * self.overlap, 0.0))) / (2.0 * k)

    @functools.cached_property
    def area_bottom(self) -> float:
        """A1 [m^2], piston area on the bottom side (seed app. A: pi/4 * 0.04^2)."""
        return math.pi / 4 * self.bore_diameter**2

    @functools.cached_property
    def area_rod(self) -> float:
        """A2 [m^2], annulus area on the rod side (seed app. A: pi/4 * (0.04^2 - 0.03^2))."""
        return math.pi / 4 * (self.bore_diameter**2 - self.rod_diameter**2)

    @property
    def four_way(self) -> bool:
        """Whether both chambers are fed by the valve (``valve_type == "4-way"``)."""
        return self.valve_type == "4-way"

    @functools.cached_property
    def orifice_constant(self) -> float:
        """C_d sqrt(2 / rho) [m^1.5 / kg^0.5] of the orifice equation (seed eq. 3.4)."""
        return self.discharge_coefficient * math.sqrt(2.0 / self.density)

    @functools.cached_property
    def stribeck_table(self) -> np.ndarray:
        """(2, 4) rows [sigma, F_c0, F_s0, c_s] for ydot < 0 (row 0) and ydot >= 0 (row 1), seed eq. (3.9)."""
        return np.array([
            [self.viscous_neg, self.coulomb_neg, self.static_neg, self.stribeck_velocity_neg],
            [self.viscous_pos, self.coulomb_pos, self.static_pos, self.stribeck_velocity_pos],
        ])

    def replace(self, **changes) -> "HydraulicParams":
        """A copy with ``changes`` applied (validated again)."""
        return dataclasses.replace(self, **changes)


@dataclass(frozen=True)
class ControllerParams:
    """Per-leg proportional position controller of the motion computer (seed §2.2.4, Fig. 2.6).

    u_v = K_p (r - y_measured) + U_c, saturated at ±u_v,max, computed at 500 Hz and held (zero-order
    hold) between samples.
    """

    kp: float = 200.0  # K_p [V/m]. The seed tuned K_p by hand (§3.3) and gives no value; 200 V/m
    # puts the loop's velocity bandwidth near 10 Hz at the operating point (1 V for 0.16 m/s with the
    # smooth flow area) with 5 mm tracking error at the seed's 0.157 m/s peak speed, and is the value
    # of the measurement-log format's example sidecar.
    rate_hz: float = 500.0  # [Hz], sampling frequency of the motion computer, seed §2.2.4
    position_noise: float = 2e-6  # [m] rms white noise on the measured piston position ("a few µm":
    # a position transducer's resolution; the seed adds measurement noise in §5.5)

    def __post_init__(self) -> None:
        _check_positive(self, "kp", "rate_hz")
        _check_nonnegative(self, "position_noise")

    def replace(self, **changes) -> "ControllerParams":
        """A copy with ``changes`` applied (validated again)."""
        return dataclasses.replace(self, **changes)


#: How an accelerometer channel is sampled (:attr:`SensorSpec.acceleration_sampling`).
ACCELERATION_SAMPLING = ("mean", "instant")
#: The :class:`SensorSpec` field that bounds each channel's sensor offset.
OFFSET_FIELDS = {"acceleration": "acceleration_offset", "p1": "pressure_offset", "p2": "pressure_offset",
                 "p_s": "pressure_offset"}


@dataclass(frozen=True)
class SensorSpec:
    """The transducers' data-sheet tolerances: how far ``hexsim validate`` may calibrate each sensor's
    offset and scale as nuisance parameters (:func:`hexsim.measured.scoring.calibrate_sensors`). A misfit that
    asks for more is physics, not the sensor (an accelerometer offset of 1.3 m/s² on an axis is an
    inclination of 30°, not a zero-g bias), and is left for the effects. The machine file's ``sensors``
    section; the defaults are typical industrial transducers'."""

    position_scale: float = 0.01  # [-] position transducer gain within ±1 % (magnetostrictive and
    # potentiometric transducers: ±0.02–1 % with the mounting's lever)
    acceleration_offset: float = 0.2  # [m/s^2] accelerometer zero-g bias within ±0.2 m/s² (±20 mg:
    # industrial MEMS and servo accelerometers' data sheets state 5–25 mg)
    acceleration_scale: float = 0.05  # [-] accelerometer sensitivity within ±5 % (data sheets ±2–5 %)
    pressure_offset: float = 1.25e5  # [Pa] pressure transducer zero within ±1.25 bar (±0.5 % of a 250 bar
    # span, industrial strain-gauge transducers' data sheets)
    # The acquisition's timing, which a replay of a log samples its model with (:mod:`hexsim.measured.acquisition`):
    sample_skew: float = 0.0  # [s] the logged position and pressures read this long after their row's valve
    # command took effect (negative: the command reached the valve after the sensors were read, an output
    # latency); hexsim's own logs: 0
    acceleration_sampling: str = "mean"  # "mean": the accelerometer's mean over the sample interval before its
    # row (a boxcar anti-alias filter, hexsim's own logs); "instant": its value at one instant
    acceleration_skew: float = 0.0  # [s] "instant": that instant, after the row's valve command took effect

    def __post_init__(self) -> None:
        _check_nonnegative(self, "position_scale", "acceleration_offset", "acceleration_scale", "pressure_offset")
        if self.acceleration_sampling not in ACCELERATION_SAMPLING:
            raise ValueError(f"acceleration_sampling must be one of {', '.join(ACCELERATION_SAMPLING)}, not "
                             f"{self.acceleration_sampling!r}")

    def offset_limit(self, channel: str) -> float | None:
        """The largest offset [channel's unit] a sensor of ``channel`` may have (None: not bounded here)."""
        return getattr(self, OFFSET_FIELDS[channel]) if channel in OFFSET_FIELDS else None

    def scale_limit(self, channel: str) -> float | None:
        """The largest scale error [-] of ``channel``'s sensor (None: its scale is not fitted)."""
        return {"position": self.position_scale, "acceleration": self.acceleration_scale}.get(channel)
