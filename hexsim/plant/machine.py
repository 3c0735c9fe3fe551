"""Machine files: everything hexsim assumes about one machine, in one versioned JSON file.

A machine file describes the valve (3-way as the seed's, or 4-way), the cylinder, the oil, the supply, the
friction per direction, the load, the sensors and the controller of a machine (``docs/machine-file.md``
lists every key with its unit, default and source). Every command takes one (``--machine FILE`` or the
name of a built-in); a measurement log's sidecar may name its own (``"machine": "PATH"``, relative to the
log). The built-in default, ``micro_motion_system``, is the seed's appendix A, and a run from it is
bit-identical to one with the dataclasses' defaults.

The file is a JSON object: ``format`` ("hexsim-machine"), ``version`` (1), ``name``, ``description``,
``system`` ("hexapod" or "single-actuator"), ``sources`` (optional: key -> where its value comes from, a
data sheet, a measurement, a guess), ``calibration`` (optional: what ``hexsim calibrate`` fitted, from
which logs, with standard errors), and sections ``valve``, ``cylinder``, ``oil``, ``supply``,
``friction`` (``positive``/``negative`` per direction), ``load``, ``sensors``, ``controller``. Keys carry
their SI unit as a suffix (``cylinder.bore_m``, ``supply.pressure_Pa``). Keys left out take the built-in
default and are listed in :attr:`Machine.defaulted`; a key set to ``null`` where the table allows it means
"not given" (``load.mass_kg``: the model's moving mass). The keys map onto
:class:`~hexsim.plant.params.HydraulicParams`, :class:`~hexsim.plant.params.ControllerParams` and
:class:`~hexsim.plant.effects.Effects`, which check the physics (a rod not smaller than the bore, a
negative volume); every problem is one :class:`~hexsim.errors.InputError` naming the file, the key and the
value.

A valve as a data sheet gives it: ``valve.rated_flow_m3ps`` Q_N through one control edge at
``valve.rated_dp_Pa`` Δp_N across that edge at full command (the "per land" convention of Moog and
Rexroth servo-valve data sheets, e.g. Q_N at 35 bar per land) sets the port width w of the sharp-edged
opening a = w (x_v - O_l) (seed eq. 3.3): w = Q_N / (C_d (x_v,max - O_l) sqrt(2 Δp_N / rho)), from the
orifice equation (3.4). It replaces ``valve.spool_diameter_m`` (set that to null).
"""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import math
import os
import pathlib
from dataclasses import dataclass, field

from hexsim.errors import InputError
from hexsim.plant.effects import Effects, LegChange
from hexsim.plant.geometry import Geometry
from hexsim.plant.machine_keys import (
    KEY_BY_PATH,
    KEYS,
    LEG_NAMES,
    OCCUPANT_KEYS,
    Key,
    is_leg_path,
    leg_key,
)
from hexsim.plant.params import (
    ControllerParams,
    HydraulicParams,
    SensorSpec,
)

FORMAT = "hexsim-machine"
VERSION = 1
SYSTEMS = ("hexapod", "single-actuator")
DEFAULT_NAME = "micro_motion_system"
_META = ("format", "version", "name", "description", "system", "sources", "calibration", "legs")


