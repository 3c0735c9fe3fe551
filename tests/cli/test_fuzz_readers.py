"""Property-based tests of every reader a user can hand a file to (issue 17), with Hypothesis.

Valid inputs — a measurement log (CSV + sidecar), a scenario file, a parameter file, sweep grid items —
are mutated by dropping, duplicating, reordering and corrupting fields, values, encodings and line
endings. For every generated input the contract holds: the reader returns, or raises one
:class:`~hexsim.errors.InputError` naming the file (never another exception); through the CLI
(`hexsim friction`, which reads a log and fits without simulating) the exit code is 0 or 2, an error is
one line on stderr without a traceback, and no output file is left behind.

CI runs a fixed, derandomised budget of :data:`EXAMPLES` examples per property. A longer campaign:
``HEXSIM_FUZZ_EXAMPLES=5000 pytest tests/cli/test_fuzz_readers.py -p no:xdist`` (random, not derandomised,
when HEXSIM_FUZZ_RANDOM=1).
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import tempfile

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hexsim.cli import build_parser, main
from hexsim.control.scenario import make_scenario
from hexsim.errors import InputError
from hexsim.measured.measurement import read_log
from hexsim.plant.machine import read_machine

EXAMPLES = int(os.environ.get("HEXSIM_FUZZ_EXAMPLES", "40"))
FUZZ = settings(max_examples=EXAMPLES, derandomize=not os.environ.get("HEXSIM_FUZZ_RANDOM"), deadline=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def _valid_log_rows() -> tuple[list[str], list[list[str]]]:
    """A 1 s single-actuator log at 1 kHz that reads without complaint and has motion both ways."""
    t = np.arange(1000) / 1000.0
    y = 0.1 + 0.01 * np.sin(2 * np.pi * 2 * t)
    header = ["time_s", "ref_m", "valve_cmd_V", "pos_m", "p1_Pa", "ps_Pa", "acc_mps2"]
    rows = [[f"{x:.3f}", f"{yy:.6f}", f"{0.3 * np.cos(4 * np.pi * x):.5f}", f"{yy:.6f}",
             f"{4.2e6 + 1e5 * np.sin(4 * np.pi * x):.1f}", "7.0e6", f"{9.8 - 1.6 * np.sin(4 * np.pi * x):.4f}"]
            for x, yy in zip(t, y)]
    return header, rows


SIDECAR = {"system": "single-actuator", "sample_rate_hz": 1000.0,
           "controller": {"type": "P", "kp_V_per_m": 200.0, "rate_hz": 500.0}, "oil_temperature_C": 35.0}

junk = st.one_of(st.sampled_from(["", "nan", "inf", "-inf", "1e999", "1,5", "0x10", " ", "NULL", "1e-400", "-0"]),
                 st.text(max_size=12), st.floats(allow_nan=True, allow_infinity=True).map(repr),
                 st.integers(min_value=-10**30, max_value=10**30).map(str))
json_junk = st.one_of(st.none(), st.booleans(), st.integers(-10**6, 10**6), st.floats(allow_nan=False),
                      st.text(max_size=8), st.lists(st.integers(), max_size=3), st.dictionaries(st.text(max_size=4),
                                                                                              st.integers(), max_size=2))


@st.composite
def table_mutations(draw, n_cols: int, n_rows: int):
    """A list of edits of a table (header + rows), each a tuple the applier understands."""
    kinds = st.sampled_from(["drop_col", "dup_col", "swap_cols", "corrupt", "drop_field", "dup_row", "swap_rows",
                             "drop_row", "long_field", "header_junk"])
    edits = []
    for _ in range(draw(st.integers(0, 3))):
        kind = draw(kinds)
        edits.append((kind, draw(st.integers(0, n_cols - 1)), draw(st.integers(0, n_cols - 1)),
                      draw(st.integers(0, n_rows - 1)), draw(st.integers(0, n_rows - 1)), draw(junk)))
    return edits


def _apply(header: list[str], rows: list[list[str]], edits) -> tuple[list[str], list[list[str]]]:
    header, rows = list(header), [list(r) for r in rows]
    for kind, c1, c2, r1, r2, text in edits:
        c1, c2 = c1 % len(header), c2 % len(header)
        r1, r2 = (r1 % len(rows), r2 % len(rows)) if rows else (0, 0)
        if kind == "drop_col" and len(header) > 1:
            del header[c1]
            rows = [r[:c1] + r[c1 + 1:] for r in rows]
        elif kind == "dup_col":
            header.append(header[c1])
            rows = [r + [r[c1] if c1 < len(r) else ""] for r in rows]
        elif kind == "swap_cols":
            header[c1], header[c2] = header[c2], header[c1]
            for r in rows:
                if max(c1, c2) < len(r):
                    r[c1], r[c2] = r[c2], r[c1]
        elif kind == "corrupt" and rows and c1 < len(rows[r1]):
            rows[r1][c1] = text
        elif kind == "drop_field" and rows and rows[r1]:
            del rows[r1][c1 % len(rows[r1])]
        elif kind == "dup_row" and rows:
            rows.insert(r2, list(rows[r1]))
        elif kind == "swap_rows" and rows:
            rows[r1], rows[r2] = rows[r2], rows[r1]
        elif kind == "drop_row" and rows:
            del rows[r1]
        elif kind == "long_field" and rows and c1 < len(rows[r1]):
            rows[r1][c1] = "1" * 140_000  # longer than the csv module's field limit (131 072)
        elif kind == "header_junk":
            header[c1] = text
    return header, rows


encodings = st.sampled_from(["plain", "crlf", "cr", "semicolon", "bom", "latin1", "truncate", "binary"])


def _write_table(path: pathlib.Path, header, rows, encoding: str, cut: int) -> None:
    sep = ";" if encoding == "semicolon" else ","
    eol = {"crlf": "\r\n", "cr": "\r"}.get(encoding, "\n")
    text = eol.join(sep.join(r) for r in [header, *rows]) + eol
    if encoding == "bom":
        text = "\ufeff" + text
    if encoding == "latin1":
        path.write_bytes(("é" + text).encode("latin-1", errors="replace"))
    elif encoding == "truncate":
        path.write_bytes(text.encode()[: max(1, cut % max(len(text), 1))])
    elif encoding == "binary":
        path.write_bytes(bytes(range(256)) + text.encode())
    else:
        path.write_bytes(text.encode("utf-8"))


@st.composite
def sidecars(draw):
    side = json.loads(json.dumps(SIDECAR))
    for _ in range(draw(st.integers(0, 2))):
        action = draw(st.sampled_from(["drop", "retype", "add", "controller"]))
        key = draw(st.sampled_from(sorted(side) + ["mass_kg", "inclination_deg", "stroke_m"]))
        if action == "drop":
            side.pop(key, None)
        elif action in ("retype", "add"):
            side[key] = draw(json_junk)
        elif isinstance(side.get("controller"), dict):
            side["controller"][draw(st.sampled_from(["type", "kp_V_per_m", "rate_hz"]))] = draw(json_junk)
    text = json.dumps(side)
    if draw(st.booleans()) and draw(st.booleans()):
        text = draw(st.sampled_from(["{not json", "[]", "null", "", "\ufffe", text[: len(text) // 2]]))
    return text


def _contract_reader(fn, path: pathlib.Path):
    """fn(path) returns, or raises InputError naming the file; anything else fails the property."""
    try:
        return fn(path)
    except InputError as exc:
        message = str(exc)
        assert path.stem in message or path.name in message, message
        assert "\n" not in message
        return None


def _mutated_log(folder: pathlib.Path, edits, encoding: str, cut: int, side: str) -> pathlib.Path:
    """The valid log with ``edits`` applied, written in ``encoding``, and the sidecar text ``side``."""
    path = folder / "log.csv"
    _write_table(path, *_apply(*_valid_log_rows(), edits), encoding, cut)
    path.with_suffix(".json").write_text(side)
    return path


@FUZZ
@given(edits=table_mutations(7, 1000), encoding=encodings, cut=st.integers(0, 10**6), side=sidecars())
def test_any_log_is_read_or_refused_with_one_clear_error(edits, encoding, cut, side):
    with tempfile.TemporaryDirectory() as tmp:
        _contract_reader(read_log, _mutated_log(pathlib.Path(tmp), edits, encoding, cut, side))


@FUZZ
@given(edits=table_mutations(7, 1000), encoding=st.sampled_from(["plain", "crlf", "bom", "truncate", "binary"]),
       cut=st.integers(0, 10**6), side=sidecars())
def test_cli_on_any_log_exits_0_or_2_with_one_line_and_no_output(edits, encoding, cut, side):
    import contextlib
    import io

    with tempfile.TemporaryDirectory() as tmp:
        path = _mutated_log(pathlib.Path(tmp), edits, encoding, cut, side)
        out = pathlib.Path(tmp) / "friction.json"
        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            code = main(["friction", str(path), "--json", str(out)])
        assert code in (0, 2), code
        if code == 2:
            text = err.getvalue()
            assert text.count("\n") == 1 and "Traceback" not in text, text
            assert not out.exists()
        else:
            doc = json.loads(out.read_text())
            assert doc["positive"]["rms_N"] >= 0


def _valid_scenario_rows() -> tuple[list[str], list[list[str]]]:
    t = np.arange(0, 8.0001, 0.01)
    rows = [[f"{x:.2f}", f"{0.03 * np.sin(2 * np.pi * 0.5 * x):.6f}", f"{0.02 * np.sin(2 * np.pi * 0.5 * x):.6f}"]
            for x in t]
    return ["time_s", "dof_ref_z_m", "dof_ref_pitch_rad"], rows


@FUZZ
@given(edits=table_mutations(3, 801), encoding=encodings, cut=st.integers(0, 10**6))
def test_any_scenario_file_is_read_or_refused_with_one_clear_error(edits, encoding, cut):
    header, rows = _apply(*_valid_scenario_rows(), edits)
    with tempfile.TemporaryDirectory() as tmp:
        path = pathlib.Path(tmp) / "motion.csv"
        _write_table(path, header, rows, encoding, cut)
        _contract_reader(lambda p: make_scenario(f"file:{p}"), path)


_SECTIONS = {"valve": ["type", "flow_area", "overlap_m", "rated_flow_m3ps", "spool_diameter_m", "nonsense"],
             "cylinder": ["bore_m", "rod_m", "stroke_m", "dead_volume_rod_m3"],
             "oil": ["bulk_modulus_Pa", "density_kgpm3"], "supply": ["pressure_Pa"],
             "load": ["mass_kg", "inclination_deg", "payload_at_m"], "controller": ["type", "kp_VPm", "rate_hz"],
             "friction": ["positive", "arctan_normalised"], "pump": ["x"]}
machine_docs = st.one_of(
    st.fixed_dictionaries(
        {"format": st.sampled_from(["hexsim-machine", "hexsim-machine", "other"]), "version": st.sampled_from([1, 1, 2])},
        optional={"system": st.one_of(st.sampled_from(["hexapod", "single-actuator"]), json_junk),
                  **{section: st.one_of(st.dictionaries(st.sampled_from(keys), json_junk, max_size=3), json_junk)
                     for section, keys in _SECTIONS.items()}}).map(json.dumps),
    st.sampled_from(["", "{", "[1, 2]", "NaN", '{"format": "hexsim-machine", "version": 1, "oil": {"bulk_modulus_Pa": NaN}}',
                     '{"format": "hexsim-machine", "version": 1, "valve": {"overlap_m": Infinity}}', "\x00\x01"]),
)


@FUZZ
@given(doc=machine_docs)
def test_any_machine_file_is_read_or_refused_with_one_clear_error(doc):
    with tempfile.TemporaryDirectory() as tmp:
        path = pathlib.Path(tmp) / "machine.json"
        path.write_text(doc, encoding="utf-8", errors="surrogatepass")
        _contract_reader(read_machine, path)


def _sweep_parser() -> argparse.ArgumentParser:
    """The sweep sub-command's parser, as ``hexsim sweep`` hands it to the grid parser."""
    return build_parser().parse_args(["sweep", "heave"]).command_parser


grid_items = st.lists(st.builds(lambda name, sep, values: f"{name}{sep}{values}",
                                st.sampled_from(["kp", "--kp", "compensator", "frequency", "buffer-time", "seed",
                                                 "amplitude", "nonsense", "", "timestep"]),
                                st.sampled_from(["=", "", "=="]),
                                st.lists(junk, min_size=0, max_size=3).map(",".join)), max_size=3)


@FUZZ
@given(items=grid_items)
def test_any_sweep_grid_is_parsed_or_refused_with_one_clear_error(items):
    from hexsim.cli.sweep import _parse_grid

    parser = _sweep_parser()
    try:
        grid = _parse_grid(parser, items)
    except InputError as exc:
        assert "--grid" in str(exc) and "\n" not in str(exc)
        return
    assert all(isinstance(v, list) and v for v in grid.values())
