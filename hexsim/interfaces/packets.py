"""The UDP packets between a simulator's host computer and ``hexsim serve`` (docs/serve.md).

A packet is a fixed sequence of binary fields (:class:`Field`: a name, a type such as ``f32`` or ``u16``
and a scale to SI units), in one byte order: a :class:`PacketLayout`. hexsim's own layouts are
:data:`HOST_PACKET` (setpoints, host -> motion system) and :data:`STATE_PACKET` (the platform's state,
motion system -> host); a host whose packet already exists describes it in a JSON layout file
(:meth:`PacketLayout.from_file`) instead of changing its code::

    {"byte_order": "big", "setpoints": "dof",
     "modes": {"park": 0, "neutral": 1, "engage": 2},
     "fields": [{"name": "version", "type": "u16", "value": 3},
                {"name": "frame", "type": "u32"}, {"name": "mode", "type": "u16"},
                {"name": "heave", "type": "f32", "scale": 0.001}, ...]}

The names a host packet understands are :data:`HOST_FIELDS`; any other name is read and ignored (a
checksum, the host's own time). A field with a ``value`` is a constant: a host packet must carry it
(a version word), a state packet always sends it. The scale multiplies the raw number into SI units
(0.001 for millimetres, pi/180 for degrees); a state packet divides by it.

Types are those of :mod:`struct` without padding: u8, i8, u16, i16, u32, i32, f32, f64.
"""

from __future__ import annotations

import dataclasses
import math
import os
import pathlib
import struct
from collections.abc import Mapping

from hexsim.errors import InputError

#: field type -> struct code
TYPES = {"u8": "B", "i8": "b", "u16": "H", "i16": "h", "u32": "I", "i32": "i", "f32": "f", "f64": "d"}
DOF = ("surge", "sway", "heave", "roll", "pitch", "yaw")
LEGS = tuple(f"leg{i}" for i in range(1, 7))
#: names a host packet understands: version (a constant), frame (a counter the host increments by one
#: or more each packet, wrapping at its type's range), mode (the host's mode word, :attr:`PacketLayout.modes`),
#: the six DOF [m, rad] relative to the neutral pose (setpoints "dof"), or the six piston positions [m] from
#: the fully retracted end (setpoints "legs")
HOST_FIELDS = ("version", "frame", "mode", *DOF, *LEGS)
#: the motion system's modes, in the host's mode word (:attr:`PacketLayout.modes`)
MODES = ("park", "neutral", "engage")

#: what a state packet can send: name -> (unit, description)
STATE_FIELDS: dict[str, tuple[str, str]] = {
    "version": ("-", "the layout's version (a constant)"),
    "frame": ("-", "the frame counter of the last host packet accepted"),
    "status": ("-", "the motion system's state: 0 parked, 1 neutral, 2 engaged, 3 engaging, 4 returning to "
                    "neutral, 5 parking, 6 raising to neutral"),
    "faults": ("-", "bit field: 1 host lost, 2 packet rejected since the last state packet, 4 overrun since the "
                    "last state packet, 8 a setpoint beyond the envelope since the last state packet"),
    "time": ("s", "simulated time"),
    **{n: ("m" if k < 3 else "rad", f"platform {n}, relative to the neutral pose") for k, n in enumerate(DOF)},
    **{f"{n}_rate": ("m/s", f"platform velocity along the world {a} axis") for n, a in zip(DOF[:3], "xyz")},
    **{f"{n}_rate": ("rad/s", f"platform angular velocity about the world {a} axis (the {n} rate at small angles)")
       for n, a in zip(DOF[3:], "xyz")},
    **{f"head_f{a}": ("m/s^2", f"specific force at the occupant's head, platform {a} axis") for a in "xyz"},
    **{f"head_w{a}": ("rad/s", f"angular velocity, platform {a} axis") for a in "xyz"},
    **{f"leg{i}": ("m", f"leg {i} piston position from the retracted end") for i in range(1, 7)},
    **{f"leg{i}_ref": ("m", f"leg {i} piston setpoint the controller follows") for i in range(1, 7)},
    **{f"p1_leg{i}": ("Pa", f"leg {i} bottom-chamber pressure P1") for i in range(1, 7)},
    "p_s": ("Pa", "supply pressure"),
    "received": ("-", "host packets received"),
    "rejected": ("-", "host packets rejected (malformed, out of order or beyond the envelope)"),
    "late": ("-", "controller ticks that started more than one period late"),
    **{f"sensed_f{a}": ("m/s^2", f"specific force the occupant's otoliths sense, platform {a} axis (the head's "
                                 "through the otolith model; +9.81 on z at rest)") for a in "xyz"},
    **{f"sensed_w{a}": ("rad/s", f"angular velocity the occupant's semicircular canals sense, platform {a} axis")
       for a in "xyz"},
    **{f"seat_a{a}": ("m/s^2", f"specific force at the seat, ISO 2631-1 {w}-weighted, platform {a} axis")
       for a, w in zip("xyz", ("W_d", "W_d", "W_k"))},
    "seat_peak": ("m/s^2", "the largest weighted seat acceleration on any axis since the last state packet "
                           "(perceived above 0.015, ISO 2631-1 Annex C)"),
}
#: the state fields the occupant's perception gives (:class:`hexsim.studies.perception.LivePerception`): a state
#: layout that names one turns the perception on in the loop
PERCEPTION_FIELDS = tuple(n for n in STATE_FIELDS if n.startswith(("sensed_", "seat_")))