@dataclass(frozen=True)
class Machine:
    """One machine: its hydraulics, controller and effects (load and sensors included) as hexsim's
    dataclasses, with the file's name, description and ``system`` ("hexapod" or "single-actuator").
    ``control`` "P" or "none" (open loop). ``rated_flow`` [m^3/s] / ``rated_dp`` [Pa]: the data sheet's
    valve rating when the port width came from it. ``path``: the file (None: built-in); ``defaulted``:
    the keys the file left out (the built-in default taken)."""

    name: str = DEFAULT_NAME
    description: str = ("Rexroth-Hydraudyne Micro Motion System: six legs with a 3-way proportional valve, seed "
                        "appendix A")
    system: str = "hexapod"
    hydraulics: HydraulicParams = field(default_factory=HydraulicParams)
    controller: ControllerParams = field(default_factory=ControllerParams)
    sensors: SensorSpec = field(default_factory=SensorSpec)  # the transducers' data-sheet tolerances
    effects: Effects = field(default_factory=Effects)
    geometry: Geometry = field(default_factory=Geometry)  # the hexapod's (unused by a single actuator)
    control: str = "P"
    rated_flow: float | None = None
    rated_dp: float = 3.5e6
    path: pathlib.Path | None = None
    defaulted: tuple[str, ...] = ()
    sources: tuple[tuple[str, str], ...] = ()  # (key, where its value comes from) as the file states them
    # what `hexsim calibrate` wrote: the logs, each fitted key's prior, bounds, value, standard error,
    # the correlations and the held-out errors (hexsim.measured.calibration); None: not calibrated
    calibration: dict | None = field(default=None, compare=False)
    # the hexapod's legs whose valve, cylinder, oil or friction differ from the shared keys: (leg 1…6,
    # ((machine-file key, value), …)), as the file's ``legs`` section states them (a calibration's per-leg values)
    legs: tuple[tuple[int, tuple[tuple[str, float], ...]], ...] = ()

    @property
    def leg_changes(self) -> tuple[LegChange, ...]:
        """The ``legs`` section as :class:`~hexsim.plant.effects.LegChange` (dataclass fields, SI units)."""
        return tuple(LegChange.of(leg, **{KEY_BY_PATH[k].target[1]: v for k, v in values}) for leg, values in self.legs)

    @property
    def label(self) -> str:
        """How outputs name the machine: ``NAME (built-in)`` or ``NAME (PATH)``."""
        return f"{self.name} ({'built-in' if self.path is None else self.path})"

    @property
    def moving_mass_kg(self) -> float:
        """The moving mass M [kg] this machine's runs carry: its ``load.mass_kg``, or where that is null the
        model's (the single actuator's slide in the MJCF, :func:`hexsim.plant.model.moving_mass`)."""
        from hexsim.plant.model import moving_mass

        return self.effects.mass_kg if self.effects.mass_kg is not None else moving_mass()

    @property
    def open_loop(self) -> bool:
        return self.control == "none"

    @property
    def spec(self) -> str:
        """What :func:`load_machine` reads this machine back from: the built-in's name or the file's path."""
        return self.name if self.path is None else str(self.path)

    def document(self) -> dict:
        """The complete machine file as a JSON-ready dict (every key, file order)."""
        doc: dict = {"format": FORMAT, "version": VERSION, "name": self.name, "description": self.description,
                     "system": self.system}
        if self.sources:
            doc["sources"] = dict(self.sources)
        if self.calibration is not None:
            doc["calibration"] = self.calibration
        if self.legs:
            doc["legs"] = {}
            for leg, values in self.legs:
                node = doc["legs"].setdefault(f"leg{leg}", {})
                for key, value in values:
                    section, leaf = key.split(".", 1)
                    node.setdefault(section, {})[leaf] = value
        for key in KEYS:
            if self._omitted(key):
                continue
            node = doc
            *sections, leaf = key.path.split(".")
            for s in sections:
                node = node.setdefault(s, {})
            node[leaf] = _json_value(self._value(key))
        return doc

    def _omitted(self, key: Key) -> bool:
        """Keys a complete file leaves out: the hexapod section on a single actuator; the built hexapod's
        numbers when an MJCF is the hexapod, the MJCF's names when it is not; a circle replaced by points."""
        if key.target[0] != "geometry":
            return False
        g, name = self.geometry, key.target[1]
        if self.system != "hexapod":
            return True
        if name.startswith("mjcf"):
            return not g.is_mjcf and name != "mjcf"
        if name in OCCUPANT_KEYS:  # the occupant sits on either kind of hexapod
            return False
        if g.is_mjcf:
            return True
        if name in ("base_radius_m", "base_height_m", "base_angles_deg"):
            return g.base_joints_m is not None
        if name in ("platform_radius_m", "platform_angles_deg"):
            return g.platform_joints_m is not None
        return False

    def _value(self, key: Key):
        section, name = key.target
        if section == "machine":  # rated_flow, rated_dp, control: the Machine's own fields
            return getattr(self, name)
        if key.path == "valve.spool_diameter_m" and self.rated_flow is not None:
            return None
        return getattr(getattr(self, section), name)


