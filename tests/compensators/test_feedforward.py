"""The model-based feedforward and its adaptive version on a machine that is not hexsim's model.

The truth is ``tests/independent_actuator.py`` (its own equations, error-controlled Dormand-Prince, no hexsim
import) with its nominal moved within data-sheet tolerances from appendix A and a port-limited spool, as in
test_calibration_transients. hexsim is told only the built-in file; it calibrates on two closed-loop
logs, then hexsim's compensators (the thing under test) run inside the independent actuator's own
500 Hz loop, handed what a motion computer has: the P output, the measured position and pressure, the
reference and its derivatives. The reversal peaks are measured on the truth's acceleration."""

from __future__ import annotations

import json

import numpy as np
import pytest
from helpers import in_the_loop, reversal_peaks
from independent_actuator import Actuator, motion, write

import compensation.curve_learning as cl
from compensation import CompensatorSettings, SettingsError, make_compensator
from compensation.leg_model import LegModel, Reference
from compensation.model_based import AdaptiveFeedforward
from hexsim.cli import main
from hexsim.engine.config import RunConfig
from hexsim.measured.calibration import calibrate
from hexsim.measured.measurement import read_log
from hexsim.measured.proof import passenger_view
from hexsim.plant.machine import dump, load_machine
from hexsim.studies import tuning
from hexsim.studies.tuning import leg_model_of, read_tuned

TRUTH = Actuator(area="port", flow_gain=1.07, k_at=0.95, overlap=8e-6, bulk=1.2e9, v_pl=1.0e-6, mass=44.0,
                 coulomb=(75.0, 52.0), viscous=(2600.0, 1500.0))


@pytest.fixture(scope="module")
def machine(tmp_path_factory):
    """TRUTH calibrated on two closed-loop sines (0.5 Hz 60 mm, 1 Hz 20 mm, 8 s each): the machine file."""
    folder = tmp_path_factory.mktemp("feedforward")
    logs = [write(motion(TRUTH, 8.0, 0.5, 0.06, np.random.default_rng(11)), folder / "a.csv", "calibration"),
            write(motion(TRUTH, 8.0, 1.0, 0.02, np.random.default_rng(12)), folder / "b.csv", "calibration")]
    prior = load_machine(None)
    calibrated = calibrate([read_log(log, machine=prior) for log in logs], prior, flow_areas=("smooth", "port")).machine
    path = folder / "calibrated.json"
    path.write_text(dump(calibrated.document()))
    return path


@pytest.fixture(scope="module")
def model(machine) -> LegModel:
    """The calibrated file's leg model, as a model-based compensator gets it on the actuator."""
    return leg_model_of(RunConfig.from_machine(load_machine(machine), "actuator"))


@pytest.fixture(scope="module")
def none_peaks() -> np.ndarray:
    """TRUTH uncompensated, 20 s."""
    return reversal_peaks(TRUTH, 20.0)


def test_the_feedforward_on_the_calibrated_machine_removes_the_bump_the_seed_leaves(model, none_peaks):
    """On the calibrated file's leg model the feedforward takes at least 85 % off the truth's mean
    reversal peak (measured 91 %), the seed's buffered compensator far less (measured 17 %)."""
    none = none_peaks
    seed = reversal_peaks(TRUTH, 20.0, in_the_loop("buffered", model))
    fed = reversal_peaks(TRUTH, 20.0, in_the_loop("feedforward", model))
    assert fed.mean() < 0.15 * none.mean()
    assert fed.mean() < 0.3 * seed.mean()
    assert fed.max() < 0.25 * none.min()


