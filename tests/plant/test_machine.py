"""Machine files (hexsim/plant/machine.py, docs/machine-file.md): one file says everything hexsim assumes
about a machine; show → set → read round-trips; every parameter of the plant is reachable from a key;
the built-in Micro Motion System from its file runs the same run to the bit; the docs' key table is the
code's."""

from __future__ import annotations

import dataclasses
import json
import math
import pathlib

import numpy as np
import pytest

import hexsim
from hexsim.cli import main
from hexsim.errors import InputError
from hexsim.plant.effects import Effects
from hexsim.plant.machine import (
    KEYS,
    Machine,
    load_machine,
    read_machine,
    reference_markdown,
)
from hexsim.plant.params import ControllerParams, HydraulicParams

ROOT = pathlib.Path(__file__).resolve().parents[2]


def test_show_set_read_round_trips(tmp_path, capsys):
    path = tmp_path / "rig.json"
    assert main(["machine", "show"]) == 0
    path.write_text(capsys.readouterr().out)
    assert read_machine(path).hydraulics == HydraulicParams()
    assert main(["machine", "set", str(path), "valve.type=4-way", "cylinder.bore_m=0.05", "load.inclination_deg=null",
                 "controller.kp_VPm=150", "name=rig"]) == 0
    assert capsys.readouterr().out.strip() == f"wrote {path}"
    m = read_machine(path)
    assert m.name == "rig" and m.hydraulics.valve_type == "4-way" and m.hydraulics.bore_diameter == 0.05
    assert m.controller.kp == 150.0 and m.effects.inclination_deg is None
    # everything not set is the built-in's
    assert m.hydraulics == HydraulicParams(valve_type="4-way", bore_diameter=0.05)
    assert m.effects == Effects() and m.controller == ControllerParams(kp=150.0)
    # show of the file prints it back, complete
    assert main(["machine", "show", str(path)]) == 0
    assert json.loads(capsys.readouterr().out) == json.loads(path.read_text())


