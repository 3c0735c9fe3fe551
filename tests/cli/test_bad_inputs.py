"""Every bad input is refused the same way (issue 6): exit code 2, one line on stderr naming the file /
column / row / parameter and the value, no traceback, and no output file left behind.

One table across the CLI options, scenario files, measurement logs, parameter files and sweep grids.
Each case builds its inputs in a temporary folder and asks for a JSON output that must not appear."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from hexsim.cli import main


def _csv(path, header, rows):
    path.write_text(",".join(header) + "\n" + "\n".join(",".join(str(v) for v in r) for r in rows) + "\n")
    return path


def _scenario(tmp, edit=None):
    t = np.arange(0, 8.0001, 0.01)
    rows = [[f"{x:.2f}", f"{0.03 * np.sin(2 * np.pi * 0.5 * x):.6f}"] for x in t]
    header = ["time_s", "dof_ref_z_m"]
    if edit:
        header, rows = edit(header, rows)
    return _csv(tmp / "motion.csv", header, rows)


def _log(tmp, edit=None, side=None):
    """A small single-actuator log (0.3 s at 1 kHz) that reads without complaint unless edited."""
    t = np.arange(300) / 1000.0
    header = ["time_s", "ref_m", "valve_cmd_V", "pos_m", "p1_Pa", "ps_Pa"]
    rows = [[f"{x:.3f}", "0.1", f"{0.5 * np.sin(6 * x):.5f}", f"{0.1 + 0.001 * x:.6f}", "4.2e6", "7.0e6"] for x in t]
    if edit:
        header, rows = edit(header, rows)
    path = _csv(tmp / "log.csv", header, rows)
    sidecar = {"system": "single-actuator", "sample_rate_hz": 1000.0,
               "controller": {"type": "P", "kp": 200.0, "rate_hz": 500.0}}
    if side is not None:
        sidecar = side(sidecar)
    if sidecar is not None:
        path.with_suffix(".json").write_text(sidecar if isinstance(sidecar, str) else json.dumps(sidecar))
    return path


def _machine(tmp, doc):
    """A machine file in ``tmp``: ``doc`` as text, or the keys of ``doc`` over a valid file's format and version."""
    path = tmp / "machine.json"
    path.write_text(doc if isinstance(doc, str) else json.dumps({"format": "hexsim-machine", "version": 1, **doc}))
    return path


def _valve_file(tmp, volts):
    """A valve-command file whose third row commands ``volts``."""
    path = tmp / "valve.csv"
    path.write_text("time_s,valve_cmd_V\n0,0\n0.001,1\n0.002,%g\n0.003,0\n" % volts)
    return path


def _set(rows, r, c, value):
    rows[r][c] = value
    return rows


RUN = ["run", "heave", "--duration", "2", "--frequency", "2"]
ACT = ["run", "actuator", "--duration", "2", "--frequency", "2"]