def test_on_a_drifting_machine_the_adaptive_version_keeps_the_gain_and_is_never_worse(model):
    """The truth's null drifts 0.05 V and its oil warms 15 K over 60 s (its viscosity halves): the
    fixed feedforward, its null now wrong, makes late reversals worse than none; the adaptive version
    keeps at least 70 % off (measured 83 %) and no reversal worse than uncompensated. Its curve is learned a
    buffer (3 s) at a time: before the second buffer is in, one reversal reaches 0.72 of none's (the version
    that learned a slope per side with the null, in 0.3 s, stayed below 0.33 throughout); from the fourth
    period on every reversal stays below half of none's (measured at most 0.36)."""
    drifting = TRUTH.replace(null_rate=0.05 / 60, warm_rate=15.0 / 60)
    none = reversal_peaks(drifting, 60.0)
    fixed = reversal_peaks(drifting, 60.0, in_the_loop("feedforward", model))
    loop = in_the_loop("adaptive", model)
    adaptive = reversal_peaks(drifting, 60.0, loop)
    n = min(len(none), len(fixed), len(adaptive))
    assert np.max(fixed[:n] / none[:n]) > 1.0
    assert np.max(adaptive[:n] / none[:n]) < 0.9
    assert np.max(adaptive[6:n] / none[6:n]) < 0.5
    assert adaptive.mean() < 0.3 * none.mean()
    assert abs(loop.compensator.null[0] - 0.05) < 0.01  # it learned the null
    assert not loop.compensator.off[0]


def test_the_adaptive_version_learns_the_rate_a_null_drifts_at_and_leaves_less_than_with_the_null_alone(
        model, monkeypatch):
    """The truth's null drifting 1 mV/s while its oil warms 15 K over 40 s: the adaptive version learns the
    rate (within 25 %; measured 1.12 mV/s, 1.06 over 60 s) and, following the drift without lag, leaves less of
    the bump over the second half than the same compensator with the rate held at zero
    (:data:`AdaptiveFeedforward.DRIFT_LIMIT` 0, the null alone: its lag paid at every reversal; measured 0.064
    against 0.205 m/s², 0.085 against 0.204 over 60 s)."""
    drifting = TRUTH.replace(null_rate=1e-3, warm_rate=15.0 / 40)
    settings = CompensatorSettings(adapt_time=1.0)
    loop = in_the_loop("adaptive", model, settings)
    tracked = reversal_peaks(drifting, 40.0, loop)
    monkeypatch.setattr(AdaptiveFeedforward, "DRIFT_LIMIT", 0.0)
    alone = reversal_peaks(drifting, 40.0, in_the_loop("adaptive", model, settings))
    half = len(tracked) // 2
    print(f"drift learned {1e3 * loop.compensator.drift[0]:.3f} mV/s; second half {tracked[half:].mean():.4f} "
          f"against {alone[half:].mean():.4f} m/s^2 with the null alone")
    assert abs(loop.compensator.drift[0] - 1e-3) < 0.25e-3
    assert tracked[half:].mean() < 0.6 * alone[half:].mean()


def test_a_flow_gain_off_is_measured_and_left_to_the_loop_not_learned_into_the_curve(model, monkeypatch):
    """The truth's valve 3 % more open than TRUTH (some 4 % against the calibrated file): the curve's learner
    measures the gain's error on each side (compensation.curve_learning.CurveLearner.gain_error; measured 4.0 and
    3.75 %) and learns the curve's shape without it, the null's learning told of it. Learned into the curve (as
    before: the tuned settings, 40 s, the second half), the corrections fell to zero within the reversals' band
    and the gain stepped at its edge either side of every reversal: the seat's ISO 2631-1 peak 16.4x the threshold
    and the mean reversal peak 0.072 m/s²; left to the P loop, 0.98x and 0.042."""
    wide = TRUTH.replace(flow_gain=TRUTH.flow_gain * 1.03)
    settings = CompensatorSettings(adapt_time=1.0, loop_filter_hz=10.0)

    def view(loop):
        cols = motion(wide, 40.0, 0.5, 0.05, np.random.default_rng(3), noise=(5e-6, 2e3, 0.0), compensate=loop)
        t = cols["time_s"]
        return passenger_view(t, cols["acc_mps2"], cols["ref_m"], 0.5, 20.0, np.gradient(cols["pos_m"], t))

    loop = in_the_loop("adaptive", model, settings)
    shape = view(loop)
    measured = loop.compensator.learner.gain_error()[0]
    monkeypatch.setattr(cl.CurveTeacher, "_without_gain", lambda self, u, w, target, evidence: (0.0 * evidence, target))
    learned = view(in_the_loop("adaptive", model, settings))
    print(f"gain error {measured}; seat {shape.seat_ratio:.2f}x against {learned.seat_ratio:.2f}x, mean "
          f"{shape.mean:.4f} against {learned.mean:.4f} m/s^2 with the gain learned into the curve")
    assert np.all((measured > 0.03) & (measured < 0.05))
    assert shape.seat_ratio < 0.25 * learned.seat_ratio
    assert shape.mean < learned.mean


