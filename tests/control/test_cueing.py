"""Motion cueing (issue 43): the classical washout on a sustained deceleration, a vehicle run's cue report,
and bad vehicle and washout files refused with one line."""

import json
import math
import subprocess
import sys

import numpy as np
import pytest

import hexsim
from hexsim.control.scenario import vehicle_scenario
from hexsim.control.washout import (
    VEHICLE_COLUMNS,
    VehicleMotion,
    WashoutParams,
    rate_limited,
    read_vehicle,
    washout,
)
from hexsim.errors import InputError
from hexsim.studies.cueing import cue_report, pose_motion


def _stop(duration=14.0, decel=2.0, fs=100.0):
    """A sustained deceleration from 1 s (0.5 s onset) that never ends within ``duration``."""
    t = np.arange(int(duration * fs) + 1) / fs
    f = np.zeros((t.size, 3))
    f[:, 0] = -decel * np.clip((t - 1.0) / 0.5, 0, 1)
    f[:, 2] = 9.81
    return VehicleMotion(t, f, np.zeros((t.size, 3)), "stop")


def test_a_sustained_deceleration_is_tilt_coordinated_within_the_rate_limit_and_the_platform_returns():
    params = WashoutParams()
    out = washout(_stop(), params, rate_hz=500.0)
    pitch = out.poses[:, 4]
    rate = np.abs(np.diff(out.tilt[:, 1])) * 500.0
    assert np.max(rate) <= math.radians(params.tilt_rate_limit_degps) * (1 + 1e-9)
    # the sustained -1 m/s^2 (scaled) is cued by tilting nose down: gravity gives -g sin(pitch) = f_x
    target = math.asin(0.5 * 2.0 / 9.81)
    assert pitch[-1] == pytest.approx(target, rel=0.02) and pitch[-1] > 0
    assert out.tilt_rate_limited > 0
    # the translational channel washes out: the onset moved the platform back, the end returns it to neutral
    x = out.translation[:, 0]
    assert x.min() < -0.02 and abs(x[-1]) < 0.05 * abs(x.min())
    assert np.all(np.abs(out.poses[-1, [1, 2, 3, 5]]) < 1e-9)


def test_the_tilt_rate_changes_within_its_acceleration_limit_and_the_tilt_does_not_overshoot():
    """A stop that begins and ends (the tilt's target rises and falls back at once): the tilt rate never flips in
    one sample (its change per sample within tilt_acceleration_limit_degps2, where a rate limiter alone
    flipped it from +1.5 to -1.5 deg/s between two samples), stays within the rate limit, and the tilt settles on its
    target without passing it."""
    m = _stop(duration=12.0, decel=3.0)
    f = m.specific_force.copy()
    f[m.t > 3.0, 0] = 0.0
    params = WashoutParams()
    out = washout(VehicleMotion(m.t, f, m.angular_velocity), params, 500.0)
    rate = np.diff(out.tilt[:, 1]) * 500.0
    accel = np.diff(rate) * 500.0
    assert np.max(np.abs(rate)) <= math.radians(params.tilt_rate_limit_degps) * (1 + 1e-9)
    assert np.max(np.abs(accel)) <= math.radians(params.tilt_acceleration_limit_degps2) * (1 + 1e-9)
    assert rate.max() > 0.9 * math.radians(params.tilt_rate_limit_degps) and rate.min() < 0  # it turned round
    assert np.abs(out.tilt[-1, 1]) < 1e-6  # back to level: the target is zero once the stop has ended
    # held to a constant target the follower arrives without passing it
    target = np.full((2000, 1), 0.05)
    followed, held = rate_limited(target, 1e-4, 1e-6)
    assert followed.max() <= 0.05 + 1e-12 and followed[-1, 0] == pytest.approx(0.05, abs=1e-12)
    assert 0 < held < 2000
    with pytest.raises(ValueError, match="must be positive"):
        rate_limited(target, 1e-4, 0.0)


def test_a_rotation_is_high_passed_back_to_neutral():
    t = np.arange(1001) / 100.0
    w = np.zeros((t.size, 3))
    w[(t > 1) & (t < 3), 2] = 0.2  # a 2 s yaw rate pulse
    f = np.tile([0.0, 0.0, 9.81], (t.size, 1))
    out = washout(VehicleMotion(t, f, w), WashoutParams(), 500.0)
    yaw = out.poses[:, 5]
    assert yaw.max() > 0.02 and abs(yaw[-1]) < 0.05 * yaw.max()


def test_pose_motion_of_a_tilted_platform_reads_gravity():
    t = np.linspace(0, 2, 1001)
    poses = np.zeros((t.size, 6))
    poses[:, 4] = 0.1  # pitched nose down, still
    pm = pose_motion(t, poses, (0.0, 0.0, 1.0))
    np.testing.assert_allclose(pm.specific_force[500], [-9.81 * math.sin(0.1), 0, 9.81 * math.cos(0.1)], atol=1e-9)