class PacketError(ValueError):
    """A packet that cannot be taken (its size, a constant, a mode word, a number): the reason, which the
    server counts under :attr:`reason`."""

    def __init__(self, reason: str, message: str) -> None:
        super().__init__(message)
        self.reason = reason


@dataclasses.dataclass(frozen=True)
class Field:
    """One binary field: ``name``, ``type`` (a key of :data:`TYPES`), ``scale`` (SI value = raw x scale) and
    ``value`` (a constant the packet carries, in raw units; None: a variable)."""

    name: str
    type: str
    scale: float = 1.0
    value: float | None = None


@dataclasses.dataclass(frozen=True)
class PacketLayout:
    """A packet's fields in order (:class:`Field`), its ``byte_order`` ("little" or "big"), for a host
    packet what the setpoints are ("dof" or "legs") and the mode word's values; ``source`` names the file
    or the built-in. Raises InputError for a layout that cannot work (an unknown type, a name twice, a zero
    scale, a host packet without frame, mode or all six setpoints)."""

    fields: tuple[Field, ...]
    byte_order: str = "little"
    setpoints: str = "dof"
    modes: Mapping[str, int] = dataclasses.field(default_factory=lambda: {"park": 0, "neutral": 1, "engage": 2})
    source: str = "built-in"

    def __post_init__(self) -> None:
        if self.byte_order not in ("little", "big"):
            raise InputError(f"packet layout {self.source}: byte_order must be 'little' or 'big', got {self.byte_order!r}")
        names = [f.name for f in self.fields]
        for f in self.fields:
            if f.type not in TYPES:
                raise InputError(f"packet layout {self.source}: field {f.name!r} has type {f.type!r}; "
                                 f"known: {', '.join(TYPES)}")
            if names.count(f.name) > 1:
                raise InputError(f"packet layout {self.source}: field {f.name!r} appears twice")
            if not (math.isfinite(f.scale) and f.scale != 0):
                raise InputError(f"packet layout {self.source}: field {f.name!r} has scale {f.scale!r}")
        if sorted(self.modes) != sorted(MODES) or len(set(self.modes.values())) != len(MODES):
            raise InputError(f"packet layout {self.source}: modes must give distinct values to "
                             f"{', '.join(MODES)}, got {dict(self.modes)}")
        if self.setpoints not in ("dof", "legs"):
            raise InputError(f"packet layout {self.source}: setpoints must be 'dof' or 'legs', got {self.setpoints!r}")

    @property
    def format(self) -> str:
        return ("<" if self.byte_order == "little" else ">") + "".join(TYPES[f.type] for f in self.fields)

    @property
    def size(self) -> int:
        """Bytes per packet."""
        return struct.calcsize(self.format)

    def check_host(self) -> PacketLayout:
        """Self, or InputError if a host packet of this layout lacks frame, mode or one of the six setpoints."""
        names = {f.name for f in self.fields}
        needed = ("frame", "mode", *(DOF if self.setpoints == "dof" else LEGS))
        missing = [n for n in needed if n not in names]
        if missing:
            raise InputError(f"packet layout {self.source}: a host packet needs the field(s) {', '.join(missing)} "
                             f"(setpoints {self.setpoints!r})")
        for f in self.fields:
            if f.name in ("frame", "mode") and f.type.startswith("f"):
                raise InputError(f"packet layout {self.source}: field {f.name!r} must be an integer type")
        return self

    def check_state(self) -> PacketLayout:
        """Self, or InputError naming a state field hexsim does not know (:data:`STATE_FIELDS`)."""
        for f in self.fields:
            if f.name not in STATE_FIELDS and f.value is None:
                raise InputError(f"packet layout {self.source}: state field {f.name!r} is not one hexsim sends; "
                                 f"known: {', '.join(STATE_FIELDS)} (or a constant with a value)")
        return self

    def unpack(self, data: bytes) -> dict[str, float]:
        """The packet's fields by name in SI units (integers unscaled, the frame counter raw, the mode word as
        its name in :data:`MODES`). Raises
        :class:`PacketError` for a packet of another size ("size"), a constant that differs ("version"), a
        mode word the layout does not know ("mode") or a non-finite number ("number")."""
        if len(data) != self.size:
            raise PacketError("size", f"{len(data)} bytes, the layout has {self.size}")
        raw = struct.unpack(self.format, data)
        out: dict[str, float] = {}
        for f, v in zip(self.fields, raw):
            if f.value is not None and v != f.value:
                raise PacketError("version", f"field {f.name} is {v}, the layout's constant {f.value:g}")
            if f.type.startswith("f") and not math.isfinite(v):
                raise PacketError("number", f"field {f.name} is {v}")
            integer = not f.type.startswith("f") and (f.scale == 1.0 or f.name in ("frame", "mode"))
            out[f.name] = v if integer else v * f.scale
        if "mode" in out:
            modes = {v: k for k, v in self.modes.items()}
            if out["mode"] not in modes:
                raise PacketError("mode", f"mode word {out['mode']} is none of {dict(self.modes)}")
            out["mode"] = modes[out["mode"]]
        return out

    def pack(self, values: Mapping[str, float]) -> bytes:
        """A packet from SI ``values`` by name (constants from the layout; integers rounded and wrapped to
        their type's range; a missing name sends 0)."""
        raw = []
        for f in self.fields:
            v = f.value if f.value is not None else values.get(f.name, 0.0) / f.scale
            if f.type.startswith("f"):
                raw.append(float(v))
            else:
                bits = struct.calcsize(TYPES[f.type]) * 8
                n = int(round(v)) % (1 << bits)
                if f.type.startswith("i") and n >= 1 << (bits - 1):
                    n -= 1 << bits
                raw.append(n)
        return struct.pack(self.format, *raw)

    def document(self) -> dict:
        """The layout as its JSON file holds it."""
        return {"byte_order": self.byte_order, "setpoints": self.setpoints, "modes": dict(self.modes),
                "fields": [{k: v for k, v in dataclasses.asdict(f).items() if v is not None and
                            not (k == "scale" and v == 1.0)} for f in self.fields]}

    @classmethod
    def from_file(cls, path: str | os.PathLike) -> PacketLayout:
        """A layout from its JSON file (module doc). Raises InputError naming the file and the key or field."""
        from hexsim.tables import read_json_object

        path = pathlib.Path(path)
        doc = read_json_object(path, "packet layout")
        unknown = sorted(set(doc) - {"byte_order", "setpoints", "modes", "fields"})
        if unknown:
            raise InputError(f"{path}: unknown packet layout key {unknown[0]!r} (known: byte_order, fields, modes, "
                             f"setpoints)")
        if not isinstance(doc.get("fields"), list) or not doc["fields"]:
            raise InputError(f"{path}: 'fields' must be a list of {{name, type[, scale][, value]}} objects")
        fields = []
        for n, item in enumerate(doc["fields"], start=1):
            if not isinstance(item, dict) or set(item) - {"name", "type", "scale", "value"} or not {"name", "type"} <= set(item):
                raise InputError(f"{path}: field {n} must be an object with name and type (and scale, value): {item!r}")
            try:
                fields.append(Field(str(item["name"]), str(item["type"]), float(item.get("scale", 1.0)),
                                    None if item.get("value") is None else float(item["value"])))
            except (TypeError, ValueError):
                raise InputError(f"{path}: field {n} ({item.get('name')!r}): scale and value must be numbers") from None
        options = {k: doc[k] for k in ("byte_order", "setpoints", "modes") if k in doc}
        if "modes" in options and not isinstance(options["modes"], dict):
            raise InputError(f"{path}: 'modes' must be an object {{park, neutral, engage}}")
        return cls(tuple(fields), source=str(path), **options)


