"""Reading and validating measurement logs (``docs/measurement-log.md``): CSV + JSON sidecar.

A log that breaks the format's rules is refused with one :class:`~hexsim.errors.InputError` naming the
file, the column and the row (or the sidecar key) and the value. Missing optional columns are allowed:
:attr:`MeasurementLog.missing` lists what the analysis cannot check, :attr:`MeasurementLog.assumed` the
defaults taken for absent sidecar keys.
"""

from __future__ import annotations

import json
import math
import pathlib
from dataclasses import dataclass, field

import numpy as np

from hexsim.errors import InputError
from hexsim.plant.machine import Machine, load_machine
from hexsim.tables import read_numeric_csv

SYSTEMS = ("single-actuator", "hexapod")
#: Physical range of each column kind (lower, upper) in SI units, and the hint when a value is outside.
_RANGES = {
    "_m": (-0.01, 0.01, "a piston position in metres within the stroke (a value in mm?)"),  # + stroke_m
    # gauge pressures; real transducers read below vacuum in the spikes of a valve switch and by their
    # offsets (the real servo cylinder's rod side: -3.1 bar at worst), so the floor is -5 bar, not -1
    "_Pa": (-5e5, 4.0e7, "a pressure in Pa between -5 bar (transducer offsets and spikes) and 400 bar"),
    "_V": (-10.5, 10.5, "a valve setpoint in V within ±10 V"),
    # a unit check: small cylinders reverse at tens of g (a 3 kg piston at 6 V: 31 g), accelerometers read ±100 g
    "_mps2": (-1000.0, 1000.0, "an acceleration in m/s^2 (below 100 g)"),
    "_radps": (-20.0, 20.0, "an angular rate in rad/s"),
    "_N": (-1e6, 1e6, "a force in N"),
}
#: A pressure column whose largest value is below this [Pa] is taken to be in bar (or MPa), not Pa.
_PRESSURE_UNIT_FLOOR = 1.0e4
DEFAULT_STROKE = 0.2  # [m], the seed's actuator (app. A); a log's sidecar may declare its own stroke_m
#: Columns a replay of the log needs (``hexsim validate``); ``hexsim friction`` needs only the position.
REPLAY_COLUMNS = ("valve_cmd_V", "pos_m")
_JITTER = 0.01  # allowed deviation of a sample period from the nominal, fraction of the period (the format)


@dataclass(frozen=True)
class MeasurementLog:
    """A validated log. ``columns``: name -> (N,) array in SI units (all columns of the CSV, unknown ones
    kept); ``time`` (N,) [s]; ``n_legs`` 1 (single actuator) or 6 (hexapod); ``machine`` the machine it is
    judged against (:class:`hexsim.plant.machine.Machine`: ``--machine``, else the sidecar's ``machine``,
    else the built-in); ``open_loop``: the sidecar's controller type is ``none`` (no position loop ran;
    ``kp`` is then the machine's, unused)."""

    path: pathlib.Path
    system: str
    sample_rate_hz: float
    columns: dict[str, np.ndarray]
    kp: float  # K_p [V/m] of the logged controller
    controller_rate_hz: float
    mass_kg: float | None  # the sidecar's moving mass (single actuator); None: the machine's
    inclination_deg: float  # the sidecar's inclination from vertical, else the machine's (single actuator)
    oil_temperature_c: float
    sidecar: dict
    stroke_m: float = DEFAULT_STROKE  # travel of the axis [m] (sidecar stroke_m)
    machine: Machine = field(default_factory=Machine)
    open_loop: bool = False
    assumed: list[str] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)

    @property
    def time(self) -> np.ndarray:
        return self.columns["time_s"]

    @property
    def n_legs(self) -> int:
        return 1 if self.system == "single-actuator" else 6

    def leg_column(self, kind: str, leg: int = 0) -> str:
        """Column name of ``kind`` (``ref_m``, ``valve_cmd_V``, ``pos_m``, ``p1_Pa``) for leg index ``leg``."""
        return kind if self.system == "single-actuator" else f"leg{leg + 1}_{kind}"

    def leg_array(self, kind: str) -> np.ndarray | None:
        """(N, n_legs) array of ``kind`` or None if the log lacks it (for any leg)."""
        names = [self.leg_column(kind, i) for i in range(self.n_legs)]
        if not all(n in self.columns for n in names):
            return None
        return np.column_stack([self.columns[n] for n in names])

    @property
    def duration(self) -> float:
        return float(self.time[-1] - self.time[0])

    @property
    def moving_mass_kg(self) -> float:
        """The moving mass [kg] of the logged run: the sidecar's (:attr:`mass_kg`), else the machine's
        (:attr:`hexsim.plant.machine.Machine.moving_mass_kg`: its ``load.mass_kg``, else the model's)."""
        return self.mass_kg if self.mass_kg is not None else self.machine.moving_mass_kg