def _json_value(value):
    if isinstance(value, tuple):
        return [_json_value(v) if isinstance(v, (tuple, str)) else float(v) for v in value]
    return value


def builtin_names() -> list[str]:
    """Names of the machine files shipped with hexsim (``models/machines/*.json``) and the default."""
    names = {DEFAULT_NAME}
    folder = _builtin_folder()
    if folder is not None:
        names |= {p.stem for p in folder.glob("*.json")}
    return sorted(names)


def _builtin_folder() -> pathlib.Path | None:
    """``machines/`` of the installed ``hexsim.models`` package, or of the checkout's ``models/``."""
    spec = importlib.util.find_spec("hexsim.models")
    if spec is not None and spec.submodule_search_locations:
        folder = pathlib.Path(list(spec.submodule_search_locations)[0]) / "machines"
    else:
        folder = pathlib.Path(__file__).resolve().parents[2] / "models" / "machines"
    return folder if folder.is_dir() else None


def load_machine(spec: str | os.PathLike | None = None, *, relative_to: pathlib.Path | None = None) -> Machine:
    """The machine ``spec`` names: None or ``micro_motion_system`` the built-in default, the name of
    another built-in (:func:`builtin_names`), or a path to a machine file (relative to ``relative_to``
    when given, as a log's sidecar names it). Raises InputError naming the file, key and value."""
    if spec is None or str(spec) == DEFAULT_NAME:
        return Machine()
    path = pathlib.Path(spec)
    if relative_to is not None and not path.is_absolute():
        path = relative_to / path
    if not path.exists() and path.suffix == "" and str(spec) in builtin_names():
        folder = _builtin_folder()
        return read_machine(folder / f"{spec}.json", builtin=True)
    return read_machine(path)


def read_machine(path: str | os.PathLike, *, builtin: bool = False) -> Machine:
    """Read and check the machine file ``path``. Raises InputError (file, key, value) for malformed
    JSON, a missing or wrong ``format``/``version``, an unknown key, a value of the wrong kind, and
    anything the parameter dataclasses refuse."""
    path = pathlib.Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such machine file (built-in machines: {', '.join(builtin_names())})")
    try:
        doc = json.loads(path.read_text(encoding="utf-8"), parse_constant=_no_constant)
    except json.JSONDecodeError as exc:
        raise InputError(f"{path}: not valid JSON ({exc.msg} at line {exc.lineno}, column {exc.colno})") from None
    except (UnicodeDecodeError, ValueError) as exc:
        raise InputError(f"{path}: {exc}") from None
    machine = machine_from_document(doc, str(path))
    mjcf = machine.geometry.mjcf
    if mjcf is not None and not pathlib.Path(mjcf).is_absolute():  # relative to the machine file
        geometry = dataclasses.replace(machine.geometry, mjcf=str((path.parent / mjcf).resolve()))
        machine = dataclasses.replace(machine, geometry=geometry)
    return dataclasses.replace(machine, path=None if builtin else path)


def _no_constant(name: str):
    raise ValueError(f"{name} is not a number JSON allows (NaN and Infinity are refused)")


def _flatten(doc: dict, where: str, prefix: str = "") -> dict[str, object]:
    out = {}
    for key, value in doc.items():
        dotted = f"{prefix}{key}"
        if isinstance(value, dict):
            if dotted in KEY_BY_PATH:
                raise InputError(f"{where}: {dotted} must be a value, got an object")
            out.update(_flatten(value, where, dotted + "."))
        else:
            out[dotted] = value
    return out