def _f32(*names: str, scale: float = 1.0) -> tuple[Field, ...]:
    return tuple(Field(n, "f32", scale) for n in names)


#: hexsim's host packet, version 1 (56 bytes, little-endian): version u16 = 1, mode u16, frame u32, then
#: the six DOF as f64 [m, rad] — or, with setpoints "legs", the same bytes read as six piston positions
HOST_PACKET = PacketLayout((Field("version", "u16", value=1), Field("mode", "u16"), Field("frame", "u32"),
                            *(Field(n, "f64") for n in DOF)))
#: hexsim's host packet with six piston positions [m] instead of the DOF
HOST_PACKET_LEGS = dataclasses.replace(HOST_PACKET, fields=(*HOST_PACKET.fields[:3], *(Field(n, "f64") for n in LEGS)),
                                       setpoints="legs")
#: hexsim's state packet, version 1, little-endian
STATE_PACKET = PacketLayout((
    Field("version", "u16", value=1), Field("status", "u16"), Field("frame", "u32"), Field("faults", "u32"),
    Field("received", "u32"), Field("rejected", "u32"), Field("late", "u32"), Field("time", "f64"),
    *_f32(*DOF), *_f32(*(f"{n}_rate" for n in DOF)), *_f32("head_fx", "head_fy", "head_fz"),
    *_f32("head_wx", "head_wy", "head_wz"), *_f32(*LEGS), *_f32(*(f"p1_leg{i}" for i in range(1, 7))),
    *_f32("p_s")))
#: hexsim's state packet with the occupant's perception, version 2, little-endian: version 1's fields, then
#: :data:`PERCEPTION_FIELDS` (``hexsim serve --perception``)
STATE_PACKET_PERCEPTION = dataclasses.replace(STATE_PACKET, fields=(
    Field("version", "u16", value=2), *STATE_PACKET.fields[1:], *_f32(*PERCEPTION_FIELDS)))
