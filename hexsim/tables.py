"""Reading numeric CSV tables with one clear error per problem (file, column, row, value).

Shared by scenario files (``file:PATH``) and measurement logs (``docs/measurement-log.md``):
one header row, then one row per sample, plain decimal or exponent numbers, first column ``time_s``
strictly increasing. Rows are numbered as a spreadsheet shows them (the header is row 1).
"""

from __future__ import annotations

import csv
import math
import os
import pathlib
import tempfile
from collections.abc import Callable

import numpy as np

from hexsim.errors import InputError


def read_numeric_csv(path: str | os.PathLike, *, required: tuple[str, ...] = ("time_s",)) -> dict[str, np.ndarray]:
    """Columns of a numeric CSV as float arrays of shape (N,), keyed by header name, in file order.

    Raises InputError naming the file (and column, row, value where it applies) when the file is
    missing, empty, not UTF-8 text or not parseable as CSV (a field over the csv module's limit), a
    header is duplicated, a required column is missing, a row has the wrong number
    of fields, a value is not a finite number, or ``time_s`` is not strictly increasing.
    """
    path = pathlib.Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    try:
        with path.open(newline="", encoding="utf-8-sig") as fh:  # -sig: tolerate a spreadsheet BOM
            reader = csv.reader(fh)
            try:
                rows = list(reader)
            except csv.Error as exc:  # e.g. a field longer than the csv module's limit (131 072 characters)
                raise InputError(f"{path}: row {reader.line_num}: not a numeric CSV row ({exc})") from None
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not a UTF-8 text CSV file ({exc.reason} at byte {exc.start})") from None
    rows = [r for r in rows if any(field.strip() for field in r)]
    if not rows:
        raise InputError(f"{path}: file is empty (expected a header row starting with time_s)")
    header = [h.strip() for h in rows[0]]
    for name in header:
        if header.count(name) > 1:
            raise InputError(f"{path}: column {name!r} appears more than once in the header")
    for name in required:
        if name not in header:
            raise InputError(f"{path}: missing column {name!r} (header: {', '.join(header)})")
    if len(rows) < 3:
        raise InputError(f"{path}: needs at least two data rows, found {len(rows) - 1}")
    data = np.empty((len(rows) - 1, len(header)))
    for r, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise InputError(f"{path}: row {r} has {len(row)} fields, the header has {len(header)}")
        for c, field in enumerate(row):
            try:
                value = float(field)
            except ValueError:
                raise InputError(f"{path}: column {header[c]!r}, row {r}: {field.strip()!r} is not a number") from None
            if not math.isfinite(value):
                raise InputError(f"{path}: column {header[c]!r}, row {r}: value {field.strip()} is not finite")
            data[r - 2, c] = value
    columns = {name: data[:, c].copy() for c, name in enumerate(header)}
    if "time_s" in columns:
        steps = np.diff(columns["time_s"])
        if np.any(steps <= 0):
            r = int(np.argmax(steps <= 0)) + 3
            raise InputError(
                f"{path}: column 'time_s', row {r}: time {columns['time_s'][r - 2]:g} s is not after the previous "
                f"row's {columns['time_s'][r - 3]:g} s (time must be strictly increasing)"
            )
    return columns


def json_text(doc) -> str:
    """``doc`` as strict JSON text (indented, newline-terminated): a number that is not finite (a standard
    error that could not be estimated) is written as null, and keys starting with "_" are left out."""
    import json

    def clean(x):
        if isinstance(x, dict):
            return {k: clean(v) for k, v in x.items() if not (isinstance(k, str) and k.startswith("_"))}
        if isinstance(x, (list, tuple)):
            return [clean(v) for v in x]
        if isinstance(x, (float, np.floating)):
            return float(x) if math.isfinite(x) else None
        return x

    return json.dumps(clean(doc), indent=2, allow_nan=False) + "\n"


def write_atomic(path: str | os.PathLike, write: Callable[[pathlib.Path], None]) -> None:
    """Call ``write(tmp)`` on a temporary file next to ``path`` and rename it into place.

    A failure leaves no partial file behind. Raises InputError if the folder does not exist.
    """
    path = pathlib.Path(path)
    if not path.parent.exists():
        raise InputError(f"{path}: folder {path.parent} does not exist")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    tmp_path = pathlib.Path(tmp)
    try:
        write(tmp_path)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp_path, 0o666 & ~umask)  # mkstemp creates 0600; give the file the usual permissions
        os.replace(tmp_path, path)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


class StdoutTarget:
    """``-`` given as an output path on the command line: the document goes to this stream (the CLI's
    standard output; its human-readable lines then go to standard error)."""

    def __init__(self, stream) -> None:
        self.stream = stream

    def __str__(self) -> str:  # for messages ("wrote <stdout>"); not a path: nothing opens it as a file
        return "<stdout>"


def software_versions() -> dict[str, str]:
    """The versions a result depends on: hexsim, MuJoCo, numpy, scipy and Python (read from the installed
    distributions' metadata, without importing them)."""
    import platform
    from importlib import metadata

    versions = {"python": platform.python_version()}
    for dist in ("hexsim", "mujoco", "numpy", "scipy"):
        try:
            versions[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:  # a source tree on sys.path, not installed
            versions[dist] = "not installed"
    return versions


def write_json(path: str | os.PathLike | StdoutTarget, doc: dict) -> None:
    """Write ``doc`` as strict JSON (:func:`json_text`) with the software versions added (key
    ``software``), atomically to ``path``, or to the stream of a :class:`StdoutTarget`. Raises
    InputError if the folder does not exist."""
    text = json_text({**doc, "software": software_versions()})
    if isinstance(path, StdoutTarget):
        path.stream.write(text)
        path.stream.flush()
        return
    write_atomic(path, lambda tmp: tmp.write_text(text))


def read_json_object(path: str | os.PathLike, what: str) -> dict:
    """The JSON object in ``path``: the settings file of ``what`` (e.g. "washout parameters"). Raises
    InputError naming the file when it is missing, not UTF-8 JSON, or not an object."""
    import json

    path = pathlib.Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(doc, dict):
        raise InputError(f"{path}: expected a JSON object of {what}")
    return doc


def read_settings(cls, path: str | os.PathLike, what: str):
    """An instance of the frozen dataclass ``cls`` (with a ``source`` field) from the JSON object in ``path``
    holding any subset of its other fields (lists as tuples; the rest default), ``source`` the path; ``what``
    names the settings in messages (e.g. "washout"). The ``software`` key hexsim's own files carry
    (:func:`write_json`: their provenance) is not a setting and is passed over. Raises InputError naming the
    file and the key for an unknown key or a value ``cls`` refuses (its own InputError)."""
    import dataclasses

    path = pathlib.Path(path)
    doc = read_json_object(path, f"{what} parameters")
    doc.pop("software", None)
    known = {f.name for f in dataclasses.fields(cls)} - {"source"}
    unknown = sorted(set(doc) - known)
    if unknown:
        raise InputError(f"{path}: unknown {what} key {unknown[0]!r} (known: {', '.join(sorted(known))})")
    try:
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in doc.items()}, source=str(path))
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from None
