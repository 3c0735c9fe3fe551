"""Calibration of a machine's nominal from calibration experiments (hexsim/measured/calibration.py,
``hexsim calibrate``): recovery on logs of a cylinder written independently of hexsim
(tests/independent_cylinder.py) whose nominal departs from the machine file within data-sheet tolerances,
with different parameters moved; what the logs cannot separate is held and named; a bound is reported;
the real servo cylinder's held-out repeats are predicted."""

from __future__ import annotations

import json
import pathlib

import numpy as np
import pytest
from independent_cylinder import Rig, experiment

from hexsim.cli import main
from hexsim.measured.calibration import calibrate
from hexsim.measured.discovery import apply_terms, equation_errors, equation_terms
from hexsim.measured.measurement import read_log
from hexsim.measured.parameters import default_parameters
from hexsim.measured.replay import nominal_plant
from hexsim.measured.scoring import Problem
from hexsim.measured.steady import features
from hexsim.measured.validation import validate
from hexsim.plant.machine import load_machine, read_machine

DATA = pathlib.Path(__file__).resolve().parents[2] / "examples" / "data" / "servo_cylinder"
NOMINAL = load_machine("servo_cylinder")  # the user's machine file: the source's geometry, guessed valve

#: Machines whose nominal departs from the file within data-sheet tolerances, each moving other parameters.
TRUTHS = {
    "valve, edges, supply, tank, friction": Rig(rated_flow=1.18e-4, overlap=2.2e-5, k_pb=0.9, k_at=1.05,
                                                supply=42e5, tank=0.8e5, coulomb_pos=80.0, coulomb_neg=60.0),
    "supply and friction only": Rig(supply=46.5e5, coulomb_pos=50.0, coulomb_neg=95.0),
    "an underlapped valve with a null offset, a weak B->T edge": Rig(overlap=-1.5e-5, null_offset=0.12, k_bt=0.88,
                                                                    rated_flow=0.95e-4, tank=1.5e5),
}
#: How close each recovered key must come to the truth (the two models differ in their laminar ranges).
TOLERANCE = {"valve.rated_flow_m3ps": 0.01e-4, "valve.overlap_m": 1.5e-6, "valve.null_offset_V": 0.02,
             "valve.edge_gain_AT": 0.015, "valve.edge_gain_PB": 0.015, "valve.edge_gain_BT": 0.015,
             "supply.pressure_Pa": 0.2e5, "supply.tank_pressure_Pa": 0.15e5, "friction.positive.coulomb_N": 2.5,
             "friction.negative.coulomb_N": 2.5}


def _truth_values(rig: Rig) -> dict[str, float]:
    return {"valve.rated_flow_m3ps": rig.rated_flow, "valve.overlap_m": rig.overlap,
            "valve.null_offset_V": rig.null_offset, "valve.edge_gain_AT": rig.k_at, "valve.edge_gain_PB": rig.k_pb,
            "valve.edge_gain_BT": rig.k_bt, "supply.pressure_Pa": rig.supply, "supply.tank_pressure_Pa": rig.tank,
            "friction.positive.coulomb_N": rig.coulomb_pos, "friction.negative.coulomb_N": rig.coulomb_neg}


def _logs(rig: Rig, folder: pathlib.Path, volts, seed: int = 3):
    rng = np.random.default_rng(seed)
    return [read_log(experiment(rig, v, folder, f"run_{v:g}V", rng), machine=NOMINAL) for v in volts]


