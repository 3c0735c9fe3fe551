"""Model-predictive motion cueing (issue 55): its model senses as the perception module does, its cues follow
the vehicle where the classical washout's do not, and its platform stays inside the machine's envelope."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.signal import lsim

from hexsim.cli import main
from hexsim.control.kinematics import HexapodGeometry
from hexsim.control.mpc_cueing import (
    N_INPUT,
    MPCParams,
    PlatformLimits,
    continuous_model,
    move_blocks,
    mpc_washout,
)
from hexsim.control.scenario import make_scenario
from hexsim.control.washout import VehicleMotion, WashoutParams, washout
from hexsim.engine.config import RunConfig
from hexsim.errors import InputError
from hexsim.plant.geometry import MICRO_MOTION_SYSTEM
from hexsim.plant.model import load_model
from hexsim.studies.acceptance import platform_limits
from hexsim.studies.cueing import pose_motion, sensed
from hexsim.studies.perception import AXES, canal, otolith, sensed_threshold

HEAD = MICRO_MOTION_SYSTEM.head_point
RATE = 500.0


def _vehicle(kind: str) -> VehicleMotion:
    """A car's motion at the head: a jerk-limited 3 m/s^2 stop held 4 s ("stop"), or a lane change's
    sway doublet of 2.5 m/s^2 with the yaw rate that goes with it ("lane")."""
    t = np.arange(0.0, 9.0, 0.01)
    f, w = np.zeros((t.size, 3)), np.zeros((t.size, 3))
    f[:, 2] = 9.81
    if kind == "stop":
        f[:, 0] = -3.0 * np.clip((t - 1.0) / 0.5, 0, 1) * (t < 5.0) - 3.0 * np.clip(1 - (t - 5.0) / 0.5, 0, 1) * (t >= 5.0)
    else:
        s = np.sin(np.pi * np.clip(t - 1.0, 0.0, 4.0) / 2.0)
        f[:, 1] = 2.5 * s
        w[:, 2] = 0.12 * np.sin(np.pi * np.clip(t - 1.0, 0.0, 4.0) / 4.0) * np.cos(np.pi * np.clip(t - 1.0, 0, 4) / 4.0)
    return VehicleMotion(t, f, w, kind)


@pytest.fixture(scope="module")
def limits() -> PlatformLimits:
    return platform_limits(RunConfig(make_scenario("heave", duration=6.0)))


def _sensed_pair(out, vehicle):
    pm = pose_motion(out.t, out.poses, HEAD)
    f, w = vehicle.at(out.t)
    return sensed(pm.channels, RATE, 9.81), sensed(np.concatenate([f, w], axis=1), RATE, 9.81)


def test_the_model_senses_what_the_perception_module_senses():
    """The MPC's linear model (platform, head, otoliths, canals) driven by a surge acceleration, a pitch
    acceleration and a tilt acceleration gives the sensed specific force and rates that the perception
    module's otolith and canal compute from the same motion (small angles: f_x = a_x + alpha_y h - g pitch)."""
    a, b, c = continuous_model(HEAD)
    t = np.arange(0.0, 6.0, 1e-3)
    u = np.zeros((t.size, N_INPUT))
    u[:, 0] = np.where((t > 0.5) & (t < 1.0), 1.0, 0.0) - np.where((t > 1.0) & (t < 1.5), 1.0, 0.0)  # surge
    u[:, 4] = 0.05 * np.sin(2 * np.pi * 0.7 * t)  # pitch (rotation)
    u[:, 7] = np.where((t > 2.0) & (t < 2.5), 0.02, 0.0)  # pitch tilt
    _, y, x = lsim((a, b, c, np.zeros((6, N_INPUT))), u, t)
    pitch, pitch_rate = x[:, 7] + x[:, 13], x[:, 10] + x[:, 15]
    alpha = u[:, 4] + u[:, 7]
    f_x = u[:, 0] + alpha * HEAD[2] - 9.81 * pitch  # the head at (0, 0, h) on the platform's centre line
    assert HEAD[0] == HEAD[1] == 0.0
    assert np.allclose(y[:, 0], otolith().apply(f_x, 1e3), atol=2e-3 * np.abs(y[:, 0]).max())
    assert np.allclose(y[:, 4], canal().apply(pitch_rate, 1e3), atol=2e-3 * np.abs(y[:, 4]).max())
    assert np.abs(y[:, 0]).max() > 0.3  # the comparison is on a signal, not on zeros