def test_the_guard_turns_a_leg_off_rather_than_keep_a_compensation_worse_than_none(model, none_peaks):
    """A leg model whose flow curve sits 0.4 V off the machine's null, with learning bounded to 0.05 V (it
    cannot learn it): the P output climbs across the dead band at every reversal, the guard turns the
    compensation off, and the bump ends no worse than uncompensated (within the scatter of 10 %)."""
    shifted = LegModel(**{**model.__dict__, "velocity": np.interp(model.u - 0.4, model.u, model.velocity[0])[None, :]})
    loop = in_the_loop("adaptive", shifted, CompensatorSettings(adapt_limit=0.05))
    guarded = reversal_peaks(TRUTH, 20.0, loop)
    assert loop.compensator.off[0]
    assert guarded[-4:].mean() < 1.1 * none_peaks[-4:].mean()


def test_a_tuned_file_round_trips_and_runs(machine, model, tmp_path, capsys, monkeypatch):
    """``hexsim tune`` on the calibrated machine chooses a model-based compensator, prints none / buffered /
    tuned, and writes a file that ``hexsim run --compensator FILE`` loads: the loaded compensator gives the
    same U_c as one built from the machine for the same inputs. Every candidate was also judged on a machine
    drawn from what the calibration leaves uncertain (``--draws 1``), which ran as a machine of its own. (The
    candidates cut to one of each kind for time: the file's round trip does not depend on which settings won.)"""
    monkeypatch.setattr(tuning, "CANDIDATES", (("none", {}), ("buffered", {}), ("feedforward", {}), ("adaptive", {})))
    out = tmp_path / "tuned.json"
    assert main(["tune", "actuator", "--machine", str(machine), "--duration", "6", "--out", str(out), "--jobs", "1",
                 "--draws", "1"]) == 0
    text = capsys.readouterr().out
    assert "buffered" in text and "tuned:" in text and "drawn1" in text.splitlines()[-2]
    name, settings, model = read_tuned(out)
    assert name in ("feedforward", "adaptive") and model is not None
    built = model
    rng = np.random.default_rng(3)
    a = make_compensator(name, 1, 500.0, settings=settings, model=model)
    b = make_compensator(name, 1, 500.0, settings=settings, model=built)
    for k in range(400):
        ref = Reference(*(np.array([x]) for x in (0.1 + 0.05 * np.sin(k / 80), 0.05 * np.cos(k / 80) / 0.16,
                                                   0.0, 0.0, 3.4e6 + 1e5 * rng.normal())))
        u_p, y = np.array([rng.normal(0, 0.2)]), np.array([0.1])
        a.observe(ref)
        b.observe(ref)
        assert a.update(u_p, y) == pytest.approx(b.update(u_p, y), abs=1e-12)
    doc = json.loads(out.read_text())
    assert set(doc["predicted"]) >= {"none", "buffered"}
    assert list(doc["neighbours"]) == ["calibrated", "drift", "underlap", "overlap", "drawn1"]
    none = {row["neighbour"]: row["final_mean_reversal_peak"] for row in doc["predicted"]["none"]}
    assert none["drawn1"] != none["calibrated"]  # the drawn machine, not the file, ran
    assert main(["run", "actuator", "--machine", str(machine), "--duration", "6", "--compensator", str(out),
                 "--quiet"]) == 0
    assert f"compensator {name}" in capsys.readouterr().out