@pytest.mark.parametrize("case", list(TRUTHS))
def test_calibration_recovers_a_machine_off_its_file_and_predicts_held_out_commands(case, tmp_path):
    truth = TRUTHS[case]
    fit = _logs(truth, tmp_path, (2.0, 4.0, 7.0))
    held = _logs(truth, tmp_path, (3.0, 5.5), seed=4)
    result = calibrate(fit, NOMINAL, held_out=held, cross_validate=False)
    calibrated, report = result.machine, result.report
    rows = {r["key"]: r for r in report["parameters"]}
    for key, value in _truth_values(truth).items():
        assert rows[key]["status"] == ("at its physical limit" if key == "supply.tank_pressure_Pa" and value == 0
                                       else "fitted"), rows[key]
        assert rows[key]["value"] == pytest.approx(value, abs=TOLERANCE[key]), key
    before, after = report["held_out"]["before"], report["held_out"]["after"]
    assert after["speed_error_max"] < 0.01 and after["pressure_error_max_Pa"] < 0.2e5, after
    assert before["speed_error_max"] > 3 * after["speed_error_max"] or before["pressure_error_max_Pa"] > 3 * after[
        "pressure_error_max_Pa"]
    # the output is a machine file: the fitted values in place, the calibration's provenance with it
    assert calibrated.calibration["logs"] == [str(log.path) for log in fit]
    assert calibrated.hydraulics.supply_pressure == pytest.approx(rows["supply.pressure_Pa"]["value"])


#: Effects added to the first machine of TRUTHS after its calibration experiments: (the truth's change, the
#: effect hexsim must name, its parameter and the value it must come back at, absolute tolerance).
EFFECTS = {
    "null": ({}, None, None, None, None),
    "leakage": ({"leakage": 3e-12}, "leakage", "C_l", 3.0, 0.3),  # [1e-12 m^3/(s Pa)]
    "cold seals": ({"coulomb_pos": 130.0, "coulomb_neg": 100.0}, "friction", "k_c", 1.65, 0.08),  # 130/80, 100/60
    "worn return edge": ({"k_at": 0.84}, "edge_asymmetry", "k_AT", 0.84, 0.03),
    "worn rod-side return edge": ({"k_bt": 0.84}, "edge_asymmetry_B", "k_BT", 0.84, 0.03),
    "null drift": ({"null_offset": 0.15}, "null_offset", "u_0", 0.15, 0.03),
}


@pytest.fixture(scope="module")
def calibrated_rig(tmp_path_factory):
    """The first machine of TRUTHS calibrated on its experiments at 2, 4 and 7 V (steady features)."""
    truth = TRUTHS["valve, edges, supply, tank, friction"]
    folder = tmp_path_factory.mktemp("rig")
    result = calibrate(_logs(truth, folder, (2.0, 4.0, 7.0)), NOMINAL, cross_validate=False)
    calibrated, report = result.machine, result.report
    return truth, calibrated, report, folder


@pytest.mark.parametrize("case", list(EFFECTS))
def test_calibrate_then_validate_names_the_effect_on_a_4_way_machine_off_its_file(calibrated_rig, case):
    """Calibrated on steady experiments, then judged on a run at 1 V, then 3 V, of the same machine with an effect
    added (or none): the null is ``none``, each effect is named at its value (at one command a null offset
    and the edges' asymmetry change the two directions' speeds alike; two commands tell them apart). The windows
    at the end stops are left out of the replay; the calibrated model's misfit on its own logs' windows enters the
    budget."""
    truth, calibrated, report, folder = calibrated_rig
    assert [r["log"].endswith(".csv") for r in report["replayed"]] == [True] * 3
    change, name, parameter, value, tol = EFFECTS[case]
    rng = np.random.default_rng(5)
    log = read_log(experiment(truth.replace(**change), (1.0, 3.0), folder, f"validate_{case.replace(' ', '_')}", rng),
                   machine=calibrated)
    doc = validate(log, jobs=2)
    assert doc["windows"]["left_out"]["end_stops"] > 0
    if name is None:
        assert doc["verdict"] == "none", doc["held_out_rms_in_budgets"]
        return
    assert doc["verdict"] == "explained", (doc["held_out_rms_in_budgets"], doc["conclusions"])
    assert [e["name"] for e in doc["added_effects"]] == [name]
    assert doc["added_effects"][0]["parameters"][parameter]["value"] == pytest.approx(value, abs=tol)