def _number(side: dict, key: str, where: str, *, positive: bool = True) -> float:
    value = side[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or (
            positive and value <= 0):
        raise InputError(f"{where}: key {key!r} must be a {'positive ' if positive else ''}number, got {value!r}")
    return float(value)


def read_sidecar(csv_path: pathlib.Path) -> dict:
    """The JSON sidecar of ``csv_path`` (same stem, .json) as a dict. Raises InputError if it is missing,
    not valid JSON or not an object."""
    path = csv_path.with_suffix(".json")
    if not path.is_file():
        raise InputError(f"{csv_path}: sidecar {path.name} is missing (the log format needs CSV + JSON of the same stem)")
    try:
        side = json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(side, dict):
        raise InputError(f"{path}: the sidecar must be a JSON object, got {type(side).__name__}")
    return side


def read_log(path, machine: Machine | str | pathlib.Path | None = None,
             needs: tuple[str, ...] = REPLAY_COLUMNS) -> MeasurementLog:
    """Read and validate ``path`` (CSV) and its sidecar, judged against ``machine`` (a
    :class:`~hexsim.plant.machine.Machine`, a machine file or a built-in's name; None: the sidecar's
    ``"machine"``, a path relative to the log, else the built-in micro_motion_system). ``needs``: the
    columns (per leg) the caller needs (default: what a replay needs, the valve setpoint and the
    position). Raises InputError naming file, column/key, row and value for: a missing or malformed
    sidecar or key, an unknown system, a sample rate that does not match ``time_s``, non-uniform sampling
    (jitter > 1 % of the period), non-numeric or non-finite values, time not increasing, a value outside
    its column's physical range (a pressure in bar, a position in mm), a log without a needed column, or
    a sidecar whose declared valve or cylinder is not the machine's."""
    path = pathlib.Path(path)
    side = read_sidecar(path)
    side_name = path.with_suffix(".json")
    if not isinstance(machine, Machine):
        named = side.get("machine")
        if machine is None and named is not None and not isinstance(named, str):
            raise InputError(f"{side_name}: key 'machine' must be the path of a machine file, got {named!r}")
        machine = load_machine(machine if machine is not None else named,
                               relative_to=None if machine is not None else path.parent)
    _check_declared_machine(side, side_name, machine)
    settings = _sidecar_settings(side, side_name, machine)
    cols = read_numeric_csv(path)
    _check_sampling(path, cols["time_s"], settings["sample_rate_hz"])
    for name, values in cols.items():
        _check_range(path, name, values, settings["stroke_m"])
    log = MeasurementLog(path=path, columns=cols, sidecar=side, machine=machine, **settings)
    for kind in needs:
        for i in range(log.n_legs):
            name = log.leg_column(kind, i)
            if name not in cols:
                raise InputError(f"{path}: missing column {name!r}, needed to replay the log (header: "
                                 f"{', '.join(cols)})")
    setpoint = () if log.open_loop else ("ref_m",)  # an open-loop experiment has no setpoint to miss
    for kind in (*setpoint, "p1_Pa", *(("p2_Pa",) if machine.hydraulics.four_way else ())):
        if log.leg_array(kind) is None:
            log.missing.append(kind if log.n_legs == 1 else f"leg*_{kind}")
    if "ps_Pa" not in cols and not machine.hydraulics.four_way:
        log.missing.append("ps_Pa")
    acc = "acc_mps2" if log.n_legs == 1 else "platform_acc_z_mps2"
    if acc not in cols:
        log.missing.append(acc)
    return log


def _check_declared_machine(side: dict, side_name: pathlib.Path, machine: Machine) -> None:
    """InputError if the sidecar declares a valve type (``"valve"``) or cylinder dimensions
    (``"cylinder": {"bore_m", "rod_m", "stroke_m"}``) that are not ``machine``'s (beyond 1 %): a log judged
    against another machine's model answers about that machine."""
    hyd = machine.hydraulics
    valve = side.get("valve")
    if valve is not None and valve != hyd.valve_type:
        raise InputError(f"{side_name}: the log's valve is {valve!r}, machine {machine.label} has a {hyd.valve_type} "
                         f"valve: pass --machine with this machine's file (docs/machine-file.md)")
    cyl = side.get("cylinder", {})
    if not isinstance(cyl, dict):
        raise InputError(f"{side_name}: key 'cylinder' must be an object (bore_m, rod_m, stroke_m), got {cyl!r}")
    for key, ours in (("bore_m", hyd.bore_diameter), ("rod_m", hyd.rod_diameter), ("stroke_m", hyd.stroke)):
        if key in cyl:
            value = _number(cyl, key, f"{side_name} cylinder")
            if abs(value - ours) > 0.01 * ours:
                raise InputError(f"{side_name}: the log's cylinder {key} is {value:g}, machine {machine.label} has "
                                 f"{ours:g}: pass --machine with this machine's file (docs/machine-file.md)")


def _sidecar_settings(side: dict, side_name: pathlib.Path, machine: Machine) -> dict:
    """The MeasurementLog fields the sidecar sets (system, rates, K_p, temperature, stroke, mass,
    inclination, open loop) and ``assumed``: the defaults taken for keys it leaves out (the machine's).
    Raises InputError naming the key for a missing required key or a bad value."""
    for key in ("system", "sample_rate_hz"):
        if key not in side:
            raise InputError(f"{side_name}: missing key {key!r} (required by the log format)")
    system = side["system"]
    if system not in SYSTEMS:
        raise InputError(f"{side_name}: key 'system' is {system!r}; expected one of {', '.join(SYSTEMS)}")
    rate = _number(side, "sample_rate_hz", str(side_name))
    assumed: list[str] = []
    ctrl = side.get("controller", {})
    if not isinstance(ctrl, dict):
        raise InputError(f"{side_name}: key 'controller' must be an object, got {ctrl!r}")
    if ctrl.get("type", "P") not in ("P", "none"):
        raise InputError(f"{side_name}: controller type {ctrl.get('type')!r} is not supported ('P' or 'none', "
                         f"open loop)")
    open_loop = ctrl.get("type", "P") == "none"

    def value(table, key, where, default, note, positive=True):
        if key in table:
            return _number(table, key, where, positive=positive)
        if note:
            assumed.append(note)
        return default

    single = system == "single-actuator"
    if not single and machine.system == "single-actuator":  # a single-actuator log may be one leg of a hexapod
        raise InputError(f"{side_name}: a hexapod log; machine {machine.label} is a single actuator: pass --machine "
                         f"with this machine's file")
    mc, load = machine.controller, machine.effects
    kp = value(ctrl, "kp_V_per_m", f"{side_name} controller", mc.kp,
               not open_loop and f"controller K_p = {mc.kp:g} V/m (machine {machine.label})")
    ctrl_rate = value(ctrl, "rate_hz", f"{side_name} controller", mc.rate_hz,
                      not open_loop and f"controller rate = {mc.rate_hz:g} Hz (machine {machine.label})")
    temp = value(side, "oil_temperature_C", str(side_name), 35.0, "oil temperature 35 °C (seed app. A)", positive=False)
    stroke = value(side, "stroke_m", str(side_name), machine.hydraulics.stroke,
                   single and f"stroke {machine.hydraulics.stroke:g} m (machine {machine.label})")
    # undeclared, the mass stays None: the machine a replay is built from gives it (a calibration's or a
    # validation's machine under test, not the one the log was read with)
    mass = value(side, "mass_kg", str(side_name), None, single and (
        f"moving mass {load.mass_kg:g} kg (machine {machine.label})" if load.mass_kg is not None
        else f"moving mass from the model ({machine.moving_mass_kg:g} kg; machine {machine.label})"))
    incl0 = load.inclination_deg or 0.0
    incl = value(side, "inclination_deg", str(side_name), incl0,
                 single and f"inclination {incl0:g}° from vertical (machine {machine.label})", positive=False)
    if not 0.0 <= incl <= 90.0:
        raise InputError(f"{side_name}: key 'inclination_deg' must be within 0…90, got {incl:g}")
    return {"system": system, "sample_rate_hz": rate, "kp": kp,
            "controller_rate_hz": ctrl_rate, "mass_kg": mass, "inclination_deg": incl, "oil_temperature_c": temp,
            "stroke_m": stroke, "assumed": assumed, "open_loop": open_loop}


def _check_sampling(path: pathlib.Path, time: np.ndarray, rate: float) -> None:
    """Raise InputError if ``time_s`` does not match the sidecar's rate or is sampled non-uniformly
    (a step more than 1 % off the period), naming the row."""
    period = 1.0 / rate
    steps = np.diff(time)
    median = float(np.median(steps))
    if abs(median - period) > _JITTER * period:
        raise InputError(
            f"{path}: column 'time_s': median sample period {median * 1e3:.4g} ms does not match the sidecar's "
            f"sample_rate_hz {rate:g} ({period * 1e3:.4g} ms)")
    bad = np.abs(steps - period) > _JITTER * period
    if np.any(bad):
        r = int(np.argmax(bad))
        raise InputError(
            f"{path}: column 'time_s', row {r + 3}: sample period {steps[r] * 1e3:.4g} ms deviates more than 1 % "
            f"from {period * 1e3:.4g} ms (non-uniform sampling)")


def _check_range(path: pathlib.Path, name: str, values: np.ndarray, stroke: float) -> None:
    for suffix, (lo, hi, what) in _RANGES.items():
        if suffix == "_m":
            hi = hi + stroke
            what = f"a piston position in metres within the 0…{stroke:g} m stroke (a value in mm?)"
        if not name.endswith(suffix) or name == "time_s":
            continue
        if suffix == "_m" and not name.endswith(("pos_m", "ref_m")):
            return  # dof_ref_{x,y,z}_m: platform offsets, not pistons
        if suffix == "_Pa" and values.max() < _PRESSURE_UNIT_FLOOR and values.max() > 0:
            r = int(np.argmax(values)) + 2
            raise InputError(f"{path}: column {name!r}, row {r}: largest value {values.max():g} is far below any "
                             f"working pressure in Pa (in bar or MPa? the format wants Pa)")
        bad = (values < lo) | (values > hi)
        if np.any(bad):
            r = int(np.argmax(bad))
            raise InputError(f"{path}: column {name!r}, row {r + 2}: value {values[r]:g} is not {what}")
        return
