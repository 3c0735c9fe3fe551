"""Verdicts that say what the data support (issue 13), on single-actuator logs the identifier is not told
about: nominal logs with sine, two-tone, step and random references and another integration step (model
mismatch without an effect -> `none`), sensor calibration errors and an accelerometer without gravity (-> `none`, reported
as calibration), two effects at once, and an effect outside the candidate list (-> `partial` or
`unexplained`, never a confident wrong name, and the discovery step finds the missing term).

The logs come from hexsim's closed loop at a physics step of 5e-5 s (the identifier replays at 1e-4 s),
with sensor noise; the identifier reads only the CSV and its sidecar.
"""

import shutil
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest
from scipy.signal import butter, filtfilt

from hexsim.control.scenario import Scenario
from hexsim.engine.config import RunConfig
from hexsim.engine.runner import simulate
from hexsim.measured.candidates import (
    CANDIDATES,
    EFFECT_NAMES,
    plausibility,
    plausible_bounds,
)
from hexsim.measured.identify import identify
from hexsim.measured.measurement import read_log
from hexsim.outputs.logio import write_log
from hexsim.plant.effects import Effects
from hexsim.plant.machine import Machine
from hexsim.plant.params import HydraulicParams
from hexsim.tables import read_numeric_csv

DURATION = 6.0
FINE = 5e-5  # the generator's physics step [s]: another integration than the replay's 1e-4 s
BAR_PER_LPM = 1e5 / (1e-3 / 60)


def _reference(kind: str) -> tuple[np.ndarray, np.ndarray]:
    """Piston setpoints (t, r) [s, m] around mid-stroke, faded in over 1 s."""
    t = np.arange(0, DURATION + 1e-9, 0.002)
    fade = np.clip(t, 0, 1)
    if kind == "twotone":
        r = 0.03 * np.sin(2 * np.pi * 0.5 * t) + 0.01 * np.sin(2 * np.pi * 2.3 * t)
    elif kind == "sine":  # the seed's 0.5 Hz sine, 5 cm
        r = 0.05 * np.sin(2 * np.pi * 0.5 * t)
    elif kind == "steps":  # steps of ±1 cm, rounded by a 3 Hz filter (the valve would cavitate on a jump)
        b, a = butter(2, 3.0 / 250)
        r = filtfilt(b, a, 0.01 * np.sign(np.sin(2 * np.pi * 0.4 * t)))
    else:  # random: white noise through a 1.5 Hz filter, 3 cm rms
        b, a = butter(2, 1.5 / 250)
        r = filtfilt(b, a, np.random.default_rng(7).normal(0, 1, t.size))
        r = 0.03 * r / np.std(r)
    return t, 0.1 + fade * r


def _make(folder, name: str, reference: str, effects: Effects, hyd: HydraulicParams, seed: int) -> str:
    t, r = _reference(reference)
    sc = Scenario(name, "actuator", DURATION, -1, 0.5, 1.0, legs=(t, r[:, None]))
    result = simulate(RunConfig(sc, machine=Machine(hydraulics=hyd, effects=effects), timestep=FINE, seed=seed))
    path = folder / f"{name}.csv"
    write_log(path, result, noise=np.random.default_rng(seed + 1))
    return str(path)


def _cases():
    rng = np.random.default_rng(2026)
    h, e = HydraulicParams(), Effects()
    return {
        "null_twotone": ("twotone", e, h),
        "null_steps": ("steps", e, h),
        "null_random": ("random", e, h),
        "null_sine": ("sine", e, h),
        "leakage": ("twotone", Effects(leakage=rng.uniform(2e-12, 5e-12)), h),
        "edge": ("random", Effects(edge_gain_at=rng.uniform(0.6, 0.8)), h),
        "supply_and_hysteresis": ("twotone", Effects(supply_resistance=rng.uniform(1.0, 2.0) * BAR_PER_LPM,
                                                     supply_time_constant=0.03, spool_play=rng.uniform(0.2, 0.4)), h),
    }


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("verdict_logs")
    cases = _cases()
    with ProcessPoolExecutor(2) as pool:
        futures = {n: pool.submit(_make, folder, n, ref, e, h, 40 + i) for i, (n, (ref, e, h)) in enumerate(cases.items())}
        paths = {n: f.result() for n, f in futures.items()}
    # sensor calibration errors on the two-tone null: position 0.5 mm + 0.8 % scale, P1 +0.3 bar, and an
    # accelerometer that logs acceleration (no +g) with a 3 % low sensitivity
    cols = read_numeric_csv(paths["null_twotone"])
    cols["pos_m"] = 0.0005 + 1.008 * cols["pos_m"]
    cols["p1_Pa"] = cols["p1_Pa"] + 0.3e5
    cols["acc_mps2"] = 0.97 * (cols["acc_mps2"] - 9.81)
    cal = folder / "calibration.csv"
    np.savetxt(cal, np.column_stack(list(cols.values())), delimiter=",", header=",".join(cols), comments="",
               fmt="%.9g")
    shutil.copy(folder / "null_twotone.json", cal.with_suffix(".json"))
    paths["calibration"] = str(cal)
    return paths


@pytest.fixture(scope="module")
def answers(logs):
    from hexsim.measured.validation import summary

    return {name: summary(identify(read_log(path), jobs=2)) for name, path in logs.items()}


@pytest.mark.parametrize("name", ["null_sine", "null_twotone", "null_steps", "null_random"])
def test_nominal_logs_from_another_integration_are_answered_none(answers, name):
    doc = answers[name]
    assert doc["verdict"] == "none", (doc["held_out_rms_in_budgets"], doc["conclusions"])
    assert doc["added_effects"] == [] and doc["added_effect"] == "none"
    assert all(v["tolerance"] >= 0 and v["noise"] > 0 for v in doc["budget"].values())


