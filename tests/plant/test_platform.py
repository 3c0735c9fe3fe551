"""The platform-only formulation (hexsim.plant.platform) against the full multi-body model it is built from.

The two differ only where the platform-only model simplifies: the legs' inertia across the leg (a point
mass of the rod's 2.5 kg at the anchor where the swinging leg has I_pivot/L² = 2.25…2.77 kg over the
stroke), the swinging legs' Coriolis and centripetal forces, and the full model's compliant connects
(0.5 ms time constant). Measured on these runs (6 s, 1 Hz): pose within 4e-8 m / 2e-8 rad, acceleration
rms difference 0.006 % of the fundamental, reversal peaks within 0.02 %, P1 within 0.001 bar. The
tolerances below are 10-25 times those, far below anything the metrics resolve (the sensor noise alone
moves a reversal peak by ~1 %), yet a missing leg-weight correction (2 % on the buffered peaks) or
massless legs (8 %) fail them.
"""

import dataclasses

import mujoco
import numpy as np
import pytest
from helpers import write_heave_pitch_profile

from hexsim.control.kinematics import HexapodGeometry
from hexsim.control.scenario import Scenario, make_scenario
from hexsim.engine.config import RunConfig, static_leg_forces
from hexsim.engine.runner import simulate
from hexsim.plant.faults import Fault
from hexsim.plant.model import PlantIndex, load_model, reset_neutral
from hexsim.studies.metrics import run_smoothness


def _statics(formulation: str, legs=None) -> np.ndarray:
    m = load_model("hexapod", formulation)
    idx = PlantIndex.from_model(m)
    if legs is not None:
        idx = dataclasses.replace(idx, legs=legs(idx.legs))
    d = mujoco.MjData(m)
    reset_neutral(m, d)
    return static_leg_forces(m, d, idx)


def test_the_platform_model_is_built_from_the_full_models_geometry():
    full, platform = load_model("hexapod", "full"), load_model("hexapod", "platform")
    assert platform.nbody == 2 and platform.nq == 7 and platform.neq == 0 and platform.nu == 0
    rods = [mujoco.mj_name2id(full, mujoco.mjtObj.mjOBJ_BODY, f"rod{i + 1}") for i in range(6)]
    plat = mujoco.mj_name2id(full, mujoco.mjtObj.mjOBJ_BODY, "platform")
    assert platform.body_mass[1] == pytest.approx(full.body_mass[plat] + full.body_mass[rods].sum(), rel=1e-12)
    a, b = HexapodGeometry.from_model(full), HexapodGeometry.from_model(platform)
    for name in ("base", "platform", "neutral_position", "l_min", "stroke"):
        np.testing.assert_allclose(getattr(b, name), getattr(a, name), rtol=0, atol=1e-12, err_msg=name)
    np.testing.assert_allclose(PlantIndex.from_model(platform).neutral_y, PlantIndex.from_model(full).neutral_y,
                               atol=1e-12)


def test_static_leg_forces_equal_the_full_models_and_need_the_leg_weight_correction():
    full, platform = _statics("full"), _statics("platform")
    np.testing.assert_allclose(platform, full, rtol=1e-8)
    # without the correction (the platform carries only the lumped rods) the legs hold a different load
    lumped_only = _statics("platform", lambda g: g._replace(s0=g.lumped * g.l_min[0]))  # S/L = m_r: no correction
    assert np.max(np.abs(lumped_only - full)) > 1.0


def _combined(tmp_path_factory):
    path = write_heave_pitch_profile(tmp_path_factory.mktemp("platform") / "heave_pitch.csv", 8.0, 0.04)
    return Scenario.from_file(path)


CASES = {
    "heave": (lambda tmp: make_scenario("heave", duration=6.0, frequency=1.0), "none"),
    "heave buffered": (lambda tmp: make_scenario("heave", duration=6.0, frequency=1.0), "buffered"),
    "roll buffered": (lambda tmp: make_scenario("roll", duration=6.0, frequency=1.0), "buffered"),
    "heave + pitch file": (_combined, "buffered"),
}


