"""``hexsim sweep``: a grid in worker processes (forked by default, spawned, or on a Dask LocalCluster)
gives the same numbers as serial runs, in grid order."""

import csv
import json

from hexsim.cli import main
from hexsim.control.scenario import make_scenario
from hexsim.engine.config import RunConfig
from hexsim.plant.machine import Machine
from hexsim.studies.sweeps import evaluate_point


def test_sweep_in_two_workers_equals_serial_runs(tmp_path, capsys):
    csv_path, json_path = tmp_path / "sweep.csv", tmp_path / "sweep.json"
    code = main(["sweep", "actuator", "--duration", "2.5", "--frequency", "2", "--grid", "seed=1,2",
                 "--grid", "kp=100,200", "--jobs", "2", "--csv", str(csv_path), "--json", str(json_path), "--quiet"])
    assert code == 0
    rows = list(csv.DictReader(csv_path.open()))
    data = json.loads(json_path.read_text())
    assert [(r["seed"], r["kp"]) for r in rows] == [("1", "100.0"), ("1", "200.0"), ("2", "100.0"), ("2", "200.0")]
    assert data["grid"] == {"seed": [1, 2], "kp": [100.0, 200.0]}
    scenario = make_scenario("actuator", duration=2.5, frequency=2.0)
    for row, jrow in zip(rows, data["rows"]):
        from hexsim.plant.params import ControllerParams

        serial = evaluate_point(RunConfig(scenario, Machine(controller=ControllerParams(kp=float(row["kp"]))),
                                          seed=int(row["seed"])))
        for key, value in serial.items():
            assert jrow[key] == value, key  # bit-identical, whichever worker ran it
    first = json_path.read_bytes()
    for options in (["--jobs", "1"], ["--jobs", "2", "--start-method", "spawn"],
                    ["--jobs", "2", "--scheduler", "local"]):  # Dask: a LocalCluster of two worker processes
        assert main(["sweep", "actuator", "--duration", "2.5", "--frequency", "2", "--grid", "seed=1,2",
                     "--grid", "kp=100,200", *options, "--json", str(json_path), "--quiet"]) == 0
        assert json_path.read_bytes() == first, options  # serial, forked, spawned and Dask workers agree


def test_an_unreachable_dask_scheduler_is_one_clear_error(capsys, monkeypatch):
    monkeypatch.setattr("hexsim.engine.workers.SCHEDULER_TIMEOUT_S", 1.0)  # the test waits 1 s, not the 10 s default
    code = main(["sweep", "actuator", "--duration", "2.5", "--frequency", "2", "--grid", "seed=1,2",
                 "--scheduler", "tcp://127.0.0.1:9", "--quiet"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and err.startswith("hexsim: error: --scheduler tcp://127.0.0.1:9") and len(err.splitlines()) == 1