def machine_from_document(doc: object, where: str = "machine file") -> Machine:
    """A :class:`Machine` from a parsed machine file ``doc``; ``where`` names it in errors. Raises
    InputError (see :func:`read_machine`)."""
    if not isinstance(doc, dict):
        raise InputError(f"{where}: expected a JSON object (a machine file), got {type(doc).__name__}")
    if doc.get("format") != FORMAT:
        raise InputError(f"{where}: key 'format' must be {FORMAT!r}, got {doc.get('format')!r} (is this a machine file?)")
    if doc.get("version") != VERSION:
        raise InputError(f"{where}: key 'version' is {doc.get('version')!r}; this hexsim reads version {VERSION}")
    meta = _checked_meta(doc, where)
    sources, calibration, system = meta.get("sources", {}), meta.get("calibration"), meta.get("system", "hexapod")
    flat = _flatten({k: v for k, v in doc.items() if k not in _META}, where)
    for key in flat:
        if key not in KEY_BY_PATH:
            section = key.split(".")[0]
            known = [k.path for k in KEYS if k.path.startswith(section + ".")]
            hint = f"; known in {section}: {', '.join(known)}" if known else \
                f"; sections: {', '.join(sorted({k.path.split('.')[0] for k in KEYS}))}"
            raise InputError(f"{where}: unknown key {key!r}{hint}")
    values = {"hydraulics": {}, "controller": {}, "effects": {}, "machine": {}, "geometry": {}, "sensors": {}}
    for path, value in flat.items():
        key = KEY_BY_PATH[path]
        values[key.target[0]][key.target[1]] = _checked(key, value, where)
    m = values["machine"]
    rated_flow, rated_dp = m.get("rated_flow"), m.get("rated_dp", Machine.rated_dp)
    hyd_values = dict(values["hydraulics"])
    if rated_flow is not None:
        if hyd_values.get("spool_diameter") is not None:
            raise InputError(f"{where}: valve.rated_flow_m3ps and valve.spool_diameter_m both set; the rated flow "
                             f"sets the port width: set valve.spool_diameter_m to null")
        hyd_values["spool_diameter"] = None
    elif "spool_diameter" in hyd_values and hyd_values["spool_diameter"] is None:
        raise InputError(f"{where}: valve.spool_diameter_m is null but valve.rated_flow_m3ps is not given: one of "
                         f"them sets the port width")
    try:
        hyd = _build_hydraulics(hyd_values, rated_flow, rated_dp)
        controller = ControllerParams(**values["controller"])
        effects = Effects(**values["effects"])
        sensors = SensorSpec(**values["sensors"])
    except InputError as exc:
        raise InputError(f"{where}: {_key_names(str(exc))}") from None
    name = meta.get("name", pathlib.Path(where).stem)
    geometry = _geometry(values["geometry"], system, hyd.stroke, name, where)
    control = m.get("control", "P")
    legs = _legs(meta.get("legs", {}), system, hyd, effects, where)
    machine = Machine(name=name, description=meta.get("description", ""),
                   system=system, hydraulics=hyd, controller=controller, effects=effects, geometry=geometry,
                   sensors=sensors, control=control,
                   rated_flow=rated_flow, rated_dp=rated_dp, sources=tuple(sources.items()),
                   calibration=calibration, legs=legs)
    defaulted = tuple(k.path for k in KEYS if k.path not in flat and not machine._omitted(k))
    return dataclasses.replace(machine, defaulted=defaulted)


def _checked_meta(doc: dict, where: str) -> dict:
    """The machine file's keys outside its sections (:data:`_META`), each checked: ``name`` and ``description``
    text, ``sources`` an object naming machine-file keys, ``calibration`` an object, ``system`` one of
    :data:`SYSTEMS`. Raises InputError naming the file and the key."""
    meta = {k: doc[k] for k in _META if k in doc}
    for k in ("name", "description"):
        if k in meta and not isinstance(meta[k], str):
            raise InputError(f"{where}: key {k!r} must be a string, got {meta[k]!r}")
    sources = meta.get("sources", {})
    if not isinstance(sources, dict) or not all(isinstance(v, str) for v in sources.values()):
        raise InputError(f"{where}: key 'sources' must be an object of key: text (where each value comes from)")
    for key in sources:
        if key not in KEY_BY_PATH and not is_leg_path(key):
            raise InputError(f"{where}: sources names {key!r}, which is not a machine-file key")
    calibration = meta.get("calibration")
    if calibration is not None and not isinstance(calibration, dict):
        raise InputError(f"{where}: key 'calibration' must be an object (as hexsim calibrate writes it)")
    system = meta.get("system", "hexapod")
    if system not in SYSTEMS:
        raise InputError(f"{where}: key 'system' is {system!r}; expected one of {', '.join(SYSTEMS)}")
    return meta


