"""The motion acceptance tests (issue 43): the describing function against the linearised position loop, the
envelope against the inverse kinematics, a tolerance file's checks and report, bad tolerance files refused."""

import json
import math
import subprocess
import sys

import numpy as np
import pytest

import hexsim
from hexsim.control.kinematics import HexapodGeometry
from hexsim.errors import InputError
from hexsim.plant import hydraulics
from hexsim.plant.model import load_model
from hexsim.plant.params import HydraulicParams
from hexsim.studies.acceptance import Tolerances, describing_function, envelope


def test_heave_frequency_response_matches_the_linearised_position_loop():
    """With a linear valve (sharp edges, no overlap) each leg's loop is y/r = 1/(1 + s/(K_p K_v)), K_v the
    static flow curve's slope at null (seed eq. 5.1) at the rest pressure, the mean of both edges' (a
    sine's fundamental sees their mean); heave moves every leg alike. The describing function of the
    simulated hexapod (oil spring, friction, 500 Hz sampling, sensor noise) follows it to 4 Hz."""
    hyd = HydraulicParams(flow_area="sharp", overlap=0.0)
    base = hexsim.RunConfig("heave", machine=hexsim.Machine(hydraulics=hyd))
    p1 = hexsim.simulate(hexsim.RunConfig(hexsim.Scenario.sine("heave", duration=6.0),
                                          hexsim.Machine(hydraulics=hyd))).p1_initial[0]
    du = 1e-3
    k_v = (hydraulics.static_velocity(du, p1, hyd) - hydraulics.static_velocity(-du, p1, hyd)) / (2 * du)
    k_p = base.controller.kp
    for f in (0.5, 2.0, 4.0):
        gain_db, phase_deg = describing_function(base, "heave", f)
        h = 1 / (1 + 2j * math.pi * f / (k_p * k_v))
        assert gain_db == pytest.approx(20 * math.log10(abs(h)), abs=0.3)
        assert phase_deg == pytest.approx(math.degrees(np.angle(h)), abs=3.0)


def test_envelope_excursion_puts_a_leg_at_its_stroke_end():
    base = hexsim.RunConfig("heave")
    env = envelope(base, ("roll",))["roll"]
    geo = HexapodGeometry.from_model(load_model("hexapod", "platform"))
    for sign, reach in ((-1, env["excursion"][0]), (1, env["excursion"][1])):
        pose = np.zeros(6)
        pose[3] = reach
        y = geo.inverse(pose, check=False)
        assert sign * reach > 0.1
        assert min(np.min(y - geo.stroke[:, 0]), np.min(geo.stroke[:, 1] - y)) == pytest.approx(0.0, abs=1e-9)
    assert env["velocity"] > 0 and env["acceleration"] > 0


def _tolerances(tmp_path, **sections):
    doc = {"format": "hexsim-acceptance", "version": 1, "source": "a test", "dofs": ["heave"],
           "frequencies_hz": [1.0], **sections}
    path = tmp_path / "tol.json"
    path.write_text(json.dumps(doc))
    return path


def test_accept_checks_each_figure_and_writes_its_report(tmp_path):
    tol = _tolerances(tmp_path, frequency_response={"gain_db": [-3, 3], "phase_deg": [-45, 0]},
                      turn_around={"max_bump_g": 0.001}, leg_balance={"max_deviation_pct": 5},
                      repeatability={"max_difference_g": 0.05}, envelope={"heave": {"excursion": 0.05}})
    out = subprocess.run([sys.executable, "-m", "hexsim", "accept", "--tolerances", str(tol), "--report", "acc",
                          "--jobs", "1", "--quiet"], cwd=tmp_path, capture_output=True, text=True, timeout=900)
    assert out.returncode == 1, out.stderr  # the turn-around bump (0.05 g) is beyond the 0.001 g asked
    assert "FAIL turn_around: heave, largest bump" in out.stdout
    doc = json.loads((tmp_path / "acc" / "acceptance.json").read_text())
    checks = {c["item"]: c for c in doc["results"][0]["checks"]}
    assert checks["heave at 1 Hz, gain"]["passed"] is True
    assert checks["heave, largest bump"]["passed"] is False and checks["heave, largest bump"]["value"] > 0.001
    assert checks["heave, excursion"]["passed"] is True
    assert checks["heave, largest acceleration difference"]["passed"] is True
    report = (tmp_path / "acc" / "report.md").read_text()
    assert "**FAIL**" in report and "frequency_response.png" in report
    assert (tmp_path / "acc" / "frequency_response.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("change, expected", [
    ({"format": "other"}, "not a hexsim acceptance tolerance file"),
    ({"leg_balanse": {}}, "unknown key 'leg_balanse'"),
    ({"dofs": ["heaven"]}, "dofs: unknown degree of freedom 'heaven'"),
    ({"frequencies_hz": [0.5, 400]}, "frequencies_hz"),
    ({"frequency_response": {"gain_db": [3, -3]}}, "frequency_response.gain_db: expected \\[lower, upper\\]"),
    ({"turn_around": {"max_bump_g": -1}}, "turn_around.max_bump_g: expected a non-negative number"),
    ({"envelope": {"heave": 0.1}}, "envelope.heave: expected an object"),
])
def test_bad_tolerance_files_are_refused_with_one_line(tmp_path, change, expected):
    doc = {"format": "hexsim-acceptance", "version": 1, **change}
    path = tmp_path / "tol.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError, match=expected):
        Tolerances.read(path)