def test_a_log_run_with_the_tuned_compensator_is_set_beside_its_prediction(machine, model, none_peaks, tmp_path,
                                                                            capsys):
    """Proof on logs: a log of the truth running with hexsim's compensator (written by the truth's own loop)
    beside the calibrated machine simulated with the same compensator on the log's setpoints. Both show the
    bump removed (measured 0.063, predicted 0.063 m/s² with the log's accelerometer noise, none 0.75); the JSON
    carries both, and the verdict is within its uncertainty, over the machines the calibration's uncertainty allows
    (the default 8 draws: reversals 1.00×, 95 % interval 0.91–1.09; between them 1.04×, 0.93–1.16) and on the
    calibrated file alone (``--draws 0``), every band of the departure 1.0× (numpy 2.4, scipy 1.17, mujoco 4.0).
    Until the leg model's grid was refined where the curve bends (:func:`compensation.leg_model.refined_grid`, which
    adds points at the valve's edges and at the port's corner) the measured run left 0.084 and the verdict was *not
    within*, the peaks between the reversals placed at the truth's port corner (0.88 V, 1.21×); which of the added
    points moved those peaks was not separated. An uncompensated log is within it (0.99×)."""
    doc = {"format": "hexsim-tuned/1", "compensator": "feedforward", "settings": {}, "model": model.to_dict()}
    tuned = tmp_path / "tuned.json"
    tuned.write_text(json.dumps(doc))
    log = write(motion(TRUTH, 12.0, 0.5, 0.05, np.random.default_rng(5), compensate=in_the_loop("feedforward", model)),
                tmp_path / "with.csv", "with the feedforward")
    assert main(["tune", "--check", str(log), "--compensator", str(tuned), "--machine", str(machine),
                 "--json", str(tmp_path / "plausible.json")]) == 0
    plausible = json.loads((tmp_path / "plausible.json").read_text())["proofs"][0]
    assert len(plausible["predicted_models"]) == 9 and plausible["verdict"]["reversals"]["models"] == 9
    predicted = plausible["predicted"]  # the models' means in every column: a mean of maxima is above the mean
    assert predicted["mean_reversal_peak"] == pytest.approx(np.mean(plausible["predicted_models"]))
    assert predicted["max_reversal_peak"] >= predicted["mean_reversal_peak"]
    assert "machines drawn from its uncertainty" in capsys.readouterr().out
    assert main(["tune", "--check", str(log), "--compensator", str(tuned), "--machine", str(machine),
                 "--draws", "0", "--json", str(tmp_path / "proof.json")]) == 0
    out = capsys.readouterr().out
    assert "predicted" in out
    proof = json.loads((tmp_path / "proof.json").read_text())["proofs"][0]
    for what in ("measured", "predicted"):
        assert proof[what]["mean_reversal_peak"] < 0.2 * none_peaks.mean()
        assert proof[what]["reversals"] >= 6
    # read with the log's accelerometer noise (the truth's 0.02 m/s^2): the prediction holds within 30 % (issue 53's
    # target) at the reversals and between them, and the verdict says so with no corner to place
    assert proof["accelerometer_noise_mps2"] == pytest.approx(0.02, rel=0.1)
    for doc_ in (plausible, proof):
        verdict = doc_["verdict"]
        assert verdict["within"] is True and verdict["corner_V"] is None, verdict
        for part in ("reversals", "between reversals"):
            assert 0.77 < verdict[part]["ratio"] < 1.3 and verdict[part]["low"] < 1.0 < verdict[part]["high"]
    assert proof["verdict"]["sentence"] in out and proof["verdict"]["sentence"].startswith("within")
    without = write(motion(TRUTH, 12.0, 0.5, 0.05, np.random.default_rng(6)), tmp_path / "without.csv", "none")
    assert main(["tune", "--check", str(without), "--compensator", "none", "--machine", str(machine),
                 "--json", str(tmp_path / "none.json")]) == 0
    assert json.loads((tmp_path / "none.json").read_text())["proofs"][0]["verdict"]["within"] is True


@pytest.mark.parametrize("change, reason", [
    # a sharp-edged spool with a 0.3 mm overlap: 5.5 V of the command moves nothing
    ({("valve", "flow_area"): "sharp", ("valve", "overlap_m"): 3e-4}, "dead band"),
    # a P gain 10x the file's: the loop through the inverse at K_p s / f_c > 0.5
    ({("controller", "kp_VPm"): 2000.0}, "would ring"),
])
def test_a_calibration_that_would_give_an_extreme_compensation_is_refused_with_the_reason(tmp_path, capsys, change,
                                                                                          reason):
    """A machine file whose leg model would make the inverse jump the valve across a wide dead band at
    every reversal, or make the P loop through it ring, is refused by the model-based compensators with
    the reason, one line, exit 2; the seed's compensators still run on it."""
    machine = load_machine(None)
    doc = machine.document()
    for (section, key), value in change.items():
        doc[section][key] = value
    path = tmp_path / "extreme.json"
    path.write_text(dump(doc))
    assert main(["run", "actuator", "--machine", str(path), "--duration", "6", "--compensator", "feedforward",
                 "--quiet"]) == 2
    err = capsys.readouterr().err
    assert reason in err and len(err.strip().splitlines()) == 1


