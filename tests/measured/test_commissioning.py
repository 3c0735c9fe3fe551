"""Commissioning on a machine hexsim did not write: run the tuned file in the machine's own loop, log it, take
the log back into the model (``hexsim tune --from-logs``), run the improved file.

The truth is the reference plant of ``../shared/reference-plants`` (machine R1: a spool whose rounded metering
edge meets the port at 0.89 V, where the flow gain halves; no dead band; 5 µm position noise), written outside
the project; its ``simulate(compensator=…)`` calls the compensator exactly as hexsim's P controller does. Its
calibration logs (a chirp that stays below 0.8 V, steps that cross the corner in milliseconds) never show the
corner slowly; the seed's sine crosses it four times a period. hexsim starts from a file that has the valve's
smooth form (the built-in's, on one actuator, with R1's logged supply and noise)."""

from __future__ import annotations

import dataclasses
import json
import pathlib
import sys

import numpy as np
import pytest

from compensation import CompensatorSettings, make_compensator
from hexsim.cli import main
from hexsim.engine.config import RunConfig
from hexsim.measured.commissioning import FILE_KEYS
from hexsim.measured.proof import passenger_view
from hexsim.plant import hydraulics
from hexsim.plant.geometry import Geometry
from hexsim.plant.machine import dump, load_machine, with_keys
from hexsim.studies.tuning import FORMAT, leg_model_of, read_tuned

REFERENCE = pathlib.Path(__file__).resolve().parents[3] / "shared" / "reference-plants"
pytestmark = pytest.mark.skipif(not (REFERENCE / "plant.py").exists(),
                                reason="the reference plants live beside the project (../shared/reference-plants)")
DURATION = 24.0


def _plant():
    sys.path.insert(0, str(REFERENCE))
    import plant
    import r1

    return plant, r1


def run_on_r1(tuned: pathlib.Path, seed: int, log: pathlib.Path | None = None, duration: float = DURATION):
    """R1 on the seed's sine for ``duration`` [s] with ``tuned`` in its loop: the passenger's view of its
    (noise-free) acceleration from the second half on; the log written to ``log``."""
    plant, r1 = _plant()
    name, settings, model = read_tuned(tuned)
    comp = make_compensator(name, 1, 500.0, settings=settings, model=model)
    rows, extra = plant.simulate(effects=r1.effects("r1_f"), ref="sine", T=duration, seed=seed, compensator=comp)
    if log is not None:
        plant.write(log.stem, rows, r1.META, log.parent)
    return passenger_view(rows[:, 0], extra["acc"], rows[:, 1], 0.5, duration / 2, extra["v"])


@pytest.fixture(scope="module")
def commissioned(tmp_path_factory):
    folder = tmp_path_factory.mktemp("commissioning")
    prior = load_machine(None)
    machine = with_keys(prior, {"supply.pressure_Pa": 6.8e6, "sensors.position_noise_m": 5e-6})
    machine = dataclasses.replace(machine, system="single-actuator", geometry=Geometry(), legs=())
    cal = folder / "machine.json"
    cal.write_text(dump(machine.document()))
    model = leg_model_of(RunConfig.from_machine(load_machine(cal), "actuator"))
    first = folder / "tuned.json"
    first.write_text(json.dumps({"format": FORMAT, "compensator": "feedforward", "motions": ["actuator"],
                                 "settings": CompensatorSettings(loop_filter_hz=10.0).__dict__,
                                 "model": model.to_dict()}))
    before = run_on_r1(first, 21, folder / "run0.csv")
    second = folder / "tuned_1.json"
    logs = [folder / "run0.csv", REFERENCE / "r1" / "cal_chirp.csv", REFERENCE / "r1" / "cal_steps.csv"]
    assert main(["tune", "--from-logs", *map(str, logs), "--compensator", str(first), "--machine", str(cal),
                 "--out", str(second), "--machine-out", str(folder / "machine_1.json"), "--jobs", "1"]) == 0
    return before, run_on_r1(second, 22), second, folder


def test_the_commissioned_file_follows_the_corner_the_calibration_logs_never_showed_slowly(commissioned):
    """The file from the smooth form leaves the passenger a weighted false cue of 10x the perception threshold at
    each crossing of the corner; one commissioning run brings it below a third of that (measured: see
    docs/compensation.md), and the reversals no worse than before (within 20 %)."""
    before, after, _, _ = commissioned
    assert before.seat_ratio > 5.0, before.seat_ratio
    assert after.seat_ratio < before.seat_ratio / 3.0, (before.seat_ratio, after.seat_ratio)
    assert after.mean < 1.2 * before.mean, (before.mean, after.mean)


