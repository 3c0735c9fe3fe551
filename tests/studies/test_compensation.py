"""The seed's chapter-5 findings and the compensation targets, reproduced in simulation.

Runs go through hexsim.studies.comparison (two worker processes), which measures on the last quarter of each run.
Margins: the seed's figures are qualitative, so the tests check directions and ratios with room for the
run-to-run spread seen between seeds (about ±15 % on the final reversal peaks).
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import write_heave_pitch_profile

from compensation import CompensatorSettings
from hexsim.control.scenario import make_scenario
from hexsim.engine.config import RunConfig
from hexsim.plant.machine import Machine
from hexsim.plant.params import HydraulicParams
from hexsim.plant.temperature import WarmUp
from hexsim.studies.comparison import compare


def _by_name(entries):
    return {e.compensator: e for e in entries}


@pytest.fixture(scope="module")
def seed_league():
    """The iterative compensators with the seed's own rule for a (held maximum of the signed table), on the
    seed's own flow area (eq. 3.11 at every opening: the seed's Fig. 5.9/5.10 come from that model; with the
    port-limited area the seed's rule lets function (2)'s a ratchet up on the single actuator too, after
    ~20 s, as on the hexapod; hexsim's per-side rule, the default, keeps it convergent: tested on heave below)."""
    base = RunConfig(make_scenario("actuator", duration=32.0),
                     Machine(hydraulics=HydraulicParams(flow_area="quadratic")),
                     compensator_settings=CompensatorSettings(held_maximum="seed"))
    return _by_name(compare(base, ("iterative-1", "iterative-2"), jobs=2))


@pytest.fixture(scope="module")
def actuator_league():
    base = RunConfig(make_scenario("actuator", duration=16.0))
    return _by_name(compare(base, ("buffered", "oracle"), jobs=2))


@pytest.fixture(scope="module")
def warm_league():
    sc = make_scenario("actuator", duration=16.0)
    base = RunConfig(sc, warm_up=WarmUp(delta_c=15.0, duration_s=sc.duration))
    return _by_name(compare(base, ("buffered", "oracle"), jobs=2))


@pytest.fixture(scope="module")
def heave_league():
    base = RunConfig(make_scenario("heave", duration=18.0))
    return _by_name(compare(base, ("iterative-2", "buffered", "directional", "oracle"), jobs=2))


def _levels(entry):
    """Mean reversal peak per period (two reversals) and its time."""
    peaks, times = entry.traces["peaks"], entry.traces["peak_t"]
    n = peaks.size // 2 * 2
    return times[1:n:2], peaks[:n].reshape(-1, 2).mean(axis=1)


def test_iterative_1_first_helps_then_diverges_but_stays_bounded(seed_league):
    # Seed Fig. 5.7/5.8: "initially the peaks in the acceleration profile decrease, but these will increase
    # because of the ever-increasing compensation due to parameter a".
    none, it1 = seed_league["none"], seed_league["iterative-1"]
    t, level = _levels(it1)
    _, level_none = _levels(none)
    early = t < 20
    best = level[early].min()
    assert best < 0.85 * level_none.mean()  # 19 % below with boxcar-filtered 1 kHz records (26 % sampled)
    assert level[-3:].mean() > 2 * best
    a = it1.traces["param_a"]
    assert a[-1] > 2 * a[np.searchsorted(it1.traces["t"], t[early][np.argmin(level[early])])]
    assert a[-1] > 1.0  # ran away: the right amplitude is ~0.25 V
    assert np.all(np.isfinite(it1.traces["acc"]))
    assert a.max() <= 10.0  # bounded by the valve range (valve saturation is counted: test_controller)


def test_iterative_2_converges_and_reduces_the_peaks(seed_league):
    # Seed Fig. 5.9/5.10: with function (2) the parameters converge and the peaks drop considerably.
    it2 = seed_league["iterative-2"]
    assert it2.reduction_pct > 50
    # converged: a moves < 15 % over the second half (iterative-1's grows > 2x) and the peaks do not grow
    a, t = it2.traces["param_a"], it2.traces["t"]
    assert a[-1] == pytest.approx(a[np.searchsorted(t, 0.5 * t[-1])], rel=0.15)
    tl, level = _levels(it2)
    half = tl > 0.5 * tl[-1]
    assert level[half][-3:].mean() < 1.3 * level[half][:3].mean()
    assert it2.saturated_samples == 0


