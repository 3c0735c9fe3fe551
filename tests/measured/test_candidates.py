"""The effect library's declarations (hexsim/measured/candidates.py), on small stand-in logs: what each
candidate declares is what the identifier reads (systems, narrowed ranges, resolution floors), and every
parameter an effect changes can be written to a machine file."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from hexsim.errors import InputError
from hexsim.measured.candidates import (
    CANDIDATE_NAMES,
    CANDIDATES,
    EFFECT_NAMES,
    RELIEF_MARGIN_BAR,
    candidates_for,
    plausibility,
    plausible_bounds,
    resolution_floor,
    touched_fields,
)
from hexsim.measured.replay import PlantModel
from hexsim.plant.effects import Effects
from hexsim.plant.machine_keys import KEYS
from hexsim.plant.params import HydraulicParams


def stand_in_log(sample_rate_hz: float, **columns: np.ndarray) -> SimpleNamespace:
    """What the bounds read of a log: its sample rate and its columns."""
    return SimpleNamespace(sample_rate_hz=sample_rate_hz, columns=columns)


def test_each_system_gets_the_candidates_that_declare_it():
    actuator, hexapod = candidates_for("single-actuator"), candidates_for("hexapod")
    assert "load" in actuator and "load" not in hexapod  # mass and inclination of one axis
    assert "payload" in hexapod and "payload" not in actuator
    assert set(actuator) | set(hexapod) == set(CANDIDATE_NAMES) == set(CANDIDATES)
    # the rod side's edges are a 4-way valve's: the seed's 3-way actuator (EFFECT_NAMES) has none
    assert "edge_asymmetry_B" in candidates_for("single-actuator", "4-way")
    assert "edge_asymmetry_B" in candidates_for("hexapod", "4-way")
    assert "edge_asymmetry_B" not in candidates_for("single-actuator", "3-way")
    assert EFFECT_NAMES == tuple(n for n in actuator if n != "edge_asymmetry_B")
    assert list(hexapod) == [n for n in CANDIDATE_NAMES if n in hexapod]  # the declared order, kept
    with pytest.raises(InputError, match="unknown system 'crane'"):
        candidates_for("crane")


def test_every_field_an_effect_changes_is_a_machine_file_key():
    """A named or calibrated effect is written into a machine file: each field it changes needs its key."""
    keyed = {k.target[1] for k in KEYS if k.target[0] in ("hydraulics", "effects")}
    for name, cand in CANDIDATES.items():
        changed = touched_fields(cand)
        assert changed, f"{name} changes nothing"
        assert changed <= keyed, f"{name}: {sorted(changed - keyed)} have no machine-file key"


def test_a_slow_log_narrows_the_spool_frequency_and_floors_the_delay():
    spool, delay = CANDIDATES["spool_dynamics"], CANDIDATES["sensor_delay"]
    slow, fast = stand_in_log(200.0), stand_in_log(2000.0)
    assert plausible_bounds(spool, slow)[1][0] == 100.0  # half the sample rate
    assert plausible_bounds(spool, fast)[1][0] == spool.upper[0]  # the plausible range
    assert resolution_floor(delay, slow) == {"tau_y": 5.0}  # one sample period, ms
    assert resolution_floor(spool, slow) == {}
    problems = plausibility(delay, slow, np.array([3.0]), np.array([0.1]))
    assert problems and "finer than the log resolves" in problems[0]
    assert not plausibility(delay, slow, np.array([8.0]), np.array([0.1]))


def test_the_supply_set_pressure_is_bounded_by_the_logged_supply_and_the_declaration_is_not_changed():
    supply = CANDIDATES["supply_pressure"]
    declared = (supply.lower, supply.upper)
    ps = np.linspace(66e5, 70e5, 101)
    lower, upper = plausible_bounds(supply, stand_in_log(1000.0, ps_Pa=ps))
    assert lower[2] == pytest.approx(np.quantile(ps, 0.01) / 1e5 - 0.5)
    assert upper[2] == pytest.approx(np.quantile(ps, 0.99) / 1e5 + RELIEF_MARGIN_BAR)
    assert (lower[:2] == supply.lower[:2]).all() and (upper[:2] == supply.upper[:2]).all()
    assert (supply.lower, supply.upper) == declared
    lower, upper = plausible_bounds(supply, stand_in_log(1000.0))  # no supply logged: the plausible range
    assert tuple(lower) == supply.lower and tuple(upper) == supply.upper


def test_a_range_spanning_decades_has_its_edge_on_the_logarithm():
    """The supply's time constant (1 ms-1 s): R1's accumulator, 5.0 ± 0.02 ms, is a finding, not "at a bound" (the
    range's width put the edge at 11 ms); 1.05 ms is at the bound. A range within a decade or two keeps its edge on
    the width (the spool's 5-300 Hz: 7 Hz is at the bound)."""
    log = stand_in_log(1000.0, ps_Pa=np.linspace(66e5, 70e5, 101))
    supply, spool = CANDIDATES["supply_pressure"], CANDIDATES["spool_dynamics"]
    se = np.array([1e-4, 0.02, 0.01])
    assert not plausibility(supply, log, np.array([0.6, 5.0, 68.9]), se)
    (problem,) = plausibility(supply, log, np.array([0.6, 1.05, 68.9]), se)
    assert problem.startswith("tau_s = 1.05 ms at a bound")
    (problem,) = plausibility(spool, log, np.array([7.0, 0.7]), np.array([0.1, 0.01]))
    assert problem.startswith("f_v = 7 Hz at a bound")


def test_a_payload_change_adds_to_the_machines_payload_with_its_weight_and_moments_exact():
    """On a calibrated machine (51 kg at c_0), m_p = 0 is that machine, and 90 kg added at c_p gives one
    payload whose mass and first moment are the sum of the two (the weight and its moments on the legs)."""
    payload = CANDIDATES["payload"]
    c0, cp = np.array([0.155, -0.104, 0.279]), np.array([0.015, -0.009, 0.205])
    model = PlantModel(HydraulicParams(), Effects(payload_kg=51.0, payload_at_m=tuple(c0)))
    same = payload.apply(model, np.array([0.0, *cp]))
    assert same.effects.payload_kg == 51.0 and np.allclose(same.effects.payload_at_m, c0)
    both = payload.apply(model, np.array([90.0, *cp])).effects
    assert both.payload_kg == pytest.approx(141.0)
    assert np.allclose(both.payload_kg * np.array(both.payload_at_m), 51.0 * c0 + 90.0 * cp)
    off = payload.apply(model, np.array([-51.0, *c0])).effects  # the payload taken off
    assert off.payload_kg == pytest.approx(0.0, abs=1e-12)
    bare = PlantModel(HydraulicParams(), Effects())  # no payload in the file: the change is the payload
    assert payload.apply(bare, np.array([90.0, *cp])).effects.payload_at_m == pytest.approx(tuple(cp))
