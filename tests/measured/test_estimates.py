"""One vocabulary for a fitted quantity and what a fit says of it (hexsim.measured.parameters.Parameter,
hexsim.measured.estimates) and the typed calibration record a validation reads (hexsim.measured.records), on
hand-made values (issue 42)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hexsim.errors import InputError
from hexsim.measured.candidates import CANDIDATES
from hexsim.measured.estimates import (
    AT_A_BOUND,
    AT_LIMIT,
    FITTED,
    HELD,
    UNIDENTIFIABLE,
    Estimate,
    at_bound,
)
from hexsim.measured.friction_id import PARAMETERS, _judge
from hexsim.measured.parameters import Parameter
from hexsim.measured.records import CalibrationRecord
from hexsim.measured.scoring import model_floor


def test_one_rule_for_at_a_bound():
    assert at_bound(0.0005, 0.0, 1.0) == 0.0 and at_bound(0.9995, 0.0, 1.0) == 1.0
    assert at_bound(0.002, 0.0, 1.0) is None and at_bound(0.5, 0.0, 1.0) is None
    # bounds that are limits (a force >= 0, an upper far beyond anything real): the typical size sets the scale
    assert at_bound(40.0, 0.0, 1e5) == 0.0 and at_bound(40.0, 0.0, 1e5, scale=50.0) is None
    assert at_bound(0.04, 0.0, 1e5, scale=50.0) == 0.0


def test_an_estimate_is_judged_held_at_its_limit_at_a_bound_or_fitted():
    judged = lambda v, **kw: Estimate.judged("supply.tank_pressure_Pa", v, 10.0, "Pa", 0.0, 1e5, **kw)  # noqa: E731
    assert judged(5e4, held="no sensitivity").status == HELD and judged(5e4, held="x").why == "x"
    assert judged(20.0, limit="the tank at atmosphere").status == AT_LIMIT  # 20 Pa: within 0.1 % of 1e5
    assert judged(20.0).status == AT_A_BOUND and judged(99_950.0, limit="tank").status == AT_A_BOUND
    fitted = judged(5e4)
    assert fitted.status == FITTED and fitted.identified and "why" not in fitted.as_row()
    assert not judged(20.0).identified and not Estimate("k", 1.0, math.nan, "-").identified
    assert Estimate.from_row(judged(20.0).as_row()) == judged(20.0)
    with pytest.raises(InputError, match="k: unknown status 'guessed'"):
        Estimate.from_row({"key": "k", "value": 1.0, "status": "guessed"})
    with pytest.raises(InputError, match="needs key, value and status"):
        Estimate.from_row({"key": "k", "value": 1.0})


def test_one_parameter_declares_the_calibration_the_candidates_and_friction():
    """A machine-file key takes the file's unit; any other name must give one. Its estimate is judged by the
    one rule against its own range, a log's narrower one, or its typical size where the range is a limit."""
    tank = Parameter("supply.tank_pressure_Pa", 0.0, 1e5, "return line", "end stop", limit="the tank at atmosphere")
    assert tank.unit == "Pa" and tank.estimate(20.0, 5.0).status == AT_LIMIT
    assert tank.estimate(5e4, 5.0, held="blind").status == HELD and tank.estimate(5e4, 5.0).status == FITTED
    assert tank.estimate(5e4, 5.0, bounds=(0.0, 5.001e4)).status == AT_A_BOUND  # a range a log narrowed
    assert tank.row(tank.estimate(5e4, 5.0)) == tank.estimate(5e4, 5.0).as_row() | {
        "bounds_source": "return line", "experiment": "end stop"}
    with pytest.raises(KeyError):
        Parameter("R_s", 0.0, 20.0)  # no machine-file key: its unit must be given
    force = Parameter("F_c0", 0.0, 1e4, unit="N", scale=50.0)
    assert force.estimate(40.0, 1.0).status == FITTED and force.estimate(0.04, 1.0).status == AT_A_BOUND
    # a candidate's parameters: name, unit, plausible range, no-effect / neutral values, the candidate's source
    supply, edges = CANDIDATES["supply_pressure"], CANDIDATES["edge_asymmetry"]
    assert supply.names == ("R_s", "tau_s", "P_s0") and supply.units == ("bar/(L/min)", "ms", "bar")
    assert supply.no_effect == (0.0, None, None) and supply.origin == (0.0, None, None)
    assert edges.no_effect == (None, None) and edges.origin == (1.0, 1.0)
    assert all(p.source == supply.source for p in supply.parameters)
    assert [p.key for p in PARAMETERS] == ["sigma", "F_c0", "F_s0", "c_s"]