def test_the_model_check_names_what_is_wrong():
    """check_model on small hand-made curves: a falling curve, one that never reverses, a bad slope."""
    u = np.linspace(-10, 10, 21)
    good = dict(u=u, velocity=(0.02 * u)[None, :], p_rest=np.array([4e6]), supply_pressure=7e6, tank_pressure=0.0,
                area_bottom=1.2e-3, bulk_modulus=1.5e9, pipeline_volume=5e-7, mass=np.array([[40.0]]),
                friction_v=np.array([-1.0, 1.0]), friction_f=np.array([-100.0, 100.0]), slope=np.array([0.02]))
    LegModel(**good)
    for change, text in (({"velocity": (-0.02 * u)[None, :]}, "falls"),
                         ({"velocity": (0.02 * u + 0.3)[None, :]}, "does not cross zero"),
                         ({"slope": np.array([0.0])}, "slope"),
                         ({"p_rest": np.array([8e6])}, "rest pressure"),
                         ({"friction_f": np.array([100.0, -100.0])}, "oppose")):
        with pytest.raises(SettingsError, match=text):
            LegModel(**{**good, **change})


def test_a_dead_band_margin_stops_the_inverse_that_far_short_of_each_valve_edge():
    """dead_band_margin m: the inverse reads the curve as opening m earlier on each edge (the tuning's underlap
    neighbour), so u_v moves m towards the curve's null (the overlap's middle), never past it; out of 0…0.1 V it is
    refused."""
    u = np.linspace(-10, 10, 2001)
    velocity = 0.02 * np.sign(u) * np.maximum(np.abs(u) - 0.1, 0.0)  # a 0.1 V overlap either side
    model = LegModel(u=u, velocity=velocity[None, :], p_rest=np.array([4e6]), supply_pressure=7e6, tank_pressure=0.0,
                     area_bottom=1.2e-3, bulk_modulus=1.5e9, pipeline_volume=5e-7, mass=np.array([[40.0]]),
                     friction_v=np.array([-1.0, 1.0]), friction_f=np.array([-100.0, 100.0]), slope=np.array([0.02]),
                     pressure_scaling=False)
    exact = make_compensator("feedforward", 1, 500.0, model=model)
    short = make_compensator("feedforward", 1, 500.0, model=model, settings=CompensatorSettings(dead_band_margin=0.01))
    p1 = np.array([4e6])
    for v, at_edge in ((1e-5, 0.1005), (-1e-5, -0.1005), (0.02, 1.1), (-0.1, -5.1)):
        assert exact.inverse(np.array([v]), p1)[0] == pytest.approx(at_edge, abs=1e-6)
        assert short.inverse(np.array([v]), p1)[0] == pytest.approx(at_edge - np.sign(v) * 0.01, abs=1e-6)
    assert short.inverse(np.array([1e-14]), p1)[0] == pytest.approx(0.0, abs=1e-9)
    # a null 0.15 V off 0 V: each edge still moves towards the null (0.05 -> 0.06, 0.25 -> 0.24), never past it
    off = LegModel(**{**model.__dict__, "velocity": np.interp(u - 0.15, u, velocity)[None, :]})
    shifted = make_compensator("feedforward", 1, 500.0, model=off, settings=CompensatorSettings(dead_band_margin=0.01))
    assert shifted.inverse(np.array([1e-5]), p1)[0] == pytest.approx(0.2405, abs=1e-6)
    assert shifted.inverse(np.array([-1e-5]), p1)[0] == pytest.approx(0.0595, abs=1e-6)
    assert shifted.inverse(np.array([1e-14]), p1)[0] == pytest.approx(0.15, abs=1e-3)
    for bad in (-0.001, 0.2, float("nan")):
        with pytest.raises(SettingsError, match="dead_band_margin"):
            CompensatorSettings(dead_band_margin=bad)