#: Effects out of the library (validate --without them): the truth's change and the discovery's terms with their
#: values (relative to the calibrated file's edge gain for an edge) and absolute tolerances.
DISCOVERED = {
    "null": ({}, {}),
    "leakage": ({"leakage": 3e-12}, {"flow:p2 - p1": (3e-12, 0.3e-12), "flow_rod:p1 - p2": (3e-12, 0.3e-12)}),
    "weak B->T edge": ({"k_bt": 0.8}, {"flow_rod:phi_BT": (0.8, 0.03)}),
}


@pytest.mark.parametrize("case", list(DISCOVERED))
def test_the_discovery_reads_a_4_way_cylinders_leak_and_edge_in_the_chambers_they_touch(calibrated_rig, case):
    """Both chambers' flow equations on the calibrated model: a leak across the piston appears in each at its
    C_l, a weak B→T edge in the rod side's only, a null has no term; with 0.3 mm of position noise the
    areas' terms are not asked (they would fit that noise with the equation's own terms at -1). What is
    found maps onto the model: one C_l for the two sides' leak terms, the edge's gain scaled."""
    truth, calibrated, _, folder = calibrated_rig
    change, expected = DISCOVERED[case]
    log = read_log(experiment(truth.replace(**change), (1.0, 3.0), folder, f"discover_{case.replace(' ', '_')}",
                              np.random.default_rng(6)), machine=calibrated)
    base = nominal_plant(log)
    if "k_bt" in change:  # the discovery's coefficient is relative to the model's edge: (1 + c) k_BT,cal
        expected = {"flow_rod:phi_BT": (change["k_bt"] / base.effects.edge_gain_bt - 1.0, 0.03)}
    terms, found, far, not_asked = equation_terms(Problem(log), equation_errors(log, base))
    assert not far and set(not_asked) == {"flow:A1 ydot", "flow_rod:A2 ydot"}
    assert set(found) == set(expected), terms
    for key, (value, tol) in expected.items():
        assert found[key] == pytest.approx(value, abs=tol), key
    model, applied = apply_terms(base, found)
    assert set(applied) == set(found)
    if "leakage" in change:
        assert model.effects.leakage == pytest.approx(found["flow:p2 - p1"])
    if "k_bt" in change:
        assert model.effects.edge_gain_bt == pytest.approx(change["k_bt"], abs=0.03)


def test_what_one_command_cannot_separate_is_held_at_its_prior_with_the_experiment_that_would(tmp_path):
    """At one command the speed fixes the opening w (x_v - O_l), not the flow gain and the overlap apart."""
    truth = TRUTHS["valve, edges, supply, tank, friction"]
    report = calibrate(_logs(truth, tmp_path, (4.0,)), NOMINAL, cross_validate=False).report
    held = {r["key"]: r for r in report["parameters"] if r["status"] == "held at its prior"}
    assert held, report["parameters"]
    assert {"valve.overlap_m", "valve.rated_flow_m3ps", "valve.null_offset_V"} & set(held)
    for row in held.values():
        assert row["value"] == pytest.approx(row["prior"]) and row["why"] and row["experiment"]


def test_a_fit_at_a_bound_is_reported_as_a_hint(tmp_path):
    truth = Rig(supply=36e5)  # 20 % under the file's 44.5 bar: outside the ±10 % bracket
    report = calibrate(_logs(truth, tmp_path, (2.0, 5.0)), NOMINAL, cross_validate=False).report
    row = next(r for r in report["parameters"] if r["key"] == "supply.pressure_Pa")
    assert row["status"] == "at a bound" and row["value"] == pytest.approx(0.9 * 44.5e5) and "lacks" in row["why"]


def test_default_parameters_know_their_key_unit_bounds_and_source():
    params = default_parameters(NOMINAL)
    keys = [p.key for p in params]
    assert "valve.edge_gain_PB" in keys and "valve.edge_gain_BT" in keys  # 4-way
    assert "valve.edge_gain_PB" not in [p.key for p in default_parameters(load_machine(None))]  # 3-way
    for p in params:
        assert p.lower < p.upper and p.unit and p.source and p.experiment


