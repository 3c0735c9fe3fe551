"""Parameter files: ``hexsim run … --params FILE.json`` overrides the seed's parameters.

The file is a JSON object with up to three sections, each mapping field names of a dataclass to numbers
(or, for the few text/boolean fields, a string/boolean)::

    {"hydraulics": {"bulk_modulus": 1.2e9, "overlap": 1e-5},   # hexsim.plant.params.HydraulicParams, SI units
     "controller": {"kp": 150},                                # hexsim.plant.params.ControllerParams
     "effects":    {"supply_resistance": 2e9}}                 # hexsim.plant.effects.Effects

Fields not given keep their defaults (seed app. A). Every problem is one :class:`~hexsim.errors.InputError`
naming the file, the section, the key and the value: malformed JSON, an unknown section or key, a value
of the wrong type, and anything the dataclasses themselves refuse (negative bulk modulus, overlap larger
than the spool stroke, a non-positive mass, …).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import pathlib

from hexsim.errors import InputError
from hexsim.plant.effects import Effects
from hexsim.plant.params import ControllerParams, HydraulicParams

#: Sections of a parameter file and the dataclass each one builds.
SECTIONS = {"hydraulics": HydraulicParams, "controller": ControllerParams, "effects": Effects}


def read_params(path: str | os.PathLike) -> dict[str, object]:
    """{"hydraulics": HydraulicParams, "controller": ControllerParams, "effects": Effects} from ``path``.

    Raises InputError (file, section, key, value) for any problem; see the module doc.
    """
    path = pathlib.Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such parameter file")
    try:
        doc = json.loads(path.read_text(encoding="utf-8"), parse_constant=_no_constant)
    except json.JSONDecodeError as exc:
        raise InputError(f"{path}: not valid JSON ({exc.msg} at line {exc.lineno}, column {exc.colno})") from None
    except (UnicodeDecodeError, ValueError) as exc:
        raise InputError(f"{path}: {exc}") from None
    if not isinstance(doc, dict):
        raise InputError(f"{path}: expected a JSON object with sections {', '.join(SECTIONS)}")
    unknown = [k for k in doc if k not in SECTIONS]
    if unknown:
        raise InputError(f"{path}: unknown section {unknown[0]!r}; expected {', '.join(SECTIONS)}")
    out = {}
    for section, cls in SECTIONS.items():
        values = doc.get(section, {})
        if not isinstance(values, dict):
            raise InputError(f"{path}: section {section!r} must be an object of name: value")
        fields = {f.name: f for f in dataclasses.fields(cls)}
        for key, value in values.items():
            if key not in fields:
                name = key if key.isidentifier() else repr(key)
                raise InputError(f"{path}: {section}.{name} is not a parameter; known: {', '.join(fields)}")
            _check_type(path, section, key, value, fields[key].default)
        try:
            out[section] = cls(**values)
        except InputError as exc:
            raise InputError(f"{path}: {section}: {exc}") from None
    return out


def _no_constant(name: str):
    raise ValueError(f"{name} is not a number JSON allows (NaN and Infinity are refused)")


def _check_type(path: pathlib.Path, section: str, key: str, value, default) -> None:
    where = f"{path}: {section}.{key}"
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise InputError(f"{where}: expected true or false, got {value!r}")
    elif isinstance(default, str):
        if not isinstance(value, str):
            raise InputError(f"{where}: expected a string, got {value!r}")
    elif isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{where}: {value!r} is not a number")
    elif not math.isfinite(value):
        raise InputError(f"{where}: {value!r} is not finite")