def test_the_inverse_reads_the_curve_where_an_overlapped_edge_opens():
    """A port-limited spool's edge opens steeply out of its 6 µm overlap (0.44 mm/s within 3 mV at 34 bar): on a
    uniform 5 mV grid the inverse's chord across it missed the flow by 0.15 mm/s, and that tick's flow step rang the
    oil column at every reversal on one side. The leg model's grid is refined there until its chords hold to
    CURVE_TOLERANCE: commands across both edges, read back through the curve the model came from, land within it;
    a smooth curve keeps its grid."""
    import dataclasses

    from compensation.leg_model import CURVE_TOLERANCE, refined_grid
    from hexsim.control.feedforward import GRID_POINTS, leg_model, static_flow_curve
    from hexsim.plant.params import HydraulicParams

    hyd, p1 = HydraulicParams(flow_area="port", overlap=6e-6), np.array([3.4e6])
    model = leg_model(hyd, p1, np.array([[42.0]]))
    uniform = np.linspace(-hyd.u_v_max, hyd.u_v_max, GRID_POINTS)
    coarse = dataclasses.replace(model, u=uniform, velocity=static_flow_curve(uniform, p1, hyd))
    u = np.r_[np.linspace(-0.2, -0.05, 1500), np.linspace(0.05, 0.2, 1500)]  # through both edges (±55 mV)
    v = static_flow_curve(u, p1, hyd)[0]
    missed = {}
    for label, m in (("refined", model), ("uniform", coarse)):
        comp = make_compensator("feedforward", 1, 500.0, model=m)
        back = np.array([static_flow_curve(comp.inverse(np.array([x]), p1), p1, hyd)[0, 0] for x in v])
        missed[label] = float(np.max(np.abs(back - v)))
    assert missed["refined"] < CURVE_TOLERANCE < 1e-4 < missed["uniform"], missed
    smooth, curve = refined_grid(lambda x: np.atleast_2d(0.02 * x + 0.001 * x**3), uniform)
    assert len(smooth) == len(uniform) and curve.shape == (1, len(uniform))


def test_an_underlapped_valve_is_inverted_edge_by_edge_at_the_measured_pressure():
    """Where both edges of a 3-way valve are open (a sharp spool with a 5 µm underlap, 45 mV), the flow at P1 is
    v_PA sqrt((P_s - P1) / (P_s - P_rest)) - v_AT sqrt((P1 - P_t) / (P_rest - P_t)) (seed eq. 3.4 per edge): the
    leg model carries the return edge's share, and the inverse gives back the command of hexsim's own orifice flow
    at 5 bar either side of rest, where scaling the curve by the edge the target's sign opens misses by up to
    3 mV. The share goes through a tuned file; an overlapped spool's model has none (its inverse unchanged)."""
    import dataclasses

    from hexsim.control.feedforward import leg_model
    from hexsim.plant import hydraulics
    from hexsim.plant.params import HydraulicParams

    hyd = HydraulicParams(flow_area="sharp", overlap=-5e-6)
    model = leg_model(hyd, np.array([4e6]), np.array([[100.0]]))
    assert model.velocity_at is not None and model.velocity_at[0, np.argmin(np.abs(model.u))] > 0.005
    edges = make_compensator("feedforward", 1, 500.0, model=model)
    one_edge = make_compensator("feedforward", 1, 500.0, model=dataclasses.replace(model, velocity_at=None))
    worst = {"edges": 0.0, "one edge": 0.0}
    for p1 in (3.5e6, 4.5e6):
        for u in (-0.06, -0.04, -0.02, 0.0, 0.02, 0.04, 0.06, 0.5):
            x_v = hydraulics.spool_position(np.array([u]), hyd)
            v = hydraulics.valve_flow(x_v, np.array([p1]), hyd) / hyd.area_bottom
            for label, comp in (("edges", edges), ("one edge", one_edge)):
                worst[label] = max(worst[label], abs(comp.inverse(v, np.array([p1]))[0] - u))
    assert worst["edges"] < 1e-5 and worst["one edge"] > 2e-3, worst
    again = LegModel.from_dict(json.loads(json.dumps(model.to_dict())))
    np.testing.assert_array_equal(again.velocity_at, model.velocity_at)
    old = {k: v for k, v in model.to_dict().items() if k != "velocity_at"}  # a file written before the share
    assert LegModel.from_dict(old).velocity_at is None
    with pytest.raises(SettingsError, match="velocity_at"):
        dataclasses.replace(model, velocity_at=-model.velocity_at - 1e-3)
    assert leg_model(HydraulicParams(flow_area="sharp", overlap=5e-6), np.array([4e6]), np.array([[100.0]])
                     ).velocity_at is None