@pytest.mark.parametrize("case", CASES)
def test_the_platform_model_reproduces_the_full_model(case, tmp_path_factory):
    make, compensator = CASES[case]
    scenario = make(tmp_path_factory)
    full = simulate(RunConfig(scenario, compensator=compensator, model="full"))
    platform = simulate(RunConfig(scenario, compensator=compensator, model="platform"))
    assert np.max(np.abs(platform.pose - full.pose)) < 1e-6  # m and rad
    assert np.max(np.abs(platform.p1 - full.p1)) < 0.05e5  # Pa
    sm_full, sm_platform = run_smoothness(full), run_smoothness(platform)
    for signal in ("acc", "angacc"):
        diff = getattr(platform, signal) - getattr(full, signal)
        scale = np.ptp(getattr(full, signal), axis=0).max()
        assert np.sqrt(np.mean(diff**2)) < 1e-3 * scale, signal
    assert sm_platform.reversal_peaks.size == sm_full.reversal_peaks.size > 0
    np.testing.assert_allclose(sm_platform.reversal_peaks, sm_full.reversal_peaks, rtol=5e-3)
    assert sm_platform.noise_ratio == pytest.approx(sm_full.noise_ratio, rel=5e-3)


def test_the_platform_model_has_no_constraints_so_their_pipeline_is_off(monkeypatch):
    """hexsim switches MuJoCo's constraint pipeline off on the platform-only model (its end stops are
    forces, contacts are off, there are no joints with limits and no equalities): a run with it on
    again, end stop hit included, is the same to the bit."""
    from hexsim.engine import runner
    from hexsim.plant import model

    m = load_model("hexapod", "platform")
    assert m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    assert m.neq == 0 and m.ngeom == 0 and not m.jnt_limited.any() and m.njnt == 1

    def constrained(name, formulation="full", effects=None, geometry=None, stroke_m=None):
        m = model.load_model(name, formulation, effects, geometry, stroke_m)
        m.opt.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
        return m

    config = RunConfig(make_scenario("heave", duration=1.5, frequency=2.0), compensator="buffered",
                       faults=(Fault.parse("end_stop:leg=4,t=0.8"),))
    off = simulate(config)
    assert off.y[:, 3].max() > 0.2  # leg 4 runs into its end stop
    monkeypatch.setattr(runner, "load_model", constrained)
    on = simulate(config)
    for name in ("y", "p1", "u_c", "acc", "pose"):
        np.testing.assert_array_equal(getattr(off, name), getattr(on, name), err_msg=name)


def test_both_engines_step_the_platform_model_alike():
    scenario = make_scenario("heave", duration=2.0, frequency=2.0)
    native = simulate(RunConfig(scenario, compensator="buffered", model="platform"))
    python = simulate(RunConfig(scenario, compensator="buffered", model="platform", engine="python"))
    for name in ("y", "ydot", "p1", "force", "acc", "u_v"):
        np.testing.assert_array_equal(getattr(python, name), getattr(native, name), err_msg=name)


@pytest.mark.parametrize("fault", ["end_stop:leg=4,t=0.8", "valve_stuck:leg=2,t=0.8,value=-3"])
def test_end_stops_hold_like_the_full_models(fault):
    """The full model's piston limits (soft constraints, 4 ms) hold the piston within 3.3 mm past the
    stroke in these faults; the platform-only model's spring-dampers (the same time constant on the legs'
    effective mass) within 2 mm: both within the fault tests' 10 mm, and both stop the piston there."""
    scenario = make_scenario("heave", duration=2.0, frequency=2.0)
    for model in ("full", "platform"):
        r = simulate(RunConfig(scenario, faults=(Fault.parse(fault),), model=model))
        lo, hi = r.stroke[0]
        past = max(lo - r.y.min(), r.y.max() - hi)
        assert 0.0 < past < 0.005, (model, past)
        assert np.all(np.isfinite(r.acc))
