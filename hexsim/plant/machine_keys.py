"""Every key of a machine file (:mod:`hexsim.plant.machine`): its dotted path, the dataclass field it sets, its
SI unit, meaning and source (docs/machine-file.md's table is generated from :data:`KEYS`), and which keys a
hexapod's legs may have of their own."""

from __future__ import annotations

from dataclasses import dataclass

from hexsim.plant.effects import SHARED_FIELDS
from hexsim.plant.params import ACCELERATION_SAMPLING, FLOW_AREAS

#: The control a machine file may name: a P loop per leg, or none (open loop).
CONTROL_TYPES = ("P", "none")
_SEED = "seed app. A"
_MMS = "Micro Motion System (models/hexapod.py)"


@dataclass(frozen=True)
class Key:
    """One key of a machine file: dotted ``path`` (section.name_unit), the dataclass field it sets
    (``target`` = (section, field) of hydraulics/controller/effects/machine), its unit, meaning, source,
    the JSON kind ("number", "text", "flag", "vector") and whether null is allowed."""

    path: str
    target: tuple[str, str]
    unit: str
    meaning: str
    source: str
    kind: str = "number"
    nullable: bool = False
    choices: tuple[str, ...] = ()


def _k(path, target, unit, meaning, source, **kw) -> Key:
    return Key(path, tuple(target.split(".")), unit, meaning, source, **kw)