def test_a_curve_read_from_flows_is_inverted_without_corners_near_null_where_both_edges_are_open():
    """Each edge's curve (flow area "curve") opening 0.3 V before null, its slope doubling at -0.06 V as a curve read
    from the flows had it on the proof's ``underlap`` machine: the leg model inverts it smoothed within 0.5 V of
    null (``hexsim.control.feedforward.rounded_near_null``, a 20 mV Gaussian), its net velocity's slope changing by at
    most 5 % of its largest per 5 mV where the curve's own changes by over 20 %, within 0.5 mm/s of the curve, and
    the curve itself beyond 0.6 V; one that rises steeply where the smoothing ends is still inverted (its velocity
    kept non-decreasing). A curve whose edges open at null (they never pass flow together) is inverted as it is."""
    from hexsim.control.feedforward import leg_model, static_flow_curve
    from hexsim.plant.params import HydraulicParams

    def opening(c: float) -> float:  # 0 at -0.3 V, 0.01 per V up to -0.06 V, 0.02 per V from there
        return 0.01 * (c + 0.3) if c < -0.06 else 0.0024 + 0.02 * (c + 0.06)

    knots = (-0.3, -0.1, -0.08, -0.065, -0.06, -0.055, -0.04, 0.0, 0.2, 0.5)
    edge = tuple((c, opening(c)) for c in knots)
    hyd = HydraulicParams(flow_area="curve", flow_curve_pa=(*edge, (10.0, 0.3)), flow_curve_at=(*edge, (10.0, 0.28)))
    p_rest = np.array([4e6])
    model = leg_model(hyd, p_rest, np.array([[100.0]]))
    curve = static_flow_curve(model.u, p_rest, hyd)
    assert model.velocity_at is not None
    u = np.arange(-0.3, 0.3001, 0.005)

    def corner(v: np.ndarray) -> float:  # the largest change of slope per 5 mV, as a share of the largest slope
        slope = np.diff(np.interp(u, model.u, v)) / 0.005
        return float(np.max(np.abs(np.diff(slope))) / np.max(np.abs(slope)))

    assert corner(curve[0]) > 0.2 and corner(model.velocity[0]) < 0.05, (corner(curve[0]), corner(model.velocity[0]))
    assert np.max(np.abs(model.velocity - curve)) < 5e-4
    far = np.abs(model.u) > 0.6
    np.testing.assert_array_equal(model.velocity[:, far], curve[:, far])
    # an edge that rises steeply right where the smoothing ends (a read curve's kink at 0.5 V): still a curve whose
    # inverse is unique (unguarded, the curve fell at -0.5 V, where the smoothing ends, and the model was refused)
    steep = ((-0.3, 0.0), (-0.06, 0.0024), (0.4, 0.0128), (0.499, 0.01281), (0.502, 0.06), (10.0, 0.3))
    model = leg_model(HydraulicParams(flow_area="curve", flow_curve_pa=steep, flow_curve_at=steep), p_rest,
                      np.array([[100.0]]))
    assert np.all(np.diff(model.velocity) >= 0.0)
    at_null = HydraulicParams(flow_area="curve", flow_curve_pa=((0.0, 0.0), (0.5, 0.05), (10.0, 0.3)),
                              flow_curve_at=((0.0, 0.0), (0.5, 0.05), (10.0, 0.28)))
    model = leg_model(at_null, p_rest, np.array([[100.0]]))
    np.testing.assert_array_equal(model.velocity, static_flow_curve(model.u, p_rest, at_null))


