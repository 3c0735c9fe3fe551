"""A hexapod machine file's ``legs`` section: each leg's own valve, cylinder, oil and friction numbers
(docs/machine-file.md), read, checked, edited by key and used by every run and replay."""

from __future__ import annotations

import json

import numpy as np
import pytest

import hexsim
from hexsim.cli import main
from hexsim.errors import InputError
from hexsim.plant.machine import (
    Machine,
    dump,
    get_key,
    machine_from_document,
    with_keys,
)

LEGS = {"leg3": {"valve": {"edge_gain_PA": 1.05, "edge_gain_AT": 0.97}}, "leg5": {"cylinder": {"leakage_m3psPa": 2e-12}}}


def _doc(legs) -> dict:
    doc = Machine().document()
    doc["legs"] = legs
    return doc


def test_the_legs_section_reads_back_as_leg_changes_and_writes_as_it_was_read():
    machine = machine_from_document(_doc(LEGS))
    assert machine.leg_changes == (hexsim.LegChange.of(3, edge_gain_pa=1.05, edge_gain_at=0.97),
                                   hexsim.LegChange.of(5, leakage=2e-12))
    assert machine.document()["legs"] == LEGS
    assert machine_from_document(json.loads(dump(machine.document()))) == machine
    assert "legs" not in Machine().document()  # a machine without own legs writes no section


@pytest.mark.parametrize("legs, named", [
    ({"leg7": {}}, "legs.leg7"),
    ({"leg2": {"supply": {"pressure_Pa": 6e6}}}, "legs.leg2.supply.pressure_Pa"),  # one supply for the machine
    ({"leg2": {"load": {"payload_kg": 10.0}}}, "legs.leg2.load.payload_kg"),
    ({"leg2": {"valve": {"edge_gain_XY": 1.0}}}, "legs.leg2.valve.edge_gain_XY"),
    ({"leg2": {"valve": {"edge_gain_PA": -0.5}}}, "legs.leg2: valve.edge_gain_PA"),
    ({"leg2": {"valve": {"type": "4-way"}}}, "legs.leg2.valve.type"),
    ({"leg2": 1.0}, "legs.leg2"),
])
def test_a_bad_legs_section_is_one_line_naming_the_leg_and_key(legs, named):
    with pytest.raises(InputError) as err:
        machine_from_document(_doc(legs), "m.json")
    assert str(err.value).startswith("m.json: ") and named in str(err.value) and "\n" not in str(err.value)


def test_a_single_actuator_has_no_legs_section():
    doc = _doc({"leg1": {"valve": {"edge_gain_PA": 1.1}}})
    doc["system"] = "single-actuator"
    doc.pop("hexapod")
    with pytest.raises(InputError, match="single-actuator has no legs of its own"):
        machine_from_document(doc, "m.json")


def test_keys_edit_a_legs_value_and_read_it_back_else_the_shared_one():
    machine = with_keys(Machine(), {"legs.leg4.valve.edge_gain_PA": 0.93, "load.payload_at_m[1]": -0.2})
    doc = machine.document()
    assert machine.leg_changes == (hexsim.LegChange.of(4, edge_gain_pa=0.93),)
    assert machine.effects.payload_at_m == (0.0, -0.2, 0.0)
    assert get_key(doc, "legs.leg4.valve.edge_gain_PA") == 0.93
    assert get_key(doc, "legs.leg2.valve.edge_gain_PA") == 1.0  # not its own: the shared key's
    assert get_key(doc, "load.payload_at_m[1]") == -0.2


def test_a_run_on_a_machine_with_legs_is_the_run_with_those_leg_changes(tmp_path):
    """The section reaches the compiled leg step: the same run, bit for bit, as the LegChange given in Python;
    and a run's own leg change of the same leg goes on top of the file's."""
    machine = machine_from_document(_doc(LEGS))
    scenario = hexsim.Scenario.sine("heave", frequency=3.0, duration=1.0)
    from_file = hexsim.simulate(hexsim.RunConfig.from_machine(machine, scenario, model="platform"))
    in_python = hexsim.simulate(hexsim.RunConfig(scenario, model="platform", leg_changes=machine.leg_changes))
    plain = hexsim.simulate(hexsim.RunConfig(scenario, model="platform"))
    assert np.array_equal(from_file.p1, in_python.p1) and not np.array_equal(from_file.p1, plain.p1)
    both = hexsim.RunConfig.from_machine(machine, scenario, leg_changes=(hexsim.LegChange.of(3, leakage=1e-12),))
    assert dict(both.legs[0].values) == {"edge_gain_pa": 1.05, "edge_gain_at": 0.97, "leakage": 1e-12}


def test_machine_set_edits_a_legs_key_and_refuses_a_shared_one(tmp_path, capsys):
    path = tmp_path / "m.json"
    path.write_text(dump(Machine().document()))
    assert main(["machine", "set", str(path), "legs.leg6.friction.positive.coulomb_N=80"]) == 0
    assert json.loads(path.read_text())["legs"] == {"leg6": {"friction": {"positive": {"coulomb_N": 80}}}}
    capsys.readouterr()
    assert main(["machine", "set", str(path), "legs.leg6.supply.pressure_Pa=6e6"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "legs.leg6.supply.pressure_Pa" in err[0]


def test_which_effects_act_on_one_leg_is_read_off_each_candidate():
    """A library effect may be fitted on one leg alone exactly when it changes no field the legs share:
    each candidate changes something, a leg-level one applied to leg 3 becomes leg 3's own change, and the
    others' fields are refused in a leg's change."""
    from hexsim.errors import InputError
    from hexsim.measured.candidates import (
        CANDIDATES,
        LEG_LEVEL,
        applier,
        changed_values,
        touched_fields,
    )
    from hexsim.measured.replay import PlantModel
    from hexsim.plant.effects import Effects, LegChange
    from hexsim.plant.params import HydraulicParams

    base = PlantModel(HydraulicParams(), Effects())
    assert "leakage" in LEG_LEVEL and "supply_pressure" not in LEG_LEVEL and "payload" not in LEG_LEVEL
    for name, cand in CANDIDATES.items():
        touched = touched_fields(cand)
        assert touched, name
        probe = np.array(cand.lower) + 0.3 * (np.array(cand.upper) - np.array(cand.lower))
        if name in LEG_LEVEL:
            model = applier(cand, 3)(base, probe)
            assert model.hydraulics == base.hydraulics and model.effects == base.effects
            assert [c.leg for c in model.leg_changes] == [3]
        else:
            values = changed_values(base, cand.apply(base, probe))
            with pytest.raises(InputError):
                LegChange.of(3, **values)