def test_move_blocks_cover_the_horizon_once():
    for steps in (2, 7, 30, 61):
        blocks = move_blocks(steps)
        assert [first for first, _ in blocks] == list(np.cumsum([0] + [n for _, n in blocks[:-1]]))
        assert sum(n for _, n in blocks) == steps and blocks[0] == (0, 1)


@pytest.mark.parametrize("kind, axis", [("stop", 0), ("lane", 1)])
def test_mpc_cues_follow_the_vehicle_within_the_stroke_and_the_tilt_threshold(limits, kind, axis):
    """On a sustained stop and a lane change the MPC's sensed cue correlates with the vehicle's (at least
    0.85) where the classical washout's does not (below 0.5), with a smaller rms error; every leg stays
    inside its stroke by the exact kinematics, the tilt's rate within its limit, every programme solved."""
    vehicle = _vehicle(kind)
    params = MPCParams()
    mpc = mpc_washout(vehicle, limits, params, HEAD, RATE)
    classical = washout(vehicle, WashoutParams(), RATE)
    figures = {}
    for name, out in (("mpc", mpc), ("classical", classical)):
        s_p, s_v = _sensed_pair(out, vehicle)
        figures[name] = (np.corrcoef(s_p[:, axis], s_v[:, axis])[0, 1], np.sqrt(np.mean((s_p[:, axis] - s_v[:, axis]) ** 2)))
    assert figures["mpc"][0] > 0.85 and figures["classical"][0] < 0.5, figures
    assert figures["mpc"][1] < figures["classical"][1], figures
    geo = HexapodGeometry.from_model(load_model("hexapod"))
    legs = np.array([geo.inverse(p, check=False) for p in mpc.poses[::10]])
    assert np.all(legs >= geo.stroke[:, 0]) and np.all(legs <= geo.stroke[:, 1])
    tilt_rate = np.diff(mpc.tilt, axis=0) * RATE
    assert np.abs(tilt_rate).max() <= math.radians(params.tilt_rate_limit_degps) * 1.01
    assert mpc.solver["unsolved"] == 0 and mpc.solver["programmes"] == len(mpc.t[::int(params.step_s * RATE)])


def test_without_preview_the_cues_come_later_and_follow_less(limits):
    """Online (the vehicle's sensed motion held over the horizon) the surge cue starts later than with the
    drive's future known and follows less (measured: correlation 0.47 against 0.97; the first sensed 0.1 m/s^2
    at 2.00 s against 1.27 s, the vehicle's at 1.10 s)."""
    vehicle = _vehicle("stop")
    onsets, corr = {}, {}
    for preview in (True, False):
        out = mpc_washout(vehicle, limits, MPCParams(preview=preview), HEAD, RATE)
        s_p, s_v = _sensed_pair(out, vehicle)
        corr[preview] = np.corrcoef(s_p[:, 0], s_v[:, 0])[0, 1]
        onsets[preview] = out.t[np.argmax(np.abs(s_p[:, 0]) > 0.1)]
    assert 0.4 < corr[False] < corr[True]
    assert onsets[False] > onsets[True]


