"""The 4-way valve on a differential cylinder, in the one compiled leg step: both chamber pressures
integrated; at a constant command the leg reaches the steady speed and pressures a hand solution of the
orifice equations gives; open-loop runs and logs; friction from both chambers.

The hand solution (sharp-edged, matched spool, turbulent orifices, seed eq. 3.4): with
k = C_d w (x_v - O_l) sqrt(2/rho) per open edge, extension gives phi_A = k sqrt(P_s - p1) = v A1,
phi_B = k sqrt(p2) = v A2, and p1 A1 - p2 A2 = F_c; so v = k sqrt((P_s A1 - F_c) / (A1^3 + A2^3)).
Retraction: |v| = k sqrt((P_s A2 - F_c) / (A1^3 + A2^3)) (Merritt, Hydraulic Control Systems, §6.4,
the asymmetric cylinder's load-flow relations, written here with hexsim's names).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import hexsim
from hexsim.cli import main
from hexsim.control.scenario import make_scenario
from hexsim.measured.friction_id import identify_friction
from hexsim.measured.measurement import read_log
from hexsim.plant import hydraulics
from hexsim.studies.metrics import steady_segments

P_S, F_C = 50e5, 40.0
HYD = hexsim.HydraulicParams(valve_type="4-way", flow_area="sharp", bore_diameter=0.025, rod_diameter=0.016,
                             supply_pressure=P_S, overlap=1e-5, spool_diameter=0.5e-3, pipeline_volume=5e-6,
                             pipeline_volume_rod=5e-6, viscous_pos=0.0, viscous_neg=0.0, coulomb_pos=F_C,
                             coulomb_neg=F_C, static_pos=0.0, static_neg=0.0, arctan_gain=1e4,
                             arctan_normalised=True)
LOAD = hexsim.Effects(mass_kg=3.0, inclination_deg=90.0)  # horizontal: no weight along the axis
MACHINE = hexsim.Machine(system="single-actuator", hydraulics=HYD, effects=LOAD,
                         controller=hexsim.ControllerParams(rate_hz=1000.0))


def _hand(u: float) -> tuple[float, float, float]:
    """(v, p1, p2) of the steady motion at command u [V], from the module doc's equations."""
    a1, a2 = math.pi / 4 * 0.025**2, math.pi / 4 * (0.025**2 - 0.016**2)
    x = abs(u) / 10.0 * HYD.x_v_max
    k = HYD.discharge_coefficient * math.pi * 0.5e-3 * (x - 1e-5) * math.sqrt(2.0 / HYD.density)
    if u > 0:
        v = k * math.sqrt((P_S * a1 - F_C) / (a1**3 + a2**3))
        return v, P_S - (v * a1 / k) ** 2, (v * a2 / k) ** 2
    v = k * math.sqrt((P_S * a2 - F_C) / (a1**3 + a2**3))
    return -v, (v * a1 / k) ** 2, P_S - (v * a2 / k) ** 2


def _valve_file(tmp_path, levels=(4.0, -4.0), hold=1.0):
    """A valve-command CSV: 0 V for 0.1 s, then each level held for ``hold`` s (or hold[i]), 1 kHz."""
    holds = np.broadcast_to(np.asarray(hold, dtype=float), (len(levels),))
    ends = 0.1 + np.cumsum(holds)
    t = np.arange(int(ends[-1] * 1000)) / 1000.0
    u = np.zeros_like(t)
    for level, start, end in zip(levels, ends - holds, ends):
        u[(t >= start) & (t < end)] = level
    path = tmp_path / "valve.csv"
    np.savetxt(path, np.column_stack([t, u]), delimiter=",", header="time_s,valve_cmd_V", comments="", fmt="%.6g")
    return path


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    path = _valve_file(tmp_path_factory.mktemp("valve"))
    return hexsim.simulate(hexsim.RunConfig(make_scenario(f"valve:{path}"), MACHINE))