#: Every key of a machine file, in file order.
KEYS: tuple[Key, ...] = (
    _k("valve.type", "hydraulics.valve_type", "-", "3-way (rod side at supply, the seed's) or 4-way (both chambers "
       "fed by the valve)", "seed Fig. 3.1 (3-way)", kind="text", choices=("3-way", "4-way")),
    _k("valve.flow_area", "hydraulics.flow_area", "-", "opening against spool position: smooth (3.11 blended onto "
       "the port), quadratic (3.11 everywhere), port ((3.11) until the port's opening is smaller, the port beyond: a kink, a real spool), "
       "sharp (3.3, linear with overlap/underlap), rounded ((3.11) from null, no dead band, until it meets the port, "
       "the port beyond: a rounded metering edge), table (opening_table), curve (flow_curve_PA/_AT: each edge's "
       "curve read from the machine's flows)",
       "seed eq. 3.3, 3.11", kind="text", choices=FLOW_AREAS),
    _k("valve.opening_table", "hydraulics.opening_table", "V, -", "flow_area table: [[u_v V, opening as a fraction "
       "of the full opening], …] to u_v,max, linear between points from (0, 0), both edges alike; a first point "
       "[-u V, 0] below null: each edge opens u before null (an underlap)",
       "valve data sheet (flow against command) or a calibration", kind="table"),
    _k("valve.flow_curve_PA", "hydraulics.flow_curve_pa", "V, -", "flow_area curve: the P→A edge's [[u_v V, opening "
       "as a fraction of the full opening], …] from where it opens (opening 0; below null: an underlap) to u_v,max, "
       "a monotone cubic (PCHIP) between points", "hexsim calibrate (the machine's flows)", kind="table"),
    _k("valve.flow_curve_AT", "hydraulics.flow_curve_at", "V, -", "flow_area curve: the A→T edge's points as "
       "flow_curve_PA's, at minus the command (empty: flow_curve_PA's)", "hexsim calibrate (the machine's flows)",
       kind="table"),
    _k("valve.command_range_V", "hydraulics.u_v_max", "V", "valve setpoint at full spool stroke u_v,max", _SEED),
    _k("valve.spool_stroke_m", "hydraulics.x_v_max", "m", "spool travel at u_v,max x_v,max", _SEED),
    _k("valve.spool_diameter_m", "hydraulics.spool_diameter", "m", "spool diameter d: port width pi d of the "
       "full-perimeter opening (null: from the rated flow)", _SEED, nullable=True),
    _k("valve.rated_flow_m3ps", "machine.rated_flow", "m^3/s", "data sheet: rated flow Q_N through one control "
       "edge at rated_dp_Pa and full command (null: the port from spool_diameter_m)", "valve data sheet",
       nullable=True),
    _k("valve.rated_dp_Pa", "machine.rated_dp", "Pa", "data sheet: pressure drop per control edge (land) at which "
       "Q_N is rated", "35 bar per land (Moog, Rexroth servo-valve data sheets)"),
    _k("valve.overlap_m", "hydraulics.overlap", "m", "overlap O_l at mid-position (negative: underlap, sharp area "
       "only)", _SEED),
    _k("valve.null_offset_V", "hydraulics.null_offset", "V", "setpoint that centres the spool u_0", "seed §5.3 (0)"),
    _k("valve.smooth_area_gain", "hydraulics.smooth_area_gain", "m^2/m^2", "k_a of the smooth area a = k_a x_v^2",
       "seed eq. 3.11 (300)"),
    _k("valve.discharge_coefficient", "hydraulics.discharge_coefficient", "-", "orifice discharge coefficient C_d",
       _SEED),
    _k("valve.spool_frequency_Hz", "effects.spool_frequency", "Hz", "spool loop natural frequency f_v (0: ideal "
       "spool, eq. 3.2)", "seed eq. 3.2 (ideal)"),
    _k("valve.spool_damping", "effects.spool_damping", "-", "spool loop damping zeta_v", "valve data sheets (0.7)"),
    _k("valve.spool_play_V", "effects.spool_play", "V", "half width of the backlash before the spool h",
       "seed §4.4 (none)"),
    _k("valve.edge_gain_PA", "effects.edge_gain_pa", "-", "flow gain of the supply edge P→A relative to (3.4)",
       "seed eq. 3.4 (1)"),
    _k("valve.edge_gain_AT", "effects.edge_gain_at", "-", "flow gain of the return edge A→T relative to (3.4)",
       "seed eq. 3.4 (1)"),
    _k("valve.edge_gain_PB", "effects.edge_gain_pb", "-", "4-way: flow gain of the supply edge P→B relative to (3.4)",
       "a matched spool (1)"),
    _k("valve.edge_gain_BT", "effects.edge_gain_bt", "-", "4-way: flow gain of the return edge B→T relative to (3.4)",
       "a matched spool (1)"),
    _k("cylinder.bore_m", "hydraulics.bore_diameter", "m", "piston (bore) diameter D: A1 = pi/4 D^2", _SEED),
    _k("cylinder.rod_m", "hydraulics.rod_diameter", "m", "rod diameter d_r: A2 = pi/4 (D^2 - d_r^2)", _SEED),
    _k("cylinder.stroke_m", "hydraulics.stroke", "m", "stroke L_s (the single actuator's slide travels 0 to it, "
       "mid-stroke its neutral; rod-side volume (L_s - y) A2 of a 4-way valve; the hexapod's leg stroke: a user "
       "MJCF's slide range must be 0 to it)", _SEED),
    _k("cylinder.dead_volume_cap_m3", "hydraulics.pipeline_volume", "m^3", "cap side dead volume (hoses, "
       "pipeline) V_pl", "seed app. A, eq. 3.1"),
    _k("cylinder.dead_volume_rod_m3", "hydraulics.pipeline_volume_rod", "m^3", "rod side dead volume V_pl,B "
       "(4-way)", "as the cap side"),
    _k("cylinder.leakage_m3psPa", "effects.leakage", "m^3/(s Pa)", "internal leakage across the piston C_l",
       "seed (none)"),
    _k("oil.bulk_modulus_Pa", "hydraulics.bulk_modulus", "Pa", "effective bulk modulus E", _SEED),
    _k("oil.density_kgpm3", "hydraulics.density", "kg/m^3", "oil density rho", "seed app. A (Tellus T46, 35 °C)"),
    _k("oil.cavitation_pressure_Pa", "hydraulics.cavitation_pressure", "Pa", "lowest chamber pressure (gauge)",
       "0.1 bar abs. (Gholizadeh et al. 2011)"),
    _k("oil.air_fraction", "effects.air_fraction", "-", "entrained air per volume at atmospheric pressure",
       "none"),
    _k("oil.air_exponent", "effects.air_exponent", "-", "polytropic exponent of that air", "1.4 (adiabatic)"),
    _k("supply.pressure_Pa", "hydraulics.supply_pressure", "Pa", "supply pressure P_s (gauge)", _SEED),
    _k("supply.tank_pressure_Pa", "hydraulics.tank_pressure", "Pa", "tank pressure P_t (gauge)", _SEED),
    _k("supply.resistance_Pa_s_per_m3", "effects.supply_resistance", "Pa s/m^3", "P_s sag per unit supply flow R_s "
       "(0: ideal supply)", "seed (ideal)"),
    _k("supply.time_constant_s", "effects.supply_time_constant", "s", "pump/accumulator time constant tau_s",
       "Merritt §4.13"),
    *(_k(f"friction.{side}.{name}", f"hydraulics.{attr}_{suffix}", unit, f"{what}, {side} velocity",
         "seed eq. 3.9, app. A")
      for side, suffix in (("positive", "pos"), ("negative", "neg"))
      for name, attr, unit, what in (("viscous_Nspm", "viscous", "N s/m", "viscous coefficient sigma"),
                                     ("coulomb_N", "coulomb", "N", "Coulomb level F_c0"),
                                     ("static_N", "static", "N", "Stribeck (static) level F_s0"),
                                     ("stribeck_velocity_mps", "stribeck_velocity", "m/s", "Stribeck velocity c_s"))),
    _k("friction.arctan_gain_spm", "hydraulics.arctan_gain", "s/m", "k of arctan(k ydot)", "seed eq. 3.9"),
    _k("friction.arctan_normalised", "hydraulics.arctan_normalised", "-", "true: (2/pi) arctan, a smoothed sign; "
       "false: arctan as published", "seed eq. 3.9", kind="flag"),
    _k("load.mass_kg", "effects.mass_kg", "kg", "moving mass M of a single actuator (null: the model's, 40 kg)",
       "seed app. A", nullable=True),
    _k("load.inclination_deg", "effects.inclination_deg", "deg", "single actuator's axis from vertical (null: "
       "vertical)", "seed eq. 3.8 (vertical)", nullable=True),
    _k("load.payload_kg", "effects.payload_kg", "kg", "hexapod: mass added to the platform", "none"),
    _k("load.payload_at_m", "effects.payload_at_m", "m", "hexapod: its centre of gravity, platform frame",
       "none", kind="vector"),
    _k("sensors.position_noise_m", "controller.position_noise", "m", "rms white noise of the position sensor",
       "a transducer's resolution"),
    _k("sensors.position_delay_s", "effects.sensor_delay", "s", "delay of the position measurement", "none"),
    _k("sensors.position_scale_tolerance", "sensors.position_scale", "-", "the position transducer's gain error a "
       "validation may calibrate (±)", "transducer data sheets: ±0.02–1 % with the mounting"),
    _k("sensors.acceleration_offset_mps2", "sensors.acceleration_offset", "m/s^2", "the accelerometer's zero-g bias "
       "a validation may calibrate (±); beyond it a misfit is physics (an inclination, a load)",
       "accelerometer data sheets: 5–25 mg"),
    _k("sensors.acceleration_scale_tolerance", "sensors.acceleration_scale", "-", "the accelerometer's sensitivity "
       "error a validation may calibrate (±)", "accelerometer data sheets: ±2–5 %"),
    _k("sensors.pressure_offset_Pa", "sensors.pressure_offset", "Pa", "each pressure transducer's zero error a "
       "validation may calibrate (±)", "±0.5 % of a 250 bar span (transducer data sheets)"),
    _k("sensors.sample_skew_s", "sensors.sample_skew", "s", "when the logged position and pressures were read, "
       "after the instant their row's valve command took effect (negative: the command reached the valve after the "
       "sensors were read, an output latency); a log's replay samples its model there",
       "hexsim calibrate (the logs' transients); hexsim's own logs: 0"),
    _k("sensors.acceleration_sampling", "sensors.acceleration_sampling", "-", "how the accelerometer was sampled: "
       "mean (over the sample interval before its row: a boxcar anti-alias filter, hexsim's own logs) or instant",
       "hexsim calibrate (the logs' transients)", kind="text", choices=ACCELERATION_SAMPLING),
    _k("sensors.acceleration_skew_s", "sensors.acceleration_skew", "s", "instant sampling: the accelerometer's "
       "instant after its row's valve command took effect", "hexsim calibrate (the logs' transients)"),
    _k("controller.type", "machine.control", "-", "P (position loop per leg) or none (open loop: the valve "
       "command is given)", "seed §2.2.4", kind="text", choices=CONTROL_TYPES),
    _k("controller.kp_VPm", "controller.kp", "V/m", "P gain K_p", "hexsim (seed §3.3 tuned by hand)"),
    _k("controller.rate_hz", "controller.rate_hz", "Hz", "controller (or command output) rate", "seed §2.2.4"),
    *(_k(f"hexapod.{name}", f"geometry.{name}", unit, meaning, source, **kw) for name, unit, meaning, source, kw in (
        ("base_radius_m", "m", "radius of the base joints' circle", _MMS, {}),
        ("base_height_m", "m", "height of the base joints above the floor (world z)", _MMS, {}),
        ("base_angles_deg", "deg", "angle of each base joint on its circle, legs 1…6 (world x axis 0)", _MMS,
         {"kind": "angles"}),
        ("platform_radius_m", "m", "radius of the platform joints' circle", _MMS, {}),
        ("platform_angles_deg", "deg", "angle of each platform joint on its circle, legs 1…6", _MMS, {"kind": "angles"}),
        ("base_joints_m", "m", "base joints as [[x, y, z], …] (world) instead of the circle (null: the circle)",
         "a drawing", {"kind": "points", "nullable": True}),
        ("platform_joints_m", "m", "platform joints as [[x, y, z], …] (platform frame: origin the upper joint "
         "plane's centre) instead of the circle (null: the circle)", "a drawing", {"kind": "points", "nullable": True}),
        ("retracted_length_m", "m", "leg length joint to joint at y = 0 (piston retracted) L_min", _MMS, {}),
        ("neutral_piston_m", "m", "piston position y at the neutral pose (null: mid-stroke); the stroke is "
         "cylinder.stroke_m", _MMS, {"nullable": True}),
        ("platform_mass_kg", "kg", "platform (frame and payload) mass", "seed §2.2.1 (about 600 kg)", {}),
        ("platform_inertia_kgm2", "kg m^2", "platform principal inertia about its centre of mass",
         "a uniform 1.2 x 1.2 x 0.4 m box", {"kind": "vector"}),
        ("platform_com_m", "m", "platform centre of mass, platform frame", "the box's centre", {"kind": "vector"}),
        ("platform_size_m", "m", "the platform's box as drawn (drawing only)", _MMS, {"kind": "vector"}),
        ("barrel_mass_kg", "kg", "cylinder barrel mass", "a Ø60 mm steel tube, 0.4 m", {}),
        ("barrel_inertia_kgm2", "kg m^2", "barrel principal inertia about its centre of mass (axial last)",
         "the tube", {"kind": "vector"}),
        ("barrel_com_m", "m", "barrel centre of mass from the base joint along the leg", "the tube", {}),
        ("barrel_length_m", "m", "barrel length as drawn (drawing only)", _MMS, {}),
        ("rod_mass_kg", "kg", "rod and piston mass", "a Ø30 mm chromed rod, 0.4 m, and piston", {}),
        ("rod_inertia_kgm2", "kg m^2", "rod principal inertia about its centre of mass (axial last)", "the rod",
         {"kind": "vector"}),
        ("rod_com_m", "m", "rod centre of mass from the platform joint back along the rod", "the rod", {}),
        ("rod_length_m", "m", "rod length as drawn (drawing only)", _MMS, {}),
        ("base_plate_m", "m", "radius of the base plate as drawn (null: 0.1 m beyond the joints; drawing only)",
         _MMS, {"nullable": True}),
        ("sensor_at_m", "m", "accelerometer and gyro (site platform_centre), platform frame", "seed §2.2",
         {"kind": "vector"}),
        ("head_at_m", "m", "the occupant's head (vestibular organs), platform frame (null: 0.77 m above the seat)",
         "sitting eye height, DINED / Tilley (2002)", {"kind": "vector", "nullable": True}),
        ("seat_at_m", "m", "the occupant's seat cushion, platform frame (null: 0.30 m above the deck's centre)",
         "SAE J1100 H30", {"kind": "vector", "nullable": True}),
        ("mjcf", "-", "a user's own MJCF of the hexapod (path, relative to this file) instead of the numbers "
         "above (docs/your-hexapod.md)", "the user", {"kind": "text", "nullable": True}),
        ("mjcf_legs", "-", "its six leg slide joints, legs 1…6 (null: joints leg1…leg6, or its only six slide "
         "joints)", "the user", {"kind": "names", "nullable": True}),
        ("mjcf_platform", "-", "its platform body (null: body 'platform', or its only free body)", "the user",
         {"kind": "text", "nullable": True}),
        ("mjcf_sensor_site", "-", "site where the accelerometer and gyro sit (null: the platform body's origin)",
         "the user", {"kind": "text", "nullable": True}),
    )),
)
#: Each key by its dotted path.
KEY_BY_PATH = {k.path: k for k in KEYS}
#: hexapod keys of the occupant, not of the machine's build: kept beside a user's MJCF
OCCUPANT_KEYS = ("head_at_m", "seat_at_m")
#: Legs of a hexapod machine file's ``legs`` section: ``leg1`` … ``leg6``.
LEG_NAMES = tuple(f"leg{i}" for i in range(1, 7))


def is_leg_path(path: str) -> bool:
    """``legs.legN.KEY`` with N a leg and KEY a key a leg may have of its own (:func:`leg_key`)."""
    head, leg, own = (path.split(".", 2) + ["", ""])[:3]
    return head == "legs" and leg in LEG_NAMES and leg_key(own)


def leg_key(key: str) -> bool:
    """Whether ``key`` (a machine-file key) may differ between a hexapod's legs (``legs.legN.KEY``): a number of
    the hydraulics or effects that is not shared by every leg (the supply, the load, the sensors' delay and
    the command range are one for the machine: :data:`hexsim.plant.effects.SHARED_FIELDS`)."""
    k = KEY_BY_PATH.get(key)
    return (k is not None and k.kind == "number" and k.target[0] in ("hydraulics", "effects")
            and k.target[1] not in SHARED_FIELDS)