def _false_cues(out, vehicle) -> float:
    """Seconds of the drive whose platform, on some axis, is sensed beyond that axis' perception threshold where
    the vehicle's sensed motion is below it or of the other sign (the cue report's false cues)."""
    s_p, s_v = _sensed_pair(out, vehicle)
    thr = np.array([sensed_threshold(a, RATE) for a in AXES])
    false = (np.abs(s_p) > thr) & ((np.abs(s_v) < thr) | (np.sign(s_p) != np.sign(s_v)))
    return float(np.sum(np.any(false, axis=1))) / RATE


@pytest.mark.parametrize("kind", ["stop", "lane"])
def test_the_platform_is_not_sensed_beyond_a_threshold_the_vehicle_is_not(limits, kind):
    """The MPC holds the platform's sensed cue within 0.9 of each axis' perception threshold wherever the
    vehicle's is below it or of the other sign (soft constraints): on the stop and the lane change no false cue
    at all (measured 0 s, the cue correlating 0.97 and 0.99), where without them 1.8 and 1.5 s of the drives have
    one (the same scale and horizon; correlating 0.99 and 0.99)."""
    vehicle = _vehicle(kind)
    with_them = mpc_washout(vehicle, limits, MPCParams(), HEAD, RATE)
    without = mpc_washout(vehicle, limits, MPCParams(threshold_share=0.0), HEAD, RATE)
    assert _false_cues(with_them, vehicle) < 0.05 and _false_cues(without, vehicle) > 1.0
    assert with_them.solver["unsolved"] == 0


def test_bad_parameters_and_limits_are_refused_by_name(tmp_path):
    path = tmp_path / "mpc.json"
    path.write_text(json.dumps({"horizon_s": 1.0, "weight_sensd": [1, 1, 1, 1, 1, 1]}))
    with pytest.raises(InputError, match=r"mpc\.json: unknown mpc cueing key 'weight_sensd'"):
        MPCParams.from_file(path)
    path.write_text(json.dumps({"margin": 1.5}))
    with pytest.raises(InputError, match=r"mpc\.json: .*margin: 1\.5 is more than the whole envelope"):
        MPCParams.from_file(path)
    with pytest.raises(InputError, match="horizon_s: 0.05 s is shorter than two steps"):
        MPCParams(horizon_s=0.05)
    with pytest.raises(InputError, match="threshold_share: expected a number from 0 .* to 1, got 1.5"):
        MPCParams(threshold_share=1.5)
    good = dict(jacobian=np.eye(6), stroke_lo=-np.ones(6), stroke_hi=np.ones(6), velocity_extend=np.ones(6),
                velocity_retract=np.ones(6), force_map=np.eye(6), force_up=np.ones(6), force_down=np.ones(6))
    PlatformLimits(**good)
    with pytest.raises(InputError, match="stroke_lo: every leg's must be below its neutral"):
        PlatformLimits(**good | {"stroke_lo": np.zeros(6)})
    with pytest.raises(InputError, match=r"force_map: expected finite numbers of shape \(6, 6\)"):
        PlatformLimits(**good | {"force_map": np.eye(5)})


def test_the_command_cues_a_vehicle_by_mpc_and_refuses_it_elsewhere(tmp_path, capsys):
    vehicle = _vehicle("lane")
    path = tmp_path / "lane.csv"
    cols = np.column_stack([vehicle.t, vehicle.specific_force, vehicle.angular_velocity])
    np.savetxt(path, cols, delimiter=",", comments="",
               header="time_s,f_x_mps2,f_y_mps2,f_z_mps2,p_radps,q_radps,r_radps")
    out = tmp_path / "cue.json"
    assert main(["run", f"vehicle:{path}", "--cueing", "mpc", "--duration", "4", "--json", str(out), "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "mpc cueing defaults" in text and "programmes of" in text and "0 unsolved" in text
    doc = json.loads(out.read_text())
    assert doc["cueing"] == "mpc" and doc["cueing_solver"]["unsolved"] == 0
    assert main(["run", "heave", "--cueing", "mpc", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--cueing applies to a vehicle:PATH scenario, not heave" in err