def test_on_an_underlapped_spool_inverting_edge_by_edge_leaves_less_of_the_bump():
    """In the loop of independent_actuator's underlapped "spool" (both edges open 6 µm before null, rounded over
    8 µm: the proof's ``underlap`` machine), the fixed feedforward on the spool's own curve, friction and rest
    pressure: scaling each edge by its own drop (``velocity_at``) leaves at least a quarter less of the reversal bump
    than scaling the net curve by the edge the target opens (measured: 0.0098 against 0.0220 m/s², 2 µm position
    noise; with 5 µm over 30 s, 0.0197 against 0.0224). The edges are read from the spool's own flow (``leg_at``)
    at two pressures."""
    import dataclasses
    import math

    from independent_actuator import _pack, leg_at

    spool = Actuator(area="spool", underlap=6e-6, rounding=8e-6, port_width=0.85, flow_gain=1.04, k_at=0.93,
                     overlap=6e-6, bulk=1.4e9, v_pl=8e-7, mass=42.0, coulomb=(72.0, 58.0), viscous=(2500.0, 1900.0),
                     static=(25.0, 35.0))
    c = _pack(spool)
    a1, a2, y = c[0], c[1], spool.stroke / 2
    p_rest = (spool.supply * a2 + spool.mass * 9.81) / a1
    base = leg_model_of(RunConfig.from_machine(load_machine(None), "actuator"))
    u = base.u

    def net(p1: float) -> np.ndarray:  # the spool's flow into the cap side at p1, as a piston velocity [m/s]
        flow = [leg_at(c, y, 0.0, p1, ui / spool.u_max * spool.x_max, spool.supply)[0] for ui in u]
        return np.array(flow) * (a1 * y + spool.v_pl) / spool.bulk / a1

    dp = 3e5  # v = v_PA sqrt((P_s - P1) / (P_s - P_rest)) - v_AT sqrt(P1 / P_rest), at P_rest and P_rest + dp
    g_s, g_t = math.sqrt(1 - dp / (spool.supply - p_rest)), math.sqrt(1 + dp / p_rest)
    at_rest, above = net(p_rest), net(p_rest + dp)
    v_at = np.maximum((at_rest * g_s - above) / (g_t - g_s), 0.0)
    friction = np.array([p_rest * a1 - spool.supply * a2 - leg_at(c, y, v, p_rest, 0.0, spool.supply)[1]
                         for v in base.friction_v])
    own = dataclasses.replace(base, velocity=at_rest[None, :], p_rest=np.array([p_rest]), friction_f=friction,
                              mass=np.array([[spool.mass]]), area_bottom=a1, bulk_modulus=spool.bulk,
                              pipeline_volume=spool.v_pl, supply_pressure=spool.supply, tank_pressure=0.0)
    assert v_at[np.argmin(np.abs(u))] > 0.005  # both edges pass some 10 mm/s at null
    edges = reversal_peaks(spool, 20.0, in_the_loop("feedforward", dataclasses.replace(own, velocity_at=v_at[None, :])))
    one_edge = reversal_peaks(spool, 20.0, in_the_loop("feedforward", own))
    print(f"edge by edge {edges.mean():.4f} (worst {edges.max():.4f}), one edge {one_edge.mean():.4f} "
          f"({one_edge.max():.4f}) m/s^2")
    assert edges.mean() < 0.75 * one_edge.mean() and edges.max() < one_edge.max()


def test_a_tune_with_no_safe_compensator_names_the_nearest_and_where_it_fails():
    """Where every candidate makes some reversal worse than none on some neighbour, the error says which came
    nearest (the smallest worst reversal), its mean bump against none's and where its worst reversal was: on an
    independent 4-way vertical axis (examples/four_way_axis.py) the bare sentence left the user nothing to act on."""
    from hexsim.studies.tuning import _nearest

    def row(label, neighbour, mean, peaks):
        return {"candidate": label, "motion": "actuator", "neighbour": neighbour, "final_mean_reversal_peak": mean,
                "final_reversal_peaks": peaks}

    none = {("actuator", n): row("none", n, 1.0, [1.0, 1.0]) for n in ("calibrated", "drift")}
    rows = {"none": list(none.values()),
            "feedforward": [row("feedforward", "calibrated", 0.5, [0.4, 0.6]),
                            row("feedforward", "drift", 0.9, [0.5, 1.4])],
            "buffered": [row("buffered", "calibrated", 0.95, [0.9, 1.0]), row("buffered", "drift", 0.97, [1.1, 0.9])]}
    said = _nearest(rows, none)
    assert said.startswith("the nearest, buffered, takes the mean reversal bump to 0.95-0.97x none's"), said
    assert said.endswith("one reversal to 1.10x none's on actuator, drift"), said