# name: (argv builder (tmp -> list of str, without the output option), regex the message must match)
CASES = {
    # command-line options
    "negative duration": (lambda tmp: RUN[:2] + ["--duration", "-1"], r"--duration must be a positive number.*-1"),
    "NaN amplitude": (lambda tmp: RUN + ["--amplitude", "nan"], r"'nan' is not a finite number"),
    "non-numeric frequency": (lambda tmp: RUN[:4] + ["--frequency", "fast"], r"'fast' is not a number"),
    "frequency above Nyquist": (lambda tmp: RUN[:4] + ["--frequency", "300"], r"--frequency 300(\.0)? Hz .*Nyquist"),
    "amplitude outside stroke": (lambda tmp: RUN + ["--amplitude", "0.5"], r"leg\d .*stroke"),
    "negative gain": (lambda tmp: RUN + ["--kp", "-5"], r"kp must be a finite positive number, got -5"),
    "negative sensor noise": (lambda tmp: RUN + ["--sensor-noise=-1e-6"], r"position_noise .*-1e-06"),
    "unknown scenario": (lambda tmp: ["run", "bounce"], r"unknown scenario 'bounce'"),
    "unknown compensator": (lambda tmp: RUN + ["--compensator", "magic"], r"invalid choice: 'magic'"),
    "timestep not dividing": (lambda tmp: RUN + ["--timestep", "3e-4"], r"timestep 0\.0003 s.*must divide"),
    # the seed's actuator at 1 ms runs (ω·dt 0.97 at its lowest setpoint, 50 mm); 95 mm of amplitude takes
    # the piston to 5 mm, where the oil spring is 470 Hz and the explicit step blows up (44 000 m/s²)
    "timestep too long for the motion": (lambda tmp: ["run", "actuator", "--duration", "6", "--timestep", "1e-3",
                                                      "--amplitude", "0.095"],
                                         r"timestep 0\.001 s is too long .* leg1's lowest setpoint y = 5\.0 mm .*470 Hz"),
    "payload not a number": (lambda tmp: RUN + ["--payload", "12x@0,0"], r"--payload: not KG\[@X,Y\[,Z\]\]: '12x@0,0'"),
    "payload on the actuator": (lambda tmp: ACT + ["--payload", "50"], r"payload applies to the hexapod"),
    "payload heavier than negative platform": (lambda tmp: RUN + ["--payload", "-900"], r"payload of -900 kg leaves the platform"),
    "payload leaving an impossible body": (lambda tmp: RUN + ["--payload", "-300"],
                                           r"payload of -300 kg at \(0\.0, 0\.0, 0\.0\) m leaves principal moments "
                                           r"59\.49, 59\.49, 146\.4 kg m\^2 that no rigid body has"),
    "zero buffer time": (lambda tmp: RUN + ["--buffer-time", "0"], r"buffer_time must be a finite positive.*0"),
    "filter above Nyquist": (lambda tmp: RUN + ["--compensator", "buffered", "--velocity-cutoff", "400"],
                             r"velocity_cutoff_hz 400.* Nyquist"),
    "wrong output suffix": (lambda tmp: RUN + ["--plot", str(tmp / "fig.txt")], r"--plot .*fig\.txt: expected a \.png"),
    "output folder missing": (lambda tmp: RUN + ["--plot", str(tmp / "nope" / "fig.png")], r"folder .*nope does not exist"),
    # scenario files
    "scenario file missing": (lambda tmp: ["run", f"file:{tmp / 'none.csv'}"], r"none\.csv: no such file"),
    "scenario file empty": (lambda tmp: ["run", f"file:{_csv(tmp / 'e.csv', [], [])}"], r"e\.csv: file is empty"),
    "scenario non-numeric": (lambda tmp: ["run", f"file:{_scenario(tmp, lambda h, r: (h, _set(r, 40, 1, 'abc')))}"],
                             r"motion\.csv: column 'dof_ref_z_m', row 42: 'abc' is not a number"),
    "scenario infinite": (lambda tmp: ["run", f"file:{_scenario(tmp, lambda h, r: (h, _set(r, 9, 1, 'inf')))}"],
                          r"column 'dof_ref_z_m', row 11: value inf is not finite"),
    "scenario time backwards": (lambda tmp: ["run", f"file:{_scenario(tmp, lambda h, r: (h, _set(r, 20, 0, '0.05')))}"],
                                r"column 'time_s', row 22"),
    "scenario unknown column": (lambda tmp: ["run", f"file:{_scenario(tmp, lambda h, r: (['time_s', 'dof_ref_z_mm'], r))}"],
                                r"unknown column 'dof_ref_z_mm'"),
    "scenario in mm": (lambda tmp: ["run", f"file:{_scenario(tmp, lambda h, r: (h, [[a, str(float(b) * 1e3)] for a, b in r]))}"],
                       r"leg\d .*stroke"),
    # measurement logs
    "log missing sidecar": (lambda tmp: ["validate", str(_log(tmp, side=lambda s: None))], r"sidecar log\.json is missing"),
    "log malformed sidecar": (lambda tmp: ["validate", str(_log(tmp, side=lambda s: "{oops"))], r"log\.json: not valid JSON"),
    "log sidecar without rate": (lambda tmp: ["validate", str(_log(tmp, side=lambda s: {"system": "single-actuator"}))],
                                 r"missing key 'sample_rate_hz'"),
    "log empty": (lambda tmp: ["validate", str(_log(tmp, lambda h, r: (h, [])))], r"log\.csv: needs at least two data rows"),
    "log field over the csv limit": (lambda tmp: ["validate", str(_log(tmp, lambda h, r: (h, _set(r, 4, 3, "1" * 140_000))))],
                                     r"log\.csv: row 6: not a numeric CSV row .*field larger than field limit"),
    "log too short for friction": (lambda tmp: ["friction", str(_log(tmp, lambda h, r: (h, r[:20])))],
                                   r"log\.csv: 20 samples, fewer than the \d+ the derivative filter needs"),
    "log pressure in bar": (lambda tmp: ["validate", str(_log(tmp, lambda h, r: (h, [x[:4] + ["42.0", "70.0"] for x in r])))],
                            r"'p1_Pa', row \d+: .*bar"),
    "log position in mm": (lambda tmp: ["validate", str(_log(tmp, lambda h, r: (h, [x[:3] + ["100.0"] + x[4:] for x in r])))],
                           r"'pos_m', row 2: value 100 .*mm"),
    "log non-uniform": (lambda tmp: ["validate", str(_log(tmp, lambda h, r: (h, r[:100] + r[101:])))],
                        r"'time_s', row 102: .*non-uniform"),
    "log missing column": (lambda tmp: ["validate", str(_log(tmp, lambda h, r: (h[:2] + h[3:], [x[:2] + x[3:] for x in r])))],
                           r"missing column 'valve_cmd_V'"),
    "log NaN": (lambda tmp: ["validate", str(_log(tmp, lambda h, r: (h, _set(r, 7, 3, "nan"))))],
                r"'pos_m', row 9: value nan is not finite"),
    "validate without an unknown effect": (lambda tmp: ["validate", str(_log(tmp)), "--without", "leakage,magic"],
                                           r"--without: unknown effect 'magic' \(the library: supply_pressure"),
    "log duplicate column": (lambda tmp: ["validate", str(_log(tmp, lambda h, r: (h[:5] + ["pos_m"], r)))],
                             r"column 'pos_m' appears more than once"),
    # machine files (hexsim/plant/machine.py, docs/machine-file.md)
    "machine negative bulk modulus": (lambda tmp: RUN + ["--machine", str(_machine(tmp, {"oil": {"bulk_modulus_Pa": -1e9}}))],
                                      r"machine\.json: oil\.bulk_modulus_Pa must be a finite positive number, got -1000000000"),
    "machine overlap beyond stroke": (lambda tmp: RUN + ["--machine", str(_machine(tmp, {"valve": {"overlap_m": 0.002}}))],
                                      r"machine\.json: valve\.overlap_m \(0\.002 m\) .*x_v_max"),
    "machine rod not smaller than bore": (lambda tmp: RUN + ["--machine", str(_machine(tmp, {"cylinder": {"rod_m": 0.05}}))],
                                          r"machine\.json: cylinder\.rod_m \(0\.05 m\) must be smaller than"),
    "machine negative volume": (lambda tmp: RUN + ["--machine", str(_machine(tmp, {"cylinder": {"dead_volume_rod_m3": -1e-6}}))],
                                r"cylinder\.dead_volume_rod_m3 must be a finite positive number, got -1e-06"),
    "machine negative mass": (lambda tmp: ACT + ["--machine", str(_machine(tmp, {"load": {"mass_kg": -40}}))],
                              r"machine\.json: load\.mass_kg must be a finite positive number, got -40"),
    "machine unknown key": (lambda tmp: RUN + ["--machine", str(_machine(tmp, {"oil": {"bulk_modulous_Pa": 1e9}}))],
                            r"unknown key 'oil\.bulk_modulous_Pa'; known in oil: oil\.bulk_modulus_Pa"),
    "machine unknown valve type": (lambda tmp: RUN + ["--machine", str(_machine(tmp, {"valve": {"type": "5-way"}}))],
                                   r"valve\.type: expected one of 3-way, 4-way, got '5-way'"),
    "machine non-numeric": (lambda tmp: RUN + ["--machine", str(_machine(tmp, {"controller": {"kp_VPm": "high"}}))],
                            r"controller\.kp_VPm: expected a number in V/m, got 'high'"),
    "machine NaN": (lambda tmp: RUN + ["--machine", str(_machine(tmp, '{"format": "hexsim-machine", "version": 1, "oil": {"density_kgpm3": NaN}}'))],
                    r"machine\.json: NaN is not a number JSON allows"),
    "machine malformed": (lambda tmp: RUN + ["--machine", str(_machine(tmp, "{valve: 1"))], r"machine\.json: not valid JSON"),
    "machine wrong version": (lambda tmp: RUN + ["--machine", str(_machine(tmp, {"version": 7}))],
                              r"key 'version' is 7; this hexsim reads version 1"),
    "machine missing": (lambda tmp: RUN + ["--machine", str(tmp / "gone.json")], r"gone\.json: no such machine file"),
    "machine single actuator on heave": (lambda tmp: RUN + ["--machine", "servo_cylinder"],
                                         r"servo_cylinder \(built-in\) is a single actuator; scenario heave needs a hexapod"),
    "machine without controller on a setpoint": (lambda tmp: ACT + ["--machine", "servo_cylinder"],
                                                 r"has no position controller \(controller\.type none\)"),
    "valve file beyond 10 V": (lambda tmp: ["run", f"valve:{_valve_file(tmp, 12.0)}"],
                               r"column 'valve_cmd_V', row 4: value 12 is not a valve setpoint"),
    # faults
    "fault without value": (lambda tmp: RUN + ["--fault", "valve_stuck:leg=2,t=1"], r"missing value="),
    "fault unknown kind": (lambda tmp: RUN + ["--fault", "melt:t=1"], r"unknown kind 'melt'"),
    "fault fractional leg": (lambda tmp: RUN + ["--fault", "sensor_frozen:leg=2.5,t=1"], r"leg = 2\.5 is not a leg number"),
    "fault leg missing": (lambda tmp: RUN + ["--fault", "end_stop:leg=7,t=1"], r"leg 7 does not exist"),
    "fault zero ramp": (lambda tmp: RUN + ["--fault", "supply_loss:t=1,ramp=0"], r"ramp must be > 0"),
    # sweep grids
    "grid without values": (lambda tmp: ["sweep", "actuator", "--grid", "kp"], r"expected NAME=V1,V2"),
    "grid non-numeric": (lambda tmp: ["sweep", "actuator", "--grid", "kp=1,abc"], r"--grid kp: value 'abc'"),
    "grid unknown option": (lambda tmp: ["sweep", "actuator", "--grid", "colour=red"], r"'colour' is not an option"),
    "grid unknown choice": (lambda tmp: ["sweep", "actuator", "--grid", "compensator=none,magic"],
                            r"value 'magic' is not one of"),
    "grid timestep not dividing": (lambda tmp: ["sweep", "actuator", "--duration", "2.5", "--frequency", "2", "--grid",
                                                "timestep=3e-4"], r"must divide"),
}


def _exit_code(argv):
    """main()'s return value, or the code argparse exits with for an option it refuses itself."""
    try:
        return main(argv)
    except SystemExit as exc:
        return exc.code


@pytest.mark.parametrize("case", list(CASES))
def test_bad_input_exits_2_with_one_clear_line_and_no_output(tmp_path, capsys, case):
    build, pattern = CASES[case]
    out = tmp_path / "out.json"
    assert _exit_code(build(tmp_path) + ["--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    assert re.search(pattern, last), err  # one line (argparse prints its usage above its own errors)
    assert not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith((".", "tmp")) or p.suffix == ".tmp"]


def test_the_table_holds_at_least_thirty_cases():
    assert len(CASES) >= 30