def test_set_refuses_a_bad_value_and_leaves_the_file_as_it_was(tmp_path, capsys):
    path = tmp_path / "rig.json"
    assert main(["machine", "set", str(path), "cylinder.bore_m=0.05"]) == 0  # made from the built-in
    before = path.read_text()
    for bad, said in (("cylinder.rod_m=0.06", "cylinder.rod_m (0.06 m) must be smaller than bore_diameter"),
                      ("cylinder.bore_mm=50", "'cylinder.bore_mm' is not a machine-file key"),
                      ("valve.type=2-way", "valve.type: expected one of 3-way, 4-way, got '2-way'"),
                      ("oil.bulk_modulus_Pa=0", "oil.bulk_modulus_Pa must be a finite positive number, got 0")):
        assert main(["machine", "set", str(path), bad]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and said in err[0], (bad, err)
        assert path.read_text() == before


def test_every_plant_parameter_has_a_key():
    """Nothing hexsim assumes about a machine is left outside the file."""
    targets = {k.target for k in KEYS}
    for section, cls in (("hydraulics", HydraulicParams), ("controller", ControllerParams), ("effects", Effects)):
        missing = [f.name for f in dataclasses.fields(cls) if (section, f.name) not in targets]
        assert not missing, f"{cls.__name__} fields without a machine-file key: {missing}"
    for key in ("valve.type", "cylinder.bore_m", "cylinder.rod_m", "cylinder.stroke_m", "supply.pressure_Pa",
                "load.mass_kg", "load.inclination_deg"):
        assert key in {k.path for k in KEYS}


def test_the_builtin_machine_from_its_file_runs_the_same_run_to_the_bit(tmp_path, capsys):
    path = tmp_path / "mms.json"
    assert main(["machine", "show"]) == 0
    path.write_text(capsys.readouterr().out)
    m = load_machine(path)
    assert (m.hydraulics, m.controller, m.effects) == (HydraulicParams(), ControllerParams(), Effects())
    scenario = hexsim.Scenario.sine("actuator", duration=6.0, frequency=1.0)
    ours = hexsim.simulate(hexsim.RunConfig(scenario, machine=m))
    default = hexsim.simulate(hexsim.RunConfig(scenario))
    for name in ("y", "p1", "p2", "force", "acc", "u_v"):
        assert np.array_equal(getattr(ours, name), getattr(default, name)), name
    assert np.array_equal(default.p2[:, 0], np.full(len(default.t), HydraulicParams().supply_pressure))  # 3-way


def test_rated_flow_sets_the_port_so_full_command_passes_the_rated_flow():
    """A data sheet's Q_N at Δp_N per land: at full command and Δp_N across one edge the valve passes Q_N
    (orifice equation, seed eq. 3.4, written out here)."""
    doc = {**Machine().document(), "valve": {"flow_area": "sharp", "spool_diameter_m": None,
                                             "rated_flow_m3ps": 1.0e-4, "rated_dp_Pa": 3.5e6, "overlap_m": 1e-5}}
    from hexsim.plant.machine import machine_from_document

    hyd = machine_from_document(doc).hydraulics
    opening = math.pi * hyd.spool_diameter * (hyd.x_v_max - hyd.overlap)
    flow = hyd.discharge_coefficient * opening * math.sqrt(2 * 3.5e6 / hyd.density)
    assert flow == pytest.approx(1.0e-4, rel=1e-12)
    from hexsim.plant import hydraulics

    a1, _ = hydraulics.flow_areas(hyd.x_v_max, hyd)
    assert float(hydraulics.edge_flow(a1, 3.5e6, hyd)) == pytest.approx(1.0e-4, rel=1e-5)  # laminar blend: 3e-6
    with pytest.raises(InputError, match="both set"):
        machine_from_document({**doc, "valve": {**doc["valve"], "spool_diameter_m": 0.01}})


def test_builtin_servo_cylinder_is_a_4_way_single_actuator_without_controller():
    m = load_machine("servo_cylinder")
    assert m.system == "single-actuator" and m.hydraulics.valve_type == "4-way" and m.open_loop
    assert (m.hydraulics.bore_diameter, m.hydraulics.rod_diameter, m.hydraulics.stroke) == (0.016, 0.01, 0.2)
    assert all(k in {key.path for key in KEYS} for k, _ in m.sources)


def test_a_single_actuators_stroke_reaches_the_run_the_replay_and_the_scene(tmp_path):
    """``cylinder.stroke_m`` is the slide's travel in every model built from a single actuator's file (a 300 mm
    cylinder): the run's (a 80 mm sine about the new mid-stroke, above 0.2 m), a log replay's batch of slides
    and the rerun scene's. The single actuator's MJCF alone says 0…0.2 m: before, such a run was refused, and
    a log's replay stopped at 0.2 m, at an end stop the machine does not have."""
    from hexsim.engine.config import RunConfig
    from hexsim.engine.runner import Simulator, simulate
    from hexsim.measured.measurement import read_log
    from hexsim.measured.replay import Windows, nominal_plant, replay
    from hexsim.outputs.logio import write_log
    from hexsim.outputs.rerun_log import _scene_model
    from hexsim.plant.machine import with_keys
    from hexsim.plant.model import PlantIndex

    prior = load_machine(None)
    single = dataclasses.replace(prior, system="single-actuator", geometry=type(prior.geometry)(), legs=())
    machine = with_keys(single, {"cylinder.stroke_m": 0.3})
    config = RunConfig.from_machine(machine, hexsim.Scenario.sine("actuator", amplitude=0.08, duration=6.0))
    sim = Simulator(config)
    assert sim.idx.stroke[0].tolist() == [0.0, 0.3] and sim.idx.neutral_y[0] == pytest.approx(0.15)
    result = simulate(config)
    assert result.y[:, 0].max() > 0.22
    assert PlantIndex.from_model(_scene_model(result)).stroke[0].tolist() == [0.0, 0.3]
    log = read_log(write_log(tmp_path / "run.csv", result)[0], machine=machine)
    top = int(np.argmax(log.columns["pos_m"]))
    windows = Windows(np.array([top - 150]), 300)  # a window through the top of the stroke, 0.22 m or more
    out = replay(log, nominal_plant(log), windows)
    measured = windows.take(log.columns["pos_m"])
    assert out["position"].max() > 0.22
    np.testing.assert_allclose(out["position"], measured, atol=2e-4)


#: Keys of a single actuator's file that do not move a model built from the machine below, and why (a model that
#: does not use a key in its setting; every other physical key must move all three: the run, a log's replay and
#: the compensator's leg model).
NOT_REACHED = {
    "valve.rated_dp_Pa": ("run", "replay", "leg"),  # the flow's rating pressure: no rated flow in this file
    "valve.edge_gain_PB": ("run", "replay", "leg"),  # the rod side's edges and volume: a 4-way valve's
    "valve.edge_gain_BT": ("run", "replay", "leg"),
    "cylinder.dead_volume_rod_m3": ("run", "replay", "leg"),
    "oil.cavitation_pressure_Pa": ("run", "replay", "leg"),  # the chamber never falls to it here
    "cylinder.stroke_m": ("replay", "leg"),  # the log's motion stays in mid-stroke; V = A1 r + V_pl
    "supply.pressure_Pa": ("replay",),  # a log that carries ps_Pa replays at its own supply level
    # the leg model is the static inverse (seed eq. 5.1, its leak included): no spool dynamics, air or supply sag
    "valve.spool_frequency_Hz": ("leg",), "valve.spool_damping": ("leg",), "valve.spool_play_V": ("leg",),
    "oil.air_fraction": ("leg",), "oil.air_exponent": ("leg",),
    "supply.resistance_Pa_s_per_m3": ("leg",), "supply.time_constant_s": ("leg",),
}


def test_every_physical_key_of_a_single_actuator_reaches_the_run_the_replay_and_the_leg_model(tmp_path):
    """Each number of a single actuator's valve, cylinder, oil, supply, friction and load sections, moved by
    10 % (or from zero), changes the run (position, P1, acceleration), a log's replay (the calibration's residual)
    and the compensator's leg model (its curve, rest pressure, friction, inertia, oil), on a machine whose effects
    are switched on so that each key has something to act on; the exceptions are :data:`NOT_REACHED`, each with
    its reason. A key that reached no model was how the mass and the stroke went missing before."""
    from hexsim.engine.config import RunConfig
    from hexsim.engine.runner import simulate
    from hexsim.measured.dynamics import ReplayEvidence
    from hexsim.measured.measurement import read_log
    from hexsim.outputs.logio import write_log
    from hexsim.plant.machine import get_key, with_keys
    from hexsim.studies.tuning import leg_model_of

    prior = load_machine(None)
    single = dataclasses.replace(prior, system="single-actuator", geometry=type(prior.geometry)(), legs=())
    base = with_keys(single, {"valve.spool_frequency_Hz": 80.0, "valve.spool_play_V": 0.01, "oil.air_fraction": 0.002,
                              "oil.air_exponent": 1.2, "supply.resistance_Pa_s_per_m3": 2e9,
                              "cylinder.leakage_m3psPa": 1e-13, "load.inclination_deg": 10.0, "load.mass_kg": 40.0})

    def run(m):
        r = simulate(RunConfig.from_machine(m, hexsim.Scenario.sine("actuator", duration=6.0)))
        return [r.y, r.p1, r.acc]

    fields = ("u", "velocity", "p_rest", "friction_f", "mass", "slope", "bulk_modulus", "pipeline_volume",
              "area_bottom", "supply_pressure", "tank_pressure")

    def leg(m):
        model = leg_model_of(RunConfig.from_machine(m, "actuator"))
        return [np.atleast_1d(np.asarray(getattr(model, f), dtype=float)) for f in fields]

    log = read_log(write_log(tmp_path / "run.csv", simulate(RunConfig.from_machine(
        base, hexsim.Scenario.sine("actuator", duration=6.0))))[0], machine=base)
    replay = ReplayEvidence.of(log, base)
    models = {"run": run, "replay": lambda m: [replay.residual(m)], "leg": leg}
    before = {name: make(base) for name, make in models.items()}

    def moved(a, b):
        return any(x.shape != y.shape or np.max(np.abs(x - y)) > 1e-12 * max(np.max(np.abs(y)), 1e-30)
                   for x, y in zip(a, b))

    doc, checked, wrong = base.document(), 0, []
    for key in KEYS:
        if key.path.split(".")[0] not in ("valve", "cylinder", "oil", "supply", "friction", "load") or \
                key.kind != "number" or key.path == "load.payload_kg":  # the payload is the hexapod's
            continue
        value = get_key(doc, key.path)
        if value is None:
            continue
        changed = with_keys(base, {key.path: (0.05 if "null" in key.path else 1e5) if value == 0 else
                                   1.1 * value if key.path != "oil.air_exponent" else 1.0})
        checked += 1
        for name, make in models.items():
            if moved(make(changed), before[name]) == (name in NOT_REACHED.get(key.path, ())):
                wrong.append(f"{key.path}: {name} {'moved' if name in NOT_REACHED.get(key.path, ()) else 'unmoved'}")
    assert checked >= 35 and not wrong, wrong


def test_unknown_machine_name_lists_the_builtins():
    with pytest.raises(InputError, match="built-in machines: large_motion_base, micro_motion_system, servo_cylinder"):
        load_machine("no_such_rig")


def test_docs_list_every_key_as_the_code_declares_it():
    doc = (ROOT / "docs" / "machine-file.md").read_text()
    assert reference_markdown() in doc, "docs/machine-file.md: regenerate the key table (hexsim.plant.machine.reference_markdown)"


def test_a_sweep_varies_the_machine(tmp_path, capsys):
    rig = tmp_path / "four_way.json"
    assert main(["machine", "set", str(rig), "valve.type=4-way"]) == 0
    out = tmp_path / "sweep.json"
    assert main(["sweep", "actuator", "--duration", "6", "--frequency", "1", "--jobs", "1", "--quiet",
                 "--grid", f"machine=micro_motion_system,{rig}", "--json", str(out)]) == 0
    rows = json.loads(out.read_text())["rows"]
    assert [r["machine"] for r in rows] == ["micro_motion_system", str(rig)]
    assert rows[0]["max_tracking_error_mm"] != rows[1]["max_tracking_error_mm"]  # the 4-way valve is another plant