def test_buffered_is_close_to_its_final_shape_after_the_first_update(actuator_league):
    # Seed Fig. 5.12: "the global shape of the compensation is nearly the right one after the first update".
    buf = actuator_league["buffered"]
    t, a = buf.traces["t"], buf.traces["param_a"]
    first = np.searchsorted(t, 3.0 + 3 * 1.0)  # first buffer (3 s) + three fade time constants
    assert a[first] == pytest.approx(a[-1], rel=0.15)
    assert buf.traces["param_b"][first] == pytest.approx(buf.traces["param_b"][-1], rel=0.15)


def test_buffered_reaches_the_oracle_on_the_actuator(actuator_league):
    # Target: buffered noise ratio within 1.3x of the oracle's (measured on the last quarter).
    assert actuator_league["buffered"].noise_ratio <= 1.3 * actuator_league["oracle"].noise_ratio
    assert actuator_league["oracle"].reduction_pct > 40  # 47-56 % measured (2 µm noise sets the floor)


def test_buffered_stays_stable_with_noise_and_warming_oil(warm_league):
    # Seed Fig. 5.13: noise and a 15 °C temperature rise; the oracle knows the true warm parameters.
    # Within 1.35x of the oracle: 1.31x measured (1.19x on the seed's quadratic area, 1.13x before the
    # accelerometer records were boxcar means): function (2) is the exact inverse of the quadratic flow area
    # only, and above 0.78 V the port-limited area leaves it; the oracle, which knows the flow curve, does not.
    buf, oracle, none = warm_league["buffered"], warm_league["oracle"], warm_league["none"]
    assert buf.noise_ratio <= 1.35 * oracle.noise_ratio
    assert buf.noise_ratio < none.noise_ratio
    for key in ("param_a", "param_b", "param_c"):
        assert np.all(np.isfinite(buf.traces[key]))
    a = buf.traces["param_a"]
    assert a[-1] < 1.2 * a[np.searchsorted(buf.traces["t"], 8.0)]  # no drift-away of the amplitude


def test_hexapod_heave_bump_reduced_by_buffered_and_directional(heave_league):
    # Target: mean reversal peak at least 60 % lower than uncompensated.
    for name in ("buffered", "directional"):
        assert heave_league[name].reduction_pct >= 60, name
    assert heave_league["oracle"].reduction_pct >= 60


def test_no_compensator_but_iterative_1_makes_things_worse(seed_league, actuator_league, heave_league):
    # hexsim's default rule for a (per side) keeps iterative-2 convergent on the hexapod's asymmetric legs
    assert heave_league["iterative-2"].reduction_pct > 25
    for league in (seed_league, actuator_league, heave_league):
        for name, entry in league.items():
            if name != "iterative-1":
                assert entry.noise_ratio <= league["none"].noise_ratio, name


def test_each_leg_adapts_to_its_own_reversals_in_roll():
    # In roll the legs move by different amounts, so each leg's compensator finds its own valve range.
    base = RunConfig(make_scenario("roll", frequency=1.0, duration=12.0))
    league = _by_name(compare(base, ("buffered",), jobs=2))
    assert league["buffered"].reduction_pct > 40
    b = np.array(league["buffered"].final_parameters["b"])
    assert b.shape == (6,) and np.std(b) / np.mean(b) > 0.05


def test_combined_heave_and_pitch_from_a_file(tmp_path):
    path = write_heave_pitch_profile(tmp_path / "combined.csv", 12.0, 0.04)
    league = _by_name(compare(RunConfig(make_scenario(f"file:{path}")), ("buffered",), jobs=2))
    assert league["buffered"].reduction_pct > 30
    assert league["buffered"].noise_ratio < league["none"].noise_ratio