def test_the_commissioned_files_say_what_they_learned(commissioned):
    """The tuned file keeps its compensator and settings, holds the new leg model, the logs it was learned from
    and the curves' reach; the machine file has each edge's curve, read beyond the corner."""
    _, _, second, folder = commissioned
    doc = json.loads(second.read_text())
    assert doc["compensator"] == "feedforward" and doc["settings"]["loop_filter_hz"] == 10.0
    learned = doc["commissioning"][-1]
    assert any(pathlib.Path(p).name == "run0.csv" for p in learned["logs"])
    assert learned["curves"]["reach_V"]["PA"] > 1.0
    # the run it learned from, measured through R1's accelerometer noise, recorded with the file that ran it
    (run,) = learned["runs"]
    assert pathlib.Path(run["log"]).name == "run0.csv" and run["seat_peak"] / 0.015 > 5.0, run
    assert learned["ran"]["model"] == json.loads((folder / "tuned.json").read_text())["model"]
    assert "kept" not in learned
    machine = load_machine(folder / "machine_1.json")
    assert machine.hydraulics.flow_area == "curve" and len(machine.hydraulics.flow_curve_pa) > 5


def test_commissioning_refuses_a_tuned_file_without_a_model_and_names_it(commissioned, tmp_path, capsys):
    _, _, _, folder = commissioned
    seedish = tmp_path / "buffered.json"
    seedish.write_text(json.dumps({"format": FORMAT, "compensator": "buffered", "settings": {}}))
    assert main(["tune", "--from-logs", str(folder / "run0.csv"), "--compensator", str(seedish), "--machine",
                 str(folder / "machine.json"), "--out", str(tmp_path / "x.json")]) == 2
    assert "holds no leg model" in capsys.readouterr().err


def test_near_null_the_commissioned_curve_keeps_the_shape_a_compensated_run_cannot_show(commissioned):
    """A compensated run jumps the command across null at every reversal, so its flows say little there, and
    the flow balance alone drew a straight line from null (at 10 and 20 mV 3.6x and 1.9x R1's opening relative
    to its opening at 0.1 V). The commissioned curve keeps the starting form's shape there, which is R1's (an
    opening rising as x_v^2 from null): within 25 % of R1's at 10 and 20 mV, the flows' own reading above."""
    _, _, _, folder = commissioned
    plant, r1 = _plant()
    p = {**plant.SEED, **r1.R1}
    hyd = load_machine(folder / "machine_1.json").hydraulics

    def shape(opening):
        return np.array([opening(u) / opening(0.1) for u in (0.01, 0.02)])

    truth = shape(lambda u: plant.port_area(u * p["xvmax"] / p["uvmax"], **p["area_kw"]))
    ours = shape(lambda u: float(hydraulics.flow_areas(np.array([u * hyd.x_v_max / hyd.u_v_max]), hyd)[0][0]))
    assert np.all(np.abs(ours / truth - 1.0) < 0.25), (ours, truth)


def test_a_commissioned_file_the_machine_runs_worse_than_the_one_before_is_not_kept(commissioned, tmp_path, capsys):
    """A model learned from logs is better on average, not on every machine (docs/compensation.md: on two of the
    proof's machines the commissioned files were felt at twice the tuned file's seat peak). Here the commissioned
    file is spoilt as a commissioning that read the valve's null 0.1 V off would spoil it; on R1 it is felt at
    several times the file before it. Its log, measured through R1's 0.05 m/s² accelerometer noise, says so, and
    the next step writes back the file before it (its compensator and model), naming why."""
    _, _, second, folder = commissioned
    doc = json.loads(second.read_text())
    doc["model"]["u"] = (np.asarray(doc["model"]["u"]) + 0.1).tolist()
    spoilt = tmp_path / "tuned_spoilt.json"
    spoilt.write_text(json.dumps(doc))
    view = run_on_r1(spoilt, 23, tmp_path / "run_spoilt.csv", duration=12.0)
    out = tmp_path / "tuned_2.json"
    assert main(["tune", "--from-logs", str(folder / "run0.csv"), str(tmp_path / "run_spoilt.csv"), "--compensator",
                 str(spoilt), "--machine", str(folder / "machine.json"), "--out", str(out), "--jobs", "1"]) == 0
    said = capsys.readouterr().out
    kept = json.loads(out.read_text())
    first = json.loads((folder / "tuned.json").read_text())
    assert {k: kept.get(k) for k in FILE_KEYS} == {k: first.get(k) for k in FILE_KEYS}  # nothing of the spoilt file's
    entry = kept["commissioning"][-1]
    assert pathlib.Path(entry["kept"]["file"]).name == "tuned.json" and "ran worse on the machine" in said, said
    (run,) = entry["runs"]  # run0 was read by the commissioning before: only the spoilt file's own run is its
    assert pathlib.Path(run["log"]).name == "run_spoilt.csv"
    before = kept["commissioning"][0]["runs"][0]  # run0's, as the first step measured it
    assert run["seat_peak"] > 1.5 * before["seat_peak"], (run, before, view.seat_ratio)