def test_sensor_calibration_is_not_physics(answers):
    doc = answers["calibration"]
    assert doc["verdict"] == "none", (doc["held_out_rms_in_budgets"], doc["conclusions"])
    cal = doc["calibration"]["nominal"]
    assert cal["position"]["scale"][0] == pytest.approx(1.008, abs=0.002)
    # the replayed accelerometer is itself ~1 % low against the 5e-5 s generator (a null log without any
    # sensor error fits 0.989: the 1 kHz sample instants, issue 14), so the 3 % error reads 4 %
    assert cal["acceleration"]["scale"][0] == pytest.approx(0.97, abs=0.015)
    assert cal["p1"]["offset"][0] == pytest.approx(0.3e5, abs=0.02e5)
    assert any("convention problem" in c for c in doc["conclusions"])


def test_effect_is_named_with_its_parameter_and_verdict_explained(answers):
    doc = answers["leakage"]
    assert doc["verdict"] == "explained" and [e["name"] for e in doc["added_effects"]] == ["leakage"]
    truth = _cases()["leakage"][1].leakage * 1e12
    assert doc["parameters"]["C_l"]["value"] == pytest.approx(truth, rel=0.15)
    assert doc["error_after"]["position"] <= 0.2 * doc["error_before"]["position"]


def test_two_effects_are_both_found_or_the_rest_is_said_to_be_left(answers):
    doc = answers["supply_and_hysteresis"]
    names = [e["name"] for e in doc["added_effects"]]
    assert names and set(names) <= {"supply_pressure", "hysteresis"}, names
    if set(names) == {"supply_pressure", "hysteresis"}:
        assert doc["verdict"] == "explained"
    else:
        assert doc["verdict"] == "partial"
    for ch in ("position", "p1", "p_s"):
        assert doc["error_after"][ch] <= 0.5 * doc["error_before"][ch], ch


@pytest.mark.parametrize("name, effect, term", [("leakage", "leakage", "p_s - p1"),
                                                ("edge", "edge_asymmetry", "phi_AT")])
def test_effect_outside_the_list_is_never_named_and_discovery_finds_its_term(logs, name, effect, term):
    """The true effect removed from the candidates: no confident wrong name, and the sparse correction of
    the flow equation finds the term on the right variables, with the right size, and recovers most of the
    held-out error once added to the model."""
    log = read_log(logs[name])
    ident = identify(log, candidates=tuple(n for n in EFFECT_NAMES if n != effect), jobs=2)
    assert ident.verdict in ("partial", "unexplained"), [f.name for f in ident.accepted]
    base = ident.nominal.held_out_rms
    for f in ident.accepted:  # what was accepted made no channel worse than its budget allows
        assert all(f.scored.held_out_rms[ch] <= max(1.1 * base[ch], base[ch] + ident.budget.total[ch]) for ch in base)
    found = {t["term"]: t for t in ident.discovery.terms if t["equation"] == "flow"}
    assert term in found, ident.discovery.terms
    truth = _cases()[name][1]
    expected = truth.leakage if effect == "leakage" else truth.edge_gain_at - 1.0
    assert found[term]["coefficient"] == pytest.approx(expected, rel=0.15)
    assert f"flow:{term}" in ident.discovery.added_to_model
    assert ident.discovery.held_out_cost_recovered >= 0.5


def test_nothing_finer_than_the_log_resolves_is_a_finding(logs):
    log = read_log(logs["null_twotone"])
    assert plausibility(CANDIDATES["sensor_delay"], log, np.array([0.105]))  # 0.105 ms < one 1 ms sample
    assert not plausibility(CANDIDATES["sensor_delay"], log, np.array([5.0]))
    lower, upper = plausible_bounds(CANDIDATES["spool_dynamics"], log)
    assert upper[0] <= 0.5 * log.sample_rate_hz
    flagged = plausibility(CANDIDATES["bulk_modulus"], log, np.array([2.0]))
    assert flagged and "bound" in flagged[0]


def test_an_effect_is_told_from_none_by_its_standard_error(logs):
    """A small effect measured precisely is a finding, a larger one within four standard errors of
    the no-effect value is not; a no-effect value that is also the range's bound (R_s >= 0) is a physical
    limit, not a bound the fit ran into."""
    log = read_log(logs["null_twotone"])
    supply = CANDIDATES["supply_pressure"]
    x = np.array([0.15, 30.0, 70.0])  # 0.15 bar/(L/min): under 1 % of R_s's 0-20 range
    assert not plausibility(supply, log, x, np.array([3e-5, 0.01, 0.001]))
    assert "without the effect" in plausibility(supply, log, x, np.array([0.05, 0.01, 0.001]))[0]
    assert "without the effect" in plausibility(supply, log, x)[0]  # no standard error: the range's 1 %


def test_sensors_are_checked_against_each_other(logs):
    """The accelerometer against the position's second derivative, before any model: a consistent log
    says nothing; a 10 % sensitivity error and a flipped sign are each named in one sentence."""
    from hexsim.measured.validation import sensor_consistency

    log = read_log(logs["null_random"])
    assert sensor_consistency(log) == []
    acc = log.columns["acc_mps2"].copy()
    log.columns["acc_mps2"] = 1.1 * acc
    (scale,) = sensor_consistency(log)
    assert "scale error" in scale
    reads = float(scale.split("reads ")[1].split(" times")[0])
    assert reads == pytest.approx(1.1, abs=0.05)  # the slope through the 51 ms derivative: within a few %
    log.columns["acc_mps2"] = -acc
    (sign,) = sensor_consistency(log)
    assert "sign or axis problem" in sign