def _legs(section: object, system: str, hyd: HydraulicParams, effects: Effects,
          where: str) -> tuple[tuple[int, tuple[tuple[str, float], ...]], ...]:
    """The ``legs`` section: ``{"leg3": {"valve": {"edge_gain_PA": 1.04}}, …}``, each leg's keys (numbers of
    :func:`leg_key`) replacing the shared ones for that leg. Raises InputError for a single actuator, an unknown
    leg, a key a leg cannot have on its own, or a value the parameter dataclasses refuse."""
    if not isinstance(section, dict):
        raise InputError(f"{where}: key 'legs' must be an object (leg1 … leg6: keys that leg has on its own)")
    if section and system != "hexapod":
        raise InputError(f"{where}: legs.{next(iter(section))}: a {system} has no legs of its own; set the keys "
                         f"themselves")
    out = []
    for name, keys in section.items():
        if name not in LEG_NAMES:
            raise InputError(f"{where}: legs.{name}: expected one of {', '.join(LEG_NAMES)}")
        if not isinstance(keys, dict):
            raise InputError(f"{where}: legs.{name} must be an object of keys (e.g. {{\"valve\": {{\"edge_gain_PA\": "
                             f"1.04}}}})")
        values = []
        for key, value in _flatten(keys, f"{where}: legs.{name}").items():
            if not leg_key(key):
                why = "not a machine-file key" if key not in KEY_BY_PATH else "shared by every leg (or not a number)"
                raise InputError(f"{where}: legs.{name}.{key}: {why}; a leg can have its own numbers of the "
                                 f"valve, cylinder, oil and friction")
            values.append((key, _checked(KEY_BY_PATH[key], value, f"{where}: legs.{name}")))
        change = LegChange.of(int(name[3:]), **{KEY_BY_PATH[k].target[1]: v for k, v in values})
        try:
            change.apply(hyd, effects)
        except InputError as exc:
            raise InputError(f"{where}: legs.{name}: {_key_names(str(exc))}") from None
        if values:
            out.append((change.leg, tuple(sorted(values))))
    return tuple(sorted(out))


def _geometry(values: dict, system: str, stroke: float, name: str, where: str) -> Geometry:
    """The hexapod's :class:`~hexsim.plant.geometry.Geometry` from the file's ``hexapod`` keys, its stroke the
    cylinder's. Raises InputError for hexapod keys on a single actuator, a built hexapod's numbers beside
    ``hexapod.mjcf``, joints given both as a circle and as points, and what Geometry refuses."""
    if values and system != "hexapod":
        raise InputError(f"{where}: hexapod.{next(iter(values))} describes a hexapod; this machine is a {system}")
    if values.get("mjcf") is not None:
        built = [name for name in values if not name.startswith("mjcf") and name not in OCCUPANT_KEYS]
        if built:
            raise InputError(f"{where}: hexapod.mjcf names the hexapod's model; hexapod.{built[0]} describes one "
                             f"hexsim builds: give one or the other")
    elif any(values.get(name) is not None for name in ("mjcf_legs", "mjcf_platform", "mjcf_sensor_site")):
        raise InputError(f"{where}: hexapod.mjcf_* name parts of a user's MJCF, but hexapod.mjcf is not given")
    for points, circle in (("base_joints_m", ("base_radius_m", "base_angles_deg", "base_height_m")),
                           ("platform_joints_m", ("platform_radius_m", "platform_angles_deg"))):
        both = [name for name in circle if name in values]
        if values.get(points) is not None and both:
            raise InputError(f"{where}: hexapod.{points} and hexapod.{both[0]} both set: give the joints as "
                             f"points or as a circle")
    try:
        return Geometry(**{**values, "stroke_m": stroke, "name": name})
    except InputError as exc:
        raise InputError(f"{where}: {_key_names(str(exc))}") from None