def test_constant_command_reaches_the_hand_computed_speed_and_pressures(run):
    rows = steady_segments(run.t, run.u_v[:, 0], run.y[:, 0], {"p1": run.p1[:, 0], "p2": run.p2[:, 0]})
    assert [r["u_V"] for r in rows] == [4.0, -4.0]
    for row in rows:
        v, p1, p2 = _hand(row["u_V"])
        assert row["velocity_mps"] == pytest.approx(v, rel=2e-3)
        assert row["p1"] == pytest.approx(p1, abs=2e3)  # 0.02 bar
        assert row["p2"] == pytest.approx(p2, abs=2e3)
    # the array function of the same equations agrees with the hand solution too
    for u in (4.0, -4.0):
        s = hydraulics.steady_state(u, 0.0, HYD)
        assert (s.velocity, s.p1, s.p2) == pytest.approx(_hand(u), rel=1e-4)


def test_both_engines_step_the_4_way_leg_alike(tmp_path):
    path = _valve_file(tmp_path, levels=(3.0, -2.0), hold=0.4)
    cfgs = [hexsim.RunConfig(make_scenario(f"valve:{path}"), MACHINE, engine=e) for e in ("native", "python")]
    a, b = (hexsim.simulate(c) for c in cfgs)
    for name in ("y", "p1", "p2", "force"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_open_loop_log_replays_with_both_pressures_as_channels(run, tmp_path):
    from hexsim.measured.identify import identify
    from hexsim.outputs.logio import write_log

    write_log(tmp_path / "open.csv", run, noise=np.random.default_rng(1))
    side = json.loads((tmp_path / "open.json").read_text())
    assert side["controller"] == {"type": "none"}
    machine = hexsim.Machine(system="single-actuator", hydraulics=HYD, effects=LOAD, control="none")
    log = read_log(tmp_path / "open.csv", machine=machine)
    assert log.open_loop and {"p1_Pa", "p2_Pa"} <= set(log.columns)
    ident = identify(log, candidates=(), jobs=1)
    before = ident.error_before
    assert {"position", "p1", "p2"} <= set(before)
    assert before["p2"] < 0.05 and before["p1"] < 0.05 and before["position"] < 0.05, before


def test_friction_from_both_chambers_recovers_the_coulomb_level(tmp_path):
    """Two speeds per direction (one cannot tell a viscous slope from a Coulomb level), each crossing the
    middle of the travel: from mid-stroke +6 V, -6 V, +3 V, -3 V."""
    from hexsim.outputs.logio import write_log

    path = _valve_file(tmp_path, levels=(6.0, -6.0, 3.0, -3.0), hold=(0.6, 1.2, 1.4, 1.6))
    run = hexsim.simulate(hexsim.RunConfig(make_scenario(f"valve:{path}"), MACHINE))
    write_log(tmp_path / "open.csv", run)
    machine = hexsim.Machine(system="single-actuator", hydraulics=HYD, effects=LOAD, control="none")
    result = identify_friction(read_log(tmp_path / "open.csv", machine=machine, needs=("pos_m",)))
    assert result.force_source.startswith("A1 p1 - A2 p2")
    for side in ("positive", "negative"):
        assert result.side(side).parameters["F_c0"].value == pytest.approx(F_C, rel=0.03)
    assert len(result.steady) == 4
    for row in result.steady:
        assert abs(row["friction_N"]) == pytest.approx(F_C, rel=0.03)


def test_friction_reads_a_force_only_log_and_names_what_a_log_lacks(tmp_path, capsys):
    """An electric drive's log (time, position, force: no valve, no pressures) is read for what it has."""
    t = np.arange(0, 8, 1e-3)
    pos = 0.1 + 0.05 * np.sin(2 * np.pi * 0.5 * t)
    vel = 0.05 * 2 * np.pi * 0.5 * np.cos(2 * np.pi * 0.5 * t)
    acc = -0.05 * (2 * np.pi * 0.5) ** 2 * np.sin(2 * np.pi * 0.5 * t)
    mass = 5.0
    friction = 300.0 * vel + np.where(vel >= 0, 20.0, 25.0) * (2 / np.pi) * np.arctan(1e3 * vel)
    force = mass * acc + friction  # horizontal
    path = tmp_path / "drive.csv"
    np.savetxt(path, np.column_stack([t, pos, force]), delimiter=",", header="time_s,pos_m,force_N", comments="",
               fmt="%.9g")
    path.with_suffix(".json").write_text(json.dumps({"system": "single-actuator", "sample_rate_hz": 1000.0,
                                                     "mass_kg": mass, "inclination_deg": 90.0}))
    machine = tmp_path / "drive_machine.json"
    assert main(["machine", "set", str(machine), "friction.arctan_gain_spm=1000", "friction.arctan_normalised=true"]) == 0
    assert main(["friction", str(path), "--machine", str(machine), "--json", str(tmp_path / "f.json")]) == 0
    doc = json.loads((tmp_path / "f.json").read_text())
    assert doc["force_source"] == "force_N"
    assert doc["positive"]["parameters"]["sigma"]["value"] == pytest.approx(300.0, rel=0.05)
    assert doc["negative"]["parameters"]["F_c0"]["value"] == pytest.approx(25.0, rel=0.1)
    # the same log without force: one line naming what friction needs
    np.savetxt(path, np.column_stack([t, pos]), delimiter=",", header="time_s,pos_m", comments="", fmt="%.9g")
    capsys.readouterr()
    assert main(["friction", str(path), "--machine", str(machine)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "needs column 'force_N', or 'p1_Pa' and 'ps_Pa'" in err[0] and "the log has pos_m" in err[0]


DATA = __import__("pathlib").Path(__file__).resolve().parents[2] / "examples" / "data" / "servo_cylinder"


def test_real_cylinder_friction_from_paired_runs_matches_the_measured_force():
    """The real servo cylinder (examples/data/servo_cylinder): the Stribeck fit to the paired pA/pB runs at
    1, 3, 5 V gives, at each steady speed, the friction A_A p_A - A_B p_B measured there within 10 %
    (the source's rough figures: 61-69 N extending, 72-80 N retracting)."""
    logs = [[read_log(DATA / f"cyl_{u}V_s1_{s}.csv", machine="servo_cylinder", needs=("pos_m",)) for s in ("pA", "pB")]
            for u in (1, 3, 5)]
    result = identify_friction(logs)
    assert len(result.steady) == 6
    for row in result.steady:
        measured = abs(row["friction_N"])
        assert (55.0 < measured < 70.0) if row["velocity_mps"] > 0 else (70.0 < measured < 82.0), row
        assert row["fitted_N"] == pytest.approx(row["friction_N"], rel=0.10), row
    # the other repeat, which the fit did not see, is predicted as well
    held = [[read_log(DATA / f"cyl_{u}V_s2_{s}.csv", machine="servo_cylinder", needs=("pos_m",)) for s in ("pA", "pB")]
            for u in (1, 3, 5)]
    other = identify_friction(held)
    for row in other.steady:
        fit = result.positive if row["velocity_mps"] > 0 else result.negative
        predicted = float(fit.friction(np.array([row["velocity_mps"]]), hexsim.load_machine("servo_cylinder").hydraulics)[0])
        assert predicted == pytest.approx(row["friction_N"], rel=0.10), row


@pytest.mark.parametrize("run_name, channel", [("cyl_3V_s1_pA", "p1"), ("cyl_3V_s1_pB", "p2")])
def test_real_cylinder_logs_replay_with_their_chamber_pressure_as_a_channel(run_name, channel):
    from hexsim.measured.identify import identify

    log = read_log(DATA / f"{run_name}.csv", machine="servo_cylinder")
    assert log.open_loop and log.machine.hydraulics.four_way
    ident = identify(log, candidates=(), jobs=1)
    before = ident.error_before
    assert set(before) == {"position", channel}
    # the uncalibrated machine file follows the real rig: position within 10 % of its range, pressure within 20 %
    assert before["position"] < 0.1 and before[channel] < 0.2, before


def test_a_real_4_way_log_against_the_builtin_3_way_machine_is_refused_with_one_line(capsys):
    assert main(["validate", str(DATA / "cyl_3V_s1_pA.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "the log's valve is '4-way', machine micro_motion_system (built-in) has a 3-way valve" in err[0]


def test_a_hexapod_runs_on_4_way_valves_and_records_both_chambers():
    hyd = hexsim.HydraulicParams(valve_type="4-way")
    result = hexsim.simulate(hexsim.RunConfig(hexsim.Scenario.sine("heave", duration=6.0, frequency=1.0),
                                              hexsim.Machine(hydraulics=hyd)))
    statics = hydraulics.rest_pressures(np.full(6, 1246.79), hyd)
    assert result.p1[0] == pytest.approx(statics[0], rel=1e-4) and result.p2[0] == pytest.approx(statics[1], rel=1e-4)
    # both chambers move, and the piston's balance P1 A1 - P2 A2 - F_f = F links them: over whole periods
    # it averages the static 1246.79 N (inertia averages out; the asymmetric friction does not, so it is
    # taken off), so P2 follows P1
    assert np.ptp(result.p2[:, 0]) > 1e5
    after = result.t >= 2.0  # the fade-in done; 4 whole periods at 1 Hz
    f = (result.p1[after] * hyd.area_bottom - result.p2[after] * hyd.area_rod
         - hydraulics.friction_force(result.ydot[after], hyd))
    assert f.mean(axis=0) == pytest.approx(np.full(6, 1246.79), rel=0.02)
    assert np.max(np.abs(result.y - result.y_ref)) < 0.01


def test_an_open_loop_hexapod_run_from_six_valve_columns(tmp_path, capsys):
    """valve:PATH with leg1…leg6_valve_cmd_V drives the hexapod open loop (no platform setpoint, no pose
    reference); its log has no setpoint columns and says controller none; validate, whose hexapod replay
    is closed loop, refuses it in one line and says what to run instead."""
    t = np.arange(0, 3, 1e-3)
    u = np.where(t < 0.5, 0.0, np.where(t < 1.5, 0.3, -0.3))
    path = tmp_path / "valves.csv"
    np.savetxt(path, np.column_stack([t] + [u] * 6), delimiter=",", comments="",
               header="time_s," + ",".join(f"leg{i}_valve_cmd_V" for i in range(1, 7)))
    log = tmp_path / "run.csv"
    assert main(["run", f"valve:{path}", "--log", str(log), "--json", str(tmp_path / "report.json")]) == 0
    report = json.loads((tmp_path / "report.json").read_text())
    speeds = [leg["steady"][0]["velocity_mps"] for leg in report["legs"]]
    assert report["open_loop"] and len(speeds) == 6 and min(speeds) > 0.005  # every leg extends at +0.3 V
    header = log.read_text().splitlines()[0]
    assert "leg1_valve_cmd_V" in header and "ref_m" not in header and "dof_ref" not in header
    assert json.loads(log.with_suffix(".json").read_text())["controller"] == {"type": "none"}
    capsys.readouterr()
    assert main(["validate", str(log)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "open-loop hexapod log" in err[0] and "hexsim run valve:" in err[0]


def test_discovery_finds_a_leak_across_one_4_way_legs_piston_on_that_leg(tmp_path):
    """A hexapod on 4-way valves: each leg's cap-side and rod-side flow equations on its own signals (P1 and
    P2 logged). A leak C_l (P2 - P1) across leg 2's piston shows as that leg's leakage term, in both chambers'
    equations with the size of the leak, and on no other leg; the nominal log gives no term on any leg."""
    from hexsim.measured.discovery import discover
    from hexsim.measured.hexapod_replay import HexapodProblem
    from hexsim.outputs.logio import write_log
    from hexsim.plant.effects import LegChange

    hyd, leak = hexsim.HydraulicParams(valve_type="4-way"), 4e-12
    machine = hexsim.Machine(hydraulics=hyd)
    found = {}
    for name, legs in (("nominal", ()), ("leak", (LegChange.of(2, leakage=leak),))):
        result = hexsim.simulate(hexsim.RunConfig(make_scenario("heave", duration=3.0, frequency=1.0), machine, seed=8,
                                                  leg_changes=legs))
        write_log(tmp_path / f"{name}.csv", result, noise=np.random.default_rng(5))
        problem = HexapodProblem(read_log(tmp_path / f"{name}.csv", machine=machine))
        assert "leg2_p2_Pa" in problem.log.columns
        found[name] = discover(problem, problem.nominal, None, None).terms
    assert found["nominal"] == []
    assert {t["leg"] for t in found["leak"]} == {2}, found["leak"]
    leaks = {t["equation"]: t["coefficient"] for t in found["leak"] if t["term"] in ("p2 - p1", "p1 - p2")}
    assert leaks, found["leak"]
    for equation, c_l in leaks.items():
        assert c_l == pytest.approx(leak, rel=0.2), equation