def test_a_vehicle_run_reports_its_cues(tmp_path):
    csv = tmp_path / "stop.csv"
    m = _stop(duration=6.0)
    cols = np.column_stack([m.t, m.specific_force, m.angular_velocity])
    np.savetxt(csv, cols, delimiter=",", header=",".join(VEHICLE_COLUMNS), comments="")
    result = hexsim.simulate(hexsim.RunConfig(vehicle_scenario(csv)))
    report = cue_report(result)
    x = report.axes["x"]
    assert x.correlation > 0.3  # the onset and the tilt follow the car's deceleration
    assert x.rms_error < x.rms_vehicle
    assert report.stroke_margin_m.min() > 0 and report.max_tilt_deg[1] > 0.5
    # the simulated hardware follows the ideal platform closely: its seat difference is a fraction of the cue
    assert report.seat["x"].max_weighted_mps2 < 0.5 * np.max(np.abs(report.sensed_vehicle[:, 0]))
    out = subprocess.run([sys.executable, "-m", "hexsim", "run", f"vehicle:{csv}", "--json", "cue.json", "--quiet"],
                         cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    doc = json.loads((tmp_path / "cue.json").read_text())
    assert set(doc["axes"]) == {"x", "y", "z", "roll", "pitch", "yaw"} and "traces" not in doc
    assert "false cues" in out.stdout


@pytest.mark.parametrize("text, expected", [
    ("time_s,f_x_mps2\n0,0\n1,0\n2,0\n", "missing column 'f_y_mps2'"),
    ("time_s,f_x_mps2,f_y_mps2,f_z_mps2,p_radps,q_radps,r_radps\n0,0,0,9.81,0,0,0\n1,500,0,9.81,0,0,0\n"
     "2,0,0,9.81,0,0,0\n", "row 3, column f_x_mps2"),
    ("time_s,f_x_mps2,f_y_mps2,f_z_mps2,p_radps,q_radps,r_radps\n0,0,0,9.81,0,0,0\n0.1,0,0,9.81,0,0,0\n"
     "0.2,0,0,9.81,0,0,0\n", "at least 1 s"),
])
def test_bad_vehicle_files_are_refused_with_one_line(tmp_path, text, expected):
    path = tmp_path / "car.csv"
    path.write_text(text)
    with pytest.raises(InputError, match=expected):
        read_vehicle(path)
    out = subprocess.run([sys.executable, "-m", "hexsim", "run", f"vehicle:{path}"], cwd=tmp_path,
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1 and expected in out.stderr
    assert "Traceback" not in out.stderr


@pytest.mark.parametrize("doc, expected", [
    ({"tilt_rate": 2}, "unknown washout key 'tilt_rate'"),
    ({"hp_omega_radps": [4, 4]}, "hp_omega_radps: expected three numbers"),
    ({"tilt_rate_limit_degps": -1}, "tilt_rate_limit_degps: expected a positive number"),
    ({"tilt_limit_deg": 45}, "tilt_limit_deg"),
])
def test_bad_washout_files_are_refused_with_one_line(tmp_path, doc, expected):
    path = tmp_path / "washout.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError, match=expected):
        WashoutParams.from_file(path)


def test_a_vehicle_motion_beyond_the_workspace_or_in_compare_is_refused_with_one_line(tmp_path):
    csv = tmp_path / "stop.csv"
    m = _stop(duration=4.0, decel=8.0)
    np.savetxt(csv, np.column_stack([m.t, m.specific_force, m.angular_velocity]), delimiter=",",
               header=",".join(VEHICLE_COLUMNS), comments="")
    (tmp_path / "w.json").write_text('{"scale_specific_force": [1, 1, 1], "limit_specific_force_mps2": [9, 9, 9]}')
    for args, expected in ((["run", f"vehicle:{csv}", "--washout", "w.json"], "the washout's setpoints leave the workspace"),
                           (["compare", f"vehicle:{csv}"], "a vehicle: scenario's figures are its cue report")):
        out = subprocess.run([sys.executable, "-m", "hexsim", *args], cwd=tmp_path, capture_output=True, text=True,
                             timeout=300)
        assert out.returncode == 2 and expected in out.stderr and len(out.stderr.strip().splitlines()) == 1


def test_washout_applies_only_to_vehicle_scenarios(tmp_path):
    path = tmp_path / "w.json"
    path.write_text("{}")
    out = subprocess.run([sys.executable, "-m", "hexsim", "run", "heave", "--washout", str(path)], cwd=tmp_path,
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 2 and "--washout applies to a vehicle:PATH scenario" in out.stderr


def test_rotations_turn_about_the_washouts_rotation_centre():
    """With the rotation centre at the driver's head, the head moves only by the translational channel:
    the platform's origin makes up for the tilt (p_origin + R c - c = translation)."""
    from scipy.spatial.transform import Rotation

    centre = np.array([0.0, 0.0, 1.47])
    out = washout(_stop(duration=8.0), WashoutParams(rotation_centre_m=(0.0, 0.0, 1.47), tilt_limit_deg=4.0), 500.0)
    turn = Rotation.from_euler("ZYX", out.poses[:, [5, 4, 3]])
    head = out.poses[:, :3] + turn.apply(centre) - centre
    np.testing.assert_allclose(head, out.translation, atol=1e-12)
    assert np.max(np.abs(out.poses[:, 0] - out.translation[:, 0])) > 0.05  # the tilt's share, made up in surge


def test_after_a_stop_the_platform_returns_to_neutral():
    """A 4 s deceleration, then none: the tilt comes back at no more than its rate limit and every degree of
    freedom returns to the neutral pose."""
    m = _stop(duration=25.0)
    f = m.specific_force.copy()
    f[m.t > 5.0, 0] = 0.0
    out = washout(VehicleMotion(m.t, f, m.angular_velocity), WashoutParams(), 500.0)
    params = WashoutParams()
    assert np.max(np.abs(np.diff(out.tilt[:, 1]))) * 500.0 <= math.radians(params.tilt_rate_limit_degps) * (1 + 1e-9)
    assert np.max(np.abs(out.poses[:, 4])) > 0.05
    np.testing.assert_allclose(out.poses[-1], 0.0, atol=2e-3)
