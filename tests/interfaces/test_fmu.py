"""``hexsim fmu``: the leg and platform FMUs built, validated and simulated by fmpy as a user's tool would
(FMI 3.0 co-simulation), against ``hexsim run`` on the same machine (issue 56)."""

from __future__ import annotations

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")  # the test extras install it; a bare install runs the rest
from fmpy import read_model_description, simulate_fmu  # noqa: E402
from fmpy.validation import validate_fmu  # noqa: E402

from hexsim.cli import main  # noqa: E402
from hexsim.control.scenario import make_scenario  # noqa: E402
from hexsim.engine.config import RunConfig  # noqa: E402
from hexsim.engine.runner import simulate  # noqa: E402
from hexsim.interfaces.cosim import peak_hold_reversal_peaks  # noqa: E402
from hexsim.interfaces.fmu import (  # noqa: E402
    LEG_OUTPUTS,
    PLATFORM_INPUTS,
    PLATFORM_OUTPUTS,
    UNITS,
    build_fmu,
)
from hexsim.plant.geometry import MICRO_MOTION_SYSTEM  # noqa: E402
from hexsim.plant.machine import dump, load_machine  # noqa: E402
from hexsim.studies.perception import point_motion  # noqa: E402

DURATION = 8.0


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    """The two FMUs of the built-in machine, and the leg's of the same machine with a noiseless position sensor
    (``quiet``: the FMU plays its input one step behind, so with noise its reversals meet other noise samples
    than the run's, and single peaks differ by a few per cent either way)."""
    out = tmp_path_factory.mktemp("fmus")
    document = load_machine(None).document()
    document["sensors"]["position_noise_m"] = 0.0
    quiet = out / "quiet.json"
    quiet.write_text(dump(document))
    return {"leg": build_fmu("leg", out), "platform": build_fmu("platform", out),
            "quiet": build_fmu("leg", out / "quiet", machine=str(quiet)), "quiet_machine": quiet}


def _peaks_from_the_fmu(result, run, h: float, axis: str) -> tuple[np.ndarray, np.ndarray]:
    """The FMU's reversal peaks from its peak hold and the run's (the FMU plays its input one step behind)."""
    return peak_hold_reversal_peaks(result["sample_time"], result[f"{axis}_max"], result[f"{axis}_min"], run, h)


def test_the_fmus_validate_and_every_variable_has_its_unit_and_description(fmus):
    """fmpy's validation finds nothing; every input, output and parameter carries a description, every real
    one a unit of the UnitDefinitions."""
    for kind, path in (("leg", fmus["leg"]), ("platform", fmus["platform"])):
        assert validate_fmu(str(path)) == [], kind
        md = read_model_description(str(path))
        assert md.fmiVersion == "3.0" and md.coSimulation is not None
        assert {u.name for u in md.unitDefinitions} == set(UNITS)
        ports = [v for v in md.modelVariables if v.causality in ("input", "output", "parameter")]
        named = {c: {v.name for v in ports if v.causality == c} for c in ("input", "output", "parameter")}
        assert named["output"] == {p.name for p in (LEG_OUTPUTS if kind == "leg" else PLATFORM_OUTPUTS)}
        assert named["input"] == ({"y_ref", "u_v_set", "F_ext"} if kind == "leg" else {p.name for p in PLATFORM_INPUTS})
        assert named["parameter"] >= {"duration_s", "interpolation"}
        for v in ports:
            assert v.description, (kind, v.name)
            if v.type == "Float64":
                assert v.unit in UNITS, (kind, v.name)


@pytest.mark.parametrize("h", [0.002, 0.01])
def test_the_leg_fmu_reproduces_hexsim_run_actuator_on_the_reversal_peak(fmus, h):
    """The piston setpoint of ``hexsim run actuator`` fed at communication steps of 2 and 10 ms: with a
    noiseless sensor every reversal's peak within 1 % of the run's (the cubic between communication points: a
    ramp gave +9 % at 10 ms); with the sensor's noise single peaks differ by up to 11 % (the noise samples
    a reversal meets are others one step later), their mean (4 reversals) within 5 %."""
    for fmu_path, machine, each, mean in ((fmus["quiet"], fmus["quiet_machine"], 0.01, 0.01),
                                          (fmus["leg"], None, None, 0.05)):
        run = simulate(RunConfig.from_machine(machine, make_scenario("actuator", duration=DURATION)))
        times = np.arange(0.0, DURATION, h)
        signal = np.zeros(len(times), dtype=[("time", float), ("y_ref", float)])
        signal["time"] = times
        signal["y_ref"] = run.y_ref[np.round(times * 1000).astype(int), 0]  # the controller's samples (t = 2 ms k)
        result = simulate_fmu(str(fmu_path), start_time=0.0, stop_time=DURATION - h, output_interval=h, input=signal,
                              start_values={"duration_s": DURATION}, output=["sample_time", "acc_max", "acc_min", "y"])
        assert np.allclose(np.diff(result["time"]), h)
        fmu, ran = _peaks_from_the_fmu(result, run, h, "acc")
        assert len(ran) >= 4
        if each is not None:
            np.testing.assert_allclose(fmu, ran, rtol=each)
        assert abs(fmu.mean() / ran.mean() - 1.0) < mean, (fmu, ran)