def test_accept_refuses_a_bad_file_before_running(tmp_path):
    path = tmp_path / "tol.json"
    path.write_text("{not json")
    out = subprocess.run([sys.executable, "-m", "hexsim", "accept", "--tolerances", str(path), "--report", "acc"],
                         cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert out.returncode == 2 and out.stderr.startswith("hexsim: error:") and "not valid JSON" in out.stderr
    assert len(out.stderr.strip().splitlines()) == 1 and not (tmp_path / "acc").exists()


def _independent_log(tmp_path, kp: float):
    """A 5 s, 1 Hz, 10 mm heave of the independent hexapod (tests/independent_hexapod.py, its own equations)
    with its P gain ``kp``, logged with the platform setpoint."""
    import independent_hexapod as ih

    def poses(t):
        p = np.zeros(6)
        p[2] = 0.01 * min(t, 1.0) * math.sin(2 * math.pi * t)
        return p

    cols = ih.motion(ih.Hexapod(kp=kp), 5.0, poses, np.random.default_rng(3))
    ref = np.array([poses(t) for t in cols["time_s"]])
    for k, name in enumerate(("x_m", "y_m", "z_m", "roll_rad", "pitch_rad", "yaw_rad")):
        cols[f"dof_ref_{name}"] = ref[:, k]
    return ih.write(cols, tmp_path / f"heave_kp{kp:g}.csv", "1 Hz heave for the acceptance test", kp=kp)


def test_a_logged_test_gives_its_measured_figures_beside_the_simulated(tmp_path):
    """The frequency-response point and turn-around bump read from a log of the independent hexapod: with the
    machine file's K_p the log and the simulation agree; with half the gain the log shows the slower loop."""
    from hexsim.measured.acceptance_logs import log_test

    base = hexsim.RunConfig("heave")
    same = log_test(_independent_log(tmp_path, 200.0), base)
    assert same["dof"] == "heave" and same["frequency_hz"] == pytest.approx(1.0, rel=0.01)
    assert same["measured"]["gain_db"] == pytest.approx(same["simulated"]["gain_db"], abs=0.5)
    assert same["measured"]["phase_deg"] == pytest.approx(same["simulated"]["phase_deg"], abs=5.0)
    assert same["measured"]["bump_g"] > 0 and same["simulated"]["bump_g"] > 0
    slow = log_test(_independent_log(tmp_path, 100.0), base)
    assert slow["measured"]["phase_deg"] < same["measured"]["phase_deg"] - 10.0
    assert slow["simulated"]["phase_deg"] == pytest.approx(same["simulated"]["phase_deg"], abs=1.0)


def test_accept_checks_its_logs_before_any_test_runs(tmp_path):
    """A log without the platform setpoint is refused with one line before the tests run (nothing written)."""
    t = np.arange(100) / 1000.0
    cols = {"time_s": t, **{f"leg{i}_pos_m": np.full(t.size, 0.1) for i in range(1, 7)}}
    np.savetxt(tmp_path / "test.csv", np.column_stack(list(cols.values())), delimiter=",", header=",".join(cols),
               comments="")
    (tmp_path / "test.json").write_text('{"system": "hexapod", "sample_rate_hz": 1000.0}')
    tol = _tolerances(tmp_path, frequency_response={})
    out = subprocess.run([sys.executable, "-m", "hexsim", "accept", "--tolerances", str(tol), "--report", "acc",
                          "--log", "test.csv"], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert out.returncode == 2 and "no dof_ref_* column" in out.stderr, out.stderr
    assert len(out.stderr.strip().splitlines()) == 1 and not (tmp_path / "acc").exists()