def _build_hydraulics(values: dict, rated_flow: float | None, rated_dp: float) -> HydraulicParams:
    """HydraulicParams from the file's values; with a rated flow, the port width from it (module doc)."""
    if rated_flow is None:
        return HydraulicParams(**values)
    base = HydraulicParams(**{k: v for k, v in values.items() if k != "spool_diameter"})
    opening = base.x_v_max - base.overlap
    width = rated_flow / (base.discharge_coefficient * opening * math.sqrt(2.0 * rated_dp / base.density))
    return base.replace(spool_diameter=width / math.pi)


def _key_names(message: str) -> str:
    """A dataclass's error with its field names replaced by the machine file's keys."""
    for key in sorted(KEYS, key=lambda k: -len(k.target[1])):  # longest first: pipeline_volume_rod before pipeline_volume
        section, name = key.target
        cls = {"hydraulics": "HydraulicParams", "controller": "ControllerParams", "effects": "Effects",
               "geometry": "Geometry", "sensors": "SensorSpec"}.get(section)
        if cls:
            message = message.replace(f"{cls}.{name} ", f"{key.path} ").replace(f"{cls}.{name}", key.path)
    return message


def _checked(key: Key, value, where: str):
    at = f"{where}: {key.path}"
    if value is None:
        if key.nullable:
            return None
        raise InputError(f"{at}: null is not allowed here ({key.meaning})")
    if key.kind == "text":
        if not isinstance(value, str) or (key.choices and value not in key.choices):
            expected = f"one of {', '.join(key.choices)}" if key.choices else "a text"
            raise InputError(f"{at}: expected {expected}, got {value!r}")
        return value
    if key.kind == "flag":
        if not isinstance(value, bool):
            raise InputError(f"{at}: expected true or false, got {value!r}")
        return value
    if key.kind == "table":
        if not (isinstance(value, list) and all(isinstance(p, list) and len(p) == 2 and all(_is_number(v) for v in p)
                                                for p in value)):
            raise InputError(f"{at}: expected [[u_V, opening], …] (numbers), got {value!r}")
        return tuple((float(u), float(f)) for u, f in value)
    if key.kind == "angles":
        if not (isinstance(value, list) and len(value) == 6 and all(_is_number(v) for v in value)):
            raise InputError(f"{at}: expected six angles [deg] (legs 1…6), got {value!r}")
        return tuple(float(v) for v in value)
    if key.kind == "points":
        if not (isinstance(value, list) and len(value) == 6 and all(
                isinstance(p, list) and len(p) == 3 and all(_is_number(v) for v in p) for p in value)):
            raise InputError(f"{at}: expected six points [[x, y, z], …] in m (legs 1…6), got {value!r}")
        return tuple(tuple(float(v) for v in p) for p in value)
    if key.kind == "names":
        if not (isinstance(value, list) and len(value) == 6 and all(isinstance(v, str) and v for v in value)):
            raise InputError(f"{at}: expected six joint names (legs 1…6), got {value!r}")
        return tuple(value)
    if key.kind == "vector":
        if not (isinstance(value, list) and len(value) == 3 and all(_is_number(v) for v in value)):
            raise InputError(f"{at}: expected [x, y, z] in {key.unit}, got {value!r}")
        return tuple(float(v) for v in value)
    if not _is_number(value):
        raise InputError(f"{at}: expected a number in {key.unit}, got {value!r}")
    if key.target == ("machine", "rated_flow") or key.target == ("machine", "rated_dp"):
        if value <= 0:
            raise InputError(f"{at}: must be a positive number in {key.unit}, got {value!r}")
    return float(value)


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def parse_assignment(text: str) -> tuple[str, object]:
    """``key=value`` of ``hexsim machine set``: the value as JSON (numbers, true/false, null, [x, y, z],
    "text"), or as text when it is not JSON (``valve.type=4-way``). Raises InputError for a malformed
    assignment or an unknown key."""
    if "=" not in text:
        raise InputError(f"{text!r}: expected key=value (e.g. cylinder.bore_m=0.016)")
    key, raw = (s.strip() for s in text.split("=", 1))
    if key.startswith("legs.") and not is_leg_path(key):
        raise InputError(f"{key!r}: a leg's own key is legs.leg1 … legs.leg6 followed by a number of the valve, "
                         f"cylinder, oil or friction (e.g. legs.leg3.valve.edge_gain_PA=1.04)")
    if key not in KEY_BY_PATH and key not in ("name", "description", "system") and not key.startswith("legs."):
        raise InputError(f"{key!r} is not a machine-file key; `hexsim machine show` lists them")
    try:
        value = json.loads(raw, parse_constant=_no_constant)
    except ValueError:
        value = raw
    return key, value