def test_a_parameter_at_a_bound_or_held_names_the_experiment_that_would_free_it():
    """Issue 52: nothing at a bound without the experiment that frees it. R1's calibration left the dead volume at its
    lower bound with only "the fit ran into the bound"; the row's experiment is now said, in the terminal table and
    the Markdown alike; a fitted row says nothing more."""
    from hexsim.measured.reports.calibration import status

    dead = Parameter("cylinder.dead_volume_cap_m3", 2.5e-7, 2e-6, "hoses", "the oil spring at both ends of the stroke")
    row = dead.row(dead.estimate(2.5e-7, 0.0)) | {"prior": 5e-7}
    assert row["status"] == AT_A_BOUND and status(row).endswith("identify it with the oil spring at both ends of "
                                                                "the stroke")
    assert status(dead.row(dead.estimate(1e-6, 1e-8))) == FITTED


def test_the_calibrations_table_says_which_commands_its_logs_measured():
    """A calibration's terminal table gives the commands its logs dwelt on (R1's: -0.743…0.728 V), and what rests on
    the extrapolation beyond them."""
    from hexsim.measured.reports.calibration import table

    text = table({"parameters": [], "commands_measured_V": [-0.743, 0.728]})
    assert "commands measured -0.743…0.728 V at the spool" in text and "add a log that dwells" in text
    assert "commands measured" not in table({"parameters": []})
    assert CalibrationRecord.of({"commands_measured_V": [-0.743, 0.728]}).commands_measured_V == (-0.743, 0.728)
    with pytest.raises(InputError, match=r"calibration.commands_measured_V: expected \[lowest, highest\] in V"):
        CalibrationRecord.of({"commands_measured_V": "wide"})


def test_friction_rows_are_estimates():
    """A friction fit with F_c0 run into its lower limit and c_s unseen: rows of the one Estimate, the
    unidentifiable ones with their reason."""
    class Sol:  # what least_squares leaves: x, the residual and its Jacobian (n, 4)
        x = np.array([1000.0, 0.0, 20.0, 0.005])
        fun = np.random.default_rng(0).normal(0.0, 1.0, 200)
        jac = np.column_stack([np.linspace(0.01, 0.1, 200), np.ones(200), np.linspace(1, 0, 200), np.zeros(200)])

    params, unidentifiable, _ = _judge(Sol)
    assert params["sigma"].status == FITTED and Estimate.from_row(params["sigma"].as_row()).unit == "N s/m"
    assert params["F_c0"].status == UNIDENTIFIABLE and "at the bound 0 N" in params["F_c0"].why
    assert params["c_s"].status == UNIDENTIFIABLE and "does not depend on it" in unidentifiable["c_s"]
    assert set(unidentifiable) == {"F_c0", "c_s"}


def _block(after: list[dict]) -> dict:
    rows = [Estimate("a", 1.0, 0.1, "-").as_row(), Estimate("b", 2.0, 0.0, "-", HELD, "blind").as_row(),
            Estimate("c", 3.0, 0.2, "-").as_row()]
    return {"parameters": rows, "correlation": {"keys": ["a", "c"], "matrix": [[1.0, 0.5], [0.5, 1.0]]},
            "transients": [{"log": f"log{i}", "after": a} for i, a in enumerate(after)],
            "flow_area": {"curve": {"commands_measured_V": [-4.0, 5.0], "from_form": "port"}}}


def test_the_calibration_record_and_the_model_floor_from_it():
    """Two own logs: position 1.5 budgets of 2 mm and 0.5 budgets (within: no excess): the floor is
    sqrt(mean(2² (1.5² - 1), 0)) = sqrt(2.5) mm; p1 only on the first log, 3 budgets of 1 bar: sqrt(8) bar."""
    block = _block([{"held_out_rms_in_budgets": {"position": 1.5, "p1": 3.0}, "budget": {"position": 2e-3, "p1": 1e5}},
                    {"held_out_rms_in_budgets": {"position": 0.5}, "budget": {"position": 2e-3}}])
    record = CalibrationRecord.of(block)
    assert record.identified() == ["a", "c"] and record.estimates["b"].status == HELD
    assert record.curve_commands_V == (-4.0, 5.0) and record.curve_form == "port"
    floor = model_floor(record, ["position", "p1", "acceleration"])
    assert floor == pytest.approx({"position": math.sqrt(2.5) * 1e-3, "p1": math.sqrt(8.0) * 1e5})
    assert CalibrationRecord.of(None) is None
    bad = _block([]) | {"correlation": {"keys": ["a", "c"], "matrix": [[1.0, 0.5, 0.0]]}}
    with pytest.raises(InputError, match="calibration.correlation"):
        CalibrationRecord.of(bad)
    assert np.array_equal(record.correlation, [[1.0, 0.5], [0.5, 1.0]])