def test_a_log_too_short_for_either_kind_of_evidence_is_refused(tmp_path, capsys):
    """A closed-loop log is evidence from its transients (tests/measured/test_calibration_transients.py); one
    shorter than four replay windows is neither a constant-command experiment nor that: one line, no file."""
    assert main(["run", "actuator", "--duration", "3", "--frequency", "1", "--log", str(tmp_path / "sine.csv")]) == 0
    capsys.readouterr()
    rows = (tmp_path / "sine.csv").read_text().splitlines()
    (tmp_path / "sine.csv").write_text("\n".join(rows[:901]) + "\n")  # 0.9 s: three 0.3 s windows
    assert main(["calibrate", str(tmp_path / "sine.csv"), "--out", str(tmp_path / "cal.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "shorter than four replay windows" in err[0]
    assert not (tmp_path / "cal.json").exists()


def test_real_cylinder_calibrated_on_one_repeat_predicts_the_other(tmp_path, capsys):
    """examples/data/servo_cylinder: fit the s1 runs (1, 3, 5 V, pA and pB), predict the s2 repeats.
    Measured (docs/calibration.md): held-out speed 5.1 % -> 2.1 % mean, pressure 1.16 -> 0.22 bar mean,
    0.60 bar worst; the pA and pB runs of one experiment themselves differ by 1-3 % in speed."""
    fit = sorted(str(p) for p in DATA.glob("cyl_*V_s1_p*.csv"))
    held = sorted(str(p) for p in DATA.glob("cyl_*V_s2_p*.csv"))
    out, rep = tmp_path / "cal.json", tmp_path / "report.json"
    assert main(["calibrate", *fit, "--machine", "servo_cylinder", "--hold-out", *held, "--out", str(out),
                 "--json", str(rep), "--no-cross-validation", "--report", str(tmp_path / "report")]) == 0
    report = json.loads(rep.read_text())
    md = (tmp_path / "report" / "report.md").read_text()
    assert "| `valve.edge_gain_PB` |" in md and "held-out logs" in md
    assert (tmp_path / "report" / "features.png").read_bytes()[:4] == b"\x89PNG"
    before, after = report["held_out"]["before"], report["held_out"]["after"]
    assert after["pressure_error_max_Pa"] < 1e5 and after["speed_error_mean"] < 0.03
    assert after["speed_error_mean"] < 0.5 * before["speed_error_mean"]
    assert after["pressure_error_mean_Pa"] < 0.5 * before["pressure_error_mean_Pa"]
    m = read_machine(out)
    assert m.calibration is not None and m.hydraulics.tank_pressure > 0.5e5  # the rig's return line back pressure
    capsys.readouterr()
    assert main(["machine", "show", str(out)]) == 0  # a calibrated file is a machine file like any other
    assert json.loads(capsys.readouterr().out)["calibration"]["logs"] == fit
    # a held-out repeat judged on the calibrated file: nothing beyond what the calibration left; the windows
    # at the stops and where the position transducer reads the end of its range (10 V) are left out
    assert main(["validate", held[2], "--machine", str(out), "--json", str(tmp_path / "v.json")]) == 0
    doc = json.loads((tmp_path / "v.json").read_text())
    assert doc["verdict"] == "none", doc["held_out_rms_in_budgets"]
    assert doc["windows"]["left_out"]["end_stops"] > 10 and doc["windows"]["count"] >= 4
    assert doc["windows"]["left_out"]["clipped_columns"]["pos_m"]["value"] == pytest.approx(0.2, abs=1e-4)
    assert "left out: " in capsys.readouterr().out


def test_features_of_a_real_run_are_its_steady_motions_and_end_stop_plateaus():
    f = features(read_log(DATA / "cyl_3V_s1_pA.csv", machine=NOMINAL))
    steady = [x for x in f if x.kind == "steady" and x.quantity == "velocity"]
    stops = [x for x in f if x.kind == "end stop"]
    assert [round(x.measured * 1e3) for x in steady] == [154, -110]  # the README of the data: 155 / 110 mm/s
    assert {round(x.u_V) for x in stops} == {3, -3}
    assert any(x.measured > 43e5 for x in stops)  # the cap side reads the supply at the extended stop


def test_validate_says_calibrate_first_when_the_nominal_is_visibly_off_a_constant_command_log():
    from hexsim.measured.advice import nominal_check

    log = read_log(DATA / "cyl_1V_s2_pB.csv", machine=NOMINAL)
    check = nominal_check(log)
    assert check.off and check.figures["speed_error_max"] > 0.1
    assert "calibrate first" in check.sentence and "valve.edge_gain_PB" in check.sentence
    assert "supply.tank_pressure_Pa 0 → " in check.sentence
    assert check.as_dict()["sentence"] == check.sentence and check.as_dict()["moved"] == list(check.moved)
    calibrated = calibrate([read_log(p, machine=NOMINAL) for p in sorted(DATA.glob("cyl_*V_s1_p*.csv"))], NOMINAL,
                           cross_validate=False).machine
    assert nominal_check(read_log(DATA / "cyl_1V_s2_pB.csv", machine=calibrated)) is None  # calibrated: judged as is


def test_a_valve_curve_as_a_table_is_calibrated_point_by_point_and_predicts_between_them(tmp_path):
    """A progressive valve (the independent plant's own curve): with flow_area "table" the openings at the
    commands of the experiments are fitted, the point beyond every command is held and named, and runs at
    commands between the points are predicted."""
    curve = ((2.0, 0.15), (4.0, 0.36), (7.0, 0.72), (10.0, 1.0))
    truth = Rig(curve=curve, overlap=0.0, k_pb=0.92, supply=43e5, tank=0.5e5)
    doc = NOMINAL.document()
    doc["valve"].update(flow_area="table", overlap_m=0.0, opening_table=[[2.0, 0.2], [4.0, 0.4], [7.0, 0.7], [10.0, 1.0]])
    from hexsim.plant.machine import machine_from_document

    table_machine = machine_from_document(doc)
    fit = [read_log(experiment(truth, v, tmp_path, f"run_{v:g}V", np.random.default_rng(5)), machine=table_machine)
           for v in (2.0, 4.0, 7.0)]
    held = [read_log(experiment(truth, v, tmp_path, f"held_{v:g}V", np.random.default_rng(6)), machine=table_machine)
            for v in (3.0, 5.5)]
    result = calibrate(fit, table_machine, held_out=held, cross_validate=False)
    calibrated, report = result.machine, result.report
    rows = {r["key"]: r for r in report["parameters"]}
    for i, (_, f) in enumerate(curve[:3]):
        assert rows[f"valve.opening_table[{i}]"]["value"] == pytest.approx(f, abs=0.004)
    assert rows["valve.opening_table[3]"]["status"] == "held at its prior"  # no command beyond 7 V
    assert "10 V" in rows["valve.opening_table[3]"]["experiment"]
    after = report["held_out"]["after"]
    assert after["speed_error_max"] < 0.015 and after["pressure_error_max_Pa"] < 0.2e5, after
    assert [list(p) for p in calibrated.hydraulics.opening_table][3] == [10.0, 1.0]


def test_a_3_way_vertical_leg_calibrates_and_names_the_weight_friction_trade(tmp_path):
    """The seed's 3-way leg, vertical, its mass null in the file (the model's 40 kg): the supply is found
    from the end stops; at constant speeds the weight and the Coulomb levels trade (extending M g + F_c+,
    retracting M g - F_c-), which the report names instead of returning three numbers. (hexsim's own logs:
    this checks the 3-way path, not a recovery from an independent plant.)"""
    import hexsim
    from hexsim.control.scenario import make_scenario
    from hexsim.outputs.logio import write_log

    truth = hexsim.HydraulicParams(supply_pressure=66e5, coulomb_pos=80.0, coulomb_neg=50.0)
    logs = []
    for volts in (0.5, 1.0, 2.0):
        t = np.arange(0, 4.0, 1e-3)
        u = np.where(t < 0.1, 0.0, np.where(t < 1.6, volts, -volts))
        valve = tmp_path / f"u{volts:g}.csv"
        np.savetxt(valve, np.column_stack([t, u]), delimiter=",", header="time_s,valve_cmd_V", comments="")
        run = hexsim.simulate(hexsim.RunConfig(make_scenario(f"valve:{valve}"), hexsim.Machine(hydraulics=truth)))
        write_log(tmp_path / f"log{volts:g}.csv", run, noise=np.random.default_rng(1))
        logs.append(read_log(tmp_path / f"log{volts:g}.csv"))
    report = calibrate(logs, load_machine(None), cross_validate=False).report
    rows = {r["key"]: r for r in report["parameters"]}
    assert rows["load.mass_kg"]["prior"] == pytest.approx(40.0)
    assert rows["supply.pressure_Pa"]["value"] == pytest.approx(66e5, abs=0.1e5)
    traded = [r for r in rows.values() if r["status"] == "held at its prior" and "load.mass_kg" in r.get("why", "")
              or r["key"] == "load.mass_kg" and r["status"] == "held at its prior"]
    assert traded, rows
    assert report["fit"]["after"]["pressure_error_max_Pa"] < 0.1e5


def test_a_calibration_worse_than_its_prior_on_its_own_logs_writes_nothing(tmp_path, monkeypatch, capsys):
    """The own-budget check worked by hand: held-out position 2.05 budgets with the prior, 4.12 calibrated, is worse
    than the prior (more than 1.1 times, and beyond the budget's sqrt 2); p1 3.0 -> 3.1 is not (within 1.1 times).
    ``hexsim calibrate`` then writes nothing, names the channel, exits 2; ``--keep-worse`` writes it."""
    from hexsim.measured import calibration
    from hexsim.measured.dynamics import own_budget
    from hexsim.measured.reports import calibration as reports

    own = own_budget({"transients": [
        {"before": {"held_out_rms_in_budgets": {"position": 2.05, "p1": 3.0}},
         "after": {"held_out_rms_in_budgets": {"position": 4.12, "p1": 3.1}}}]})
    assert own["worse_than_prior"] == {"position": [2.05, 4.12]} and not own["reached"]
    # per log: the steps log 19 -> 29 budgets in p1 is worse than its prior though another log's prior missed by more
    # (the 4-way axis calibrated on three logs)
    three = own_budget({"transients": [
        {"before": {"held_out_rms_in_budgets": {"p1": 19.0}},
         "after": {"log": "logs/cal_steps.csv", "held_out_rms_in_budgets": {"p1": 29.1}}},
        {"before": {"held_out_rms_in_budgets": {"p1": 37.7}},
         "after": {"log": "logs/null.csv", "held_out_rms_in_budgets": {"p1": 5.5}}}]})
    assert three["worse_than_prior"] == {"p1": [19.0, 29.1]} and three["worse_than_prior_on"] == {"p1": "cal_steps.csv"}
    monkeypatch.setattr(calibration, "calibrate",
                        lambda logs, machine, **_: calibration.Calibration(machine, {"own_budget": own}))
    monkeypatch.setattr(reports, "table", lambda report: "")
    log = str(pathlib.Path(__file__).parents[2] / "examples" / "data" / "servo_cylinder" / "cyl_1V_s1_pA.csv")
    out = tmp_path / "cal.json"
    assert main(["calibrate", log, "--machine", "servo_cylinder", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "position 2.05 → 4.12 budgets" in err and "nothing written" in err and not out.exists()
    assert main(["calibrate", log, "--machine", "servo_cylinder", "--out", str(out), "--keep-worse"]) == 0
    assert out.exists()