def shared_path(path: str) -> str:
    """The shared key a path names: ``legs.legN.KEY`` -> ``KEY``; any other key itself."""
    return path.split(".", 2)[2] if path.startswith("legs.") else path


def get_key(doc: dict, key: str):
    """The value of ``key`` in a machine-file document ``doc`` (:meth:`Machine.document`), the keys as
    :func:`with_keys` sets them; ``valve.opening_table[i]``: the opening of point i;
    ``load.payload_at_m[i]``: element i; ``legs.legN.KEY``: leg N's own value, else the shared KEY's."""
    path, _, index = key.partition("[")
    if path.startswith("legs."):
        _, leg, own = path.split(".", 2)
        node = doc.get("legs", {}).get(leg, {})
        for part in own.split("."):
            node = node.get(part, {}) if isinstance(node, dict) else node
        return node if not isinstance(node, dict) else get_key(doc, own)
    node = doc
    for part in path.split("."):
        node = node[part]
    if not index:
        return node
    return node[int(index[:-1])][1] if isinstance(node[0], list) else node[int(index[:-1])]


def with_keys(machine: Machine, values: dict[str, float | str]) -> Machine:
    """``machine`` with each dotted key of ``values`` set to its number, or its text for a text key
    (``valve.opening_table[i]``: the opening of point i; ``load.payload_at_m[i]``: element i of a vector;
    ``legs.legN.KEY``: leg N's own value of KEY, the ``legs`` section), the file checked again as any machine
    file (InputError names the key and value)."""
    doc = json.loads(json.dumps(machine.document()))
    for key, value in values.items():
        path, _, index = key.partition("[")
        own = shared_path(path)  # the key's kind: the shared key's
        *sections, leaf = path.split(".")
        node = doc
        for part in sections:
            node = node.setdefault(part, {})
        if index and KEY_BY_PATH[own].kind == "table":
            node[leaf][int(index[:-1])][1] = float(value)
        elif index:  # a vector's element
            node[leaf][int(index[:-1])] = float(value)
        else:
            node[leaf] = value if KEY_BY_PATH[own].kind == "text" else float(value)
    return dataclasses.replace(machine_from_document(doc, machine.label), path=machine.path)


def with_valve(machine: Machine, **valve) -> Machine:
    """``machine`` with the ``valve`` section's entries ``valve`` set (any value: a form's name, a table, a curve),
    the file checked again as any machine file (InputError names the key and value)."""
    doc = set_keys(machine.document(), [(f"valve.{key}", value) for key, value in valve.items()])
    return dataclasses.replace(machine_from_document(doc, machine.label), path=machine.path)


def set_keys(doc: dict, assignments: list[tuple[str, object]]) -> dict:
    """A copy of the machine-file ``doc`` with the dotted keys of ``assignments`` set (sections created
    where missing)."""
    out = json.loads(json.dumps(doc))
    for key, value in assignments:
        node = out
        *sections, leaf = key.split(".")
        for s in sections:
            node = node.setdefault(s, {})
            if not isinstance(node, dict):
                raise InputError(f"{key}: {s} is not a section in this file")
        node[leaf] = value
    return out


def dump(doc: dict) -> str:
    """The machine file's text: two-space indented JSON with a final newline."""
    return json.dumps(doc, indent=2, ensure_ascii=False) + "\n"


def reference_markdown() -> str:
    """The table of every key (unit, default of the built-in, meaning, source) for docs/machine-file.md."""
    default = Machine()
    rows = ["| key | unit | default (built-in) | meaning | source |", "|---|---|---|---|---|"]
    for key in KEYS:
        value = default._value(key)
        shown = json.dumps(_json_value(value)) if not isinstance(value, float) else f"{value:.6g}"
        rows.append(f"| `{key.path}` | {key.unit} | {shown} | {key.meaning} | {key.source} |")
    return "\n".join(rows) + "\n"
