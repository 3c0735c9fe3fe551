"""The hexapod with seed hydraulics: static hold, reversal bumps on heave, fundamental, constraints,
determinism, rotations and file scenarios."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import write_heave_pitch_profile

from hexsim.control.scenario import Scenario, make_scenario
from hexsim.engine.config import RunConfig
from hexsim.engine.runner import simulate
from hexsim.errors import InputError
from hexsim.plant.machine import Machine
from hexsim.signals import fit_fundamental
from hexsim.studies.metrics import STANDARD_GRAVITY, run_smoothness


def test_platform_at_rest_stays_at_rest():
    # Initial P1 per leg from static equilibrium in the neutral pose (MuJoCo statics incl. leg weights).
    hold = Scenario("hold", "hexapod", 2.0, 2, 0.5, 2.0, 0.0)
    r = simulate(RunConfig(hold))
    drift = np.max(np.abs(r.pose[:, :3]))
    assert drift < 0.5e-3
    specific_force = np.linalg.norm(r.acc, axis=1)
    assert np.max(np.abs(specific_force - r.gravity)) < 0.01 * STANDARD_GRAVITY
    assert np.all(np.abs(r.y - 0.1) < 0.5e-3)
    # Six legs share 600 kg + legs: P1 between tank and supply, equal by the three-fold symmetry (rigid statics)
    assert np.ptp(r.p1_initial) / r.p1_initial.mean() < 1e-6


def test_start_from_rigid_statics_is_quiet(heave_run):
    # Issue 14: the legs start at the rigid statics, J^T f = m g with the legs' weight (40.55 bar each), and
    # the platform does not jolt at t = 0: |a - g| over the first 0.5 s below the heave run's noise floor.
    from hexsim.plant.params import HydraulicParams

    hold = simulate(RunConfig(Scenario("hold", "hexapod", 1.0, 2, 0.5, 2.0, 0.0)))
    p = HydraulicParams()
    force = hold.p1_initial * p.area_bottom - p.supply_pressure * p.area_rod
    assert force == pytest.approx(np.full(6, 1246.79), abs=0.01)
    early = hold.t < 0.5
    jolt = np.abs(np.linalg.norm(hold.acc[early], axis=1) - hold.gravity).max()
    assert jolt < run_smoothness(heave_run).noise_floor


def test_payload_shifts_the_static_leg_forces_as_the_jacobian_predicts():
    # A 150 kg payload at (0.25, -0.1, 0.3) m: the change of the legs' static forces solves J^T df = w, the
    # payload's weight as a wrench at the platform frame's origin (J = dy/dpose by finite differences of the IK)
    from hexsim.control.kinematics import HexapodGeometry
    from hexsim.engine.runner import Simulator
    from hexsim.plant.effects import Effects
    from hexsim.plant.model import load_model
    from hexsim.plant.params import HydraulicParams

    hold = Scenario("hold", "hexapod", 1.0, 2, 0.5, 2.0, 0.0)
    mass, at = 150.0, np.array([0.25, -0.1, 0.3])
    p1 = [Simulator(RunConfig(hold, machine=Machine(effects=Effects(payload_kg=kg, payload_at_m=tuple(at))))).p1_initial
          for kg in (0.0, mass)]
    df = (p1[1] - p1[0]) * HydraulicParams().area_bottom
    m = load_model("hexapod")
    geom, g, h = HexapodGeometry.from_model(m), float(np.linalg.norm(m.opt.gravity)), 1e-7
    jac = ((geom.leg_lengths(np.eye(6) * h) - geom.leg_lengths(-np.eye(6) * h)) / (2 * h)).T
    force = np.array([0.0, 0.0, -mass * g])
    wrench = np.concatenate([-force, -np.cross(at, force)])  # what the legs must add to hold it
    assert df == pytest.approx(np.linalg.solve(jac.T, wrench), rel=1e-4, abs=1e-3)


def test_accelerometer_records_are_the_mean_over_each_sample_interval():
    # Issue 14: a 1 kHz record is the mean of the acceleration over the millisecond before it (boxcar
    # anti-alias filter, Δv/Δt), so it equals the mean of ten 10 kHz records, and its fundamental is the
    # 10 kHz reference's (an instantaneous 1 kHz sample locked to the 500 Hz controller aliased by ~1 %).
    sc = make_scenario("heave", duration=6.0)
    fast = simulate(RunConfig(sc, record_rate_hz=10_000.0))
    slow = simulate(RunConfig(sc))
    assert np.array_equal(fast.t[::10], slow.t)
    n = len(slow.t) - 1
    for name in ("acc", "angacc"):  # the accelerometer and the platform's angular acceleration
        blocks = getattr(fast, name)[1:1 + 10 * n].reshape(n, 10, 3)  # records k-9 … k at 10 kHz: steps k-10 … k-1
        np.testing.assert_allclose(getattr(slow, name)[1:], blocks.mean(axis=1), rtol=0, atol=1e-12)
    assert run_smoothness(slow).fundamental_amplitude == pytest.approx(run_smoothness(fast).fundamental_amplitude,
                                                                      rel=1e-3)


def test_heave_shows_reversal_bumps_at_the_reversals(heave_run):
    sm = run_smoothness(heave_run)
    assert sm.reversal_times.size >= 3
    # every bump is within ±50 ms of the platform's velocity reversal and far above the noise floor
    assert np.all(np.abs(sm.reversal_peak_times - sm.reversal_times) <= 0.05)
    assert np.all(sm.reversal_peaks > 5 * sm.noise_floor)
    # and the bump is what dominates the acceleration noise
    assert sm.peak_noise == pytest.approx(sm.reversal_peaks.max())


def test_heave_fundamental_matches_the_commanded_acceleration(heave_run):
    sc = heave_run.config.scenario
    sm = run_smoothness(heave_run)
    w = 2 * math.pi * sc.frequency
    # Physics consistency: the accelerometer's fundamental is w^2 times that of the measured heave (2 %).
    sel = heave_run.t >= sm.window[0]
    _, z_amp, _, _ = fit_fundamental(heave_run.t[sel], heave_run.pose[sel, 2], sc.frequency)
    assert sm.fundamental_amplitude == pytest.approx(w**2 * z_amp, rel=0.02)
    # Against the command A w^2: the P loop tracks with a lag (max error ~5 mm, i.e. 10 % of 0.05 m,
    # mostly phase) and loses a few % of amplitude in the dead band; 5 % covers it.
    assert sm.fundamental_amplitude == pytest.approx(sc.amplitude * w**2, rel=0.05)
    # offset of the accelerometer is gravity (specific force at rest reads +g)
    assert sm.offset == pytest.approx(heave_run.gravity, abs=0.02)


def test_connect_constraints_hold_during_heave(heave_run):
    assert heave_run.constraint_violation.max() < 1e-4
    assert heave_run.saturated_samples == 0


def test_same_seed_gives_identical_runs_and_other_seed_differs():
    sc = Scenario("short", "hexapod", 0.5, 2, 2.0, 0.5, 0.02)
    a = simulate(RunConfig(sc, seed=3))
    b = simulate(RunConfig(sc, seed=3))
    c = simulate(RunConfig(sc, seed=4))
    for name in ("y", "p1", "u_v", "acc", "pose"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert not np.array_equal(a.u_v, c.u_v)


def test_roll_reversal_bumps_on_angular_acceleration():
    r = simulate(RunConfig(make_scenario("roll", frequency=1.0, duration=4.0)))
    sm = run_smoothness(r)
    assert sm.unit == "rad/s^2" and sm.peak_noise_g is None
    w = 2 * math.pi
    assert sm.fundamental_amplitude == pytest.approx(math.radians(5) * w**2, rel=0.10)
    assert sm.reversal_peaks.size >= 1 and np.all(sm.reversal_peaks > 3 * sm.noise_floor)
    assert r.constraint_violation.max() < 1e-4


def test_file_scenario_heave_plus_pitch(tmp_path):
    path = write_heave_pitch_profile(tmp_path / "profile.csv", 6.0, 0.03)
    sc = make_scenario(f"file:{path}")
    assert sc.axis_name == "z" and sc.frequency == pytest.approx(0.5, rel=0.02)  # the fade-in bends the fit
    r = simulate(RunConfig(sc))
    # the 2° pitch at 1.3 Hz rides on the heave: small leg motions sit in the flat zone of the flow curve,
    # so the P loop lags; its amplitude is still followed within 25 %
    sel = r.t > 2.0
    _, pitch_amp, _, _ = fit_fundamental(r.t[sel], r.pose[sel, 4], 1.3)
    assert pitch_amp == pytest.approx(math.radians(2), rel=0.25)
    sm = run_smoothness(r)
    assert sm.fundamental_amplitude == pytest.approx(0.03 * (2 * np.pi * 0.5) ** 2, rel=0.1)


def test_scenario_options_are_checked():
    with pytest.raises(InputError, match="Nyquist"):
        make_scenario("heave", frequency=300.0)
    with pytest.raises(InputError, match="too short"):
        make_scenario("heave", duration=2.0)
    with pytest.raises(InputError, match="unknown scenario"):
        make_scenario("bounce")


def test_non_finite_state_raises_naming_time_and_leg(monkeypatch):
    from hexsim.engine import config
    from hexsim.errors import PhysicsError

    real = config.advance_legs

    def poisoned(*args, **kwargs):
        state, force = real(*args, **kwargs)
        state.p1[2] = np.nan  # leg3's chamber pressure goes bad
        return state, force

    monkeypatch.setattr(config, "advance_legs", poisoned)
    with pytest.raises(PhysicsError, match=r"non-finite P1 of leg3 at t = 0\.\d+ s"):
        simulate(RunConfig(Scenario("short", "hexapod", 0.1, 2, 2.0, 0.5, 0.02), engine="python"))


def test_native_engine_raises_on_a_non_finite_state_naming_time_and_leg(monkeypatch):
    from hexsim.engine import config
    from hexsim.errors import PhysicsError

    real = config.leg_table

    def poisoned(*args):
        table = real(*args)
        table["bulk_modulus"] = np.nan  # every P1 goes bad in the first step
        return table

    monkeypatch.setattr(config, "leg_table", poisoned)
    with pytest.raises(PhysicsError, match=r"non-finite P1 of leg1 at t = 0\.0000 s"):
        simulate(RunConfig(Scenario("short", "hexapod", 0.1, 2, 2.0, 0.5, 0.02)))


def test_island_discovery_off_changes_nothing(monkeypatch):
    """hexsim switches MuJoCo's island discovery off (hexsim.plant.model.no_islands) for speed; the hexapod is
    one island (either formulation), so the run must be bit-identical to one with discovery on."""
    import mujoco

    from hexsim.engine import runner
    from hexsim.plant import model

    def discovering(name, formulation="full", effects=None, geometry=None, stroke_m=None):
        m = model.load_model(name, formulation, effects, geometry, stroke_m)
        m.opt.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_ISLAND)
        return m

    for formulation in model.FORMULATIONS:
        config = RunConfig(make_scenario("heave", duration=1.5, frequency=2.0), compensator="buffered", seed=2,
                           model=formulation)
        monkeypatch.undo()
        off = simulate(config)
        assert mujoco.mjtDisableBit.mjDSBL_ISLAND & runner.load_model("hexapod", formulation).opt.disableflags
        monkeypatch.setattr(runner, "load_model", discovering)
        on = simulate(config)
        for name in ("y", "p1", "u_c", "acc", "pose"):
            np.testing.assert_array_equal(getattr(off, name), getattr(on, name), err_msg=f"{formulation} {name}")


def test_one_leg_may_differ_from_the_others():
    """LegChange: the same change on every leg is the global effect, bit for bit; on one leg it moves that
    leg most; both engines agree; shared or unknown fields and legs the model lacks are refused."""
    from hexsim.plant.effects import Effects, LegChange

    sc = make_scenario("heave", duration=1.5, frequency=2.0)
    every = simulate(RunConfig(sc, machine=Machine(effects=Effects(leakage=3e-12)), seed=1))
    each = simulate(RunConfig(sc, leg_changes=tuple(LegChange.of(i, leakage=3e-12) for i in range(1, 7)), seed=1))
    assert np.array_equal(every.p1, each.p1) and np.array_equal(every.y, each.y)
    nominal = simulate(RunConfig(sc, seed=1))
    one = RunConfig(sc, leg_changes=(LegChange.of(3, leakage=3e-12),), seed=1)
    leg3 = simulate(one)
    moved = np.abs(leg3.y - nominal.y).max(axis=0)
    assert np.argmax(moved) == 2 and moved[2] > 5 * np.delete(moved, 2).max()
    python = simulate(RunConfig(sc, leg_changes=one.leg_changes, seed=1, engine="python"))
    assert np.allclose(python.y, leg3.y, atol=1e-9)
    for bad in ({"supply_pressure": 6e6}, {"bore": 0.1}):
        with pytest.raises(InputError, match="leg3"):
            LegChange.of(3, **bad)
    with pytest.raises(InputError, match="leg7"):
        simulate(RunConfig(sc, leg_changes=(LegChange.of(7, leakage=1e-12),)))


def test_oil_spring_modes_of_the_600_kg_platform():
    # Issue 14: hand-computed 27.8/27.8/31.8/42.2/42.2/55.2 Hz (platform, E A1^2 / V1 per leg at mid-stroke)
    from hexsim.studies.modes import oil_spring_modes

    modes = oil_spring_modes()
    np.testing.assert_allclose([mode.frequency_hz for mode in modes], [27.8, 27.8, 31.8, 42.2, 42.2, 55.2], rtol=0.02)
    assert {modes[0].dominant, modes[1].dominant} == {"surge", "sway"}
    assert modes[2].dominant == "yaw" and modes[5].dominant == "heave"
    assert {modes[3].dominant, modes[4].dominant} == {"roll", "pitch"}