def test_the_platform_fmu_reproduces_hexsim_run_heave_at_10_ms_steps(fmus):
    """The heave of ``hexsim run heave`` fed as DOF setpoints every 10 ms: the mean reversal peak of the
    platform's accelerometer within 1 % of the run's; the head's specific force follows the run's."""
    scenario = make_scenario("heave", duration=DURATION)
    run = simulate(RunConfig.from_machine(None, scenario))
    h = 0.01
    times = np.arange(0.0, DURATION, h)
    names = ("surge", "sway", "heave", "roll", "pitch", "yaw")
    signal = np.zeros(len(times), dtype=[("time", float)] + [(n, float) for n in names])
    signal["time"] = times
    poses = scenario.poses(times)
    for k, n in enumerate(names):
        signal[n] = poses[:, k]
    result = simulate_fmu(str(fmus["platform"]), start_time=0.0, stop_time=DURATION - h, output_interval=h, input=signal,
                          start_values={"duration_s": DURATION},
                          output=["sample_time", "acc_z_max", "acc_z_min", "heave_out", "head_fz", "leg1_p1"])
    fmu, ran = _peaks_from_the_fmu(result, run, h, "acc_z")
    assert abs(fmu.mean() / ran.mean() - 1.0) < 0.01
    assert np.max(np.abs(result["heave_out"])) == pytest.approx(np.max(np.abs(poses[:, 2])), rel=0.1)
    head = point_motion(run, MICRO_MOTION_SYSTEM.head_point).specific_force[:, 2]
    ran = np.interp(result["sample_time"] - h, run.t, head)
    assert np.corrcoef(result["head_fz"], ran)[0, 1] > 0.95
    assert np.sqrt(np.mean((result["head_fz"] - ran) ** 2)) < 0.1 * np.std(ran)
    assert np.all(result["leg1_p1"] > 1e5)


def test_the_external_force_moves_the_cap_pressure_by_force_over_area_and_the_valve_drives_open_loop(fmus):
    """Held at neutral, an extending external force of 2 kN lowers P1 by 2 kN / A1 (statics through the P loop
    and the hydraulics); open loop, a 2 V valve setpoint extends the piston with no controller (u_v = 2 V,
    U_c = 0)."""
    def p1_with(force: float) -> float:
        signal = np.array([(0.0, force)], dtype=[("time", float), ("F_ext", float)])
        result = simulate_fmu(str(fmus["leg"]), start_time=0.0, stop_time=1.5, output_interval=0.01, input=signal,
                              start_values={"duration_s": 2.0}, output=["p1"])
        return float(result["p1"][-1])

    area = RunConfig.from_machine(None, "actuator").hydraulics.area_bottom
    assert p1_with(0.0) - p1_with(2000.0) == pytest.approx(2000.0 / area, rel=0.02)
    signal = np.array([(0.0, 2.0)], dtype=[("time", float), ("u_v_set", float)])
    result = simulate_fmu(str(fmus["leg"]), start_time=0.0, stop_time=0.3, output_interval=0.005, input=signal,
                          start_values={"duration_s": 1.0, "closed_loop": False}, output=["y", "ydot", "u_v", "u_c"])
    assert result["ydot"][-1] > 0.02 and result["y"][-1] > result["y"][0] + 0.005
    assert np.all(result["u_v"][1:] == 2.0) and np.all(result["u_c"] == 0.0)


def test_a_step_that_is_not_whole_milliseconds_is_refused_in_one_message(fmus):
    messages = []
    with pytest.raises(Exception):
        simulate_fmu(str(fmus["leg"]), start_time=0.0, stop_time=0.01, output_interval=0.0015,
                     start_values={"duration_s": 1.0}, logger=lambda *args: messages.append(str(args)))
    assert any("whole number of the 1 ms record period" in m for m in messages), messages


def test_the_command_writes_the_fmu_and_refuses_a_platform_of_a_single_actuator(tmp_path, capsys):
    assert main(["fmu", "leg", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "HexsimLeg.fmu").is_file()
    assert "inputs: y_ref [m] or u_v_set [V], F_ext [N]" in capsys.readouterr().out
    assert main(["fmu", "platform", "--machine", "servo_cylinder", "--out", str(tmp_path / "p")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "needs a hexapod machine" in err[0]
    assert not (tmp_path / "p").exists()
